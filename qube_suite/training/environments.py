"""Vectorised environments for training and evaluation with stable-baselines3 (imports it).

The simulated domain without randomization runs as the native vector environment
(all worlds in one MuJoCo rollout call) through `qube_suite.wrappers.sb3`; with a
randomization, each world is a single environment in SB3's `DummyVecEnv` (the
native vector env does not randomize yet); the hardware domain is one substitute
board per process (`SubprocVecEnv`), as real boards are separate machines.
Observations leave through the policy's feature map (`VecFeatures`) and episode
returns are recorded by `VecMonitor`.
"""

from __future__ import annotations

from typing import Any

import gymnasium
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv, VecMonitor

from qube_suite.policies.features import FEATURE_MAPS
from qube_suite.wrappers.registration import gymnasium_id
from qube_suite.wrappers.sb3 import VecFeatures, make_sb3_vec_env


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
    if domain == "qube" and randomization is None and not domain_kwargs:
        venv = make_sb3_vec_env(env_id, num_envs=num_envs, threads=1)
    elif domain == "qube":
        venv = DummyVecEnv([_single(env_id, randomization=randomization, domain_kwargs=domain_kwargs)
                            for _ in range(num_envs)])
    else:
        boards = [_single(env_id, randomization=randomization, domain_kwargs=domain_kwargs)
                  for _ in range(num_envs)]
        venv = SubprocVecEnv(boards) if num_envs > 1 else DummyVecEnv(boards)
    venv.seed(seed)
    return venv


def make_vec_env(task: str, num_envs: int, seed: int, feature_map: str = "trig", **kwargs: Any) -> VecEnv:
    """`raw_vec_env(...)` with its episode returns recorded and observations mapped to features."""
    return VecFeatures(VecMonitor(raw_vec_env(task, num_envs, seed, **kwargs)), FEATURE_MAPS[feature_map])
