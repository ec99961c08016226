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
(the rigid-body model of `devices/qube/model.xml`). The weak form needs the angles' first
derivative only, and only under an integral against a smooth weight: the smoothing
filter's error on fast motion (its velocities are off by 0.05 rad/s RMS on the
substitute) averages out instead of biasing the estimates, as accelerations from a
double derivative or momenta at window ends did (pendulum mass 4 to 10 % low on the
default substitute, against 1 % now). The motor torque is kt times the current read
at the end of each sample interval. Coulomb friction is exact: a window enters a
joint's equation only if the joint slides throughout (speed above `SLIDING_SPEED`),
so the fit never models sticking. The voltage-only fit (`fit_voltage`) can also take the
arm's windows in which it reverses without sticking (`REVERSAL_SAMPLES`, `reversals=True`): a
real Qube's chirps reverse the arm 20 times a second at their start, and only there does the
arm creep across the cable's pull near the encoder's zero.

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
from collections.abc import Callable

import mujoco.minimize
import numpy as np
from scipy.ndimage import label, maximum_filter1d, minimum_filter1d

from qube_suite.calibration.identifiability import FITTED, OFFSETS, Fitted
from qube_suite.calibration.measurements import PENDULUM_ENCODERS, Encoders, Measurements
from qube_suite.devices.qube import parameters

SLIDING_SPEED = 0.05
"""A joint counts as sliding where its speed stays above this (rad/s) across the smoothing window."""
REVERSAL_SAMPLES = 3
"""Longest run of samples below `SLIDING_SPEED` of a reversal that the arm is driven through rather than
stuck in (12 ms at 250 Hz; a 1.5 V, 10 Hz chirp passes in one sample): where `signals` takes reversals,
a window of the arm's equation may hold such runs, but no longer one."""
MAX_LATENCY = 3
"""Largest latency (samples) the fit considers."""

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
    alpha: np.ndarray | None
    """The pendulum's angle (rad); None for a device without one."""
    dtheta: np.ndarray
    dalpha: np.ndarray | None
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
    """For each interval: whether the arm slides throughout, or where reversals are taken never sticks
    (its friction torque is then known)."""
    pendulum_sliding: np.ndarray | None
    """For each interval: whether the pendulum slides throughout (None without a pendulum)."""
    block: np.ndarray
    """Block (`BLOCK_SECONDS` long) of each sample."""
    sample_time: float


def signals(measurements: Measurements, latency: int, samples: np.ndarray | None = None,
            reversals: bool = False) -> Signals:
    """The fit's inputs from `measurements` for `latency` (samples), using only the sample indices
    `samples` (None: all; the filter's edges and the first samples are never used). `reversals`: the
    arm's equation also takes the windows where it reverses without sticking (`REVERSAL_SAMPLES`)."""
    theta, dtheta = measurements.derivatives(measurements.theta)
    pendulum = measurements.alpha
    alpha, dalpha = (None, None) if pendulum is None else measurements.derivatives(pendulum)
    current = measurements.current
    shift = 1 + latency
    voltage_before = np.concatenate([np.zeros(shift), measurements.voltage[:-shift]])
    n = len(measurements)
    usable = np.zeros(n, dtype=bool)
    edge = measurements.smoothing_window
    usable[max(edge, MAX_LATENCY + 1):n - edge] = True
    if samples is not None:
        chosen = np.zeros_like(usable)
        chosen[samples] = True
        usable &= chosen
    starts = np.arange(0, n - INTERVAL, INTERVAL // 2)
    whole = minimum_filter1d(usable.astype(float), INTERVAL + 1, origin=-(INTERVAL // 2))[starts] > 0
    starts = starts[whole]

    def sliding(speed: np.ndarray) -> np.ndarray:
        slow = minimum_filter1d(np.abs(speed), INTERVAL + 1 + 2 * edge,
                                origin=-(INTERVAL // 2)) > SLIDING_SPEED
        return slow[starts]

    def never_sticking(speed: np.ndarray) -> np.ndarray:
        runs, _ = label(np.abs(speed) <= SLIDING_SPEED)
        stuck = (np.bincount(runs) > REVERSAL_SAMPLES)[runs] & (runs > 0)
        return maximum_filter1d(stuck, INTERVAL + 1 + 2 * edge, origin=-(INTERVAL // 2))[starts] == 0

    return Signals(theta=theta, alpha=alpha, dtheta=dtheta, dalpha=dalpha, current=current,
                   current_after=np.append(current[1:], current[-1]), voltage_before=voltage_before,
                   rows=np.flatnonzero(usable), starts=starts,
                   arm_sliding=never_sticking(dtheta) if reversals else sliding(dtheta),
                   pendulum_sliding=None if dalpha is None else sliding(dalpha),
                   block=(measurements.time / BLOCK_SECONDS).astype(int),
                   sample_time=measurements.sample_time)


Column = Callable[[np.ndarray], np.ndarray]
"""Turns a per-sample signal into the shape of the unknowns' values: itself for one estimate (n,),
a column for a batch of estimates (n, k)."""


@dataclasses.dataclass(frozen=True)
class Model:
    """What a device gives the fit: its unknowns, its momentum balances and its encoders.

    The motor's circuit is every Qube's and the fit writes it (`circuit`), so a device's unknowns
    include `motor_resistance` and `motor_back_emf`. Bounds of the scaled unknowns: those in
    `positive` within 0.3 to 3 times their scale, offsets (names ending in "offset") within +-30
    times, the others (friction-like, whose truth may be 0) within 0 and 30 times.
    """

    unknowns: tuple[Fitted, ...]
    """The fit's unknowns in order: parameters by their device table's long names, then offsets."""
    positive: frozenset[str]
    balances: Callable[[dict[str, np.ndarray], Signals, Column], tuple[np.ndarray, ...]]
    """(unknowns by name, signals, column) -> each momentum balance's residuals (N m s), one per window
    it uses."""
    balance_starts: Callable[[Signals], tuple[np.ndarray, ...]]
    """The first samples of the windows each balance uses, in the order of `balances`."""
    start_weights: tuple[float, ...]
    """1 / a rough spread of the circuit's residual (V) and of each balance's (N m s), to start with."""
    encoders: Encoders = PENDULUM_ENCODERS
    """Which raw encoder columns of a recording hold its angles."""

    @property
    def names(self) -> tuple[str, ...]:
        """The unknowns' names, in the fit's order."""
        return tuple(q.name for q in self.unknowns)

    @property
    def scales(self) -> np.ndarray:
        """Scale of each unknown: the fit works on value / scale."""
        return np.array([q.scale for q in self.unknowns])

    @property
    def lower(self) -> np.ndarray:
        """Lower bounds of the scaled unknowns."""
        return np.array([0.3 if name in self.positive else (-30.0 if name.endswith("offset") else 0.0)
                         for name in self.names])

    @property
    def upper(self) -> np.ndarray:
        """Upper bounds of the scaled unknowns."""
        return np.array([3.0 if name in self.positive else 30.0 for name in self.names])


def physical(x: np.ndarray, model: Model | None = None) -> dict[str, np.ndarray]:
    """The unknowns by name from scaled `x` (shape (n,) or (n, k)); `model`: the pendulum's if None."""
    model = PENDULUM if model is None else model
    scales = model.scales
    values = x * (scales if x.ndim == 1 else scales[:, None])
    return dict(zip(model.names, values, strict=True))


def circuit(p: dict[str, np.ndarray], s: Signals, column: Column) -> np.ndarray:
    """The motor circuit's residual (V, per sample the fit uses): V - Rm i - km theta'."""
    rows = s.rows
    return (column(s.voltage_before[rows]) - p["motor_resistance"] * column(s.current[rows])
            - p["motor_back_emf"] * column(s.dtheta)[rows])


def equations(x: np.ndarray, s: Signals, model: Model | None = None) -> tuple[np.ndarray, ...]:
    """Residuals of the motor circuit (V, per sample) and of each momentum balance of `model` (the
    pendulum's if None: the arm's and the pendulum's; N m s, per interval in which the joint slides) at
    scaled unknowns `x` (n,) or a batch (n, k): arrays (rows[, k])."""
    model = PENDULUM if model is None else model
    p = physical(x, model)
    column = (lambda a: a[:, None]) if x.ndim > 1 else (lambda a: a)
    return (circuit(p, s, column), *model.balances(p, s, column))


def pendulum_balances(p: dict[str, np.ndarray], s: Signals, column: Column) -> tuple[np.ndarray, np.ndarray]:
    """The arm's and the pendulum's momentum balances (see the module)."""
    th, dth = column(s.theta), column(s.dtheta)
    arm_momentum, pendulum_momentum, pendulum_torque = rigid_body(
        p, s, column, p["pendulum_mass"], parameters.NOMINAL["rotor_inertia"])
    motor_torque = p["motor_torque_constant"] * column(s.current_after)
    arm_torque = (-p["arm_damping"] * dth - p["arm_friction"] * np.sign(dth)
                  - p["cable_stiffness"] * th + p["arm_torque_offset"])
    arm = balance(arm_momentum, arm_torque, motor_torque, s.starts[s.arm_sliding], s.sample_time)
    pendulum = balance(pendulum_momentum, pendulum_torque, 0.0, s.starts[s.pendulum_sliding], s.sample_time)
    return arm, pendulum


def rigid_body(p: dict[str, np.ndarray], s: Signals, column: Column, pendulum_mass, rotor_inertia
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Furuta pendulum's arm and pendulum momenta (N m s) and the pendulum's torque (N m:
    inertial, gravity, damping, Coulomb) at the signals `s`, for the pendulum length, encoder offset
    and pendulum damping and friction in `p`, a pendulum mass (kg) and rotor inertia (kg m^2)."""
    dth, dal = column(s.dtheta), column(s.dalpha)
    al = column(s.alpha) + p["pendulum_encoder_offset"]
    sin, cos = np.sin(al), np.cos(al)
    mp, lp, lr = pendulum_mass, p["pendulum_length"], parameters.NOMINAL["arm_length"]
    half = 0.5 * lp
    axial = 0.5 * mp * parameters.PENDULUM_ROD_RADIUS**2
    transverse = mp * lp * lp / 12.0
    base = (parameters.arm_inertia(parameters.NOMINAL["arm_mass"], lr) + rotor_inertia
            + mp * lr * lr + axial)
    swing = mp * half * half + transverse - axial
    coupling = mp * lr * half
    m22 = mp * half * half + transverse
    m12 = -coupling * cos
    arm_momentum = (base + swing * sin * sin) * dth + m12 * dal
    pendulum_momentum = m12 * dth + m22 * dal
    pendulum_torque = (swing * sin * cos * dth * dth + coupling * sin * dth * dal
                       + mp * parameters.NOMINAL["gravity"] * half * sin
                       - p["pendulum_damping"] * dal - p["pendulum_friction"] * np.sign(dal))
    return arm_momentum, pendulum_momentum, pendulum_torque


PENDULUM = Model(
    unknowns=FITTED + OFFSETS,
    positive=frozenset({"motor_resistance", "motor_back_emf", "motor_torque_constant", "pendulum_mass",
                        "pendulum_length"}),
    balances=pendulum_balances,
    balance_starts=lambda s: (s.starts[s.arm_sliding], s.starts[s.pendulum_sliding]),
    start_weights=(10.0, 1e4, 1e5),  # 1 / (0.1 V, 0.1 mN m s, 0.01 mN m s)
)
"""The Qube pendulum's model: the identified parameters and offsets of `identifiability`, the arm's
and the pendulum's momentum balances."""
NAMES = PENDULUM.names
"""Names of the pendulum's unknowns, in order."""
SCALES = PENDULUM.scales
LOWER, UPPER = PENDULUM.lower, PENDULUM.upper


def balance(momentum: np.ndarray, state_torque: np.ndarray, input_torque: np.ndarray | float,
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
    weights: tuple[float, ...]
    """1 / spread of the circuit (V) and of each balance's (N m s; the pendulum: the arm's, the
    pendulum's) residuals at the estimate."""
    signals: Signals
    model: Model = dataclasses.field(default_factory=lambda: PENDULUM)

    @property
    def names(self) -> tuple[str, ...]:
        """The unknowns' names, in order (the model's)."""
        return self.model.names

    @property
    def scales(self) -> np.ndarray:
        """The unknowns' scales (the model's)."""
        return self.model.scales

    @property
    def values(self) -> dict[str, float]:
        """The estimates by name, in their units."""
        return {name: float(value) for name, value in physical(self.x, self.model).items()}

    def residual(self, x: np.ndarray) -> np.ndarray:
        """Weighted residual vector at scaled `x` (n,) or (n, k)."""
        return weighted_residual(x, self.signals, self.weights, self.model)

    def jacobian(self) -> np.ndarray:
        """Jacobian of the weighted residual with respect to the scaled unknowns at the estimate."""
        r = self.residual(self.x)
        jacobian, _ = mujoco.minimize.jacobian_fd(
            residual=self.residual, x=self.x[:, None], r=r[:, None], eps=1e-6, n_res=0,
            bounds=[self.model.lower[:, None], self.model.upper[:, None]])
        return np.asarray(jacobian)

    def blocks(self) -> np.ndarray:
        """The block index of each residual, in the residual's order."""
        s = self.signals
        balances = self.model.balance_starts(s)
        return np.concatenate([s.block[s.rows], *(s.block[starts] for starts in balances)])


def weighted_residual(x: np.ndarray, s: Signals, weights: tuple[float, ...],
                      model: Model | None = None) -> np.ndarray:
    """The equations' residuals, each times its weight, stacked."""
    parts = equations(x, s, model)
    return np.concatenate([w * part for w, part in zip(weights, parts, strict=True)], axis=0)


def fit(measurements: Measurements, samples: np.ndarray | None = None, latency: int | None = None,
        x0: np.ndarray | None = None, model: Model | None = None) -> FitResult:
    """Fit `model`'s unknowns (the pendulum's if None) to `measurements` on sample indices `samples`
    (None: all).

    `latency`: the samples between a voltage's recording and its action (None: the best of
    0..MAX_LATENCY). `x0`: start (scaled; None: nominal, offsets at 0, friction-like ones at their scale).
    """
    model = PENDULUM if model is None else model
    if latency is None:
        latency = best_latency(measurements, samples)
    s = signals(measurements, latency, samples)
    names = model.names
    x = np.ones(len(names)) if x0 is None else np.asarray(x0, dtype=float)
    if x0 is None:
        x[[i for i, name in enumerate(names) if name.endswith("offset")]] = 0.0
    weights = model.start_weights
    bounds = [model.lower, model.upper]
    for _ in range(2):  # then reweight by the spreads found
        x, _ = mujoco.minimize.least_squares(x, lambda z, w=weights: weighted_residual(z, s, w, model),
                                             bounds=bounds, verbose=0, max_iter=100)
        weights = tuple(1.0 / max(float(np.sqrt(np.mean(part**2))), 1e-12) for part in equations(x, s, model))
    return FitResult(x=x, latency=latency, weights=weights, signals=s, model=model)


def best_latency(measurements: Measurements, samples: np.ndarray | None = None) -> int:
    """The latency (samples) whose motor-circuit equation fits the current best (linear least squares)."""
    errors = []
    for latency in range(MAX_LATENCY + 1):
        s = signals(measurements, latency, samples)
        design = np.column_stack([s.current[s.rows], s.dtheta[s.rows]])
        _, residual, *_ = np.linalg.lstsq(design, s.voltage_before[s.rows], rcond=None)
        errors.append(float(residual[0]) if residual.size else math.inf)
    return int(np.argmin(errors))


# -- from the encoders and the voltage alone ---------------------------------------------------------
#
# Without the motor current the circuit equation is gone and the motor's torque over each sample
# interval follows from the voltage that acted in it: (kt / Rm) (V - km theta'), with km = kt (one
# constant in SI units). Only kt / Rm is identified, so Rm stays at nominal. The torque scale is
# anchored by the pendulum's mass (weighed: Quanser's 24 g) rather than by the arm-axis inertia,
# which on a real Qube includes the hub and the encoder disc and is fitted here as the rotor's.
# The arm's viscous damping and the back-EMF both oppose theta' in proportion: only their sum is
# identified, reported as a combination. The encoder cable pulls towards its rest angle
# (arm_torque_offset / cable_stiffness) only beyond a slack band of half-width cable_slack around it:
# torque -kc (theta - clip(theta, rest - slack, rest + slack)), a linear spring when the slack is 0.

VOLTAGE_ONLY: tuple[Fitted, ...] = (
    Fitted("motor_torque_constant", parameters.NOMINAL["motor_torque_constant"], "N m/A"),
    Fitted("rotor_inertia", parameters.NOMINAL["rotor_inertia"], "kg m^2"),
    Fitted("pendulum_length", parameters.NOMINAL["pendulum_length"], "m"),
    Fitted("arm_damping", 1.0e-5, "N m s/rad", 2.0e-5),
    Fitted("arm_friction", 1.0e-3, "N m", 1.5e-4),
    Fitted("cable_stiffness", 1.0e-3, "N m/rad", 1.5e-4),
    Fitted("pendulum_damping", 1.0e-6, "N m s/rad", 1.0e-6),
    Fitted("pendulum_friction", 1.0e-4, "N m", 1.5e-5),
    Fitted("voltage_deadzone", 0.1, "V", 0.01),
    Fitted("cable_slack", 0.1, "rad", 0.05),  # searched on SLACK_GRID
) + OFFSETS
"""The unknowns of the voltage-only fit, in its order."""
VOLTAGE_NAMES = tuple(q.name for q in VOLTAGE_ONLY)
VOLTAGE_SCALES = np.array([q.scale for q in VOLTAGE_ONLY])
VOLTAGE_LOWER = np.array([0.3 if name in ("motor_torque_constant", "pendulum_length")
                          else (-30.0 if name.endswith("offset") else 0.0) for name in VOLTAGE_NAMES])
VOLTAGE_UPPER = np.array([3.0 if name in ("motor_torque_constant", "pendulum_length")
                          else (30.0 if name.endswith("offset") or name == "voltage_deadzone" else 100.0)
                          for name in VOLTAGE_NAMES])
"""Bounds of the scaled unknowns: the torque constant and the length within 0.3 to 3 times nominal,
the rotor's inertia and the friction-like ones within 0 and 100 times their scale."""
LATENCY_STEP = 0.25
"""Resolution (samples) of the latency search of the voltage-only fit."""
SLACK_STEP = 0.2
SLACK_GRID = tuple(SLACK_STEP * k for k in range(5))
"""Half-widths of the cable's slack band (rad) the voltage-only fit tries (then half a step either
side of the best): its cost has local minima in the slack, which least squares would stop in."""
REVERSALS_SLACK_STEP = 0.1
"""The slack grid's step (rad) where the fit takes the arm's reversals: they show the cable near its rest,
where the cost's two minima on a real Qube's chirps (0.1 and 0.5 rad) are closer than `SLACK_STEP`
resolves (on four chirps the coarse grid stopped in the worse one)."""


def voltage_signals(measurements: Measurements, samples: np.ndarray | None = None,
                    reversals: bool = False) -> Signals:
    """The voltage-only fit's inputs from `measurements` (the latency enters later, in
    `voltage_equations`); `samples` and `reversals` as for `signals`."""
    return signals(dataclasses.replace(measurements, current=np.zeros(len(measurements))), 0, samples,
                   reversals)


def delayed_voltage(voltage: np.ndarray, latency: float) -> np.ndarray:
    """The voltage that acts over each sample interval when the recorded one acts `latency` samples
    late (a fraction of a sample mixes two neighbours in proportion); 0 V before the recording."""
    whole = int(math.floor(latency))
    fraction = latency - whole
    padded = np.concatenate([np.zeros(whole + 1), voltage])
    current = padded[1:len(voltage) + 1]
    before = padded[:len(voltage)]
    return (1.0 - fraction) * current + fraction * before


def voltage_equations(x: np.ndarray, s: Signals, voltage: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The arm's and the pendulum's momentum-balance residuals (N m s, per interval in which the
    joint slides) at scaled voltage-only unknowns `x` (n,) or (n, k), `voltage` acting over each
    sample interval (V, latency applied)."""
    values = x * (VOLTAGE_SCALES if x.ndim == 1 else VOLTAGE_SCALES[:, None])
    p = dict(zip(VOLTAGE_NAMES, values, strict=True))
    column = (lambda a: a[:, None]) if x.ndim > 1 else (lambda a: a)
    th, dth = column(s.theta), column(s.dtheta)
    arm_momentum, pendulum_momentum, pendulum_torque = rigid_body(
        p, s, column, parameters.NOMINAL["pendulum_mass"], p["rotor_inertia"])
    kt = p["motor_torque_constant"]
    gain = kt / parameters.NOMINAL["motor_resistance"]
    middle_speed = 0.5 * (dth + np.concatenate([dth[1:], dth[-1:]]))
    drive = column(voltage)
    drive = np.sign(drive) * np.maximum(np.abs(drive) - p["voltage_deadzone"], 0.0)
    motor_torque = gain * (drive - kt * middle_speed)
    stiffness, slack = p["cable_stiffness"], p["cable_slack"]
    rest = p["arm_torque_offset"] / np.maximum(stiffness, 1e-12)
    slackening = stiffness * np.clip(th - rest, -slack, slack)
    arm_torque = (-p["arm_damping"] * dth - p["arm_friction"] * np.sign(dth)
                  - stiffness * th + p["arm_torque_offset"] + slackening)
    arm = balance(arm_momentum, arm_torque, motor_torque, s.starts[s.arm_sliding], s.sample_time)
    pendulum = balance(pendulum_momentum, pendulum_torque, 0.0, s.starts[s.pendulum_sliding], s.sample_time)
    return arm, pendulum


@dataclasses.dataclass(frozen=True)
class VoltageFitResult:
    """The voltage-only fit's scaled estimate, latency (samples, a fraction allowed), weights and
    the recordings' signals and voltages it was fitted on."""

    x: np.ndarray
    latency: float
    weights: tuple[float, float]
    """1 / spread of the arm's and the pendulum's residuals (N m s) at the estimate."""
    signals: tuple[Signals, ...]
    voltages: tuple[np.ndarray, ...]
    """Each recording's voltage, as recorded (V)."""
    names: tuple[str, ...] = VOLTAGE_NAMES
    scales: np.ndarray = dataclasses.field(default_factory=lambda: VOLTAGE_SCALES)

    @property
    def values(self) -> dict[str, float]:
        """The estimates by name, in their units."""
        return {name: float(value) for name, value in zip(self.names, self.x * self.scales, strict=True)}

    def residual(self, x: np.ndarray) -> np.ndarray:
        """Weighted residual vector at scaled `x` (n,) or (n, k), every recording's stacked."""
        return _voltage_residual(x, self.signals, self.voltages, self.latency, self.weights)

    def jacobian(self) -> np.ndarray:
        """Jacobian of the weighted residual with respect to the scaled unknowns at the estimate."""
        r = self.residual(self.x)
        jacobian, _ = mujoco.minimize.jacobian_fd(
            residual=self.residual, x=self.x[:, None], r=r[:, None], eps=1e-6, n_res=0,
            bounds=[VOLTAGE_LOWER[:, None], VOLTAGE_UPPER[:, None]])
        return np.asarray(jacobian)

    def blocks(self) -> np.ndarray:
        """The block index of each residual (distinct between recordings), in the residual's order."""
        arms, pendulums = [], []
        for i, s in enumerate(self.signals):
            offset = i * 1_000_000
            arms.append(offset + s.block[s.starts[s.arm_sliding]])
            pendulums.append(offset + s.block[s.starts[s.pendulum_sliding]])
        return np.concatenate(arms + pendulums)


def _voltage_parts(x, signals_, voltages, latency) -> tuple[np.ndarray, np.ndarray]:
    parts = [voltage_equations(x, s, delayed_voltage(v, latency))
             for s, v in zip(signals_, voltages, strict=True)]
    return (np.concatenate([arm for arm, _ in parts], axis=0),
            np.concatenate([pendulum for _, pendulum in parts], axis=0))


def _voltage_residual(x, signals_, voltages, latency, weights) -> np.ndarray:
    arm, pendulum = _voltage_parts(x, signals_, voltages, latency)
    return np.concatenate([weights[0] * arm, weights[1] * pendulum], axis=0)


def fit_voltage(recordings: list[Measurements], samples: list[np.ndarray | None] | None = None,
                latency: float | None = None, free: tuple[str, ...] | None = None,
                slack: float | None = None, reversals: bool = False) -> VoltageFitResult:
    """Fit the voltage-only unknowns to several `recordings` at once, each on its sample indices
    `samples` (None: all).

    `latency` (samples, a fraction allowed): None searches 0 to MAX_LATENCY in steps of LATENCY_STEP.
    `free`: the unknowns fitted (None: all of `VOLTAGE_ONLY`); the others stay at their nominal value
    (0 for the friction-like ones and the offsets), which is how the benchmark measures what each
    part of the model buys. `slack`: the cable's slack (rad; None: searched on `SLACK_GRID` if free).
    `reversals`: the arm's equation also takes the windows where it reverses without sticking
    (`signals`), and the slack's grid is finer (`REVERSALS_SLACK_STEP`).
    """
    samples = samples or [None] * len(recordings)
    signals_ = tuple(voltage_signals(m, chosen, reversals)
                     for m, chosen in zip(recordings, samples, strict=True))
    voltages = tuple(m.voltage for m in recordings)
    free = VOLTAGE_NAMES if free is None else free
    unknown = set(free) - set(VOLTAGE_NAMES)
    if unknown:
        raise ValueError(f"unknown unknowns {sorted(unknown)}; valid: {', '.join(VOLTAGE_NAMES)}")
    mask = np.array([name in free for name in VOLTAGE_NAMES])
    mask[VOLTAGE_NAMES.index("cable_slack")] = False  # searched on a grid, not by least squares
    start = np.array([1.0 if name in ("motor_torque_constant", "rotor_inertia", "pendulum_length") else 0.0
                      for name in VOLTAGE_NAMES])
    slack_index = VOLTAGE_NAMES.index("cable_slack")

    def solve(lat: float, slack: float = 0.0, x0: np.ndarray = start
              ) -> tuple[np.ndarray, tuple[float, float], float]:
        x = x0.copy()
        x[slack_index] = slack / VOLTAGE_SCALES[slack_index]
        weights = (1e4, 1e5)
        for _ in range(2):
            def residual(z, w=weights):
                full = np.repeat(x[:, None], z.shape[1], axis=1) if z.ndim > 1 else x.copy()
                full[mask] = z
                return _voltage_residual(full, signals_, voltages, lat, w)
            z, _ = mujoco.minimize.least_squares(x[mask], residual, verbose=0, max_iter=100,
                                                 bounds=[VOLTAGE_LOWER[mask], VOLTAGE_UPPER[mask]])
            x[mask] = z
            weights = tuple(1.0 / max(float(np.sqrt(np.mean(part**2))), 1e-12)
                            for part in _voltage_parts(x, signals_, voltages, lat))
        arm, _ = _voltage_parts(x, signals_, voltages, lat)
        cost = float(np.mean(arm**2))
        return x, weights, cost

    if latency is not None:
        best = solve(latency) + (latency,)
    else:  # whole samples first, then quarter samples around the best
        best = min((solve(float(lat)) + (float(lat),) for lat in range(MAX_LATENCY + 1)), key=lambda f: f[2])
        for lat in (best[3] - 2 * LATENCY_STEP, best[3] - LATENCY_STEP, best[3] + LATENCY_STEP,
                    best[3] + 2 * LATENCY_STEP):
            if 0.0 <= lat <= MAX_LATENCY:
                best = min(best, solve(lat) + (lat,), key=lambda f: f[2])
    if slack is not None:
        best = solve(best[3], slack, best[0]) + (best[3],)
    elif "cable_slack" in free:  # a grid (local minima), then half its step either side of the best
        lat, linear = best[3], best[0]
        step = REVERSALS_SLACK_STEP if reversals else SLACK_STEP
        for slack in (step * k for k in range(1, round(SLACK_GRID[-1] / step) + 1)):
            best = min(best, solve(lat, slack, linear) + (lat,), key=lambda f: f[2])
        chosen = best[0][slack_index] * VOLTAGE_SCALES[slack_index]
        for slack in (chosen - 0.5 * step, chosen + 0.5 * step):
            if slack > 0.0:
                best = min(best, solve(lat, slack, linear) + (lat,), key=lambda f: f[2])
    x, weights, _, lat = best
    return VoltageFitResult(x=x, latency=float(lat), weights=weights, signals=signals_, voltages=voltages)
