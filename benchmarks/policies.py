"""The shipped learned policies on their tasks: return and success over seeded episodes.

Each shipped policy (`qube_suite.policies.shipped()`, "ppo:<task>") runs on its
task with default settings (250 Hz, 3 V) on the simulated Qube and on the hardware
substitute (`qube_hardware`), through
`qube_suite.evaluate` (success as there: no termination and the pendulum within
10 degrees of its goal for the final 2 s; rotor: at least 5 revolutions). The
table also gives each policy's training record: environment steps and wall-clock
time on the machine that trained it.

    python benchmarks/policies.py [--episodes 20] [--seed 0] [--json results.json]
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from qube_suite import evaluate
from qube_suite.policies import load_policy, shipped


def evaluate_on_fresh_qubes(policy, domain: str, task: str, episodes: int, seed: int) -> dict:
    """`evaluate(...).to_dict()` with every episode on a fresh Qube: on the hardware substitute,
    an episode that ends with the arm flung past its limit would otherwise stop the board in the
    next reset (as on a real Qube) and end the evaluation."""
    results = [evaluate(policy, domain=domain, task=task, episodes=1, seed=seed + episode)
               for episode in range(episodes)]
    returns = [r for result in results for r in result.returns]
    return {"mean_return": float(np.mean(returns)), "std_return": float(np.std(returns)),
            "success_rate": float(np.mean([s for result in results for s in result.successes])),
            "returns": returns}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", default=None, help="also write the results to this JSON file")
    args = parser.parse_args()
    rows = []
    print("| policy | domain | task | return (mean ± std) | success | training steps | training wall time |")
    print("|---|---|---|---|---|---|---|")
    for spec in shipped():
        policy = load_policy(spec)
        training = policy.meta.get("training", {})
        for domain in ("qube", "qube_hardware"):
            result = evaluate_on_fresh_qubes(policy, domain, policy.tasks[0], args.episodes, args.seed)
            row = {**result, "policy": spec, "training_steps": training.get("steps"),
                   "training_wall_time_s": training.get("wall_time_s"),
                   "randomization": training.get("randomization")}
            rows.append(row)
            unit = " revolutions" if policy.tasks[0] == "rotor" else ""
            print(f"| `{spec}` | {domain} | {policy.tasks[0]} | {row['mean_return']:.0f} ± "
                  f"{row['std_return']:.0f}{unit} | {100 * row['success_rate']:.0f} % | "
                  f"{row['training_steps'] / 1e6:.2f} M | {row['training_wall_time_s'] / 60:.0f} min |")
    if args.json:
        with open(args.json, "w") as file:
            json.dump(rows, file, indent=2)


if __name__ == "__main__":
    main()
