"""Sim-to-hardware study of learned swing-up: which training randomization transfers, and which
simulator detail matters.

Starts from one PPO swing-up run on the nominal simulation (`base`: `--base DIR`,
or trained here as the shipped policy is, balance then swing-up from it), then
continues it for `--steps` more on the nominal simulation and, from the same
start, under each randomization preset (mild, moderate, sim2real, wide), and
under one accuracy option or effect at a time (ablations: Coulomb friction on
both joints and the cable's spring, both at the sim2real preset's ranges; one
control step of action delay; Quanser's 50 rad/s velocity filter; 2048-count
encoders). Every such run has the same budget and the same start. The adaptive
row is trained as `ppo:swingup_adaptive` is (its recipe: imitation of the
swing-up controller under `wide`, history 8), not from the base. `--seeds N`
trains each N times (seeds 0 to N-1). Runs already in `--runs` are reused.

Rows without training: the calibrated rows (`--calibrated N`) calibrate each of
the first N held-out plants (the one-minute experiment on the substitute with
that plant) and fine-tune `ppo:swingup_adaptive` under a randomization centred on the
calibration (`--calibrated-steps`; `calibrated.fine_tuning`), scored on that plant; the model-based
swing-up controller with nominal parameters and with each plant's calibration;
and `--policies` (files or shipped names) as they are.
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
time) by default, on a Ray cluster with `--address`. Each score is kept in
`RUNS/scores/<run>__seed<k>__<condition>.json` with what it scored (the job:
policy path, episodes, seeds) and a hash of the policy file's content (and of a
controller's calibration); a later invocation reuses it unless one of them
changed (a retrained policy is scored again), so rows can be added one
invocation at a time. The tables, `RUNS/sim2real.json` and the plots cover
every score present: the kept ones whose policy is unchanged, and the rows of
an earlier `sim2real.json` without such records (`--import-scores` files them
under this invocation's jobs, to be reused).

    python benchmarks/sim2real.py [--base DIR] [--steps 2000000] [--episodes 20] [--seeds 1]
                                  [--held-out 10] [--runs runs/sim2real] [--jobs 2] [--train-jobs 1]
                                  [--address ray://head:10001] [--main-only] [--rows ROW ...]
                                  [--calibrated 3] [--calibrated-steps 1000000]
                                  [--policies ppo:swingup ...] [--held-out-only]
                                  [--summary-only] [--import-scores OLD/sim2real.json]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import pathlib
import re
import shutil

import held_out
import numpy as np

from qube_suite import baselines, evaluate, policies
from qube_suite.grid import run_grid
from qube_suite.hardware.plant import plant_parameters
from qube_suite.policies import load_policy
from qube_suite.randomization.presets import PRESETS
from qube_suite.training.recipes import RECIPES

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
ADAPTIVE = RECIPES["swingup_adaptive"].stages[0]
"""The adaptive row is trained as `ppo:swingup_adaptive`'s imitation stage is, with the row's seed."""
MODEL_BASED = ("model-based (nominal)", "model-based (calibrated)")
"""Rows of the swing-up controller, designed for the nominal model or for each plant's calibration."""
CALIBRATED = "calibrated fine-tuning"
"""The row of `ppo:swingup_adaptive` fine-tuned for each plant's calibration (one run per plant)."""
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


BASE_RECIPE = (("balance", 500_000), ("swingup", 5_000_000))
"""How the base is trained when no `--base` is given: the first two stages of the `swingup_follow`
recipe, PPO's swing-up (task, steps), each stage starting from the previous one."""


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
    (seed `job["seed"]`) into `job["out"]`; the adaptive row by its recipe's imitation stage."""
    from qube_suite.training import train
    from qube_suite.training.imitation import imitate

    if job["name"] == "adaptive":
        print(f"training adaptive, seed {job['seed']} ({ADAPTIVE.steps} steps imitating "
              f"{ADAPTIVE.teacher})", flush=True)
        settings = dict(ADAPTIVE.hyperparameters)
        imitate(ADAPTIVE.task, ADAPTIVE.teacher, ADAPTIVE.steps, seed=job["seed"],
                randomization=ADAPTIVE.randomization, out=job["out"], history=settings.pop("history"),
                hyperparameters=settings, progress=False)
        return
    print(f"training {job['name']}, seed {job['seed']} ({job['steps']} steps from the base)", flush=True)
    train("swingup", steps=job["steps"], seed=job["seed"], randomization=TRAINING[job["name"]],
          init=job["base"], progress=False, out=job["out"])


def calibrate_plant(job: dict) -> None:
    """Calibrate the substitute with plant `job["plant"]` (the one-minute experiment) into
    `job["out"]`, and if `job["steps"]`, fine-tune for it into the same directory (from
    `ppo:swingup_adaptive`, as `train(calibration=...)` does without init)."""
    from qube_suite import calibration
    from qube_suite.training import train

    out = pathlib.Path(job["out"])
    out.mkdir(parents=True, exist_ok=True)
    result = calibration.calibrate("qube_hardware", {"plant": job["plant"]},
                                   recording=out / "calibration.jsonl")
    result.save(out / "calibration.yaml")
    if job["steps"]:
        print(f"fine-tuning ppo:swingup_adaptive for {out.name} ({job['steps']} steps)", flush=True)
        train("swingup", steps=job["steps"], seed=0, calibration=out / "calibration.yaml", progress=False,
              out=out)


def calibrate_missing(runs: pathlib.Path, held_out_count: int, fine_tuned: int, steps: int,
                      grid: dict) -> None:
    """Calibrations of the `held_out_count` held-out plants that `runs` lacks, the first `fine_tuned`
    also fine-tuned for (`runs/calibrated/held-out_<i>`)."""
    todo = []
    for i, (condition, plant) in enumerate(held_out_conditions(held_out_count).items()):
        out = calibrated_directory(runs, condition)
        wanted = out / (POLICY if i < fine_tuned else "calibration.yaml")
        if not wanted.exists():
            todo.append({"plant": plant, "out": str(out), "steps": steps if i < fine_tuned else 0})
    run_grid(calibrate_plant, todo, name="sim2real_calibrations", **grid)


def calibrated_directory(runs: pathlib.Path, condition: str) -> pathlib.Path:
    """Where the calibration (and fine-tuned run) for a held-out `condition` lives."""
    return runs / "calibrated" / condition.replace(" ", "_")


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
    if path in baselines.names():  # a controller, on a board: one step of latency
        policy = path if job.get("parameters") is None else baselines.make(
            path, latency_steps=1, parameters=job["parameters"])
    else:
        policy = load_policy(path)
    results = [evaluate(policy, domain=domain, task="swingup", episodes=1, seed=seed + episode,
                        domain_kwargs=None if domain == "qube" else
                        {"plant": episode_plant(condition, seed + episode, job["held_out"])})
               for episode in range(episodes)]
    returns = [result.returns[0] for result in results]
    successes = sum(result.successes[0] for result in results)
    low, high = bootstrap_interval(returns)
    success_low, success_high = held_out.wilson_interval(successes, episodes)
    return {"run": run, "training_seed": job["training_seed"], "condition": condition,
            "mean_return": float(np.mean(returns)),
            "return_ci": [low, high], "success_rate": successes / episodes,
            "success_ci": [success_low, success_high], "returns": returns}


SCORES = "scores"
"""Directory of the kept scores, under the runs directory."""


def fingerprint(job: dict) -> str:
    """SHA-256 of what a score job evaluates: its policy file's content (a shipped name's file; a
    controller's name) and its calibration file's, if any; a missing file hashes as its name."""
    digest = hashlib.sha256()
    for spec in (job["path"], job.get("parameters")):
        if spec is None:
            continue
        file = policies.shipped().get(spec, pathlib.Path(spec))
        digest.update(file.read_bytes() if file.is_file() else f"missing {spec}".encode())
    return digest.hexdigest()


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9.+-]+", "_", text).strip("_")


def score_file(runs: pathlib.Path, job: dict) -> pathlib.Path:
    """Where the score of `job` is kept: `runs/scores/<run>__seed<k>__<condition>.json`."""
    return runs / SCORES / f"{_slug(job['run'])}__seed{job['training_seed']}__{_slug(job['condition'])}.json"


def keep_score(runs: pathlib.Path, job: dict, row: dict) -> None:
    """Keep the score `row` of `job`, with the job and its `fingerprint`."""
    path = score_file(runs, job)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"job": job, "fingerprint": fingerprint(job), "row": row}, indent=1))


def kept_score(runs: pathlib.Path, job: dict) -> dict | None:
    """The kept score of exactly `job` if its policy (and calibration) are unchanged, else None."""
    path = score_file(runs, job)
    if not path.is_file():
        return None
    kept = json.loads(path.read_text())
    return kept["row"] if kept["job"] == job and kept["fingerprint"] == fingerprint(job) else None


def kept_scores(runs: pathlib.Path) -> list[dict]:
    """Every kept score in `runs` whose policy (and calibration) are unchanged, in row order."""
    rows, stale = [], []
    for path in sorted((runs / SCORES).glob("*.json")):
        kept = json.loads(path.read_text())
        row = {**kept["row"], "fingerprint": kept["fingerprint"]}
        (rows if kept["fingerprint"] == fingerprint(kept["job"]) else stale).append(row)
    if stale:
        print(f"{len(stale)} kept scores left out: their policy changed or is gone "
              f"({', '.join(sorted({row['run'] for row in stale}))})")
    return sorted(rows, key=row_order)


def row_order(row: dict) -> tuple:
    """Sort key of score rows: the study's rows in `TRAINING`, `MODEL_BASED`, `CALIBRATED` order, then
    others by name; then training seed; then condition (`CONDITIONS`, then held-out plants by number)."""
    known = (*TRAINING, *MODEL_BASED, CALIBRATED)
    run = (known.index(row["run"]), "") if row["run"] in known else (len(known), row["run"])
    condition = row["condition"]
    place = ((list(CONDITIONS).index(condition), 0) if condition in CONDITIONS
             else (len(CONDITIONS), int(condition.split()[-1])) if condition.startswith("held-out")
             else (len(CONDITIONS) + 1, 0))
    return (*run, row["training_seed"], *place)


def legacy_rows(path: pathlib.Path) -> list[dict]:
    """The score rows of a `sim2real.json` that have no kept score (written before scores were
    kept, or imported there): those without a `fingerprint`."""
    if not path.is_file():
        return []
    rows = json.loads(path.read_text())["rows"]
    return [row for row in rows if "returns" in row and "fingerprint" not in row]


def import_scores(runs: pathlib.Path, path: pathlib.Path, jobs: list[dict]) -> None:
    """Keep the rows of an earlier `sim2real.json` at `path` as the scores of this invocation's `jobs`
    of the same (run, training seed, condition), for the policies as they are now; rows of no job, or
    of another episode count, are left out (and named)."""
    by_key = {(job["run"], job["training_seed"], job["condition"]): job for job in jobs}
    imported, left = 0, []
    for row in legacy_rows(path):
        job = by_key.get((row["run"], row["training_seed"], row["condition"]))
        if job is None or len(row["returns"]) != job["episodes"]:
            left.append(f"{row['run']} / {row['condition']}")
            continue
        keep_score(runs, job, row)
        imported += 1
    print(f"imported {imported} scores from {path} into {runs / SCORES}")
    if left:
        print(f"left out {len(left)} (no such job here, or other episodes): {', '.join(left)}")


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


def plot_held_out(summary: list[dict], path: pathlib.Path) -> None:
    """Success rate of every row on every held-out plant, as a table of colours."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot

    plants = sorted({plant for row in summary for plant in row["plants"]}, key=lambda c: int(c.split()[-1]))
    grid = np.array([[row["plants"].get(plant, np.nan) for plant in plants] for row in summary])
    figure, axes = pyplot.subplots(figsize=(1.0 + 0.7 * len(plants), 0.9 + 0.42 * len(summary)))
    image = axes.imshow(100 * grid, vmin=0, vmax=100, cmap="RdYlGn", aspect="auto")
    for (r, c), value in np.ndenumerate(grid):
        if not np.isnan(value):
            axes.text(c, r, f"{100 * value:.0f}", ha="center", va="center", fontsize=8)
    axes.set_xticks(range(len(plants)), [plant.split()[-1] for plant in plants])
    axes.set_yticks(range(len(summary)), [f"{row['row']} ({row['seeds']})" for row in summary])
    axes.set_xlabel("held-out plant of the hardware substitute")
    axes.set_title("Swing-up success (%) on held-out plants")
    figure.colorbar(image, ax=axes, label="success (%)")
    figure.tight_layout()
    figure.savefig(path, dpi=110)


def episodes(row: dict) -> int:
    """Episodes behind a score row (its returns, or the count of a row from `held_out.py`)."""
    return len(row["returns"]) if "returns" in row else row["episodes"]


def held_out_rows(path: str, names: dict[str, str]) -> list[dict]:
    """Score rows from a `benchmarks/held_out.py --json` file (the same plants and episodes when run
    with its default seeds and `--plants` = `--held-out`), each policy's row named by `names`; its
    cells on the substitute's own plant (`--substitute`) as the condition "hardware"."""
    cells = json.loads(pathlib.Path(path).read_text())["cells"]
    return [{"run": names.get(cell["policy"], cell["policy"]), "training_seed": 0,
             "condition": "hardware" if cell["plant"] == held_out.SUBSTITUTE else f"held-out {cell['plant']}",
             "mean_return": cell["mean_return"],
             "success_rate": cell["successes"] / cell["episodes"], "episodes": cell["episodes"]}
            for cell in cells]


def summarize(rows: list[dict], costs: dict[str, dict]) -> list[dict]:
    """Per row, over its seeds and the held-out plants: success with a Wilson interval, per-plant
    success, worst plant, mean return, the substitute's success, and the training cost."""
    summary = []
    for run in dict.fromkeys(row["run"] for row in rows):
        mine = [row for row in rows if row["run"] == run]
        held = [row for row in mine if row["condition"].startswith("held-out")]
        if not held:
            continue
        trials = sum(episodes(row) for row in held)
        successes = round(sum(row["success_rate"] * episodes(row) for row in held))
        plants: dict[str, list[float]] = {}
        for row in held:
            plants.setdefault(row["condition"], []).append(row["success_rate"])
        substitute = [row["success_rate"] for row in mine if row["condition"] == "hardware"]
        spent = [cost for name, cost in costs.items() if name.rsplit(",", 1)[0] == run]
        summary.append({
            "row": run, "seeds": len({row["training_seed"] for row in held}), "episodes": trials,
            "success_rate": successes / trials,
            "success_ci": list(held_out.wilson_interval(successes, trials)),
            "plants": {plant: float(np.mean(values)) for plant, values in plants.items()},
            "worst_plant": float(min(min(values) for values in plants.values())),
            "mean_return": float(np.mean([row["mean_return"] for row in held])),
            "substitute": float(np.mean(substitute)) if substitute else None,
            "steps_per_run": float(np.mean([c["steps"] for c in spent])) if spent else 0.0,
            "wall_time_s_per_run": float(np.mean([c["wall_time_s"] for c in spent])) if spent else 0.0})
    return summary


def score_jobs(args: argparse.Namespace, runs: pathlib.Path, rows_wanted: tuple[str, ...],
               names: tuple[str, ...], conditions: tuple[str, ...], held: dict) -> list[dict]:
    """The score jobs of the rows wanted, for the runs, calibrations and policies present."""
    common = {"episodes": args.episodes, "seed": args.seed, "held_out": args.held_out}
    jobs = []
    for name in names:
        for training_seed in range(args.seeds):
            path = run_directory(runs, name, training_seed) / POLICY
            if path.exists():
                for condition in conditions if name in MAIN else ("hardware",):
                    jobs.append({"run": name, "training_seed": training_seed, "path": str(path),
                                 "condition": condition, **common})
    for spec in args.policies:
        jobs += [{"run": spec, "training_seed": 0, "path": spec, "condition": c, **common}
                 for c in conditions]
    if MODEL_BASED[0] in rows_wanted:
        jobs += [{"run": MODEL_BASED[0], "training_seed": 0, "path": "swingup", "condition": c, **common}
                 for c in conditions]
    for condition in held:
        directory = calibrated_directory(runs, condition)
        if MODEL_BASED[1] in rows_wanted and (directory / "calibration.yaml").exists():
            jobs.append({"run": MODEL_BASED[1], "training_seed": 0, "path": "swingup", "condition": condition,
                         "parameters": str(directory / "calibration.yaml"), **common})
        if CALIBRATED in rows_wanted and (directory / POLICY).exists():
            jobs.append({"run": CALIBRATED, "training_seed": 0, "path": str(directory / POLICY),
                         "condition": condition, **common})
    return jobs


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
    parser.add_argument("--train-jobs", type=int, default=None,
                        help="cores for the training trials (default: --jobs); scoring uses --jobs")
    parser.add_argument("--address", default=None, help="run the trials on this Ray cluster instead")
    parser.add_argument("--no-train", action="store_true", help="only score the runs already present")
    parser.add_argument("--plot", type=pathlib.Path, default=DOCS / "sim2real.png", help="plot file")
    parser.add_argument("--held-out-plot", type=pathlib.Path, default=DOCS / "sim2real_held_out.png",
                        help="plot file of the rows' success on each held-out plant")
    parser.add_argument("--main-only", action="store_true",
                        help="only the nominal run and the presets, without the ablations")
    parser.add_argument("--rows", nargs="+", default=None, choices=(*TRAINING, *MODEL_BASED, CALIBRATED),
                        help="train and score only these rows (default: all)")
    parser.add_argument("--calibrated", type=int, default=3,
                        help="held-out plants the calibrated fine-tuning row is run for (default: 3)")
    parser.add_argument("--calibrated-steps", type=int, default=1_000_000,
                        help="fine-tuning steps of each calibrated run (default: 1000000)")
    parser.add_argument("--policies", nargs="*", default=[],
                        help="also score these policies (files or shipped names) as rows, as they are")
    parser.add_argument("--held-out-json", nargs="*", default=[],
                        help="also summarize and plot the rows of these benchmarks/held_out.py --json files")
    parser.add_argument("--name", nargs="*", default=[], metavar="POLICY=ROW",
                        help="row names for the policies of --held-out-json")
    parser.add_argument("--summary-only", action="store_true",
                        help="no training or scoring: summarize the scores present (RUNS/scores, and rows "
                             "of RUNS/sim2real.json without a kept score)")
    parser.add_argument("--import-scores", type=pathlib.Path, default=None, metavar="SIM2REAL.json",
                        help="keep the scores of an earlier sim2real.json as those of this invocation's "
                             "jobs (same run, seed, condition and episodes), to be reused")
    parser.add_argument("--held-out-only", action="store_true",
                        help="score on the substitute and the held-out plants only (not on the simulation "
                             "and the named variations)")
    args = parser.parse_args()
    runs = pathlib.Path(args.runs).resolve()  # trials run in other directories
    rows_wanted = args.rows or (*(MAIN if args.main_only else TRAINING), *MODEL_BASED, CALIBRATED)
    names = tuple(name for name in rows_wanted if name in TRAINING)
    grid = {"address": args.address, "cpus": args.jobs, "storage": runs / "ray"}
    training_grid = {**grid, "cpus": args.train_jobs or args.jobs}
    if not (args.no_train or args.summary_only):
        if [name for name in names if name != "adaptive"]:
            train_missing(runs, args.base, args.steps, args.seeds, names, training_grid)
        elif names:  # the adaptive row does not start from the base
            todo = [{"name": "adaptive", "seed": seed, "steps": ADAPTIVE.steps, "base": None,
                     "out": str(run_directory(runs, "adaptive", seed))} for seed in range(args.seeds)
                    if not (run_directory(runs, "adaptive", seed) / POLICY).exists()]
            run_grid(train_one, todo, name="sim2real_training", **training_grid)
        if MODEL_BASED[1] in rows_wanted or CALIBRATED in rows_wanted:
            fine_tuned = args.calibrated if CALIBRATED in rows_wanted else 0
            calibrate_missing(runs, args.held_out, fine_tuned, args.calibrated_steps, training_grid)
    held = held_out_conditions(args.held_out)
    conditions = ("hardware", *held) if args.held_out_only else (*CONDITIONS, *held)
    jobs = score_jobs(args, runs, rows_wanted, names, conditions, held)
    if args.import_scores:
        import_scores(runs, args.import_scores, jobs)
    if not args.summary_only:
        todo = [job for job in jobs if kept_score(runs, job) is None]
        print(f"scores: {len(jobs) - len(todo)} of {len(jobs)} kept in {runs / SCORES}; "
              f"computing {len(todo)}", flush=True)
        for job, row in zip(todo, run_grid(score, todo, name="sim2real_scores", **grid), strict=True):
            keep_score(runs, job, row)
    rows = kept_scores(runs)
    kept = {(row["run"], row["training_seed"], row["condition"]) for row in rows}
    legacy = [row for row in legacy_rows(runs / "sim2real.json")
              if (row["run"], row["training_seed"], row["condition"]) not in kept]
    rows = sorted(rows + legacy, key=row_order)
    names = dict(pair.split("=", 1) for pair in args.name)
    imported = [row for path in args.held_out_json for row in held_out_rows(path, names)]
    costs = {}
    seeds = max([args.seeds, *(row["training_seed"] + 1 for row in rows)])
    for name in ("base", *TRAINING):
        for training_seed in range(seeds):
            record = run_directory(runs, name, training_seed) / "training.json"
            if record.exists():
                data = json.loads(record.read_text())
                costs[f"{name}, seed {training_seed}"] = {"steps": data["steps"],
                                                          "wall_time_s": data["wall_time_s"]}
    for condition in held:
        record = calibrated_directory(runs, condition) / "training.json"
        if record.exists():
            data = json.loads(record.read_text())
            costs[f"{CALIBRATED}, {condition}"] = {"steps": data["steps"], "wall_time_s": data["wall_time_s"]}
    print(f"{len(rows) - len(legacy)} kept scores in {runs / SCORES}"
          + (f" and {len(legacy)} from {runs / 'sim2real.json'}" if legacy else ""))
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
    summary = summarize(rows + imported, costs)
    print("\n| row | seeds | held-out success (95 % CI) | plants at 100 % | worst plant | mean return | "
          "substitute | training per run |\n|---|---|---|---|---|---|---|---|")
    for row in summary:
        low, high = row["success_ci"]
        perfect = sum(value == 1.0 for value in row["plants"].values())
        substitute = "–" if row["substitute"] is None else f"{100 * row['substitute']:.0f} %"
        cost = (f"{row['steps_per_run'] / 1e6:.1f} M steps, {row['wall_time_s_per_run'] / 60:.0f} min"
                if row["steps_per_run"] else "none")
        print(f"| {row['row']} | {row['seeds']} | {100 * row['success_rate']:.1f} % ({100 * low:.0f}–"
              f"{100 * high:.0f} %) | {perfect} of {len(row['plants'])} | {100 * row['worst_plant']:.0f} % | "
              f"{row['mean_return']:.0f} | {substitute} | {cost} |")
    (runs / "sim2real.json").write_text(json.dumps({"rows": rows + imported, "training": costs,
                                                    "summary": summary}, indent=2))
    main_rows = [row for row in rows if row["training_seed"] == 0 and row["condition"] in CONDITIONS
                 and row["run"] in MAIN]
    if main_rows and not args.held_out_only:
        plot(main_rows, args.plot)
    if summary:
        plot_held_out(summary, args.held_out_plot)

if __name__ == "__main__":
    main()
