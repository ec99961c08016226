"""iLQR: receding-horizon optimal control of the Qube on its closed-form model.

Model: x = [theta, alpha, dtheta, dalpha], u = motor voltage; the rigid-body
equations of `qube_suite.devices.qube.controllers.model` stepped with RK4 over one control
period h. Derivatives: the continuous-time Jacobian of those equations in closed
form, chained through the four RK4 stages, so A = dx'/dx and B = dx'/du are
exact for the discrete model (`benchmarks/ilqr.py` compares them with MuJoCo's
`mjd_transitionFD` for accuracy and cost).

Cost of a plan of N knots, the arm reference r_n with speed r'_n:

    sum_n h l(x_n, u_n) + w_N l(x_N, 0),
    l = q_alpha (1 - cos alpha) + q_theta (theta - r)^2 + q_dtheta (dtheta - r')^2
        + q_dalpha dalpha^2 + q_u u^2 + q_limit max(0, |theta| - theta_limit)^2
        + q_lean max(0, |alpha| - alpha_lean)^2

with |u| <= the voltage limit; alpha's lean is counted from the nearest upright, and
its term is on only while the pendulum is balanced (see `IterativeLQR`).

One iteration (Li and Todorov 2004; Tassa, Mansard and Todorov 2014 for the
control limits and the regularisation): roll the plan out from the current
state with its own feedback gains; linearise along it; backward pass for the
feed-forward k_n and gains K_n, where a voltage that would leave the limits is
clamped and its gain set to 0 (the box QP of one input); forward line search
over k's step size, keeping the new plan only if its cost is lower. The
regularisation mu added to Q_uu grows when the backward pass or the line search
fails and shrinks after a success; at its largest value a failed backward pass
leaves the plan as it is for this step.

The compiled kernel (`_ilqr.pyx`) runs these iterations; this module holds the
controller and a numpy transcription of one iteration (`reference_iteration`),
which documents the steps and against which the tests check the kernel.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import numpy as np

from qube_suite.angles import wrap_angle
from qube_suite.conventions import DEFAULT_VOLTAGE_LIMIT
from qube_suite.devices.qube.controllers._ilqr import Kernel
from qube_suite.devices.qube.controllers.base import Controller
from qube_suite.devices.qube.controllers.follow import REFERENCE_LIMIT, TargetSpeed, arm_set_point
from qube_suite.devices.qube.controllers.lqr import BalanceLQR
from qube_suite.devices.qube.controllers.model import RigidBodyModel
from qube_suite.devices.qube.controllers.observer import UNMODELLED_TORQUE
from qube_suite.devices.qube.controllers.swingup import CATCH_VOLTAGE, RELEASE_VOLTAGE, SwingupController

DIAGONAL = (np.arange(4), np.arange(4))

REFERENCE_STEP = math.radians(20.0)
"""Largest distance (rad) of the plan's first arm reference, and of its swing-up's and LQR plans' arm
set-point, from the arm. `FollowController`'s own is shorter (12.5 degrees: its one saturated LQR
dropped a real Qube's pendulum at 20); a plan that looks ahead keeps the figures measured with 20."""
REFERENCE_SPEED = 3.0
"""Fastest the arm reference moves away from the arm over the horizon (rad/s), beyond `REFERENCE_STEP`.

Without it a jump of the target put the whole jump into the reference at once: on a 112 degree
jump of the default schedule on the substitute board, the plan leaned the pendulum out of the
balanced set (which switches the lean limit off) and then swept the arm through -138 degrees at
17 rad/s, which neither the arm-limit cost nor 3 V of braking could stop before the board's
120 degree safety limit. Led by a reference the arm can follow with the pendulum up, the same
episodes keep the arm within 81 degrees."""

SWING_UPS = ("plan", "energy")
"""`IterativeLQR`'s swing-ups: planned by the MPC, or by `SwingupController`'s energy shaping."""

MAX_REGULARIZATION = 10.0
"""Largest mu (the kernel's too): beyond it a step would only be shorter."""


@dataclasses.dataclass(frozen=True)
class Cost:
    """Weights of the cost (see the module); angles in rad, speeds in rad/s, voltage in V."""

    pendulum: float = 40.0
    """q_alpha on 1 - cos alpha (about q_alpha / 2 alpha^2 near upright)."""
    arm: float = 20.0
    """q_theta on (theta - r)^2: steps held 3 s within +-60 degrees followed to 0.06 rad, 2 s to 0.11;
    stiffer (30 to 100) follows them no closer (docs/optimal_control.md)."""
    arm_speed: float = 0.05
    """q_dtheta on (dtheta - r')^2."""
    pendulum_speed: float = 0.2
    """q_dalpha on dalpha^2."""
    voltage: float = 0.05
    """q_u on u^2."""
    arm_limit: float = math.radians(75.0)
    """theta_limit: the arm pays beyond this angle ..."""
    limit_weight: float = 1000.0
    """... q_limit times the square of the excess."""
    lean_limit: float = math.radians(12.0)
    """alpha_lean: while balancing, the pendulum pays beyond this lean from upright ..."""
    lean_weight: float = 1000.0
    """... q_lean times the square of the excess."""
    terminal: float = 1.0
    """w_N: weight of the last knot's cost, in seconds of running cost."""


class IterativeLQR(Controller):
    """Receding-horizon iLQR from the estimated state, warm-started from the last plan each step.

    Every call moves the plan one control period on (the first voltage was sent),
    does `iterations` iLQR iterations from the observer's estimate (predicted
    over the latency) and sends the plan's first voltage. The arm reference is the
    target within +-60 degrees, extrapolated over the horizon with the target's
    speed (estimated as in `FollowController`), and led towards a far target as a
    ramp: at most 20 degrees from the arm at the first knot, then `reference_speed`
    (3 rad/s, `REFERENCE_SPEED`).

    While the pendulum is balanced (its lean and speed inside the balance LQR's catch
    ellipsoid, the arm's state left out; it leaves outside the larger release
    ellipsoid, as in `SwingupController`), the plan also pays for leaning the pendulum
    beyond `cost.lean_limit`: a plan that moves the arm as fast as the arm weight
    asks leans it about 17 degrees on a 60 degree step, which a real Qube's friction
    and latency carry past the balance tasks' 20 degree limit. Balanced, each step
    also starts from the balance LQR's closed loop instead of the shifted plan when
    that is cheaper (`_start_from_cheaper`): after a jump of the target the shifted
    plan's rollout could drop the pendulum, and the iteration then turned it round a
    full revolution to reach the new target.

    The plan keeps `UNMODELLED_TORQUE`'s worth of voltage (0.2 V on a nominal Qube)
    out of its limit for the `Controller` to cancel friction and the cable's spring
    with: a plan at the full limit, clipped by the cancellation, is one the Qube
    cannot follow (on the substitute board the swing-up took 2.6 s instead of 1.2).
    Three iterations a step (0.5 ms) rather than one converge to a jumped target's
    plan within a few steps instead of 0.2 s.

    With `swing_up="energy"` the plan starts only once the pendulum is balanced, from the
    balance LQR's closed loop; until then, and whenever the pendulum leaves the balanced
    set, `SwingupController` swings it up (energy shaping about the arm's set-point, as in
    `FollowController`). That swing-up is a smooth function of the state, which a network
    can learn by imitation; the planned one ("plan") is near time-optimal, bang-bang at the
    voltage limit, and has not been learnt (docs/reinforcement-learning.md).

    Args:
        control_frequency, voltage_limit, parameters, latency_steps: as `Controller`.
        horizon: planning horizon (s); the knots are one control period apart.
        iterations: iLQR iterations per control step.
        cost: the cost's weights: a `Cost`, or a mapping of its fields to change from the defaults
            (e.g. `{"lean_limit": math.radians(8)}`).
        reference_speed: fastest the arm reference moves away from the arm (rad/s); 2 rather
            than 3 leans the pendulum less on large steps and follows them a little later.
        swing_up: "plan" (the MPC plans the swing-up) or "energy" (energy shaping swings up).
    """

    name = "ilqr"
    tasks = ("swingup", "swingup_sparse", "swingup_follow", "swingup_follow_sparse",
             "balance", "balance_sparse", "balance_follow", "balance_follow_sparse")

    def __init__(self, control_frequency: float = 250.0, voltage_limit: float = DEFAULT_VOLTAGE_LIMIT,
                 parameters: Mapping[str, float] | None = None, latency_steps: int = 0,
                 horizon: float = 0.8, iterations: int = 3, cost: Cost | Mapping[str, float] | None = None,
                 reference_speed: float = REFERENCE_SPEED, swing_up: str = "plan"):
        super().__init__(control_frequency, voltage_limit, parameters, latency_steps)
        if not (isinstance(iterations, int) and iterations >= 1):
            raise ValueError(f"iterations must be a positive integer, got {iterations!r}")
        if not (isinstance(horizon, (int, float)) and horizon * control_frequency >= 2):
            raise ValueError(f"horizon must cover at least two control periods, got {horizon!r} s")
        if not (isinstance(reference_speed, (int, float)) and reference_speed > 0):
            raise ValueError(f"reference_speed must be a positive speed in rad/s, got {reference_speed!r}")
        if swing_up not in SWING_UPS:
            raise ValueError(f"unknown swing_up {swing_up!r}; valid: {', '.join(SWING_UPS)}")
        self.cost = cost if isinstance(cost, Cost) else cost_from(cost or {})
        self.reference_speed = float(reference_speed)
        self.swingup = (SwingupController(control_frequency, voltage_limit, parameters)
                        if swing_up == "energy" else None)
        self.target_speed = TargetSpeed(control_frequency)
        self.iterations = iterations
        self.balance = BalanceLQR(control_frequency, voltage_limit, parameters)
        self._catch_level = self.balance.level_for_voltage(CATCH_VOLTAGE)
        self._release_level = self.balance.level_for_voltage(RELEASE_VOLTAGE)
        knots = round(horizon * control_frequency)
        self.plan_voltage_limit = voltage_limit - min(UNMODELLED_TORQUE / self.model.torque_per_volt,
                                                      0.5 * voltage_limit)
        self.kernel = Kernel(self.model, self.cost, knots, 1.0 / control_frequency, self.plan_voltage_limit)
        self._times = np.arange(self.kernel.knots + 1) / control_frequency
        self.reset()

    def reset(self) -> None:
        super().reset()
        self.kernel.U[:] = 0.0
        self.kernel.K[:] = 0.0
        self.kernel.X[:] = 0.0
        self.kernel.regularization = 0.0
        self.kernel.lean_limit = math.inf
        self.balancing = False
        self._started = False
        self.target_speed.reset()
        if self.swingup is not None:
            self.swingup.reset()

    def voltage_for(self, state: np.ndarray, target: float = 0.0) -> float:
        """Voltage (V) for `state` [theta, alpha, dtheta, dalpha] with the arm's target at `target` (rad)."""
        speed = self.target_speed(target)
        kernel = self.kernel
        state = np.array(state, dtype=np.float64)
        level = self._release_level if self.balancing else self._catch_level
        self.balancing = self.balance.cost_to_go(np.array([0.0, wrap_angle(state[1]), 0.0, state[3]])) < level
        if self.swingup is not None:
            # the swing-up learns every swing
            volts = self.swingup.voltage_for(state, arm_set_point(state[0], target, REFERENCE_STEP))
            if not self.balancing:
                self._started = False  # the plan starts afresh at the next catch
                return volts
        kernel.lean_limit = self.cost.lean_limit if self.balancing else math.inf
        if self._started:
            kernel.shift(1)
            # alpha as the plan counts it (it may have gone round): the gains act on a small difference
            state[1] = kernel.X[0, 1] + wrap_angle(state[1] - kernel.X[0, 1])
        else:
            self._first_plan(state, target)
        reference, reference_speed = self._reference(state[0], target, speed)
        if self.balancing:
            self._start_from_cheaper(state, target, reference, reference_speed)
        for _ in range(self.iterations):
            kernel.iterate(state, reference, reference_speed)
        return float(kernel.U[0])

    def _reference(self, theta: float, target: float, speed: float) -> tuple[np.ndarray, np.ndarray]:
        """The arm reference r_n and its speed r'_n (rad, rad/s) at the plan's knots, for the arm at
        `theta` and the target at `target` moving at `speed`: the target extrapolated with its speed
        within +-`REFERENCE_LIMIT`, and within `REFERENCE_STEP` + `reference_speed` t_n of the arm."""
        reference = np.clip(target + speed * self._times, -REFERENCE_LIMIT, REFERENCE_LIMIT)
        reference_speed = np.where(np.abs(reference) < REFERENCE_LIMIT, speed, 0.0)
        reach = REFERENCE_STEP + self.reference_speed * self._times
        ramp = np.clip(reference, theta - reach, theta + reach)
        ramp_speed = np.sign(ramp - theta) * self.reference_speed
        reference_speed = np.where(ramp == reference, reference_speed, ramp_speed)
        return ramp, reference_speed

    def _start_from_cheaper(self, state: np.ndarray, target: float, reference: np.ndarray,
                            reference_speed: np.ndarray) -> None:
        """Replace the plan by the balance LQR's closed loop about `Follow`'s arm set-point if that
        costs less from `state`. A target's jump can leave the shifted plan's rollout far from what
        it planned (its clamped knots run open loop), and one iteration from a plan whose rollout
        drops the pendulum finds, at best, a plan that swings it round a full turn."""
        kernel = self.kernel
        shifted = kernel.rollout_cost(state, reference, reference_speed)
        plan = kernel.U.copy(), kernel.X.copy(), kernel.K.copy()
        self._lqr_plan(arm_set_point(state[0], target, REFERENCE_STEP), state[1])
        if not kernel.rollout_cost(state, reference, reference_speed) < shifted:
            kernel.U[:], kernel.X[:], kernel.K[:] = plan

    def _lqr_plan(self, set_point: float, alpha: float) -> None:
        """The balance LQR's closed loop about the arm at `set_point` as the plan, upright counted
        nearest to `alpha` (rad)."""
        kernel = self.kernel
        kernel.U[:] = 0.0
        kernel.X[:] = [set_point, 2 * math.pi * round(alpha / (2 * math.pi)), 0.0, 0.0]
        kernel.K[:] = -self.balance.gain

    def _first_plan(self, state: np.ndarray, target: float) -> None:
        """The plan to start from. Near upright (inside the balance LQR's catch ellipsoid): the LQR's
        closed loop about the target; one iteration from 0 V alone would drop a pendulum that starts
        balanced. Caught after an energy swing-up: the LQR's closed loop about `FollowController`'s
        arm set-point. Elsewhere: a swing of half the voltage limit at the pendulum's natural
        frequency; at rest hanging, 0 V is a stationary point of the cost, where iLQR would stay."""
        kernel = self.kernel
        set_point = min(max(target, -REFERENCE_LIMIT), REFERENCE_LIMIT)
        if self.swingup is not None:
            self._lqr_plan(arm_set_point(state[0], target, REFERENCE_STEP), state[1])
        elif self.balance.cost_to_go(state, set_point) < self._catch_level:
            self._lqr_plan(set_point, 0.0)
        else:
            natural_frequency = math.sqrt(self.model.gravity_torque / self.model.pendulum_inertia)
            kernel.U[:] = 0.5 * self.voltage_limit * np.sin(natural_frequency * self._times[:-1])
            kernel.X[:] = state
            kernel.K[:] = 0.0
        self._started = True


def cost_from(changes: Mapping[str, float]) -> Cost:
    """`Cost()` with the fields named in `changes` changed; ValueError naming an unknown field."""
    fields = [field.name for field in dataclasses.fields(Cost)]
    unknown = sorted(set(changes) - set(fields))
    if unknown:
        raise ValueError(f"unknown cost weights {', '.join(unknown)}; valid: {', '.join(fields)}")
    return Cost(**changes)


def reference_iteration(model: RigidBodyModel, cost: Cost, h: float, voltage_limit: float, x0: np.ndarray,
                        U: np.ndarray, X: np.ndarray, K: np.ndarray, reference: np.ndarray,
                        reference_speed: np.ndarray, regularization: float, kernel: Kernel,
                        line_search: int = 6) -> tuple[float, np.ndarray, np.ndarray, np.ndarray, float]:
    """One iteration in numpy, as the kernel does it: (cost, U, X, K, regularization) after it.

    `kernel` provides only the RK4 step and its Jacobian (`Kernel.step`), the part the tests check
    against finite differences separately, and the lean limit in force (`Kernel.lean_limit`).
    """
    N = len(U)

    def stage(x, u, r, rd, scale):
        e, ed, over = x[0] - r, x[2] - rd, abs(x[0]) - cost.arm_limit
        lean = x[1] - 2 * math.pi * round(x[1] / (2 * math.pi))
        leaning = abs(lean) - kernel.lean_limit
        value = (cost.pendulum * (1 - math.cos(x[1])) + cost.arm * e * e + cost.arm_speed * ed * ed
                 + cost.pendulum_speed * x[3] ** 2 + cost.voltage * u * u)
        lx = np.array([2 * cost.arm * e, cost.pendulum * math.sin(x[1]), 2 * cost.arm_speed * ed,
                       2 * cost.pendulum_speed * x[3]])
        lxx = np.zeros((4, 4))
        lxx[DIAGONAL] = (2 * cost.arm, cost.pendulum * math.cos(x[1]), 2 * cost.arm_speed,
                         2 * cost.pendulum_speed)
        if over > 0:
            value += cost.limit_weight * over * over
            lx[0] += 2 * cost.limit_weight * over * math.copysign(1.0, x[0])
            lxx[0, 0] += 2 * cost.limit_weight
        if leaning > 0:
            value += cost.lean_weight * leaning * leaning
            lx[1] += 2 * cost.lean_weight * leaning * math.copysign(1.0, lean)
            lxx[1, 1] += 2 * cost.lean_weight
        return scale * value, scale * lx, scale * lxx, scale * 2 * cost.voltage * u, scale * 2 * cost.voltage

    def rollout(Xref, Uref, k, K, step_size):
        Xn, Un, total = np.zeros((N + 1, 4)), np.zeros(N), 0.0
        Xn[0] = x0
        for n in range(N):
            u = min(max(Uref[n] + step_size * k[n] + K[n] @ (Xn[n] - Xref[n]), -voltage_limit), voltage_limit)
            Un[n] = u
            total += stage(Xn[n], u, reference[n], reference_speed[n], h)[0]
            Xn[n + 1] = kernel.step(Xn[n], u, h)[0]
        return total + stage(Xn[N], 0.0, reference[N], reference_speed[N], cost.terminal)[0], Xn, Un

    current, X, U = rollout(X, U, np.zeros(N), K, 0.0)
    jacobians = [kernel.step(X[n], U[n], h)[1] for n in range(N)]
    k, K = np.zeros(N), np.zeros((N, 4))
    while True:
        _, Vx, Vxx, _, _ = stage(X[N], 0.0, reference[N], reference_speed[N], cost.terminal)
        for n in range(N - 1, -1, -1):
            _, lx, lxx, lu, luu = stage(X[n], U[n], reference[n], reference_speed[n], h)
            A, B = jacobians[n][:, :4], jacobians[n][:, 4]
            Qu, Quu = lu + B @ Vx, luu + B @ Vxx @ B + regularization
            if Quu <= 1e-12:
                break
            Qx, Qux, Qxx = lx + A.T @ Vx, B @ Vxx @ A, lxx + A.T @ Vxx @ A
            kk = -Qu / Quu
            if abs(U[n] + kk) > voltage_limit:
                kk = min(max(U[n] + kk, -voltage_limit), voltage_limit) - U[n]
            else:
                K[n] = -Qux / Quu
            k[n] = kk
            Vx = Qx + K[n] * (Quu * kk + Qu) + Qux * kk
            Vxx = Qxx + Quu * np.outer(K[n], K[n]) + np.outer(K[n], Qux) + np.outer(Qux, K[n])
            Vxx = 0.5 * (Vxx + Vxx.T)
        else:
            break
        if regularization >= MAX_REGULARIZATION:
            return current, U, X, K, regularization  # Q_uu stays negative: keep the plan
        regularization = min(max(2 * regularization, 1e-4), MAX_REGULARIZATION)
        K[:] = 0.0
    step_size = 1.0
    for _ in range(line_search):
        new, Xn, Un = rollout(X, U, k, K, step_size)
        if new < current:
            return new, Un, Xn, K, (0.5 * regularization if regularization > 1e-6 else 0.0)
        step_size *= 0.5
    return current, U, X, K, min(max(4 * regularization, 1e-3), MAX_REGULARIZATION)
