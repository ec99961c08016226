"""Does the substitute board behave like a real Qube? The real chirps replayed on its plants, judged alike.

Each of TU Darmstadt's ten chirps of a real Qube-Servo 2 (`../shared/real_qube/`, or `--data DIR`)
is replayed on a substitute board (`qube_suite.hardware.quanser.QubeServo2`, fast mode): a board
opened for it alone (seed = the chirp's index, a session of its own), its Qube put at the
recording's first angles at rest, then the recorded voltages written one per sample at the
recording's period, the encoders read as a real logger reads them. The replays are written in the
recordings' CSV format and judged exactly as `benchmarks/real_qube.py` judges the real chirps: a
held-out chirp is predicted by a calibration on the other nine (`calibration.calibrate_recordings`,
all unknowns) and by the nominal model, RMS of both angles' errors 0.1 and 0.5 s ahead
(`real_qube.predict`: states fitted to the 0.1 s before each start).

The same held-out chirps are scored on the real recordings in the same run, and each plant's
figures are given as a ratio to them: a plant behaves like the real Qube when the calibrated and
the nominal model's errors are both within 1.5x of the real ones. A plant far easier to predict
than the real Qube fails as much as one far from it.

    python benchmarks/substitute_fidelity.py [--data DIR] [--held-out neg_0 pos_2 ... | all]
        [--plants estimated real_qube_servo2] [--out FILE.json]

By default two chirps are held out (neg_0, pos_2: six calibrations in all, 6 to 15 minutes on a
shared 2-core machine); `--held-out all` scores all ten as `real_qube.py` does (30 calibrations).
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import sys
import tempfile
import time

import numpy as np

from qube_suite import calibration
from qube_suite.angles import wrap_angle
from qube_suite.calibration import fit, recordings
from qube_suite.hardware import conventions, quanser

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from real_qube import DEFAULT_DATA, predict, rms  # noqa: E402  (the benchmark beside this one)

HORIZONS = (0.1, 0.5)
HELD_OUT = ("neg_0", "pos_2")
"""Chirps held out by default (one starting each way)."""
PLANTS = ("estimated", "real_qube_servo2")
TOLERANCE = 1.5
"""A plant's error may differ from the real Qube's by this factor either way."""


def replay(path: str, plant: str, seed: int, destination: str) -> str:
    """Replay the recording at `path`'s voltages on a substitute board with `plant` (a name of
    `hardware.plant.PLANTS`) seeded with `seed`; write what its encoders
    read to `destination` in the recordings' CSV format and return that path."""
    recorded = recordings.read(path)
    start = [recorded.theta[0], np.pi + wrap_angle(recorded.alpha[0] - np.pi), 0.0, 0.0]  # hanging: near pi
    qube = quanser.QubeServo2(1.0 / recorded.sample_time, plant=plant, arm_limit=None)
    qube.open()
    try:
        qube.board.seed(seed)
        qube.board.set_true_state(start)
        qube.action(0.0)  # the sample taken when the board opened is stale: the next one is the start
        angles = np.empty((len(recorded), 2))
        for k, volts in enumerate(recorded.voltage):
            _, counts, _ = qube.action(conventions.board_voltage(float(volts)))
            angles[k] = (conventions.arm_angle(counts[0]),
                         wrap_angle(conventions.pendulum_angle_unwrapped(counts[1])))
    finally:
        qube.close()
    table = np.column_stack([recorded.time, recorded.voltage, angles])
    np.savetxt(destination, table, delimiter=",", header="time,voltage,arm_angle,pendulum_angle",
               comments="", fmt="%.9g")
    return destination


def calibrate(paths: list[str], notes: list[str]) -> calibration.Calibration:
    """`calibration.calibrate_recordings(paths)`; where the fit leaves the rotor's inertia at its bound
    0, which no calibration file may hold, the same with the rotor's inertia held at nominal (noted)."""
    try:
        return calibration.calibrate_recordings(paths)
    except ValueError as error:
        if "rotor_inertia" not in str(error):
            raise
        notes.append(f"{error}: fitted again with the rotor's inertia held at nominal")
        return calibration.calibrate_recordings(paths, free=tuple(n for n in fit.VOLTAGE_NAMES
                                                                  if n != "rotor_inertia"))


def score(chirps: list[str], held_out: list[str]) -> dict:
    """Nominal and calibrated (on the other chirps) prediction RMS (rad) of the held-out chirps."""
    nominal = {h: [] for h in HORIZONS}
    calibrated = {h: [] for h in HORIZONS}
    notes: list[str] = []
    for path in held_out:
        recorded = recordings.read(path)
        fitted = calibrate([p for p in chirps if p != path], notes)
        for h in HORIZONS:
            nominal[h].append(predict(None, recorded, h))
            calibrated[h].append(predict(fitted, recorded, h))
    return {"nominal": {f"{h:g}": rms(nominal[h]) for h in HORIZONS},
            "calibrated": {f"{h:g}": rms(calibrated[h]) for h in HORIZONS}, "notes": notes}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=DEFAULT_DATA)
    parser.add_argument("--held-out", nargs="+", default=list(HELD_OUT),
                        help="chirps to hold out, e.g. neg_0 pos_2, or 'all'")
    parser.add_argument("--plants", nargs="+", default=list(PLANTS),
                        help="names of qube_suite.hardware.plant.PLANTS")
    parser.add_argument("--out", default=None, help="write the results as JSON here")
    args = parser.parse_args()
    started = time.perf_counter()
    chirps = sorted(glob.glob(os.path.join(args.data, "qs2_chirp_*.csv")))
    if len(chirps) != 10:
        raise SystemExit(f"expected 10 chirps in {args.data}, found {len(chirps)}")
    names = [os.path.basename(p)[len("qs2_chirp_"):-len(".csv")] for p in chirps]
    held = names if args.held_out == ["all"] else args.held_out
    unknown = sorted(set(held) - set(names))
    if unknown:
        raise SystemExit(f"no chirp {', '.join(unknown)}; the chirps: {', '.join(names)}")
    results: dict = {"held_out": held, "machine": "see docs/hardware.md"}
    results["real"] = score(chirps, [chirps[names.index(n)] for n in held])
    print("real Qube", results["real"], flush=True)
    with tempfile.TemporaryDirectory() as folder:
        for plant in args.plants:
            replays = [replay(path, plant, index,
                              os.path.join(folder, f"{plant}_{os.path.basename(path)}"))
                       for index, path in enumerate(chirps)]
            found = score(replays, [replays[names.index(n)] for n in held])
            found["ratio_to_real"] = {model: {h: found[model][h] / results["real"][model][h]
                                              for h in found[model]} for model in ("nominal", "calibrated")}
            found["like_the_real_qube"] = all(
                1.0 / TOLERANCE <= found["ratio_to_real"][model]["0.5"] <= TOLERANCE
                for model in ("nominal", "calibrated"))
            results[plant] = found
            print(plant, found, flush=True)
    results["wall_seconds"] = time.perf_counter() - started
    print(f"\n| held-out chirps {', '.join(held)} (rad) | real Qube | "
          + " | ".join(p for p in args.plants) + " |")
    print("|---|---|" + "---|" * len(args.plants))
    for model in ("nominal", "calibrated"):
        for h in HORIZONS:
            key = f"{h:g}"
            cells = [f"{results[p][model][key]:.4f} ({results[p]['ratio_to_real'][model][key]:.2f}x)"
                     for p in args.plants]
            print(f"| {model}, {key} s | {results['real'][model][key]:.4f} | " + " | ".join(cells) + " |")
    print(f"wall time {results['wall_seconds']:.0f} s")
    if args.out:
        with open(args.out, "w", encoding="utf-8") as file:
            json.dump(results, file, indent=1)


if __name__ == "__main__":
    main()
