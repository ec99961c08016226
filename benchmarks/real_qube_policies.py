"""The shipped controllers and policies on a simulated real Qube: success against the nominal model.

Runs each (task, policy) pair for `--episodes` seeded episodes in simulation of the nominal
model and of the calibrated real Qube-Servo 2 (`qube_suite.devices.qube.parameters.REAL_QUBE_SERVO2`:
its parameters, latency, voltage dead zone, cable and encoder offset), the latter twice: with the
simulation's exact angles and velocities, and measured as its board measures it (angles in whole
encoder counts, velocities through the hardware domain's filter: `MEASURED_BY_THE_BOARD`), and
prints the success rates side by side.

    python benchmarks/real_qube_policies.py [--episodes 10] [--also swingup=runs/my_policy.npz ...]

`--also TASK=POLICY` adds a pair: a policy file (`qube-suite train`'s) or any controller name.
"""

from __future__ import annotations

import argparse
import time

from qube_suite import evaluate
from qube_suite.devices.qube import parameters
from qube_suite.velocity_filter import VELOCITY_FILTER_CUTOFF

PAIRS = (("swingup", "swingup"), ("balance", "balance"), ("swingup", "ppo:swingup"),
         ("swingup", "ppo:swingup_adaptive"), ("balance", "ppo:balance"))

MEASURED_BY_THE_BOARD = {"parameters": {}, "effects": {
    "quantization": {"counts_per_revolution": parameters.ENCODER_COUNTS_PER_REVOLUTION},
    "velocity_filter": {"cutoff": VELOCITY_FILTER_CUTOFF}}}
"""A randomization that draws nothing: the encoders' counts and the velocity estimate of a board
(`qube_hardware`'s filter, 50 rad/s), which a simulation otherwise gives exactly."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--also", nargs="*", default=[], metavar="TASK=POLICY")
    args = parser.parse_args()
    pairs = PAIRS + tuple(tuple(pair.split("=", 1)) for pair in args.also)
    real = {"parameters": parameters.REAL_QUBE_SERVO2}
    started = time.perf_counter()
    print("| task | policy | nominal model | calibrated real Qube-Servo 2 | the same, measured by its "
          "board |\n|---|---|---|---|---|")
    for task, policy in pairs:
        rates = [evaluate(policy, "qube", task, episodes=args.episodes, domain_kwargs=kwargs,
                          randomization=randomization).success_rate
                 for kwargs, randomization in ((None, None), (real, None), (real, MEASURED_BY_THE_BOARD))]
        print(f"| {task} | {policy} | {rates[0]:.0%} | {rates[1]:.0%} | {rates[2]:.0%} |", flush=True)
    print(f"wall time {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
