"""Sim-to-hardware study of learned swing-up: which training randomization transfers, and which
simulator detail matters.

Starts from one PPO swing-up run on the nominal simulation (`base`: `--base DIR`,
or trained here as the shipped policy is, balance then swing-up from it), then
continues it for `--steps` more on the nominal simulation and, from the same
start, under each randomization preset (mild, moderate, sim2real, wide), under
`wide` with an observation history of 8 steps (adaptive), and under one
accuracy option or effect at a time (ablations: Coulomb friction on both joints
and the cable's spring, both at the sim2real preset's ranges; one control step of
action delay; Quanser's 50 rad/s velocity filter; 2048-count encoders). Every run
has the same budget and the same start; `--seeds N` trains each N times (seeds
0 to N-1). Runs already in `--runs` are reused.
Then scores each run's final policy over seeded episodes on the hardware substitute
(`qube_hardware`, whose plant the policies never saw) and on held-out variations
of that plant (`domain_kwargs={"plant": ...}`; in every hardware episode the
plant's friction and cable spring are drawn within +-50 % of the condition's),
the main runs also on the nominal simulation and on `--held-out` plants drawn
from the held-out ranges (`benchmarks/held_out.py`). Reports mean return with a 95 % bootstrap interval,
success (no termination, the pendulum within 10 degrees of upright for the final
2 s) with a 95 % Wilson interval, and each run's training steps and wall time;
writes the table as JSON beside the runs and the plot to docs/sim2real.png.

Every training run and every (run, condition) score is a Ray Tune trial
(`qube_suite.grid`, the `grid` extra): on this machine's cores (`--jobs` at a
time) by default, on a Ray cluster with `--address`.

    python benchmarks/sim2real.py [--base DIR] [--steps 2000000] [--episodes 20] [--seeds 1]
                                  [--held-out 10] [--runs runs/sim2real] [--jobs 2]
                                  [--address ray://head:10001] [--main-only]
"""

from __future__ import annotations

import argparse
import json
import math
import pathlib
import shutil

import held_out
import numpy as np

from qube_suite import evaluate
from qube_suite.grid import run_grid
from qube_suite.hardware.plant import plant_parameters
from qube_suite.policies import load_policy
from qube_suite.randomization.presets import PRESETS

DOCS = pathlib.Path(__file__).resolve().parent.parent / "docs"
_SIM2REAL = PRESETS["sim2real"]["parameters"]
_FRICTION = {name: _SIM2REAL[name] for name in ("arm_friction", "pendulum_friction")}

TRAINING: dict[str, object] = {
    "nominal": None, "mild": "mild", "moderate": "moderate", "sim2real": "sim2real", "wide": "wide",
    "adaptive": "wide",
    "action delay only": {"effects": {"action_delay": {"steps": 1}}},
    "velocity filter only": {"effects": {"velocity_filter": {"cutoff": 50.0}}},
    "quantization only": {"effects": {"quantization": {"counts_per_revolution": 2048}}},
    "friction only": {"parameters": _FRICTION},
    "cable spring only": {"parameters": {"cable_stiffness": _SIM2REAL["cable_stiffness"]}},
}
"""Training run name -> randomization."""
HISTORY = {"adaptive": 8}
"""Training run name -> observation history (steps) of its policy; the others have none."""
MAIN = ("nominal", "mild", "moderate", "sim2real", "wide", "adaptive")
"""Runs scored on every condition; the others (ablations) on the hardware substitute only."""

_PLANT = plant_parameters()
CONDITIONS: dict[str, tuple[str, dict | None]] = {
    "sim (nominal)": ("qube", None),
    "hardware": ("qube_hardware", None),
    "pendulum +30 % mass": ("qube_hardware", {"pendulum_mass": 1.3 * _PLANT["pendulum_mass"]}),
    "pendulum -30 % mass": ("qube_hardware", {"pendulum_mass": 0.7 * _PLANT["pendulum_mass"]}),
    "3x friction": ("qube_hardware", {"arm_friction": 3 * _PLANT["arm_friction"],
                                      "pendulum_friction": 3 * _PLANT["pendulum_friction"]}),
    "4x cable stiffness": ("qube_hardware", {"cable_stiffness": 4 * _PLANT["cable_stiffness"]}),
    "motor resistance +25 %": ("qube_hardware", {"motor_resistance": 1.25 * _PLANT["motor_resistance"]}),
}
"""Evaluation condition -> (domain, plant overrides of the hardware substitute)."""

POLICY = "policy.npz"
"""Each run is scored by its final policy, after its whole budget. Not by `best_policy.npz`: under a
randomization its periodic evaluations (8 episodes of randomized draws) pick a policy by chance as
much as by merit (sim2real, 2 M steps: best 35 % on the substitute, final 90 %)."""

UNMODELLED = ("arm_friction", "pendulum_friction", "cable_stiffness")
PLANT_SPREAD = 0.5
"""Every hardware episode's plant draws the `UNMODELLED` terms within +-50 % of the condition's
values (`episode_plant`): started hanging at rest, the substitute is otherwise deterministic, and
all episodes of a condition would be the same one."""


def bootstrap_interval(values: list[float], level: float = 0.95,
                       resamples: int = 10_000) -> tuple[float, float]:
    """Percentile bootstrap interval of the mean (seeded, so the table is reproducible)."""
    rng = np.random.default_rng(0)
    means = rng.choice(np.asarray(values), size=(resamples, len(values))).mean(axis=1)
    return tuple(float(q) for q in np.quantile(means, [(1 - level) / 2, (1 + level) / 2]))


def wilson_interval(successes: int, trials: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson score interval of a success rate."""
    p = successes / trials
    centre = (p + z * z / (2 * trials)) / (1 + z * z / trials)
    half = z * math.sqrt(p * (1 - p) / trials + z * z / (4 * trials * trials)) / (1 + z * z / trials)
    return max(0.0, centre - half), min(1.0, centre + half)


BASE_RECIPE = (("balance", 500_000), ("swingup", 5_000_000))
"""How the base is trained when no `--base` is given: the shipped swing-up's recipe (task, steps),
each stage starting from the previous one."""


def train_base(runs: pathlib.Path, seed: int) -> None:
    """Train the base swing-up run into `runs/base` by `BASE_RECIPE` (stages already there are kept)."""
    from qube_suite.training import train

    previous = None
    for task, steps in BASE_RECIPE:
        directory = runs / ("base" if task == "swingup" else f"base_{task}")
        if not (directory / "model.zip").exists():
            print(f"training the base: {task}, {steps} steps")
            train(task, steps=steps, seed=seed, out=directory, init=previous, progress=False)
        previous = directory


def run_directory(runs: pathlib.Path, name: str, seed: int) -> pathlib.Path:
    """Where the run `name` (a key of `TRAINING`) with training seed `seed` lives."""
    return runs / (name.replace(" ", "_") + ("" if seed == 0 else f"_seed{seed}"))


def train_one(job: dict) -> None:
    """Continue the base run `job["base"]` under `TRAINING[job["name"]]` for `job["steps"]` steps
    (seed `job["seed"]`) into `job["out"]`."""
    from qube_suite.training import train

    print(f"training {job['name']}, seed {job['seed']} ({job['steps']} steps from the base)", flush=True)
    train("swingup", steps=job["steps"], seed=job["seed"], randomization=TRAINING[job["name"]],
          init=job["base"], progress=False, out=job["out"],
          hyperparameters={"history": HISTORY.get(job["name"], 0)})


def train_missing(runs: pathlib.Path, base: pathlib.Path | None, steps: int, seeds: int,
                  names: tuple[str, ...], grid: dict) -> None:
    """Every run of `names` (keys of `TRAINING`) and seeds 0 to `seeds - 1` that has no policy in
    `runs` yet, as grid trials (`grid`: `run_grid`'s options), from `base` (copied into `runs/base`)
    or from a base trained here (seed 0)."""
    if not (runs / "base" / "model.zip").exists():
        if base is None:
            train_base(runs, 0)
        else:
            shutil.copytree(base, runs / "base", dirs_exist_ok=True)
    base = runs / "base"
    todo = [{"name": name, "seed": seed, "steps": steps, "base": str(base),
             "out": str(run_directory(runs, name, seed))} for name in names for seed in range(seeds)
            if not (run_directory(runs, name, seed) / POLICY).exists()]
    run_grid(train_one, todo, name="sim2real_training", **grid)


HELD_OUT_SEED = 2026
"""Seed of the held-out plant draws (`held_out.draw_plants`)."""


def held_out_conditions(count: int) -> dict[str, dict[str, float]]:
    """Condition name -> plant, for `count` plants drawn from the held-out ranges."""
    return {f"held-out {i}": plant for i, plant in enumerate(held_out.draw_plants(count, HELD_OUT_SEED))}


def episode_plant(condition: str, seed: int, held_out_count: int = 0) -> dict[str, float]:
    """The substitute's plant for one episode of a hardware `condition`: the condition's overrides,
    with the unmodelled terms (`UNMODELLED`) drawn within +-`PLANT_SPREAD` of their values, seeded
    by the episode's `seed`; a held-out plant's within `held_out.EPISODE_SPREAD`."""
    if condition.startswith("held-out"):
        return held_out.episode_plant(held_out_conditions(held_out_count)[condition], seed)
    plant = dict(CONDITIONS[condition][1] or {})
    random = np.random.default_rng(seed)
    for name in UNMODELLED:
        plant[name] = plant.get(name, _PLANT[name]) * random.uniform(1.0 - PLANT_SPREAD, 1.0 + PLANT_SPREAD)
    return plant


def score(job: dict) -> dict:
    """Evaluate one (run, training seed, policy file, condition) over `episodes` episodes from `seed`,
    each on a fresh Qube (see `benchmarks/policies.py`), each hardware episode on its own
    `episode_plant`."""
    run, path, condition = job["run"], job["path"], job["condition"]
    episodes, seed = job["episodes"], job["seed"]
    domain = CONDITIONS[condition][0] if condition in CONDITIONS else "qube_hardware"
    policy = load_policy(path)
    results = [evaluate(policy, domain=domain, task="swingup", episodes=1, seed=seed + episode,
                        domain_kwargs=None if domain == "qube" else
                        {"plant": episode_plant(condition, seed + episode, job["held_out"])})
               for episode in range(episodes)]
    returns = [result.returns[0] for result in results]
    successes = sum(result.successes[0] for result in results)
    low, high = bootstrap_interval(returns)
    success_low, success_high = wilson_interval(successes, episodes)
    return {"run": run, "training_seed": job["training_seed"], "condition": condition,
            "mean_return": float(np.mean(returns)),
            "return_ci": [low, high], "success_rate": successes / episodes,
            "success_ci": [success_low, success_high], "returns": returns}


def plot(rows: list[dict], path: pathlib.Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot

    figure, (left, right) = pyplot.subplots(1, 2, figsize=(14, 4.8), gridspec_kw={"width_ratios": [3, 1.4]})
    conditions = list(CONDITIONS)
    width = 0.8 / len(MAIN)
    for i, run in enumerate(MAIN):
        found = {r["condition"]: r for r in rows if r["run"] == run}
        x = np.arange(len(conditions)) + (i - (len(MAIN) - 1) / 2) * width
        means = [found[c]["mean_return"] if c in found else np.nan for c in conditions]
        errors = np.array([[found[c]["mean_return"] - found[c]["return_ci"][0],
                            found[c]["return_ci"][1] - found[c]["mean_return"]] if c in found else [0, 0]
                           for c in conditions]).T
        left.bar(x, means, width, yerr=errors, capsize=2, label=f"trained: {run}")
    left.set_xticks(np.arange(len(conditions)), conditions, rotation=20, ha="right")
    left.set_ylabel("swing-up return (max 2048)")
    left.set_title("Trained in simulation (by randomization), scored in simulation and on the substitute")
    left.legend(fontsize=8)
    hardware = {r["run"]: r for r in rows if r["condition"] == "hardware"}
    names = [name for name in TRAINING if name in hardware]
    means = [hardware[n]["mean_return"] for n in names]
    errors = np.array([[hardware[n]["mean_return"] - hardware[n]["return_ci"][0],
                        hardware[n]["return_ci"][1] - hardware[n]["mean_return"]] for n in names]).T
    right.barh(np.arange(len(names)), means, xerr=errors, capsize=2,
               color=["tab:gray" if n in MAIN else "tab:purple" for n in names])
    right.set_yticks(np.arange(len(names)), names)
    right.invert_yaxis()
    right.set_xlabel("return on the hardware substitute")
    right.set_title("Every training run, on the substitute")
    figure.tight_layout()
    figure.savefig(path, dpi=110)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", type=pathlib.Path, help="a finished swing-up training run to start from "
                        "(default: train one as the shipped policy is)")
    parser.add_argument("--steps", type=int, default=2_000_000, help="training steps of each run")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0, help="first evaluation seed")
    parser.add_argument("--seeds", type=int, default=1, help="training seeds per run (0 to N-1)")
    parser.add_argument("--held-out", type=int, default=10, help="held-out plants of the main runs")
    parser.add_argument("--runs", default="runs/sim2real", help="directory of the training runs")
    parser.add_argument("--jobs", type=int, default=2, help="cores of this machine for the trials (one each)")
    parser.add_argument("--address", default=None, help="run the trials on this Ray cluster instead")
    parser.add_argument("--no-train", action="store_true", help="only score the runs already present")
    parser.add_argument("--plot", type=pathlib.Path, default=DOCS / "sim2real.png", help="plot file")
    parser.add_argument("--main-only", action="store_true",
                        help="only the nominal run and the presets, without the ablations")
    args = parser.parse_args()
    runs = pathlib.Path(args.runs).resolve()  # trials run in other directories
    names = MAIN if args.main_only else tuple(TRAINING)
    grid = {"address": args.address, "cpus": args.jobs, "storage": runs / "ray"}
    if not args.no_train:
        train_missing(runs, args.base, args.steps, args.seeds, names, grid)
    conditions = (*CONDITIONS, *held_out_conditions(args.held_out))
    jobs = []
    for name in names:
        for training_seed in range(args.seeds):
            path = run_directory(runs, name, training_seed) / POLICY
            if path.exists():
                for condition in conditions if name in MAIN else ("hardware",):
                    jobs.append({"run": name, "training_seed": training_seed, "path": str(path),
                                 "condition": condition, "episodes": args.episodes, "seed": args.seed,
                                 "held_out": args.held_out})
    rows = run_grid(score, jobs, name="sim2real_scores", **grid)
    costs = {}
    for name in ("base", *TRAINING):
        for training_seed in range(args.seeds):
            record = run_directory(runs, name, training_seed) / "training.json"
            if record.exists():
                data = json.loads(record.read_text())
                costs[f"{name}, seed {training_seed}"] = {"steps": data["steps"],
                                                          "wall_time_s": data["wall_time_s"]}
    print("| trained with | seed | evaluated on | return (95 % CI) | success (95 % CI) |")
    print("|---|---|---|---|---|")
    for row in rows:
        low, high = row["return_ci"]
        success_low, success_high = row["success_ci"]
        print(f"| {row['run']} | {row['training_seed']} | {row['condition']} | {row['mean_return']:.0f} "
              f"({low:.0f}–{high:.0f}) | {100 * row['success_rate']:.0f} % "
              f"({100 * success_low:.0f}–{100 * success_high:.0f} %) |")
    print("\n| run | training steps | wall time |\n|---|---|---|")
    for name, cost in costs.items():
        print(f"| {name} | {cost['steps'] / 1e6:.2f} M | {cost['wall_time_s'] / 60:.0f} min |")
    (runs / "sim2real.json").write_text(json.dumps({"rows": rows, "training": costs}, indent=2))
    plot([row for row in rows if row["training_seed"] == 0 and row["condition"] in CONDITIONS], args.plot)


if __name__ == "__main__":
    main()
