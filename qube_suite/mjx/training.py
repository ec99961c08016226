"""Training on the JAX backend with Brax's PPO, written as the project's numpy policy files.

    from qube_suite.mjx import training
    result = training.train("swingup", steps=60_000_000, randomization="sim2real", out="runs/swingup_jax")

The policy file (`policy.npz`, `qube_suite.policies.mlp`) runs unchanged on the
numpy domains, the hardware, the CLI and `evaluate`: its features are the task's
trig observation, its normalisation Brax's running statistics, its layers Brax's
policy network (the mean of the action), squashed by tanh and scaled to the
task's voltage limit as the JAX environment scales its actions.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import pathlib
import time
from collections.abc import Callable, Mapping
from typing import Any

import jax
import numpy as np
from brax.training.agents.ppo import networks as ppo_networks
from brax.training.agents.ppo import train as ppo

from qube_suite.mjx import brax_compat
from qube_suite.mjx.environment import QubeMjx
from qube_suite.policies import mlp

HYPERPARAMETERS: dict[str, Any] = {
    "num_envs": 4096, "num_eval_envs": 128, "num_evals": 6, "reward_scaling": 10.0, "unroll_length": 32,
    "num_minibatches": 32, "num_updates_per_batch": 8, "discounting": 0.995, "learning_rate": 1e-3,
    "entropy_cost": 1e-2, "batch_size": 1024, "normalize_observations": True, "max_grad_norm": 1.0,
    "policy_hidden_layer_sizes": (32, 32, 32, 32), "value_hidden_layer_sizes": (256, 256, 256, 256, 256),
}
"""Brax PPO's settings (MuJoCo Playground's for dm_control tasks, with 4096 worlds and 8 updates per
batch); the episode length is the task's (2048 steps at 250 Hz)."""
ENVIRONMENT_SETTINGS: dict[str, Any] = {"history": 0, "privileged_critic": False}
"""Settings of the environment trained on (`QubeMjx`'s keywords), given with the hyperparameters: the
policy's observation history, and a critic that sees the exact state and the world's plant."""
NETWORK_KEYS = ("policy_hidden_layer_sizes", "value_hidden_layer_sizes")
EPISODE_STEPS = 2048
"""Control steps per episode: the numpy environments' time limit at 250 Hz."""
ACTIVATION = "swish"
"""Brax's default activation of its networks, which the policy file names."""


@dataclasses.dataclass(frozen=True)
class Result:
    """A finished training: the policy file, and the evaluations (env steps, mean return) with the
    wall time (s, compilation included) at each."""

    policy_path: pathlib.Path
    evaluations: list[tuple[int, float, float]]
    wall_time: float


def train(task: str = "swingup", steps: int = 60_000_000, randomization="none", seed: int = 0,
          out: str | pathlib.Path = "runs/jax", hyperparameters: Mapping[str, Any] | None = None,
          progress: Callable[[str], None] | None = print, snapshots: bool = False,
          task_kwargs: Mapping[str, Any] | None = None) -> Result:
    """Train `task` (with the settings `task_kwargs`, e.g. a follow task's target schedule) on MJX with
    Brax's PPO for `steps` env steps, worlds drawn from `randomization`; write `out/policy.npz` and
    `out/training.json` (and with `snapshots`, the policy of every evaluation as
    `out/snapshots/<steps>.npz`)."""
    brax_compat.ensure_device_put_replicated()
    known = {**HYPERPARAMETERS, **ENVIRONMENT_SETTINGS}
    settings = {**known, **dict(hyperparameters or {})}
    unknown = set(settings) - set(known)
    if unknown:
        raise ValueError(f"unknown hyperparameters {sorted(unknown)}; known: {', '.join(known)}")
    world = {key: settings[key] for key in ENVIRONMENT_SETTINGS}
    world["task_kwargs"] = dict(task_kwargs or {})
    env = QubeMjx(task, randomization=randomization, seed=seed, **world)
    eval_env = QubeMjx(task, randomization=randomization, seed=seed + 1_000_000, **world)
    critic = {"value_obs_key": "privileged_state"} if env.privileged_critic else {}
    network = functools.partial(ppo_networks.make_ppo_networks, **critic,
                                **{key: tuple(settings[key]) for key in NETWORK_KEYS})
    start = time.perf_counter()
    evaluations: list[tuple[int, float, float]] = []

    def report(step: int, metrics: Mapping[str, Any]) -> None:
        returned = float(metrics.get("eval/episode_reward", float("nan")))
        evaluations.append((int(step), returned, time.perf_counter() - start))
        if progress is not None:
            progress(f"{task}: {int(step):>11,} steps, return {returned:7.1f}, "
                     f"{time.perf_counter() - start:6.1f} s")

    out = pathlib.Path(out)

    def snapshot(step: int, _, params) -> None:
        if snapshots:
            moment = {"steps": int(step), "wall_time_s": time.perf_counter() - start}
            policy = export(params, task, env.task.voltage_limit, moment, env.history,
                            env.task_observation_size)
            mlp.save(policy, out / "snapshots" / f"{int(step)}.npz")

    ppo_settings = {key: value for key, value in settings.items() if key in HYPERPARAMETERS
                    and key not in NETWORK_KEYS}
    randomized = bool(env.config.parameters) or bool(env.config.effects)
    _, params, _ = ppo.train(environment=env, eval_env=eval_env, num_timesteps=steps, seed=seed,
                             episode_length=EPISODE_STEPS, network_factory=network, progress_fn=report,
                             policy_params_fn=snapshot,
                             randomization_fn=env.draw_worlds if randomized else None, **ppo_settings)
    wall_time = time.perf_counter() - start
    record = {"task": task, "steps": steps, "randomization": randomization if isinstance(randomization, str)
              else "custom", "seed": seed, "backend": "jax", "algo": "brax_ppo",
              "task_kwargs": world["task_kwargs"],
              "hyperparameters": {key: list(v) if isinstance(v, tuple) else v for key, v in settings.items()},
              "evaluations": evaluations, "wall_time_s": wall_time,
              "devices": [str(device) for device in jax.devices()]}
    policy = export(params, task, env.task.voltage_limit, record, env.history, env.task_observation_size)
    path = mlp.save(policy, out / "policy.npz")
    (out / "training.json").write_text(json.dumps(record, indent=1))
    return Result(path, evaluations, wall_time)


def export(params, task: str, voltage_limit: float, record: Mapping[str, Any],
           history: int = 0, observation_size: int = 4) -> mlp.MLPPolicy:
    """The numpy policy of Brax PPO's `params` (normalizer, policy, value): the policy network's layers
    up to the action's mean (its first output), normalised by the running statistics (of the policy's
    part of the observation, with a privileged critic); `history` and `observation_size` (4, or 5 with a
    follow target): the environment's."""
    normalizer, policy = params[0], params[1]
    if isinstance(normalizer.mean, Mapping):  # a privileged critic's observation: the policy's part
        normalizer = normalizer.replace(mean=normalizer.mean["state"], std=normalizer.std["state"])
    layers = policy["params"]
    names = sorted(layers, key=lambda name: int(name.rsplit("_", 1)[1]))
    weights = [np.asarray(layers[name]["kernel"], dtype=np.float64).T for name in names]
    biases = [np.asarray(layers[name]["bias"], dtype=np.float64) for name in names]
    weights[-1], biases[-1] = weights[-1][:1], biases[-1][:1]  # the mean; the rest is the scale
    std = np.asarray(normalizer.std, dtype=np.float64)
    meta = {"format": mlp.FORMAT, "feature_map": "trig", "activation": ACTIVATION, "squash": True,
            "epsilon": 0.0, "clip": 1e6, "voltage_limit": float(voltage_limit),
            "observation_size": int(observation_size), "history": int(history), "task": task,
            "algo": "brax_ppo", "training": dict(record)}
    return mlp.MLPPolicy(weights, biases, np.asarray(normalizer.mean, dtype=np.float64), std**2, meta)
