"""The shipped controllers and policies on a simulated real Qube: success against the nominal model.

Runs each (task, policy) pair for `--episodes` seeded episodes in simulation of the nominal
model and of the calibrated real Qube-Servo 2 (`qube_suite.devices.qube.parameters.REAL_QUBE_SERVO2`:
its parameters, latency, voltage dead zone, cable and encoder offset), the latter twice: with the
simulation's exact angles and velocities, and measured as its board measures it (angles in whole
encoder counts, velocities through the hardware domain's filter: `MEASURED_BY_THE_BOARD`), and
prints the success rates side by side. `--substitute` adds the hardware substitute (`qube_hardware`):
the estimated plant (`plant="estimated"`, its default until 2026-11-28), its default plant, that of the
real Qube (`plant="real_qube_servo2"`, `qube_suite.hardware.plant`), and that plant with the calibration
given to the domain (`parameters`: what the model-based controllers and the reset controllers are
designed with; a learned policy is the same policy).

    python benchmarks/real_qube_policies.py [--episodes 10] [--also swingup=runs/my_policy.npz ...]
                                            [--substitute] [--pairs swingup=swingup ...]

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
REAL = {"parameters": parameters.REAL_QUBE_SERVO2}
SIMULATION = {"nominal model": ("qube", None, None),
              "calibrated real Qube-Servo 2": ("qube", REAL, None),
              "the same, measured by its board": ("qube", REAL, MEASURED_BY_THE_BOARD)}
"""Columns: domain, domain_kwargs, randomization."""
SUBSTITUTE = {"estimated plant": ("qube_hardware", {"plant": "estimated"}, None),
              "real-Qube substitute (default)": ("qube_hardware", {"plant": "real_qube_servo2"}, None),
              "real-Qube substitute, calibration given": (
                  "qube_hardware", {"plant": "real_qube_servo2", **REAL}, None)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--also", nargs="*", default=[], metavar="TASK=POLICY")
    parser.add_argument("--pairs", nargs="*", default=None, metavar="TASK=POLICY",
                        help="instead of the shipped pairs")
    parser.add_argument("--substitute", action="store_true", help="also on the hardware substitute")
    args = parser.parse_args()
    chosen = PAIRS if args.pairs is None else tuple(tuple(pair.split("=", 1)) for pair in args.pairs)
    pairs = chosen + tuple(tuple(pair.split("=", 1)) for pair in args.also)
    columns = {**SIMULATION, **(SUBSTITUTE if args.substitute else {})}
    started = time.perf_counter()
    print("| task | policy | " + " | ".join(columns) + " |\n|---|---|" + "---|" * len(columns))
    for task, policy in pairs:
        rates = [evaluate(policy, domain, task, episodes=args.episodes, domain_kwargs=kwargs,
                          randomization=randomization).success_rate
                 for domain, kwargs, randomization in columns.values()]
        print(f"| {task} | {policy} | " + " | ".join(f"{rate:.0%}" for rate in rates) + " |", flush=True)
    print(f"wall time {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
