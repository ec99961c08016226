"""The Aero 2's hardware side on the substitute board: baselines, speed, calibration across plants.

results: the LQR, and each policy given with `--policy TASK=FILE.npz` (at the control frequency it
was trained at), on the substitute board (`aero2_hardware`, the default hidden Aero), on the runs of
`benchmarks/aero2_baselines.py` (its tasks and configurations, seeds 0 .. episodes-1, 18 V), as a
markdown table; with `--page docs/aero2.md` it replaces what is between the page's
`<!-- substitute-results:begin -->` and `<!-- substitute-results:end -->` markers.

speed: wall time of LQR episodes of `hover` on the substitute board (`aero2_hardware`) against the
same on the MuJoCo simulation (`aero2`) in the same run, and the substitute's speed over real time.
calibration: records the excitation experiment on substitute Aeros drawn with seeds `--seed`,
`--seed + 1`, ... (`qube_suite.devices.aero2.calibration`), calibrates from each and prints each
estimate's error against the plant's truth and whether the truth lies in its 95 % interval.

    python benchmarks/aero2_hardware.py results [--episodes 10] [--policy hover=F.npz] [--page docs/aero2.md]
    python benchmarks/aero2_hardware.py speed [--episodes 5]
    python benchmarks/aero2_hardware.py calibration [--plants 6] [--seed 1]
"""

from __future__ import annotations

import argparse
import pathlib
import re
import tempfile
import time

from aero2_baselines import LQR_RUNS, cell, trained_frequency  # this folder's simulation baselines

from qube_suite.devices.aero2 import calibration, substitute
from qube_suite.evaluation import evaluate
from qube_suite.policies import load_policy

BEGIN, END = "<!-- substitute-results:begin -->", "<!-- substitute-results:end -->"


def results(episodes: int, policies: list[str], page: pathlib.Path | None) -> None:
    runs = [("LQR", task, configuration, "lqr", 250.0) for task, configuration in LQR_RUNS]
    for spec in policies:
        task, path = spec.split("=", 1)
        configuration = "pitch_only" if task.startswith("pitch") else "2dof"
        runs.append((f"PPO (`{pathlib.Path(path).name}`)", task, configuration, path,
                     trained_frequency(load_policy(path))))
    lines = ["| baseline | task | configuration | control | return | success |", "|---|---|---|---|---|---|"]
    for label, task, configuration, spec, frequency in runs:
        policy = spec if spec == "lqr" else load_policy(spec)
        result = evaluate(policy, domain="aero2_hardware", task=task, episodes=episodes,
                          domain_kwargs={"configuration": configuration},
                          environment_kwargs={"control_frequency": frequency})
        lines.append(f"| {label} | {task} | {configuration} | {frequency:g} Hz | {cell(result)} |")
        print(lines[-1], flush=True)
    table = "\n".join(lines)
    if page is not None:
        text = page.read_text()
        text = re.sub(f"{re.escape(BEGIN)}.*{re.escape(END)}", f"{BEGIN}\n{table}\n{END}", text, flags=re.S)
        page.write_text(text)


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
    resulting = commands.add_parser("results")
    resulting.add_argument("--episodes", type=int, default=10)
    resulting.add_argument("--policy", action="append", default=[], metavar="TASK=FILE.npz")
    resulting.add_argument("--page", type=pathlib.Path)
    commands.add_parser("speed").add_argument("--episodes", type=int, default=5)
    calibrating = commands.add_parser("calibration")
    calibrating.add_argument("--plants", type=int, default=6)
    calibrating.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    if args.command == "results":
        results(args.episodes, args.policy, args.page)
    elif args.command == "speed":
        speed(args.episodes)
    else:
        calibrations(args.plants, args.seed)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
