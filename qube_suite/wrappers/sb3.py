"""The vector environment as a stable-baselines3 `VecEnv`, and a policy feature map as a `VecEnv` wrapper.

    from qube_suite.wrappers.sb3 import make_sb3_vec_env
    venv = make_sb3_vec_env("QubeSuite/Swingup-v0", num_envs=16)
    model = stable_baselines3.PPO("MlpPolicy", venv)

This module imports stable-baselines3, which qube_suite does not depend on; nothing
else in qube_suite imports this module.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from qube_suite.wrappers.vector_env import QubeVectorEnv


class SB3VecEnv(VecEnv):
    """A `QubeVectorEnv` with stable-baselines3's `VecEnv` API.

    SB3 resets a finished world within the step that ends it and passes the last
    observation as `info["terminal_observation"]`, with `info["TimeLimit.truncated"]`
    telling truncation from termination; the wrapped environment must therefore use
    `autoreset_mode=SAME_STEP`. Attributes and methods reached through `get_attr`,
    `set_attr` and `env_method` are those of the `QubeVectorEnv`, which serves every
    index. As in SB3's `DummyVecEnv`, `reset_infos[i]` is world i's info at the start of
    its current episode: with a randomization, what it drew (`"parameters"`, `"effects"`).
    """

    def __init__(self, env: QubeVectorEnv):
        if env.autoreset_mode is not AutoresetMode.SAME_STEP:
            raise ValueError("stable-baselines3 needs autoreset_mode=SAME_STEP; make the vector env with it")
        self.env = env  # before SB3's constructor, which asks get_attr for the render mode
        self._actions: np.ndarray | None = None
        super().__init__(env.num_envs, env.single_observation_space, env.single_action_space)

    def reset(self) -> np.ndarray:
        seeds = self._seeds if any(seed is not None for seed in self._seeds) else None
        observations, info = self.env.reset(seed=seeds)
        self._reset_seeds()
        self.reset_infos = [world_info(info, world) for world in range(self.num_envs)]
        return observations

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        observations, rewards, terminated, truncated, info = self.env.step(self._actions)
        dones = terminated | truncated
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for world in np.flatnonzero(dones).tolist():
            infos[world]["terminal_observation"] = info["final_obs"][world]
            infos[world]["TimeLimit.truncated"] = bool(truncated[world])
            self.reset_infos[world] = world_info(info, world)
        return observations, rewards.astype(np.float32), dones, infos

    def close(self) -> None:
        self.env.close()

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        return [getattr(self.env, attr_name)] * len(self._indices(indices))

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        setattr(self.env, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        method = getattr(self.env, method_name)
        return [method(*method_args, **method_kwargs) for _ in self._indices(indices)]

    def env_is_wrapped(self, wrapper_class: type[gymnasium.Wrapper], indices=None) -> list[bool]:
        return [False] * len(self._indices(indices))

    def _indices(self, indices: None | int | Iterable[int]) -> Sequence[int]:
        if indices is None:
            return range(self.num_envs)
        return [indices] if isinstance(indices, int) else list(indices)


def world_info(info: dict[str, Any], world: int) -> dict[str, Any]:
    """World `world`'s entries of a Gymnasium vector environment's `info` (each key's value at
    `world` where its mask `_key` is set; nested dicts likewise), as its single environment's
    info would hold them."""
    return {key: world_info(value, world) if isinstance(value, dict) else value[world]
            for key, value in info.items()
            if not key.startswith("_") and key not in ("final_obs", "final_info") and info[f"_{key}"][world]}


def make_sb3_vec_env(env_id: str, num_envs: int, **kwargs) -> SB3VecEnv:
    """`gymnasium.make_vec(env_id, num_envs, autoreset_mode=SAME_STEP, **kwargs)` as an SB3 `VecEnv`."""
    env = gymnasium.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point",
                             autoreset_mode=AutoresetMode.SAME_STEP, **kwargs)
    return SB3VecEnv(env)


class VecFeatures(VecEnvWrapper):
    """Observations (and terminal observations) of `venv` mapped by `features`, a function of a
    batch of observations (n, k) -> (n, m) (`qube_suite.policies.features`), as float32."""

    def __init__(self, venv: VecEnv, features: Callable[[np.ndarray], np.ndarray]):
        self._features = features
        size = features(np.zeros((1,) + venv.observation_space.shape)).shape[1]
        super().__init__(venv, observation_space=spaces.Box(-np.inf, np.inf, (size,), np.float32))

    def reset(self) -> np.ndarray:
        return self._map(self.venv.reset())

    def step_wait(self):
        observations, rewards, dones, infos = self.venv.step_wait()
        for info in infos:
            if "terminal_observation" in info:
                info["terminal_observation"] = self._map(info["terminal_observation"][None, :])[0]
        return self._map(observations), rewards, dones, infos

    def _map(self, observations: np.ndarray) -> np.ndarray:
        return self._features(observations).astype(np.float32)
