"""Swing-up policies and controllers on held-out plants: Qubes nobody described to them.

Draws `--plants` plants of the hardware substitute (`qube_hardware`,
`domain_kwargs={"plant": ...}`) from the held-out ranges below (seeded by
`--plant-seed`; a draw inside every one of the `sim2real` preset's ranges is
redrawn, so every plant lies outside what `sim2real` trains on), and runs each
policy `--episodes` episodes of swing-up on each. The substitute starts every
episode hanging at rest and is otherwise deterministic, so each episode varies
the plant's Coulomb friction and cable stiffness by up to +-`EPISODE_SPREAD`
(clipped to the held-out ranges), seeded by the episode. Reports per plant and
overall the mean return and success (no termination, the pendulum within 10
degrees of upright for the final 2 s) with a 95 % Wilson interval.

The plants are drawn about the substitute's default plant, the real Qube's (`real_qube_servo2`);
`--base NAME` draws them about another named plant (`qube_suite.hardware.plant.PLANTS`; `--base
estimated`: the estimated plant, about which the figures published before 2026-11-28 were
measured): the relative ranges about that plant's values, every other parameter (its latency,
dead zone, cable band...) kept.
`--substitute` also scores every policy on that plant itself (the default plant without
`--base`), its episodes varied as a held-out plant's, in the row "substitute".
`--calibrated swingup` also scores the model-based controllers named, each built from its
plant's calibration (`qube_suite.calibration.calibrate`: the one-minute experiment on the
substitute with that plant, seed 0, as `benchmarks/sim2real.py` calibrates), as the policy
"swingup (calibrated)". An episode whose reset cannot reach its start counts as failed with
return 0 (`evaluate`'s rule); the table says how many did. The transfer study's headline rows on
the substitute like a real Qube (docs/transfer.md):

    python benchmarks/held_out.py --substitute \
        --policy ppo:swingup_adaptive ppo:swingup swingup --calibrated swingup

    python benchmarks/held_out.py [--policy ppo:swingup ...] [--plants 10] [--episodes 20]
                                  [--plant-seed 2026] [--jobs 1] [--json FILE] [--base NAME]
                                  [--substitute] [--calibrated CONTROLLER ...]
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing
import time

import numpy as np

from qube_suite import baselines, calibration, evaluate
from qube_suite.devices.qube import parameters as nominal_parameters
from qube_suite.hardware.plant import named_plant, plant_parameters
from qube_suite.randomization.presets import PRESETS

RELATIVE = {"pendulum_mass": 0.30, "pendulum_length": 0.10, "motor_resistance": 0.25,
            "motor_torque_constant": 0.15, "rotor_inertia": 0.30}
"""Held-out ranges: parameter -> half-width relative to the plant they are drawn about (uniform)."""
ABSOLUTE = {"arm_friction": 4e-3, "pendulum_friction": 2e-4, "cable_stiffness": 4e-3}
"""Held-out ranges: parameter -> upper end (N m, N m, N m/rad), from 0 (uniform)."""
EPISODE_SPREAD = 0.1
"""Relative variation of each episode's friction and cable stiffness around its plant's values."""


def inside_sim2real(plant: dict[str, float]) -> bool:
    """Whether every value of `plant` lies within the `sim2real` preset's range for it."""
    ranges = PRESETS["sim2real"]["parameters"]
    for name, value in plant.items():
        spec = ranges[name]
        scale = 1.0 if spec.get("relative", True) is False else nominal_parameters.NOMINAL[name]
        if not spec["low"] * scale <= value <= spec["high"] * scale:
            return False
    return True


def draw_plants(count: int, seed: int, base: str | None = None) -> list[dict[str, float]]:
    """`count` plants from the held-out ranges, each outside the `sim2real` ranges (seeded); about the
    named plant `base` (None: the substitute's default plant), whose other parameters they keep."""
    random = np.random.default_rng(seed)
    around = plant_parameters("qube_servo2_usb", base)
    plants = []
    while len(plants) < count:
        plant = {name: around[name] * random.uniform(1 - w, 1 + w) for name, w in RELATIVE.items()}
        plant |= {name: random.uniform(0.0, high) for name, high in ABSOLUTE.items()}
        if not inside_sim2real(plant):
            plants.append(plant if base is None else {**named_plant(base), **plant})
    return plants


def episode_plant(plant: dict[str, float], seed: int) -> dict[str, float]:
    """`plant` with its friction and cable stiffness varied by +-`EPISODE_SPREAD`, seeded by `seed`."""
    random = np.random.default_rng(seed)
    varied = dict(plant)
    for name, high in ABSOLUTE.items():
        varied[name] = min(high, plant[name] * random.uniform(1 - EPISODE_SPREAD, 1 + EPISODE_SPREAD))
    return varied


def wilson_interval(successes: int, trials: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson score interval of a success rate."""
    p = successes / trials
    centre = (p + z * z / (2 * trials)) / (1 + z * z / trials)
    half = z * math.sqrt(p * (1 - p) / trials + z * z / (4 * trials * trials)) / (1 + z * z / trials)
    return max(0.0, centre - half), min(1.0, centre + half)


SUBSTITUTE = "substitute"
"""The plant label of the cells on the plant the held-out ones are drawn about (`--substitute`)."""
CALIBRATED = " (calibrated)"
"""Suffix of a model-based controller built from its plant's calibration (`--calibrated`)."""


def score(job: tuple[str, int | str, dict[str, float], int, int, object]) -> dict:
    """One (policy, plant) cell: `episodes` episodes from `seed`, each on a fresh substitute; a
    controller with a calibration (the job's last item, else None) is built from it, for a board's
    one step of latency."""
    policy, index, plant, episodes, seed, parameters = job
    spec = policy.removesuffix(CALIBRATED)
    results = [evaluate(spec if parameters is None else baselines.make(spec, latency_steps=1,
                                                                        parameters=parameters),
                        domain="qube_hardware", task="swingup", episodes=1, seed=seed + episode,
                        domain_kwargs={"plant": episode_plant(plant, seed + episode)})
               for episode in range(episodes)]
    successes = sum(result.successes[0] for result in results)
    return {"policy": policy, "plant": index, "parameters": plant, "successes": int(successes),
            "episodes": episodes, "mean_return": float(np.mean([r.returns[0] for r in results])),
            "failed_resets": sum(len(r.failed_resets) for r in results)}


def calibrate_plant(plant: dict[str, float]) -> calibration.Calibration:
    """The calibration of the substitute with `plant`: the one-minute experiment, seed 0."""
    return calibration.calibrate("qube_hardware", {"plant": plant}, seed=0)


def failures(cells: list[dict]) -> str:
    """", n failed resets" for cells whose episodes had any (`evaluate`: failed, return 0), else ""."""
    count = sum(cell.get("failed_resets", 0) for cell in cells)
    return f", {count} failed reset{'' if count == 1 else 's'}" if count else ""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policy", nargs="+", default=["ppo:swingup", "swingup"],
                        help="policies (shipped names or files) or controller names")
    parser.add_argument("--plants", type=int, default=10)
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--plant-seed", type=int, default=2026, help="seed of the plant draws")
    parser.add_argument("--seed", type=int, default=0, help="first episode seed")
    parser.add_argument("--jobs", type=int, default=1, help="cells scored in parallel")
    parser.add_argument("--json", default=None, help="also write the cells to this JSON file")
    parser.add_argument("--base", default=None,
                        help="draw about this named plant (default: the substitute's, real_qube_servo2)")
    parser.add_argument("--substitute", action="store_true",
                        help="also score on the plant the held-out ones are drawn about")
    parser.add_argument("--calibrated", nargs="*", default=[], metavar="CONTROLLER",
                        help="also these controllers, built from each plant's calibration")
    args = parser.parse_args()
    unknown = [name for name in args.calibrated if name not in baselines.names()]
    if unknown:
        parser.error(f"--calibrated takes controllers ({', '.join(baselines.names())}), not {unknown}")
    started = time.perf_counter()
    plants: dict[int | str, dict[str, float]] = dict(enumerate(draw_plants(args.plants, args.plant_seed,
                                                                           args.base)))
    if args.substitute:
        plants[SUBSTITUTE] = plant_parameters("qube_servo2_usb", args.base)
    calibrations = {index: calibrate_plant(plant) for index, plant in plants.items() if args.calibrated}
    jobs = [(policy, index, plant, args.episodes, args.seed, None) for policy in args.policy
            for index, plant in plants.items()]
    jobs += [(name + CALIBRATED, index, plant, args.episodes, args.seed, calibrations[index])
             for name in args.calibrated for index, plant in plants.items()]
    with multiprocessing.Pool(args.jobs) as pool:
        cells = pool.map(score, jobs, chunksize=1)
    print("| policy | plant | return | success (95 % CI) |\n|---|---|---|---|")
    for policy in dict.fromkeys(job[0] for job in jobs):
        mine = [cell for cell in cells if cell["policy"] == policy]
        for cell in mine:
            low, high = wilson_interval(cell["successes"], cell["episodes"])
            rate = cell["successes"] / cell["episodes"]
            print(f"| {policy} | {cell['plant']} | {cell['mean_return']:.0f} | "
                  f"{100 * rate:.0f} % ({100 * low:.0f}–{100 * high:.0f} %){failures([cell])} |")
        held = [cell for cell in mine if cell["plant"] != SUBSTITUTE]
        successes, trials = sum(c["successes"] for c in held), sum(c["episodes"] for c in held)
        low, high = wilson_interval(successes, trials)
        worst = min(c["successes"] / c["episodes"] for c in held)
        print(f"| {policy} | all {len(held)} held-out | {np.mean([c['mean_return'] for c in held]):.0f} | "
              f"{100 * successes / trials:.1f} % ({100 * low:.0f}–{100 * high:.0f} %); worst plant "
              f"{100 * worst:.0f} %{failures(held)} |")
    print(f"{(time.perf_counter() - started) / 60:.1f} min")
    if args.json:
        with open(args.json, "w") as file:
            json.dump({"plants": [plants[i] for i in range(args.plants)], "cells": cells}, file, indent=2)


if __name__ == "__main__":
    main()
