"""The fit: the Qube's equations of motion and its motor circuit against the measured signals.

An equation-error (inverse-dynamics) fit. The motor circuit must hold at every sample,

    V(k - 1 - d) = Rm i(k) + km theta'(k)          (d: latency in samples; the current read at
                                                    sample k answers the voltage of the interval before)

and each joint's momentum balance dp/dt = torque over every window of `INTERVAL`
samples (0.2 s), in its weak form: multiplied by w(t) = sin^2(pi t / T), which is 0
at both ends, and integrated by parts,

    integral of (w torque + w' p) dt = 0,
    arm:       p = M11 theta' + M12 alpha',
               torque = kt i - Dr theta' - Fr sign(theta') - kc theta + arm_torque_offset
    pendulum:  p = M12 theta' + M22 alpha',
               torque = K s c theta'^2 + mp Lr l s theta' alpha' + mp g l s - Dp alpha' - Fp sign(alpha')

with s, c of alpha + pendulum_encoder_offset and the coefficients of `baselines.model`
(the rigid-body model of `assets/qube.xml`). The weak form needs the angles' first
derivative only, and only under an integral against a smooth weight: the smoothing
filter's error on fast motion (its velocities are off by 0.05 rad/s RMS on the
substitute) averages out instead of biasing the estimates, as accelerations from a
double derivative or momenta at window ends did (pendulum mass 4 to 10 % low on the
default substitute, against 1 % now). The motor torque is kt times the current read
at the end of each sample interval. Coulomb friction is exact: a window enters a
joint's equation only if the joint slides throughout (speed above `SLIDING_SPEED`),
so the fit never models sticking.

The residuals, weighted by each equation's own spread, are minimised over the
unknowns scaled near 1 (`identifiability.FITTED`, `OFFSETS`) by
`mujoco.minimize.least_squares` (Gauss-Newton / Levenberg-Marquardt with box
bounds); the latency d is the integer that best explains the current.

Why equation error rather than fitting MuJoCo rollouts to the angles (output error,
`mujoco.sysid`'s rollout residuals): the residual is an explicit function of the
parameters, so the fit takes about a second and can neither be trapped by the
pendulum's chaos at large swings nor biased by MuJoCo's Coulomb friction, which
is soft where the Qube's is not. MuJoCo rollouts then judge the fitted model:
`prediction` (0.5 s-ahead predictions on held-out segments).
"""

from __future__ import annotations

import dataclasses
import math

import mujoco.minimize
import numpy as np
from scipy.ndimage import minimum_filter1d

from qube_suite import parameters
from qube_suite.calibration.identifiability import FITTED, OFFSETS
from qube_suite.calibration.measurements import SMOOTHING_WINDOW, Measurements

SLIDING_SPEED = 0.05
"""A joint counts as sliding where its speed stays above this (rad/s) across the smoothing window."""
MAX_LATENCY = 3
"""Largest latency (samples) the fit considers."""

NAMES = tuple(q.name for q in FITTED + OFFSETS)
"""Names of the fit's unknowns, in order."""
SCALES = np.array([q.scale for q in FITTED + OFFSETS])
"""Scale of each unknown: the fit works on value / scale."""
_POSITIVE = ("motor_resistance", "motor_back_emf", "motor_torque_constant", "pendulum_mass",
             "pendulum_length")
LOWER = np.array([0.3 if name in _POSITIVE else (-30.0 if name.endswith("offset") else 0.0)
                  for name in NAMES])
UPPER = np.array([3.0 if name in _POSITIVE else 30.0 for name in NAMES])
"""Bounds of the scaled unknowns: physical parameters within 0.3 to 3 times nominal, friction-like
ones within 0 and 30 times their scale, offsets within +-30 times theirs."""


INTERVAL = 50
"""Samples per momentum-balance window (0.2 s at 250 Hz)."""
BLOCK_SECONDS = 2.0
"""Length of the blocks the residuals are grouped in for the intervals (s): longer than their
correlation."""


@dataclasses.dataclass(frozen=True)
class Signals:
    """The fit's inputs for one latency: per-sample arrays over the whole recording, and which samples
    and intervals the fit uses."""

    theta: np.ndarray
    alpha: np.ndarray
    dtheta: np.ndarray
    dalpha: np.ndarray
    current: np.ndarray
    """Current read at each sample (A)."""
    current_after: np.ndarray
    """Current read at the next sample (A): the current of the interval that starts at each sample."""
    voltage_before: np.ndarray
    """Voltage that acted in the interval before each sample, latency taken into account (V)."""
    rows: np.ndarray
    """Samples whose motor-circuit equation the fit uses."""
    starts: np.ndarray
    """First samples of the momentum-balance intervals the fit may use."""
    arm_sliding: np.ndarray
    """For each interval: whether the arm slides throughout (its friction torque is then known)."""
    pendulum_sliding: np.ndarray
    """For each interval: whether the pendulum slides throughout."""
    block: np.ndarray
    """Block (`BLOCK_SECONDS` long) of each sample."""
    sample_time: float


def signals(measurements: Measurements, latency: int, samples: np.ndarray | None = None) -> Signals:
    """The fit's inputs from `measurements` for `latency` (samples), using only the sample indices
    `samples` (None: all; the filter's edges and the first samples are never used)."""
    theta, dtheta = measurements.derivatives(measurements.theta)
    alpha, dalpha = measurements.derivatives(measurements.alpha)
    current = measurements.current
    shift = 1 + latency
    voltage_before = np.concatenate([np.zeros(shift), measurements.voltage[:-shift]])
    n = len(measurements)
    usable = np.zeros(n, dtype=bool)
    usable[max(SMOOTHING_WINDOW, MAX_LATENCY + 1):n - SMOOTHING_WINDOW] = True
    if samples is not None:
        chosen = np.zeros_like(usable)
        chosen[samples] = True
        usable &= chosen
    starts = np.arange(0, n - INTERVAL, INTERVAL // 2)
    whole = minimum_filter1d(usable.astype(float), INTERVAL + 1, origin=-(INTERVAL // 2))[starts] > 0
    starts = starts[whole]

    def sliding(speed: np.ndarray) -> np.ndarray:
        slow = minimum_filter1d(np.abs(speed), INTERVAL + 1 + 2 * SMOOTHING_WINDOW,
                                origin=-(INTERVAL // 2)) > SLIDING_SPEED
        return slow[starts]

    return Signals(theta=theta, alpha=alpha, dtheta=dtheta, dalpha=dalpha, current=current,
                   current_after=np.append(current[1:], current[-1]), voltage_before=voltage_before,
                   rows=np.flatnonzero(usable), starts=starts, arm_sliding=sliding(dtheta),
                   pendulum_sliding=sliding(dalpha), block=(measurements.time / BLOCK_SECONDS).astype(int),
                   sample_time=measurements.sample_time)


def physical(x: np.ndarray) -> dict[str, np.ndarray]:
    """The unknowns by name from scaled `x` (shape (n,) or (n, k))."""
    values = x * (SCALES if x.ndim == 1 else SCALES[:, None])
    return dict(zip(NAMES, values, strict=True))


def equations(x: np.ndarray, s: Signals) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Residuals of the motor circuit (V, per sample), the arm's and the pendulum's momentum
    balance (N m s, per interval in which the joint slides) at scaled unknowns `x` (n,) or a
    batch (n, k): arrays (rows[, k])."""
    p = physical(x)
    column = (lambda a: a[:, None]) if x.ndim > 1 else (lambda a: a)
    th, dth, dal = column(s.theta), column(s.dtheta), column(s.dalpha)
    al = column(s.alpha) + p["pendulum_encoder_offset"]
    sin, cos = np.sin(al), np.cos(al)
    mp, lp = p["pendulum_mass"], p["pendulum_length"]
    lr = parameters.NOMINAL["arm_length"]
    half = 0.5 * lp
    axial = 0.5 * mp * parameters.PENDULUM_ROD_RADIUS**2
    transverse = mp * lp * lp / 12.0
    base = (parameters.arm_inertia(parameters.NOMINAL["arm_mass"], lr) + parameters.NOMINAL["rotor_inertia"]
            + mp * lr * lr + axial)
    swing = mp * half * half + transverse - axial
    coupling = mp * lr * half
    m22 = mp * half * half + transverse
    m12 = -coupling * cos
    rows = s.rows
    circuit = (column(s.voltage_before[rows]) - p["motor_resistance"] * column(s.current[rows])
               - p["motor_back_emf"] * dth[rows])
    arm_momentum = (base + swing * sin * sin) * dth + m12 * dal
    pendulum_momentum = m12 * dth + m22 * dal
    motor_torque = p["motor_torque_constant"] * column(s.current_after)
    arm_torque = (-p["arm_damping"] * dth - p["arm_friction"] * np.sign(dth)
                  - p["cable_stiffness"] * th + p["arm_torque_offset"])
    pendulum_torque = (swing * sin * cos * dth * dth + coupling * sin * dth * dal
                       + mp * parameters.NOMINAL["gravity"] * half * sin
                       - p["pendulum_damping"] * dal - p["pendulum_friction"] * np.sign(dal))
    arm = _balance(arm_momentum, arm_torque, motor_torque, s.starts[s.arm_sliding],
                   s.sample_time)
    pendulum = _balance(pendulum_momentum, pendulum_torque, 0.0, s.starts[s.pendulum_sliding], s.sample_time)
    return circuit, arm, pendulum


def _balance(momentum: np.ndarray, state_torque: np.ndarray, input_torque: np.ndarray | float,
             starts: np.ndarray, h: float) -> np.ndarray:
    """The momentum balance dp/dt = torque over each window [start, start + INTERVAL], weighted
    by w(t) = sin^2(pi t / T) and integrated by parts (w is 0 at both ends):
    integral of (w torque + w' p) dt = 0. `state_torque` is a function of the state at each
    sample, `input_torque` is held over each sample interval (the motor's, from the current read
    at its end). Smooth w' makes the smoothed velocities' high-frequency error average out."""
    phase = np.pi * np.arange(INTERVAL + 1) / INTERVAL
    weight, slope = np.sin(phase) ** 2, np.sin(2.0 * phase) * np.pi / (INTERVAL * h)
    middle = np.sin(phase[:-1] + 0.5 * np.pi / INTERVAL) ** 2
    window = starts[:, None] + np.arange(INTERVAL + 1)
    shape = (1, -1) + (1,) * (momentum.ndim - 1)
    total = np.sum(weight.reshape(shape) * state_torque[window] + slope.reshape(shape) * momentum[window],
                   axis=1)
    if isinstance(input_torque, np.ndarray):
        total += np.sum(middle.reshape(shape) * input_torque[window[:, :-1]], axis=1)
    return total * h


@dataclasses.dataclass(frozen=True)
class FitResult:
    """The scaled estimate, the latency, the weights and the data it was fitted on."""

    x: np.ndarray
    latency: int
    weights: tuple[float, float, float]
    """1 / spread of the circuit (V), arm (N m) and pendulum (N m) residuals at the estimate."""
    signals: Signals

    @property
    def values(self) -> dict[str, float]:
        """The estimates by name, in their units."""
        return {name: float(value) for name, value in physical(self.x).items()}

    def residual(self, x: np.ndarray) -> np.ndarray:
        """Weighted residual vector at scaled `x` (n,) or (n, k)."""
        return weighted_residual(x, self.signals, self.weights)

    def jacobian(self) -> np.ndarray:
        """Jacobian of the weighted residual with respect to the scaled unknowns at the estimate."""
        r = self.residual(self.x)
        jacobian, _ = mujoco.minimize.jacobian_fd(
            residual=self.residual, x=self.x[:, None], r=r[:, None], eps=1e-6, n_res=0,
            bounds=[LOWER[:, None], UPPER[:, None]])
        return np.asarray(jacobian)

    def blocks(self) -> np.ndarray:
        """The block index of each residual, in the residual's order."""
        s = self.signals
        return np.concatenate([s.block[s.rows], s.block[s.starts[s.arm_sliding]],
                               s.block[s.starts[s.pendulum_sliding]]])


def weighted_residual(x: np.ndarray, s: Signals, weights: tuple[float, float, float]) -> np.ndarray:
    """The three equations' residuals, each times its weight, stacked."""
    parts = equations(x, s)
    return np.concatenate([w * part for w, part in zip(weights, parts, strict=True)], axis=0)


def fit(measurements: Measurements, samples: np.ndarray | None = None, latency: int | None = None,
        x0: np.ndarray | None = None) -> FitResult:
    """Fit the unknowns to `measurements` on sample indices `samples` (None: all).

    `latency`: the samples between a voltage's recording and its action (None: the best of
    0..MAX_LATENCY). `x0`: start (scaled; None: nominal, friction-like ones at their scale).
    """
    if latency is None:
        latency = best_latency(measurements, samples)
    s = signals(measurements, latency, samples)
    x = np.ones(len(NAMES)) if x0 is None else np.asarray(x0, dtype=float)
    if x0 is None:
        x[[NAMES.index(q.name) for q in OFFSETS]] = 0.0
    weights = (10.0, 1e4, 1e5)  # 1 / (0.1 V, 0.1 mN m s, 0.01 mN m s): rough spreads to start with
    for _ in range(2):  # then reweight by the spreads found
        x, _ = mujoco.minimize.least_squares(x, lambda z, w=weights: weighted_residual(z, s, w),
                                             bounds=[LOWER, UPPER], verbose=0, max_iter=100)
        weights = tuple(1.0 / max(float(np.sqrt(np.mean(part**2))), 1e-12) for part in equations(x, s))
    return FitResult(x=x, latency=latency, weights=weights, signals=s)


def best_latency(measurements: Measurements, samples: np.ndarray | None = None) -> int:
    """The latency (samples) whose motor-circuit equation fits the current best (linear least squares)."""
    errors = []
    for latency in range(MAX_LATENCY + 1):
        s = signals(measurements, latency, samples)
        design = np.column_stack([s.current[s.rows], s.dtheta[s.rows]])
        _, residual, *_ = np.linalg.lstsq(design, s.voltage_before[s.rows], rcond=None)
        errors.append(float(residual[0]) if residual.size else math.inf)
    return int(np.argmin(errors))
