"""Swing-up and balance by sampling-based model-predictive control (MPPI) on MuJoCo rollouts."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import mujoco
import numpy as np
from mujoco import rollout

from qube_suite.baselines.base import Controller, split_observation
from qube_suite.baselines.lqr import BalanceLQR
from qube_suite.domains import qube
from qube_suite.tasks.base import DEFAULT_VOLTAGE_LIMIT

ARM_MARGIN = math.radians(80.0)
"""Planned trajectories pay a large cost for the arm beyond +-80 degrees."""


class SamplingMPC(Controller):
    """Model-predictive path-integral control (MPPI) with an LQR near upright.

    Every `knot_interval` seconds it perturbs its voltage plan `samples` times,
    simulates each candidate for `horizon` seconds on the MuJoCo model (with
    `mujoco.rollout`), and moves the plan towards the cheap candidates, weighted
    by exp(-cost / temperature). Cost per simulated step:

        (1 - cos alpha) + 0.1 (theta - theta_target)^2 + 0.001 dtheta^2
        + 100 if |theta| > 80 degrees

    Within `handover_angle` of upright the LQR of `BalanceLQR` takes over.

    Args:
        control_frequency: control steps per second (Hz).
        voltage_limit: largest voltage (V) it plans or outputs.
        parameters: physical parameters of the model it plans with (nominal by default).
        samples: candidate plans per replanning.
        horizon: planning horizon (s).
        knot_interval: time (s) each planned voltage is held; the plan is revised
            at every knot.
        handover_angle: |alpha| (rad) below which the LQR acts.
        threads: rollout threads.
        seed: seed of the sampling noise.
    """

    name = "mpc"
    tasks = ("swingup", "swingup_sparse", "swingup_follow", "swingup_follow_sparse",
             "balance", "balance_sparse", "balance_follow", "balance_follow_sparse")

    def __init__(self, control_frequency: float = 250.0, voltage_limit: float = DEFAULT_VOLTAGE_LIMIT,
                 parameters: Mapping[str, float] | None = None, samples: int = 64, horizon: float = 0.8,
                 knot_interval: float = 0.02, handover_angle: float = 0.3, threads: int = 2,
                 seed: int = 0):
        self.voltage_limit = voltage_limit
        self.samples = samples
        self.handover_angle = handover_angle
        self._balance = BalanceLQR(control_frequency, voltage_limit, parameters)
        self._physics = qube.make_physics(control_frequency, parameters)
        self._model = self._physics.model.ptr
        substeps = qube.substeps_per_control_period(control_frequency)
        self._steps_per_knot = max(1, round(knot_interval * control_frequency))
        self._knots = max(1, round(horizon / knot_interval))
        self._physics_steps_per_knot = self._steps_per_knot * substeps
        self._threads = max(1, threads)
        self._rollout = rollout.Rollout(nthread=self._threads if self._threads > 1 else 0)
        self._datas = [mujoco.MjData(self._model) for _ in range(self._threads)]
        self._scratch = mujoco.MjData(self._model)
        self._signature = mujoco.mjtState.mjSTATE_FULLPHYSICS
        self._initial_state = np.empty(mujoco.mj_stateSize(self._model, self._signature))
        self._seed = seed
        self.reset()

    def reset(self) -> None:
        self._random = np.random.default_rng(self._seed)
        self._plan = np.zeros(self._knots)
        self._steps_since_replan = self._steps_per_knot  # replan at the first call

    def __call__(self, observation: Any) -> float:
        state, target = split_observation(observation)
        if abs(state[1]) < self.handover_angle:
            self._steps_since_replan = self._steps_per_knot
            return self._balance.voltage_for(state, target)
        if self._steps_since_replan >= self._steps_per_knot:
            self._replan(state, target)
            self._steps_since_replan = 0
        self._steps_since_replan += 1
        return float(self._plan[0])

    def close(self) -> None:
        self._rollout.close()

    def _replan(self, state: np.ndarray, target: float) -> None:
        """Shift the plan by one knot and improve it by one MPPI iteration from `state`."""
        self._plan = np.append(self._plan[1:], self._plan[-1])
        noise = self._random.normal(0.0, 0.5 * self.voltage_limit, (self.samples, self._knots))
        noise[0] = 0.0  # keep the current plan among the candidates
        candidates = np.clip(self._plan + noise, -self.voltage_limit, self.voltage_limit)

        self._scratch.qpos[:] = state[:2]
        self._scratch.qvel[:] = state[2:]
        mujoco.mj_getState(self._model, self._scratch, self._initial_state, self._signature)
        controls = np.repeat(candidates, self._physics_steps_per_knot, axis=1)[:, :, None]
        states, _ = self._rollout.rollout(self._model, self._datas, self._initial_state[None], controls)
        theta, alpha, dtheta = states[:, :, 1], states[:, :, 2], states[:, :, 3]  # after time

        cost = (1.0 - np.cos(alpha)) + 0.1 * (theta - target) ** 2 + 0.001 * dtheta**2
        cost += 100.0 * (np.abs(theta) > ARM_MARGIN)
        total = cost.sum(axis=1)
        spread = np.median(total) - total.min()
        weights = np.exp(-(total - total.min()) / (0.1 * spread + 1e-9))
        self._plan = weights @ candidates / weights.sum()
