"""Vectorised environments for training and evaluation with stable-baselines3 (imports it).

The simulated domain runs as the native vector environment (all worlds in one
MuJoCo rollout call, each with its own randomization draws) through
`qube_suite.wrappers.sb3`; with changed physical parameters (`domain_kwargs`), which
it does not take, each world is a single environment in SB3's `DummyVecEnv`; the
hardware domain is one substitute board per process (`SubprocVecEnv`), as real
boards are separate machines.
Observations leave through the policy's feature map (`VecFeatures`), extended by
the last steps' features and voltages for policies with history (`VecHistory`),
and episode returns are recorded by `VecMonitor`. Training environments of swing-up tasks in
simulation may start some episodes anywhere (`ExploringStarts`); evaluation
environments always start as the task does.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv, VecEnvWrapper, VecMonitor

from qube_suite.policies.features import FEATURE_MAPS
from qube_suite.policies.history import History, input_size
from qube_suite.wrappers.registration import gymnasium_id
from qube_suite.wrappers.sb3 import VecFeatures, make_sb3_vec_env


class ExploringStarts:
    """A task's start distribution that, in a `fraction` of episodes, starts anywhere instead.

    "Anywhere": theta uniform in +-0.5 rad, alpha uniform on the circle, and, in
    equal shares, either both velocities uniform in +-1 rad/s, or the arm at rest
    and the pendulum swinging with about the energy of rest upright (between
    `APPROACH_ENERGY` times the swing-up energy 2 mp g l, rigid-body model of
    `qube_suite.devices.qube.controllers.model`). Swing-up policies then meet the upright region
    from the first episodes on, both slowly (where balancing is learnt) and at the
    end of a swing (where catching is learnt), instead of only after they have
    learnt to swing up; without the swinging starts PPO settled on spinning the
    pendulum round (about 0.6 per step). Drawn from the task's random state.
    """

    APPROACH_ENERGY = (-0.15, 0.05)

    def __init__(self, task_start: Callable[[np.random.RandomState], np.ndarray], fraction: float):
        from qube_suite.devices.qube.controllers.model import RigidBodyModel

        self._task_start = task_start
        self._fraction = fraction
        self._model = RigidBodyModel.from_parameters()

    def __call__(self, random: np.random.RandomState) -> np.ndarray:
        if random.random_sample() >= self._fraction:
            return self._task_start(random)
        theta, alpha = random.uniform(-0.5, 0.5), random.uniform(-math.pi, math.pi)
        if random.random_sample() < 0.5:
            return np.array([theta, alpha, random.uniform(-1.0, 1.0), random.uniform(-1.0, 1.0)])
        model = self._model
        energy = random.uniform(*self.APPROACH_ENERGY) * model.swing_up_energy
        kinetic = energy - model.gravity_torque * (math.cos(alpha) - 1.0)  # J, arm at rest
        speed = math.sqrt(2.0 * max(kinetic, 0.0) / model.pendulum_inertia)
        return np.array([theta, alpha, 0.0, speed if random.random_sample() < 0.5 else -speed])


def explore_starts(venv: VecEnv, fraction: float) -> None:
    """Give the tasks of a simulated `raw_vec_env` `ExploringStarts` (from their next episode on)."""
    tasks = [venv.env.task] if hasattr(venv, "env") else [env.unwrapped.task for env in venv.envs]
    for task in tasks:
        task.initial_state = ExploringStarts(task.initial_state, fraction)


def _single(env_id: str, **kwargs: Any):
    def make() -> gymnasium.Env:
        import qube_suite  # noqa: F401  (registers the ids in a fresh subprocess)

        return gymnasium.make(env_id, disable_env_checker=True, **kwargs)

    return make


def raw_vec_env(task: str, num_envs: int, seed: int, domain: str = "qube", randomization: Any = None,
                domain_kwargs: dict[str, Any] | None = None,
                task_kwargs: dict[str, Any] | None = None,
                environment_kwargs: dict[str, Any] | None = None) -> VecEnv:
    """`num_envs` environments of `task` on `domain` with the standard observation, seeded
    `seed`, `seed + 1`, ... at their first reset; `task_kwargs` (e.g. a follow task's target
    schedule) and `environment_kwargs` (`control_frequency`, `time_limit`) as in `suite.load`."""
    env_id = gymnasium_id(task, domain)
    task_kwargs = {**(task_kwargs or {}), **(environment_kwargs or {})}  # gymnasium.make takes both
    if domain == "qube" and not domain_kwargs and environment_kwargs:
        raise ValueError("environment_kwargs: the pendulum's native vector environment runs at its defaults; "
                         "give domain_kwargs to train on single environments")
    if domain == "qube" and not domain_kwargs:
        venv = make_sb3_vec_env(env_id, num_envs=num_envs, threads=1, randomization=randomization,
                                **task_kwargs)
    elif domain == "qube":
        venv = DummyVecEnv([_single(env_id, randomization=randomization, domain_kwargs=domain_kwargs,
                                    **task_kwargs) for _ in range(num_envs)])
    else:
        boards = [_single(env_id, randomization=randomization, domain_kwargs=domain_kwargs, **task_kwargs)
                  for _ in range(num_envs)]
        venv = SubprocVecEnv(boards) if num_envs > 1 else DummyVecEnv(boards)
    venv.seed(seed)
    return venv


class VecHistory(VecEnvWrapper):
    """Feature observations of `venv` extended by each world's last `length` features and
    voltages (`qube_suite.policies.history`), restarted at every episode's first step."""

    def __init__(self, venv: VecEnv, length: int):
        self._features_size = venv.observation_space.shape[0]
        size = input_size(self._features_size, length)
        super().__init__(venv, observation_space=spaces.Box(-np.inf, np.inf, (size,), np.float32))
        self._history = History(length, venv.num_envs, self._features_size, np.float32)
        self._last = np.zeros((venv.num_envs, self._features_size), np.float32)
        self._voltages = np.zeros(venv.num_envs, np.float32)

    def reset(self) -> np.ndarray:
        self._last = self.venv.reset()
        self._history.start(self._last)
        return self._history.inputs(self._last)

    def step_async(self, actions: np.ndarray) -> None:
        self._voltages = np.asarray(actions, dtype=np.float32).reshape(self.num_envs, -1)[:, 0]
        self.venv.step_async(actions)

    def step_wait(self):
        observations, rewards, dones, infos = self.venv.step_wait()
        self._history.push(self._last, self._voltages)
        for world, info in enumerate(infos):
            if "terminal_observation" in info:
                terminal = info["terminal_observation"][None, :]
                info["terminal_observation"] = self._history.inputs(terminal, [world])[0]
        if np.any(dones):
            self._history.start(observations[dones], dones)
        self._last = observations
        return self._history.inputs(observations), rewards, dones, infos


def make_vec_env(task: str, num_envs: int, seed: int, feature_map: str = "trig",
                 exploring_starts: float = 0.0, history: int = 0, **kwargs: Any) -> VecEnv:
    """`raw_vec_env(...)` with its episode returns recorded and observations mapped to features;
    `exploring_starts`: the fraction of episodes that start anywhere (simulation only); `history`:
    past steps added to the observations (`VecHistory`)."""
    venv = raw_vec_env(task, num_envs, seed, **kwargs)
    if exploring_starts:
        explore_starts(venv, exploring_starts)
    venv = VecFeatures(VecMonitor(venv), FEATURE_MAPS[feature_map])
    return VecHistory(venv, history) if history else venv
