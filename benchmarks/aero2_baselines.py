"""The Aero 2's baselines in simulation: the LQR with integral action that Quanser's labs teach, and
learned policies, scored on the tasks each is meant for.

Runs the LQR (`qube_suite.devices.aero2.controllers`) on every task, the pitch tasks in both
configurations (1-DOF, yaw locked, and the 2-DOF helicopter with its yaw free), and each policy file
given with `--policy TASK=FILE.npz` on TASK at the control frequency it was trained at (and the LQR
there too, for comparison), on the `aero2` domain at 18 V with `qube_suite.evaluate` (seeds 0 ..
episodes-1), and prints a markdown table: mean return and its standard deviation, and success (pitch,
track: at the goal for 60 % of the steps; hover: at the goal throughout the final 2 s). Returns are
sums over the episode's steps: at 50 Hz an episode has a fifth of the steps it has at 250 Hz.

With `--page docs/aero2.md` the table replaces what is between the page's `<!-- results:begin -->`
and `<!-- results:end -->` markers.

    python benchmarks/aero2_baselines.py [--episodes 10] [--policy hover=FILE.npz] [--page docs/aero2.md]
"""

from __future__ import annotations

import argparse
import pathlib
import re

from qube_suite import evaluate
from qube_suite.evaluation import EvaluationResult
from qube_suite.policies import load_policy

BEGIN, END = "<!-- results:begin -->", "<!-- results:end -->"
LQR_RUNS = (("pitch", "pitch_only"), ("pitch", "2dof"), ("pitch_sparse", "pitch_only"), ("hover", "2dof"),
            ("hover_sparse", "2dof"), ("track", "2dof"), ("track_sparse", "2dof"))
"""(task, configuration) of the LQR's runs at 250 Hz."""


def trained_frequency(policy) -> float:
    """The control frequency (Hz) a policy file was trained at (250 unless its record says)."""
    record = policy.meta.get("training", {}).get("environment_kwargs") or {}
    return float(record.get("control_frequency", 250.0))


def cell(result: EvaluationResult) -> str:
    """Return and success cells of `result`."""
    return f"{result.mean_return:.0f} ± {result.std_return:.0f} | {100 * result.success_rate:.0f} %"


def main(argv: list[str] | None = None) -> str:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--policy", action="append", default=[], metavar="TASK=FILE.npz")
    parser.add_argument("--page", type=pathlib.Path)
    args = parser.parse_args(argv)
    runs = [("LQR", task, configuration, "lqr", 250.0) for task, configuration in LQR_RUNS]
    for spec in args.policy:
        task, path = spec.split("=", 1)
        configuration = "pitch_only" if task.startswith("pitch") else "2dof"
        frequency = trained_frequency(load_policy(path))
        if frequency != 250.0:
            runs.append(("LQR", task, configuration, "lqr", frequency))
        runs.append((f"PPO (`{pathlib.Path(path).name}`)", task, configuration, path, frequency))
    lines = ["| baseline | task | configuration | control | return | success |", "|---|---|---|---|---|---|"]
    for label, task, configuration, spec, frequency in runs:
        policy = spec if spec == "lqr" else load_policy(spec)
        result = evaluate(policy, domain="aero2", task=task, episodes=args.episodes,
                          domain_kwargs={"configuration": configuration},
                          environment_kwargs={"control_frequency": frequency})
        lines.append(f"| {label} | {task} | {configuration} | {frequency:g} Hz | {cell(result)} |")
        print(lines[-1], flush=True)
    table = "\n".join(lines)
    if args.page:
        text = args.page.read_text()
        text = re.sub(f"{re.escape(BEGIN)}.*{re.escape(END)}", f"{BEGIN}\n{table}\n{END}", text, flags=re.S)
        args.page.write_text(text)
    print(table)
    return table


if __name__ == "__main__":
    main()
