"""The shipped controllers and policies on a simulated real Qube: success against the nominal model.

Runs each (task, policy) pair for `--episodes` seeded episodes in simulation of the nominal
model and of the calibrated real Qube-Servo 2 (`qube_suite.devices.qube.parameters.REAL_QUBE_SERVO2`:
its parameters, latency, voltage dead zone, cable and encoder offset), and prints the success
rates side by side.

    python benchmarks/real_qube_policies.py [--episodes 10] [--also swingup=runs/my_policy.npz ...]

`--also TASK=POLICY` adds a pair: a policy file (`qube-suite train`'s) or any controller name.
"""

from __future__ import annotations

import argparse
import time

from qube_suite import evaluate
from qube_suite.devices.qube import parameters

PAIRS = (("swingup", "swingup"), ("balance", "balance"), ("swingup", "ppo:swingup"),
         ("swingup", "ppo:swingup_adaptive"), ("balance", "ppo:balance"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--also", nargs="*", default=[], metavar="TASK=POLICY")
    args = parser.parse_args()
    pairs = PAIRS + tuple(tuple(pair.split("=", 1)) for pair in args.also)
    started = time.perf_counter()
    print("| task | policy | nominal model | calibrated real Qube-Servo 2 |\n|---|---|---|---|")
    for task, policy in pairs:
        rates = [evaluate(policy, "qube", task, episodes=args.episodes, domain_kwargs=kwargs).success_rate
                 for kwargs in (None, {"parameters": parameters.REAL_QUBE_SERVO2})]
        print(f"| {task} | {policy} | {rates[0]:.0%} | {rates[1]:.0%} |", flush=True)
    print(f"wall time {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
