"""The shipped learned policies on their tasks: return and success over seeded episodes.

Each shipped policy (`qube_suite.policies.shipped()`, "ppo:<task>") runs on its
task with the task settings it was trained with (e.g. a follow task's target
schedule; otherwise the defaults, 250 Hz, 3 V) on the simulated Qube and on the
hardware substitute (`qube_hardware`, its default plant: the real Qube-Servo 2's), through
`qube_suite.evaluate` (success as there: no termination and the pendulum within
10 degrees of its goal for the final 2 s; rotor: at least 5 revolutions). The
table also gives each policy's training record: environment steps and wall-clock
time on the machine that trained it. `--plant NAME` scores them on the substitute with a named
plant too (`qube_suite.hardware.plant.PLANTS`, e.g. `estimated`: the plant this project estimated,
the default until 2026-11-28), in rows `qube_hardware (NAME)`.

    python benchmarks/policies.py [--episodes 20] [--seed 0] [--json results.json] [--policies SPEC ...]
                                  [--plant NAME]
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from qube_suite import evaluate
from qube_suite.hardware.plant import PLANTS
from qube_suite.policies import load_policy, shipped


def evaluate_on_fresh_qubes(policy, domain: str, task: str, episodes: int, seed: int,
                            task_kwargs: dict, domain_kwargs: dict | None = None) -> dict:
    """`evaluate(...).to_dict()` with every episode on a fresh Qube: on the hardware substitute,
    an episode that ends with the arm flung past its limit would otherwise stop the board in the
    next reset (as on a real Qube) and end the evaluation. `follow_error`: the episodes' mean (rad)."""
    results = [evaluate(policy, domain=domain, task=task, episodes=1, seed=seed + episode,
                        task_kwargs=task_kwargs, domain_kwargs=domain_kwargs) for episode in range(episodes)]
    returns = [r for result in results for r in result.returns]
    follow_errors = [result.follow_error for result in results if result.follow_error is not None]
    return {"mean_return": float(np.mean(returns)), "std_return": float(np.std(returns)),
            "success_rate": float(np.mean([s for result in results for s in result.successes])),
            "returns": returns, "follow_error": float(np.mean(follow_errors)) if follow_errors else None}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", default=None, help="also write the results to this JSON file")
    parser.add_argument("--policies", nargs="+", metavar="SPEC", choices=list(shipped()),
                        default=list(shipped()), help="the shipped policies to score (default: all)")
    parser.add_argument("--plant", choices=list(PLANTS), default=None,
                        help="also score on the substitute with this named plant")
    args = parser.parse_args()
    domains = {"qube": ("qube", None), "qube_hardware": ("qube_hardware", None)}
    if args.plant:
        domains[f"qube_hardware ({args.plant})"] = ("qube_hardware", {"plant": args.plant})
    rows = []
    print("| policy | domain | task | return (mean ± std) | success | follow error | training steps | "
          "training wall time |")
    print("|---|---|---|---|---|---|---|---|")
    for spec in args.policies:
        policy = load_policy(spec)
        training = policy.meta.get("training", {})
        task_kwargs = training.get("task_kwargs") or {}
        task = policy.tasks[0] + "".join(f", {key}={value}" for key, value in task_kwargs.items())
        for domain, (domain_name, domain_kwargs) in domains.items():
            result = evaluate_on_fresh_qubes(policy, domain_name, policy.tasks[0], args.episodes, args.seed,
                                             task_kwargs, domain_kwargs)
            row = {**result, "policy": spec, "domain": domain, "training_steps": training.get("steps"),
                   "training_wall_time_s": training.get("wall_time_s"),
                   "randomization": training.get("randomization"), "task_kwargs": task_kwargs}
            rows.append(row)
            unit = " revolutions" if policy.tasks[0] == "rotor" else ""
            error = "–" if row["follow_error"] is None else f"{row['follow_error']:.3f} rad"
            print(f"| `{spec}` | {domain} | {task} | {row['mean_return']:.0f} ± "
                  f"{row['std_return']:.0f}{unit} | {100 * row['success_rate']:.0f} % | {error} | "
                  f"{row['training_steps'] / 1e6:.2f} M | {row['training_wall_time_s'] / 60:.0f} min |")
    if args.json:
        with open(args.json, "w") as file:
            json.dump(rows, file, indent=2)


if __name__ == "__main__":
    main()
