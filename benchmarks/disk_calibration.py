"""How far the disk-loaded Qube's calibration lands from plants it did not know.

Draws `--plants` disk-loaded Qubes on the substitute board (disk mass 0.6 to 1.6 times Quanser's
53 g, the shaft's viscous damping 0.3 to 3 times the table's, its Coulomb friction 0.5 to 2 mN m;
every other plant a Qube-Servo 3, the others a Qube-Servo 2), records the excitation experiment on
each (`qube_suite.devices.qube_disk.calibration.record_experiment`, 25 s) and calibrates from it,
then prints each estimate's relative error against the plant's truth and whether the truth lies in
its 95 % interval.

    python benchmarks/disk_calibration.py [--plants 8] [--seed 100]
"""

from __future__ import annotations

import argparse
import pathlib
import tempfile

import numpy as np

from qube_suite.devices.qube_disk import calibration

DRAWN = ("disk_mass", "disk_damping", "disk_friction")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--plants", type=int, default=8)
    parser.add_argument("--seed", type=int, default=100, help="draws the plants and the experiments' phases")
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    print("| plant | board | " + " | ".join(f"{name} error (in interval)" for name in DRAWN) + " |")
    print("|---" * (2 + len(DRAWN)) + "|")
    with tempfile.TemporaryDirectory() as folder:
        for plant in range(args.plants):
            truth = {"disk_mass": 0.053 * rng.uniform(0.6, 1.6), "disk_damping": 5e-6 * rng.uniform(0.3, 3.0),
                     "disk_friction": 1e-3 * rng.uniform(0.5, 2.0)}
            device = "qube_servo3" if plant % 2 else "qube_servo2"
            path = calibration.record_experiment(pathlib.Path(folder) / f"plant{plant}.jsonl",
                                                 domain_kwargs={"parameters": truth, "device": device},
                                                 seed=args.seed + plant, seconds=25.0)
            found = calibration.calibrate_recording(path)
            cells = []
            for name in DRAWN:
                low, high = found.intervals[name]
                error = found.parameters[name] / truth[name] - 1.0
                cells.append(f"{100 * error:+.2f} % ({'yes' if low <= truth[name] <= high else 'no'})")
            print(f"| {plant} | {device} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
