"""Cost of domain randomization: reset with each preset against none, step with effects on against off.

Times Gymnasium `reset` and `step` of QubeSuite/Balance-v0 in one process, or with
`--num-envs N` those of its vector environment of N worlds (per world: a reset
call's time over N, a step's over N env-steps; steps include the autoresets of
ended worlds). The configurations take turns call by call (one reset of each,
then the next round), so load from other processes on a shared machine falls on
all of them alike; the table gives the 10th percentile of the single-call times,
an estimate of the cost on a quiet machine, and its ratio to the run without
randomization. Steps use the LQR balance controller's voltages, so episodes run
long. Goal: a reset with randomization costs under 2x one without.

    python benchmarks/randomization.py [--resets 3000] [--steps 20000]
    python benchmarks/randomization.py --num-envs 64 --resets 30 --steps 1000
"""

from __future__ import annotations

import argparse
import time

import gymnasium
import numpy as np

import qube_suite  # noqa: F401  (registers the Gymnasium ids)
from qube_suite import baselines

ALL_EFFECTS = {"effects": {
    "quantization": True, "velocity_filter": True, "observation_noise": {"std": [0.002, 0.002, 0.05, 0.05]},
    "observation_delay": {"steps": 1}, "action_delay": {"steps": 1}, "voltage_offset": {"voltage": 0.02},
    "dead_zone": {"voltage": 0.05}, "saturation": {"voltage": 2.5}, "control_jitter": {"fraction": 0.05},
}}

RESETS = {"no randomization": None, "none": "none", "mild": "mild", "moderate": "moderate",
          "sim2real": "sim2real", "all effects": ALL_EFFECTS}
"""Label -> randomization timed at reset."""

STEPS = {"no randomization": None, "all effects": ALL_EFFECTS,
         **{f"{name} only": {"effects": {name: value}} for name, value in ALL_EFFECTS["effects"].items()},
         "sim2real": "sim2real"}
"""Label -> randomization timed at step."""

PERCENTILE = 10


def make(randomization, num_envs: int | None):
    """The environment (`num_envs` None) or vector environment, reset with seed 0."""
    if num_envs is None:
        env = gymnasium.make("QubeSuite/Balance-v0", randomization=randomization).unwrapped
    else:
        env = gymnasium.make_vec("QubeSuite/Balance-v0", num_envs=num_envs, randomization=randomization)
    env.reset(seed=0)
    return env


def time_resets(configs: dict, count: int, num_envs: int | None = None) -> dict[str, np.ndarray]:
    """Label -> seconds of each of `count` resets (per world), the configurations taking turns."""
    envs = {label: make(randomization, num_envs) for label, randomization in configs.items()}
    times = {label: np.empty(count) for label in configs}
    for i in range(count):
        for label, env in envs.items():
            start = time.perf_counter()
            env.reset()
            times[label][i] = (time.perf_counter() - start) / (num_envs or 1)
    return times


def time_steps(configs: dict, count: int, num_envs: int | None = None) -> dict[str, np.ndarray]:
    """Label -> seconds of each of `count` steps (per env-step; a single environment's resets not
    counted), the configurations taking turns."""
    controller = baselines.make("balance")
    envs = {label: make(randomization, num_envs) for label, randomization in configs.items()}
    observations = {label: env.reset(seed=0)[0] for label, env in envs.items()}
    times = {label: np.empty(count) for label in configs}
    for i in range(count):
        for label, env in envs.items():
            if num_envs is None:
                action = np.array([controller(observations[label])], np.float32)
            else:  # the same LQR law for every world at once
                volts = -observations[label][:, :4].astype(np.float64) @ controller.gain
                action = np.clip(volts, -controller.voltage_limit, controller.voltage_limit)[:, None]
            start = time.perf_counter()
            observation, _, terminated, truncated, _ = env.step(action.astype(np.float32))
            times[label][i] = (time.perf_counter() - start) / (num_envs or 1)
            ended = num_envs is None and (terminated or truncated)
            observations[label] = env.reset()[0] if ended else observation
    return times


def print_table(title: str, unit: str, times: dict[str, np.ndarray]) -> None:
    base = np.percentile(times["no randomization"], PERCENTILE)
    print(f"{title:24s} {unit:>10s} {'x none':>7s}")
    for label, seconds in times.items():
        value = np.percentile(seconds, PERCENTILE)
        print(f"{label:24s} {value * 1e6:10.2f} {value / base:7.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resets", type=int, default=3000)
    parser.add_argument("--steps", type=int, default=20000)
    parser.add_argument("--num-envs", type=int, default=None, help="time a vector environment of N worlds")
    args = parser.parse_args()
    per = "" if args.num_envs is None else f" (vector env, N={args.num_envs}, per world)"
    print_table("reset with" + per, "us/reset", time_resets(RESETS, args.resets, args.num_envs))
    print()
    print_table("step with" + per, "us/step", time_steps(STEPS, args.steps, args.num_envs))


if __name__ == "__main__":
    main()
