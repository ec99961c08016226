"""Time per call of learned policies with and without observation history, in one run.

Calls each policy on a stream of swing-up observations (a dm_env-style mapping,
as `evaluate` and the hardware loop give it) and reports the median and 99th
percentile time per call (microseconds) after a warm-up. The peer is the
shipped memoryless `ppo:swingup` (two tanh layers of 128); the history policies are the same network
widened to a history of k steps (the inputs a trained adaptive policy has).

    python benchmarks/policy_inference.py [--calls 20000] [--history 4 8 16]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from qube_suite.policies import MLPPolicy, load_policy
from qube_suite.policies.history import input_size


def widened(policy: MLPPolicy, history: int) -> MLPPolicy:
    """`policy` with a history of `history` steps (zero weights on it): the shapes of an adaptive policy."""
    features = policy.observation_mean.shape[0]
    size = input_size(features, history)
    first = np.zeros((policy.weights[0].shape[0], size))
    first[:, :features] = policy.weights[0]
    mean, var = np.zeros(size), np.ones(size)
    mean[:features], var[:features] = policy.observation_mean, policy.observation_var
    meta = {**policy.meta, "format": 2, "history": history}
    return MLPPolicy([first, *policy.weights[1:]], policy.biases, mean, var, meta, name=f"history {history}")


def time_calls(policy: MLPPolicy, observations: np.ndarray) -> np.ndarray:
    """Seconds per call of `policy` on each observation in turn (one episode)."""
    policy.reset()
    times = np.empty(len(observations))
    for i, state in enumerate(observations):
        observation = {"state": state}
        start = time.perf_counter()
        policy(observation)
        times[i] = time.perf_counter() - start
    return times


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=20_000)
    parser.add_argument("--history", type=int, nargs="+", default=[4, 8, 16])
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    observations = rng.normal(size=(args.calls, 4)) * [0.5, 2.0, 3.0, 10.0]
    peer = load_policy("ppo:swingup")
    policies = [peer, *(widened(peer, k) for k in args.history)]
    for policy in policies:  # warm-up
        time_calls(policy, observations[:500])
    print("| policy | inputs | median (us) | 99th percentile (us) | ratio to memoryless |")
    print("|---|---|---|---|---|")
    rounds = {policy.name: [] for policy in policies}
    for _ in range(3):  # interleaved, so that load on the machine hits all alike
        for policy in policies:
            rounds[policy.name].append(time_calls(policy, observations))
    reference = np.median(np.concatenate(rounds[peer.name]))
    for policy in policies:
        times = np.concatenate(rounds[policy.name]) * 1e6
        print(f"| {policy.name} | {policy.observation_mean.shape[0]} | {np.median(times):.1f} | "
              f"{np.percentile(times, 99):.1f} | {np.median(times) / (reference * 1e6):.2f} |")


if __name__ == "__main__":
    main()
