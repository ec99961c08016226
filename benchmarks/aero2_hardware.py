"""The Aero 2's hardware side on the substitute board: its speed, and its calibration across plants.

speed: wall time of LQR episodes of `hover` on the substitute board (`aero2_hardware`) against the
same on the MuJoCo simulation (`aero2`) in the same run, and the substitute's speed over real time.
calibration: records the excitation experiment on substitute Aeros drawn with seeds `--seed`,
`--seed + 1`, ... (`qube_suite.devices.aero2.calibration`), calibrates from each and prints each
estimate's error against the plant's truth and whether the truth lies in its 95 % interval.

    python benchmarks/aero2_hardware.py speed [--episodes 5]
    python benchmarks/aero2_hardware.py calibration [--plants 6] [--seed 1]
"""

from __future__ import annotations

import argparse
import pathlib
import tempfile
import time

from qube_suite.devices.aero2 import calibration, substitute
from qube_suite.evaluation import evaluate


def speed(episodes: int) -> None:
    seconds = {}
    for domain in ("aero2", "aero2_hardware"):
        start = time.perf_counter()
        evaluate("lqr", domain=domain, task="hover", episodes=episodes, seed=0)
        seconds[domain] = time.perf_counter() - start
    simulated = episodes * 8.192
    for domain, wall in seconds.items():
        print(f"{domain:15s} {wall:6.2f} s for {simulated:.1f} s of episodes: "
              f"{simulated / wall:5.1f} x real time")
    print(f"substitute board / MuJoCo simulation: {seconds['aero2_hardware'] / seconds['aero2']:.2f}")


def calibrations(plants: int, seed: int) -> None:
    misses = 0
    with tempfile.TemporaryDirectory() as folder:
        for plant_seed in range(seed, seed + plants):
            path = calibration.record_experiment(pathlib.Path(folder) / f"aero{plant_seed}.npz",
                                                 domain_kwargs={"plant_seed": plant_seed})
            found = calibration.calibrate_recording(path)
            truth = substitute.make_plant(seed=plant_seed).parameters
            row = []
            for q in calibration.UNKNOWNS:
                low, high = found.intervals[q.name]
                estimate = found.parameters.get(q.name, (found.identified or {}).get(q.name))
                inside = low <= truth[q.name] <= high
                misses += not inside
                error = 100 * (estimate / truth[q.name] - 1)
                row.append(f"{q.name} {error:+.1f}%{'' if inside else ' MISS'}")
            print(f"seed {plant_seed}: " + ", ".join(row))
    print(f"{misses} of {plants * len(calibration.UNKNOWNS)} truths outside their intervals")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    commands = parser.add_subparsers(dest="command", required=True)
    commands.add_parser("speed").add_argument("--episodes", type=int, default=5)
    calibrating = commands.add_parser("calibration")
    calibrating.add_argument("--plants", type=int, default=6)
    calibrating.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    if args.command == "speed":
        speed(args.episodes)
    else:
        calibrations(args.plants, args.seed)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
