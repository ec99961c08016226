"""Confidence intervals of the estimates that hold under model mismatch, not only under noise.

The 95 % half-width of an estimate is the sum of three parts, and never less than its
tolerances (`identifiability.Fitted`):

1. statistical: 1.96 standard deviations of a block sandwich (cluster-robust)
   covariance, (J^T J)^-1 (sum over blocks b of J_b^T r_b r_b^T J_b) (J^T J)^-1 with
   blocks of `fit.BLOCK_SECONDS`, times `INFLATION`. The residuals are correlated in
   time (the smoothing, stick-slip, the motion itself); the plain curvature
   covariance s^2 (J^T J)^-1 (`mujoco.sysid.calculate_intervals`, kept for comparison
   as `curvature_half_widths`) assumes they are not, and its 95 % intervals contain
   the truth for 41 % of (plant, parameter) pairs (`benchmarks/calibration.py`);
2. the fixed parameters (`identifiability.FIXED`): the rotor's inertia anywhere
   within its tolerance moves every torque-scaled estimate by up to
   tolerance x Jm / (Jr + Jm), 2 % (a bound, not a spread: added in full);
3. the fit's own bias (`bias_bound`), measured on the substitute against known plants:
   what the velocity estimate leaves in the weak-form equations.
"""

from __future__ import annotations

import numpy as np

from qube_suite.calibration.fit import NAMES, SCALES, VOLTAGE_ONLY, FitResult
from qube_suite.calibration.identifiability import FITTED, FIXED, OFFSETS, TORQUE_SCALED, Fitted
from qube_suite.devices.qube import parameters

Z95 = 1.959963984540054
"""Two-sided 95 % quantile of the normal distribution."""

INFLATION = 2.0
"""Scale of the block-sandwich standard deviations. On the substitute, whose current sensor and
encoders add no noise beyond quantisation, the statistical part is small and the bounds below
dominate; the factor 2 keeps room for a real Qube's noise, which this part grows with."""

TORQUE_SCALE_BIAS = 0.017
"""Bound on the fit's own relative bias of every torque-scaled estimate. With the rotor's effect
removed, kt / (Jr + Jm) came out 0.65 to 1.63 % high on the plants of
`benchmarks/calibration.py --calibrate-intervals --plants 8 --seed 100` (not those the benchmark
validates on): what the smoothed velocities leave in the weak-form equations."""
PENDULUM_MASS_BIAS = 0.01
"""Bound on the further relative bias of the pendulum's mass: relative to kt it came out 0.28 to
0.93 % high on the same plants."""


def bias_bound(name: str) -> float:
    """Bound on the fit's own relative bias of unknown `name` (see the two above)."""
    if name not in TORQUE_SCALED:
        return 0.0
    return TORQUE_SCALE_BIAS + (PENDULUM_MASS_BIAS if name == "pendulum_mass" else 0.0)


def curvature_half_widths(result: FitResult) -> np.ndarray:
    """95 % half-widths (scaled unknowns) from the fit's curvature alone (`mujoco.sysid`, which needs
    MuJoCo's `sysid` extra: `pip install 'qube_suite[sysid]'`)."""
    from mujoco import sysid

    if not hasattr(sysid, "calculate_intervals"):  # the module is there, its dependencies are not
        raise ImportError("curvature intervals need mujoco.sysid's dependencies: "
                          "pip install 'qube_suite[sysid]'")
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


def fixed_parameter_bounds(values: dict[str, float]) -> dict[str, float]:
    """How far (in each unit) the fixed parameters' tolerances can move each estimate."""
    nominal = parameters.NOMINAL
    arm_axis = parameters.arm_inertia(nominal["arm_mass"], nominal["arm_length"]) + nominal["rotor_inertia"]
    relative = FIXED["rotor_inertia"] * nominal["rotor_inertia"] / arm_axis
    return {name: relative * abs(values[name]) if name in TORQUE_SCALED else 0.0 for name in values}


def standard_deviations(result: FitResult, inflation: float = INFLATION) -> dict[str, float]:
    """Statistical standard deviation of every unknown by name, in its unit: the block sandwich's
    times `inflation` (see the module)."""
    statistical = np.sqrt(np.maximum(np.diag(block_covariance(result)), 0.0)) * SCALES * inflation
    return {name: float(sigma) for name, sigma in zip(NAMES, statistical, strict=True)}


def half_width(name: str, value: float, statistical: float, fixed: float) -> float:
    """95 % half-width of unknown `name` estimated at `value`, from its statistical standard deviation
    and how far the fixed parameters can move it (see the module)."""
    quantity = QUANTITIES[name]
    return max(Z95 * statistical + fixed + bias_bound(name) * abs(value), quantity.absolute_tolerance,
               quantity.relative_tolerance * abs(value))


QUANTITIES = {q.name: q for q in FITTED + OFFSETS}


def intervals(result: FitResult) -> dict[str, tuple[float, float]]:
    """95 % interval (low, high) of every unknown by name, in its unit (see the module)."""
    values = result.values
    fixed = fixed_parameter_bounds(values)
    found = {}
    for name, statistical in standard_deviations(result).items():
        half = half_width(name, values[name], statistical, fixed[name])
        low = values[name] - half
        if name in parameters.PARAMETERS:
            low = max(low, 0.0)
        found[name] = (low, values[name] + half)
    return found


def voltage_only_intervals(result) -> dict[str, tuple[float, float]]:
    """95 % interval (low, high) of every unknown of a voltage-only fit (`fit.VoltageFitResult`), in
    its unit (`statistical_intervals`). No bias bound: there is no known plant to measure one against;
    the benchmark (`benchmarks/real_qube.py`) compares these widths with the spread of per-recording
    calibrations."""
    return statistical_intervals(result, VOLTAGE_ONLY)


def statistical_intervals(result, quantities: tuple[Fitted, ...]) -> dict[str, tuple[float, float]]:
    """95 % interval (low, high) of every unknown of `result` (a fit result with `names`, `scales`,
    `values`), in its unit: 1.96 block-sandwich standard deviations times `INFLATION`, never narrower
    than the unknown's tolerance (its `quantities` entry); parameters never below 0."""
    sigma = np.sqrt(np.maximum(np.diag(block_covariance(result)), 0.0)) * result.scales * INFLATION
    by_name = {q.name: q for q in quantities}
    found = {}
    for name, value in result.values.items():
        quantity = by_name[name]
        half = max(Z95 * float(sigma[result.names.index(name)]), quantity.absolute_tolerance,
                   quantity.relative_tolerance * abs(value))
        low = max(value - half, 0.0) if not name.endswith("offset") else value - half
        found[name] = (low, value + half)
    return found
