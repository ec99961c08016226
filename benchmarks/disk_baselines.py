"""The inertia disk's baselines on both of its domains: the classical controllers labs teach and
learned policies, scored on the tasks each is meant for.

Runs each controller of `qube_suite.devices.qube_disk.controllers.CONTROLLERS` on its tasks, and each
policy file given with `--policy TASK=FILE.npz` on TASK, on `qube_disk` (MuJoCo) and
`qube_disk_hardware` (the substitute board: Coulomb friction, the motor's inductance, encoder
quantisation, the velocity filter, one sample of latency) at 250 Hz and 3 V with
`qube_suite.evaluate` (seeds 0 .. episodes-1), and prints a markdown table: mean return and its
standard deviation, and success (position: within 3 degrees of the target for 80 % of the steps;
speed: within 2 rad/s of the target for the final 2 s).

With `--page docs/devices/qube_disk.md` the table replaces what is between the page's
`<!-- results:begin -->` and `<!-- results:end -->` markers.

    python benchmarks/disk_baselines.py [--episodes 10] [--policy position=runs/ppo/best_policy.npz]
        [--page docs/devices/qube_disk.md]
"""

from __future__ import annotations

import argparse
import pathlib
import re

from qube_suite import evaluate
from qube_suite.devices.qube_disk.controllers import CONTROLLERS
from qube_suite.evaluation import EvaluationResult
from qube_suite.policies import load_policy

DOMAINS = ("qube_disk", "qube_disk_hardware")
BEGIN, END = "<!-- results:begin -->", "<!-- results:end -->"


def cell(result: EvaluationResult) -> str:
    """Return and success cells of `result`."""
    return f"{result.mean_return:.0f} ± {result.std_return:.0f} | {100 * result.success_rate:.0f} %"


def main(argv: list[str] | None = None) -> str:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--policy", action="append", default=[], metavar="TASK=FILE.npz")
    parser.add_argument("--page", type=pathlib.Path)
    args = parser.parse_args(argv)
    runs = [(name, task, name) for name, cls in CONTROLLERS.items() for task in cls.tasks
            if not task.endswith("_sparse")]
    for spec in args.policy:
        task, path = spec.split("=", 1)
        runs.append((f"PPO (`{pathlib.Path(path).name}`)", task, path))
    lines = ["| baseline | task | " + " | ".join(f"{d} return | {d} success" for d in DOMAINS) + " |",
             "|---|---|" + "---|---|" * len(DOMAINS)]
    for label, task, spec in runs:
        cells = []
        for domain in DOMAINS:
            policy = spec if spec in CONTROLLERS else load_policy(spec)
            cells.append(cell(evaluate(policy, domain=domain, task=task, episodes=args.episodes)))
        lines.append(f"| {label} | {task} | " + " | ".join(cells) + " |")
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
