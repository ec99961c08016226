"""Swing-up and balance by sampling-based model-predictive control (MPPI) on MuJoCo rollouts.

Real-time budget: at 250 Hz a control step has 4 ms, and one RK4 step of the
Qube model costs about 10 us in `mujoco.rollout` on the machine this was
measured on. The planner therefore

* spreads its work over the control steps of each 20 ms knot: every call rolls
  out one slice of the candidate plans, so all calls cost about the same and
  results do not depend on timing (a background thread would make them depend
  on the machine's load, and could not keep pace with a simulation run faster
  than real time);
* plans on a copy of the model stepped with RK4 at the knot interval (20 ms)
  instead of 4 ms: over its 0.4 s horizon the median error against the 4 ms
  model is 5 mrad in alpha (90th percentile 0.07 rad, for random voltages from
  random states), small beside the model error of a real Qube, and the plan is
  made again from the measured state every knot. A model with faster modes gets
  shorter planning steps (`STABLE_RK4_STEP`): the calibrated real Qube-Servo 2's
  damping puts them near -250 /s, where one 20 ms RK4 step diverges;
* warm-starts every knot from the last plan, so 16 candidates per knot suffice.

`benchmarks/controllers.py` measures the compute per step.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import mujoco
import numpy as np
from mujoco import rollout

from qube_suite.conventions import DEFAULT_VOLTAGE_LIMIT
from qube_suite.devices.qube import simulation as qube
from qube_suite.devices.qube.controllers.base import Controller
from qube_suite.devices.qube.controllers.follow import arm_set_point
from qube_suite.devices.qube.controllers.linearization import fastest_mode
from qube_suite.devices.qube.controllers.lqr import BalanceLQR
from qube_suite.devices.qube.controllers.swingup import CATCH_VOLTAGE, RELEASE_VOLTAGE

STABLE_RK4_STEP = 2.0
"""Largest |lambda| h of a planning step, lambda the model's fastest mode (RK4 is stable to 2.78 on the
negative real axis)."""
ARM_MARGIN = math.radians(80.0)
"""Planned trajectories pay a large cost for the arm beyond +-80 degrees."""


class SamplingMPC(Controller):
    """Model-predictive path-integral control (MPPI) with an LQR near upright.

    The plan holds one voltage per knot (`knot_interval` seconds). During each
    knot the controller applies the plan's current voltage and, spread over the
    knot's control steps, evaluates `samples` perturbed copies of the rest of the
    plan: each is simulated for `horizon` seconds from the state measured at the
    knot's start, first with the current voltage to the next knot, on a copy of
    the MuJoCo model stepped at `planning_timestep` (with `mujoco.rollout`). At
    the knot's last step the plan moves towards the cheap candidates, weighted by
    exp(-cost / temperature), and takes effect at the next knot. Cost per
    simulated step:

        (1 - cos alpha) + 0.1 (theta - theta_target)^2 + 0.001 dtheta^2
        + 100 if |theta| > 80 degrees

    The balance LQR (`BalanceLQR`) takes over inside the same cost-to-go
    ellipsoid as in `SwingupController`, with the arm set-point of `FollowController`.

    Args:
        control_frequency: control steps per second (Hz).
        voltage_limit: largest voltage (V) it plans or outputs.
        parameters: physical parameters of the model it plans with (nominal by default).
        latency_steps: as `Controller`.
        samples: candidate plans per knot.
        horizon: planning horizon (s).
        knot_interval: time (s) each planned voltage is held; a multiple of the
            control period.
        planning_timestep: RK4 timestep (s) of the planning model; it divides the
            knot interval.
        threads: rollout threads.
        seed: seed of the sampling noise.
    """

    name = "mpc"
    tasks = ("swingup", "swingup_sparse", "swingup_follow", "swingup_follow_sparse",
             "balance", "balance_sparse", "balance_follow", "balance_follow_sparse")

    def __init__(self, control_frequency: float = 250.0, voltage_limit: float = DEFAULT_VOLTAGE_LIMIT,
                 parameters: Mapping[str, float] | None = None, latency_steps: int = 0, samples: int = 16,
                 horizon: float = 0.4, knot_interval: float = 0.02, planning_timestep: float = 0.02,
                 threads: int = 1, seed: int = 0):
        super().__init__(control_frequency, voltage_limit, parameters, latency_steps)
        self._balance = BalanceLQR(control_frequency, voltage_limit, parameters)
        self._catch_level = self._balance.level_for_voltage(CATCH_VOLTAGE)
        self._release_level = self._balance.level_for_voltage(RELEASE_VOLTAGE)

        physics = qube.make_physics(control_frequency, parameters)
        self._model = physics.model.ptr
        steps_per_knot = max(1, round(knot_interval / planning_timestep),
                             math.ceil(knot_interval * fastest_mode(physics) / STABLE_RK4_STEP))
        self._model.opt.timestep = knot_interval / steps_per_knot
        self._calls_per_knot = max(1, round(knot_interval * control_frequency))
        self._knots = max(1, round(horizon / knot_interval))
        self._steps_per_knot = steps_per_knot
        self._threads = max(1, threads)
        self._rollout = rollout.Rollout(nthread=self._threads if self._threads > 1 else 0)
        self._datas = [mujoco.MjData(self._model) for _ in range(self._threads)]
        self._scratch = mujoco.MjData(self._model)
        self._signature = mujoco.mjtState.mjSTATE_FULLPHYSICS
        self._initial_state = np.empty(mujoco.mj_stateSize(self._model, self._signature))
        steps = (self._knots + 1) * steps_per_knot
        self._slices = [_Slice(which, self._model, steps, self._initial_state.size)
                        for which in np.array_split(np.arange(samples), self._calls_per_knot) if which.size]
        self._samples = samples
        self._seed = seed
        self.reset()

    @property
    def planning_steps_per_knot(self) -> int:
        """RK4 steps of the planning model per knot."""
        return self._steps_per_knot

    def reset(self) -> None:
        super().reset()
        self._random = np.random.default_rng(self._seed)
        self._plan = np.zeros(self._knots)
        self._next_plan = None
        self._phase = 0
        self._balancing = False

    def voltage_for(self, state: np.ndarray, target: float = 0.0) -> float:
        """Voltage (V) for `state` [theta, alpha, dtheta, dalpha] with the arm's target at `target` (rad)."""
        set_point = arm_set_point(state[0], target)
        level = self._release_level if self._balancing else self._catch_level
        self._balancing = self._balance.cost_to_go(state, set_point) < level
        if self._balancing:
            self._phase, self._next_plan = 0, None
            return self._balance.voltage_for(state, set_point)
        if self._phase == 0:
            self._start_knot(state, target)
        if self._phase < len(self._slices):
            self._evaluate(self._slices[self._phase])
        self._phase += 1
        if self._phase == self._calls_per_knot:
            self._next_plan = self._improved_plan()
            self._phase = 0
        return self._voltage

    def close(self) -> None:
        self._rollout.close()

    def _start_knot(self, state: np.ndarray, target: float) -> None:
        """Take up the plan made during the last knot and draw this knot's candidates."""
        if self._next_plan is not None:
            self._plan = self._next_plan
        self._voltage = float(self._plan[0])
        self._target = target
        following = np.append(self._plan[1:], self._plan[-1])
        noise = self._random.normal(0.0, 0.5 * self.voltage_limit, (self._samples, self._knots))
        noise[0] = 0.0  # keep the current plan among the candidates
        self._candidates = np.clip(following + noise, -self.voltage_limit, self.voltage_limit)
        self._costs = np.empty(self._samples)
        self._scratch.qpos[:] = state[:2]
        self._scratch.qvel[:] = state[2:]
        mujoco.mj_getState(self._model, self._scratch, self._initial_state, self._signature)

    def _evaluate(self, part: _Slice) -> None:
        """Simulate and cost one slice of the candidates, each after this knot's voltage."""
        first = self._steps_per_knot
        part.initial_state[:] = self._initial_state
        part.control[:, :first, 0] = self._voltage
        part.control[:, first:, 0] = np.repeat(self._candidates[part.which], first, axis=1)
        self._rollout.rollout(part.models, self._datas, part.initial_state, part.control, skip_checks=True,
                              nstep=part.control.shape[1], state=part.state, sensordata=part.sensordata,
                              control_spec=mujoco.mjtState.mjSTATE_CTRL.value)
        states = part.state[:, first:]  # the candidates' own knots
        theta, alpha, dtheta = states[:, :, 1], states[:, :, 2], states[:, :, 3]  # after time
        cost = (1.0 - np.cos(alpha)) + 0.1 * (theta - self._target) ** 2 + 0.001 * dtheta**2
        cost += 100.0 * (np.abs(theta) > ARM_MARGIN)
        total = cost.sum(axis=1)
        self._costs[part.which] = np.where(np.isfinite(total), total, np.inf)  # a rollout that diverged

    def _improved_plan(self) -> np.ndarray:
        """The candidates averaged with weights exp(-cost / temperature); the current plan if every
        candidate's rollout diverged."""
        finite = np.isfinite(self._costs)
        if not finite.any():
            return self._plan
        total, candidates = self._costs[finite], self._candidates[finite]
        spread = np.median(total) - total.min()
        weights = np.exp(-(total - total.min()) / (0.1 * spread + 1e-9))
        return weights @ candidates / weights.sum()


class _Slice:
    """The candidates one call simulates, with preallocated rollout buffers."""

    def __init__(self, which: np.ndarray, model: mujoco.MjModel, steps: int, state_size: int):
        self.which = which
        self.models = [model] * which.size
        self.initial_state = np.empty((which.size, state_size))
        self.control = np.empty((which.size, steps, 1))
        self.state = np.empty((which.size, steps, state_size))
        self.sensordata = np.empty((which.size, steps, 0))
