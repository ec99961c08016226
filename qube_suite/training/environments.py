"""Vectorised environments for training and evaluation with stable-baselines3 (imports it).

The simulated domain runs as the native vector environment (all worlds in one
MuJoCo rollout call, each with its own randomization draws) through
`qube_suite.wrappers.sb3`; with changed physical parameters (`domain_kwargs`), which
it does not take, each world is a single environment in SB3's `DummyVecEnv`; the
hardware domain is one substitute board per process (`SubprocVecEnv`), as real
boards are separate machines.
Observations leave through the policy's feature map (`VecFeatures`) and episode
returns are recorded by `VecMonitor`. Training environments of swing-up tasks in
simulation may start some episodes anywhere (`ExploringStarts`); evaluation
environments always start as the task does.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import gymnasium
import numpy as np
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv, VecMonitor

from qube_suite.policies.features import FEATURE_MAPS
from qube_suite.wrappers.registration import gymnasium_id
from qube_suite.wrappers.sb3 import VecFeatures, make_sb3_vec_env


class ExploringStarts:
    """A task's start distribution that, in a `fraction` of episodes, starts anywhere instead.

    "Anywhere": alpha uniform on the circle, theta uniform in +-0.5 rad, both
    velocities uniform in +-1 rad/s. Swing-up policies then meet the upright
    region, where balancing is learnt, from the first episodes on, instead of only
    after they have learnt to swing up. Drawn from the task's random state.
    """

    def __init__(self, task_start: Callable[[np.random.RandomState], np.ndarray], fraction: float):
        self._task_start = task_start
        self._fraction = fraction

    def __call__(self, random: np.random.RandomState) -> np.ndarray:
        if random.random_sample() >= self._fraction:
            return self._task_start(random)
        return np.array([random.uniform(-0.5, 0.5), random.uniform(-math.pi, math.pi),
                         random.uniform(-1.0, 1.0), random.uniform(-1.0, 1.0)])


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
                domain_kwargs: dict[str, Any] | None = None) -> VecEnv:
    """`num_envs` environments of `task` on `domain` with the standard observation, seeded
    `seed`, `seed + 1`, ... at their first reset."""
    env_id = gymnasium_id(task, domain)
    if domain == "qube" and not domain_kwargs:
        venv = make_sb3_vec_env(env_id, num_envs=num_envs, threads=1, randomization=randomization)
    elif domain == "qube":
        venv = DummyVecEnv([_single(env_id, randomization=randomization, domain_kwargs=domain_kwargs)
                            for _ in range(num_envs)])
    else:
        boards = [_single(env_id, randomization=randomization, domain_kwargs=domain_kwargs)
                  for _ in range(num_envs)]
        venv = SubprocVecEnv(boards) if num_envs > 1 else DummyVecEnv(boards)
    venv.seed(seed)
    return venv


def make_vec_env(task: str, num_envs: int, seed: int, feature_map: str = "trig",
                 exploring_starts: float = 0.0, **kwargs: Any) -> VecEnv:
    """`raw_vec_env(...)` with its episode returns recorded and observations mapped to features;
    `exploring_starts`: the fraction of episodes that start anywhere (simulation only)."""
    venv = raw_vec_env(task, num_envs, seed, **kwargs)
    if exploring_starts:
        explore_starts(venv, exploring_starts)
    return VecFeatures(VecMonitor(venv), FEATURE_MAPS[feature_map])
