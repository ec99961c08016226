"""Confidence intervals of the estimates that hold under model mismatch, not only under noise.

Three parts, combined as standard deviations:

1. the fit's curvature, made robust to the residual's structure: a block sandwich
   (cluster-robust) covariance (J^T J)^-1 (sum over blocks b of J_b^T r_b r_b^T J_b) (J^T J)^-1
   with blocks of `fit.BLOCK_SECONDS`. The residuals are correlated in time (the
   smoothing, stick-slip, the motion itself); the plain curvature covariance s^2 (J^T J)^-1
   (`mujoco.sysid.calculate_intervals`, kept for comparison as `curvature_half_widths`)
   assumes they are not, and its 95 % intervals cover the truth far less often
   (`benchmarks/calibration.py` measures both);
2. the parameters fixed at nominal (`identifiability.FIXED`): the rotor's inertia
   within its tolerance moves every torque-scaled estimate by up to
   Jm tolerance x Jm / (Jr + Jm) (uniform);
3. what remains of the estimation error's bias (the velocity estimate's smoothing,
   MuJoCo-free but not error-free): the covariance is scaled by `INFLATION`, a factor
   calibrated on the substitute against known plants (see its note).

The 95 % half-width is 1.96 times the combined standard deviation, and never less
than the parameter's tolerances (`identifiability.Fitted`).
"""

from __future__ import annotations

import math

import numpy as np
from mujoco import sysid

from qube_suite import parameters
from qube_suite.calibration.fit import NAMES, SCALES, FitResult
from qube_suite.calibration.identifiability import FITTED, FIXED, OFFSETS, TORQUE_SCALED

Z95 = 1.959963984540054
"""Two-sided 95 % quantile of the normal distribution."""

INFLATION = 2.0
"""Scale of the block-sandwich standard deviations. Calibrated on the substitute: refitting
`benchmarks/calibration.py --calibrate-intervals` plants (not those the benchmark validates on)
and taking the factor that makes 95 % of the (plant, parameter) errors fall within the intervals."""


def curvature_half_widths(result: FitResult) -> np.ndarray:
    """95 % half-widths (scaled unknowns) from the fit's curvature alone (`mujoco.sysid`)."""
    jacobian = result.jacobian()
    _, half_widths = sysid.calculate_intervals([result.residual(result.x)], jacobian)
    return np.asarray(half_widths)


def block_covariance(result: FitResult) -> np.ndarray:
    """Block-sandwich covariance of the scaled unknowns (see the module)."""
    jacobian = result.jacobian()
    residual = result.residual(result.x)
    blocks = result.blocks()
    bread = np.linalg.pinv(jacobian.T @ jacobian)
    meat = np.zeros_like(bread)
    for block in np.unique(blocks):
        score = jacobian[blocks == block].T @ residual[blocks == block]
        meat += np.outer(score, score)
    return bread @ meat @ bread


def fixed_parameter_std(values: dict[str, float]) -> dict[str, float]:
    """Standard deviation (in each unit) that the fixed parameters' tolerances add to each estimate."""
    nominal = parameters.NOMINAL
    arm_axis = parameters.arm_inertia(nominal["arm_mass"], nominal["arm_length"]) + nominal["rotor_inertia"]
    relative = FIXED["rotor_inertia"] * nominal["rotor_inertia"] / arm_axis / math.sqrt(3.0)
    return {name: relative * abs(values[name]) if name in TORQUE_SCALED else 0.0 for name in values}


def standard_deviations(result: FitResult, inflation: float = INFLATION) -> dict[str, tuple[float, float]]:
    """(statistical, fixed-parameter) standard deviation of every unknown by name, in its unit: the
    block sandwich's times `inflation`, and the fixed parameters' (see the module)."""
    statistical = np.sqrt(np.maximum(np.diag(block_covariance(result)), 0.0)) * SCALES * inflation
    fixed = fixed_parameter_std(result.values)
    return {name: (float(sigma), fixed[name]) for name, sigma in zip(NAMES, statistical, strict=True)}


def half_width(name: str, value: float, statistical: float, fixed: float) -> float:
    """95 % half-width of unknown `name` estimated at `value` from its two standard deviations (see
    the module)."""
    quantity = QUANTITIES[name]
    return max(Z95 * math.hypot(statistical, fixed), quantity.absolute_tolerance,
               quantity.relative_tolerance * abs(value))


QUANTITIES = {q.name: q for q in FITTED + OFFSETS}


def intervals(result: FitResult) -> dict[str, tuple[float, float]]:
    """95 % interval (low, high) of every unknown by name, in its unit (see the module)."""
    values = result.values
    found = {}
    for name, (statistical, fixed) in standard_deviations(result).items():
        half = half_width(name, values[name], statistical, fixed)
        low = values[name] - half
        if name in parameters.PARAMETERS:
            low = max(low, 0.0)
        found[name] = (low, values[name] + half)
    return found
