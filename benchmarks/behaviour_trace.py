"""Record a few steps of every task on every domain, and compare two recordings bit for bit.

    python benchmarks/behaviour_trace.py record before.npz      # with one version of qube_suite
    python benchmarks/behaviour_trace.py record after.npz       # with another
    python benchmarks/behaviour_trace.py compare before.npz after.npz

A refactoring that must not change behaviour (e.g. moving a device's files) is checked
with it: observations, rewards, discounts and the voltages applied, through `suite.load`
on both domains, with every randomization preset and every effect, through
`gymnasium.make` for every id and through `gymnasium.make_vec`. Actions are drawn from
a seeded generator. `compare` prints every trace that differs and exits with status 1
if any does.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

STEPS = 40
"""Steps recorded per episode (two episodes per case)."""

EVERY_EFFECT = {"effects": {
    "quantization": {"counts_per_revolution": 2048},
    "velocity_filter": {"cutoff": 50.0},
    "observation_noise": {"std": [0.002, 0.002, 0.05, 0.05]},
    "observation_delay": {"steps": 1},
    "action_delay": {"steps": {"distribution": "uniform", "low": 0, "high": 1}},
    "voltage_offset": {"voltage": {"distribution": "uniform", "low": -0.05, "high": 0.05}},
    "dead_zone": {"voltage": 0.2},
    "saturation": {"voltage": 2.5},
}}
"""Every sensor and actuator effect at once (control jitter is in the `moderate` preset)."""


def _dm_env_trace(environment, seed: int) -> np.ndarray:
    """Rows of [observation..., reward, discount, voltage] of two episodes under seeded actions."""
    actions = np.random.default_rng(seed).uniform(-3.0, 3.0, (2, STEPS, 1))
    rows = []
    for episode in range(2):
        timestep = environment.reset()
        for action in actions[episode]:
            timestep = environment.step(action)
            observation = np.concatenate([np.ravel(value) for value in timestep.observation.values()])
            rows.append(np.concatenate([observation, [timestep.reward or 0.0, timestep.discount or 0.0,
                                                      environment.physics.voltage()]]))
            if timestep.last():
                break
    environment.close()
    return np.array(rows)


def _gymnasium_trace(env, seed: int, vector: bool = False) -> np.ndarray:
    """Rows of [observation..., reward, terminated, truncated] of seeded actions from a seeded reset."""
    shape = env.action_space.shape
    actions = np.random.default_rng(seed).uniform(-3.0, 3.0, (STEPS, *shape)).astype(np.float32)
    observation, _ = env.reset(seed=seed)
    rows = [np.ravel(observation)]
    for action in actions:
        observation, reward, terminated, truncated, _ = env.step(action)
        rows.append(np.concatenate([np.ravel(observation), np.ravel(reward), np.ravel(terminated),
                                    np.ravel(truncated)]))
        if not vector and (terminated or truncated):
            break
    env.close()
    return np.array(rows[1:])


def record(path: str) -> None:
    import gymnasium

    import qube_suite  # noqa: F401  (registers the ids)
    from qube_suite import suite
    from qube_suite.randomization import PRESETS
    from qube_suite.wrappers import GYMNASIUM_IDS, HARDWARE_GYMNASIUM_IDS

    traces = {}
    tasks = suite.TASKS_BY_DOMAIN["qube"]
    for index, task in enumerate(tasks):
        for domain in ("qube", "qube_hardware"):
            environment = suite.load(domain, task, task_kwargs={"random": index})
            traces[f"{domain}/{task}"] = _dm_env_trace(environment, index)
        for preset in PRESETS:
            environment = suite.load("qube", task, task_kwargs={"random": index}, randomization=preset)
            traces[f"qube/{task}/{preset}"] = _dm_env_trace(environment, index)
        for domain in ("qube", "qube_hardware"):
            environment = suite.load(domain, task, task_kwargs={"random": index}, randomization=EVERY_EFFECT)
            traces[f"{domain}/{task}/every_effect"] = _dm_env_trace(environment, index)
    def pendulum(ids):  # the pendulum's ids, in the order (and so with the seeds) they always had
        return [env_id for env_id in sorted(ids)
                if gymnasium.spec(env_id).kwargs["domain"] in ("qube", "qube_hardware")]

    for index, env_id in enumerate(pendulum(GYMNASIUM_IDS) + pendulum(HARDWARE_GYMNASIUM_IDS)):
        traces[f"gymnasium/{env_id}"] = _gymnasium_trace(gymnasium.make(env_id), index)
    for index, env_id in enumerate(pendulum(GYMNASIUM_IDS)):
        env = gymnasium.make_vec(env_id, num_envs=3, randomization="sim2real")
        traces[f"make_vec/{env_id}"] = _gymnasium_trace(env, index, vector=True)
    np.savez_compressed(path, **traces)
    print(f"{len(traces)} traces written to {path}")


def compare(before: str, after: str) -> int:
    """Print every trace that differs; return the number of differences."""
    old, new = np.load(before), np.load(after)
    differences = sorted(set(old.files) ^ set(new.files))
    for name in differences:
        print(f"{name}: only in {before if name in old.files else after}")
    for name in sorted(set(old.files) & set(new.files)):
        a, b = old[name], new[name]
        if a.shape != b.shape or not np.array_equal(a, b, equal_nan=True):
            differences.append(name)
            print(f"{name}: differs (shapes {a.shape}, {b.shape})")
    print(f"{len(set(old.files) & set(new.files))} traces compared, {len(differences)} differ")
    return len(differences)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)
    commands.add_parser("record").add_argument("path")
    comparing = commands.add_parser("compare")
    comparing.add_argument("before")
    comparing.add_argument("after")
    args = parser.parse_args(argv)
    if args.command == "record":
        record(args.path)
        return 0
    return 1 if compare(args.before, args.after) else 0


if __name__ == "__main__":
    sys.exit(main())
