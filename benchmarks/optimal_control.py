"""LQR, energy + LQR, MPPI, iLQR-MPC and PPO on swing-up and balance, on four kinds of Qube.

Rows: each controller on the tasks it is compared on (`ROWS`): `balance` (LQR),
`swingup` (energy shaping + LQR), `mpc` (MPPI), `ilqr` (iLQR MPC) and the shipped
PPO policies (`ppo:swingup`, `ppo:balance`, and on the swing-up `ppo:swingup_adaptive`, which
acts on a history of observations). Plants, for each row:

* `nominal simulation`: the `qube` domain (MuJoCo, the nominal model), seeds 0 .. episodes-1;
* `substitute`: `qube_hardware` on its default plant (fast mode), the same seeds;
* `held-out, nominal`: `--plants` plants of the substitute drawn as `benchmarks/held_out.py`
  draws them (pendulum mass +-30 %, motor resistance +-25 %, arm friction 0 to 4e-3 N m, ...;
  each outside the `sim2real` preset), `--plant-episodes` episodes on each with its friction
  and cable stiffness varied per episode as there; controllers designed for the nominal model;
* `held-out, calibrated`: the same episodes, each controller built from the parameters that
  `qube_suite.calibration.calibrate` (the 60 s experiment on that plant, seed 0) identified
  (`baselines.for_environment(name, env, parameters=calibration)`). A learned policy has no
  parameters to calibrate: its row is left out.

Metrics per cell, over its episodes: return (mean and standard deviation); success (the task's own
rule, `QubeTask.succeeded`: no termination, the pendulum within 10 degrees of upright for the final
2 s; an episode whose reset could not reach its start on the substitute counts as failed with return
0, `evaluation.start_or_fail`, and the cell says how many); time to upright (s): from the start
until the pendulum is within 10 degrees of upright for the rest of the episode, mean over the
successful episodes; the largest |arm angle| (degrees), mean and worst over the episodes; electrical
energy (J): the motor's ∫ V i dt over the episode (V the voltage applied, i the current the domain
reports; on the substitute the current read at a sample answers the voltage of the interval before
it), mean; compute per step (ms): wall-clock median and 99th percentile of the controller call, with
the 99th percentile of the thread's CPU time.

The episode loop is `qube_suite.evaluate`'s with the motor current and the arm recorded
(`tests/test_optimal_control_benchmark.py` checks it gives `evaluate`'s returns and success).
With `--page docs/optimal_control.md` the tables replace what is between the page's
`<!-- results:begin -->` and `<!-- results:end -->` markers. `--quick` runs one episode
per cell on one plant.

    python benchmarks/optimal_control.py [--episodes 30] [--plants 10] [--plant-episodes 3]
        [--controllers swingup ilqr ...] [--tasks swingup balance] [--quick] [--page FILE]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import pathlib
import sys
import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from controllers import write_between_markers  # noqa: E402
from held_out import draw_plants, episode_plant  # noqa: E402

from qube_suite import baselines, calibration, suite  # noqa: E402
from qube_suite.conventions import GOAL_PENDULUM_TOLERANCE  # noqa: E402
from qube_suite.evaluation import FAILED_RESET_RETURN, policy_for, start_or_fail  # noqa: E402

ROWS: dict[str, tuple[str, ...]] = {
    "swingup": ("swingup", "mpc", "ilqr", "ppo:swingup", "ppo:swingup_adaptive"),
    "balance": ("balance", "swingup", "mpc", "ilqr", "ppo:balance"),
}
"""Task -> the controllers and policies compared on it."""
LABELS = {"balance": "LQR", "swingup": "energy + LQR", "mpc": "MPPI", "ilqr": "iLQR-MPC",
          "ppo:swingup": "PPO", "ppo:balance": "PPO", "ppo:swingup_adaptive": "PPO with history"}
PLANTS = ("nominal simulation", "substitute", "held-out, nominal", "held-out, calibrated")
CURRENT_LAG = {"qube": 0, "qube_hardware": 1}
"""Samples between a voltage and the current reading that answers it, per domain: the substitute
(like a real board) reads a sample's current before writing that sample's voltage."""


@dataclasses.dataclass
class Episode:
    """One episode's figures: return, success, time to upright (s, None if not upright at the end),
    largest |theta| (rad), electrical energy (J), and per-step wall-clock and CPU times (s); an episode
    whose reset failed (`reset_failed`) has no steps: return 0, failed, the other figures empty."""

    episode_return: float
    success: bool
    upright_time: float | None
    arm_excursion: float
    energy: float
    step_times: list[float]
    cpu_times: list[float]
    reset_failed: bool = False


def run_episode(spec: str, domain: str, task: str, seed: int,
                domain_kwargs: Mapping[str, Any] | None = None, parameters: Any = None) -> Episode:
    """One episode of `spec` (a controller name or a policy) from seed `seed` on a fresh environment.

    `parameters`: build the controller from these physical parameters (a `Calibration`, a mapping)
    instead of the domain's design parameters.
    """
    environment = suite.load(domain, task, task_kwargs={"random": seed}, domain_kwargs=domain_kwargs)
    try:
        if parameters is None:
            policy = policy_for(spec, environment)
        else:
            policy = baselines.for_environment(spec, environment, parameters=parameters)
        try:
            return _episode(policy, environment, domain, task, seed)
        finally:
            if hasattr(policy, "close"):
                policy.close()
    finally:
        environment.close()


def _episode(policy, environment, domain: str, task: str, seed: int) -> Episode:
    physics = environment.physics
    environment.task.random.seed(seed)
    if hasattr(policy, "reset"):
        policy.reset()
    timestep = start_or_fail(environment)
    if timestep is None:
        return Episode(FAILED_RESET_RETURN, False, None, math.nan, math.nan, [], [], reset_failed=True)
    step_times, cpu_times, errors, at_goal, arms, volts, amperes = [], [], [], [], [], [], []
    episode_return = 0.0
    while not timestep.last():
        start, cpu_start = time.perf_counter(), time.thread_time()
        action = policy(timestep.observation)
        step_times.append(time.perf_counter() - start)
        cpu_times.append(time.thread_time() - cpu_start)
        timestep = environment.step(action)
        episode_return += timestep.reward
        errors.append(abs(physics.pendulum_angle()))
        at_goal.append(environment.task.at_goal(physics))
        arms.append(abs(physics.arm_angle()))
        volts.append(physics.applied_voltage())
        amperes.append(physics.motor_current())
    errors = np.array(errors)
    lag = CURRENT_LAG[domain]
    power = np.array(volts[:len(volts) - lag]) * np.array(amperes[lag:])
    outside = np.flatnonzero(errors > GOAL_PENDULUM_TOLERANCE)
    upright_step = 0 if outside.size == 0 else int(outside[-1]) + 1
    upright = upright_step < len(errors)
    return Episode(
        episode_return=float(episode_return),
        success=environment.task.succeeded(np.array(at_goal), timestep.discount == 0.0,
                                          environment.control_frequency),
        upright_time=upright_step / environment.control_frequency if upright else None,
        arm_excursion=float(max(arms)), energy=float(power.sum() / environment.control_frequency),
        step_times=step_times, cpu_times=cpu_times)


def cell(episodes: Sequence[Episode]) -> list[str]:
    """Table cells of one (controller, task, plants): return, success (with the count of failed
    resets), time to upright, largest |theta|, energy, compute; the last three over the episodes that ran."""
    returns = [e.episode_return for e in episodes]
    upright = [e.upright_time for e in episodes if e.success and e.upright_time is not None]
    ran = [e for e in episodes if not e.reset_failed]
    failed_resets = len(episodes) - len(ran)
    success = f"{100 * np.mean([e.success for e in episodes]):.0f} %"
    if failed_resets:
        success += f" ({failed_resets} failed reset{'' if failed_resets == 1 else 's'})"
    if not ran:
        return [f"{np.mean(returns):.0f} ± {np.std(returns):.0f}", success, "–", "–", "–", "–"]
    arms = np.degrees([e.arm_excursion for e in ran])
    times = np.concatenate([e.step_times for e in ran]) * 1e3
    cpu = np.concatenate([e.cpu_times for e in ran]) * 1e3
    return [f"{np.mean(returns):.0f} ± {np.std(returns):.0f}", success,
            f"{np.mean(upright):.2f}" if upright else "–",
            f"{np.mean(arms):.0f} / {np.max(arms):.0f}",
            f"{np.mean([e.energy for e in ran]):.2f}",
            f"{np.median(times):.2f} / {np.percentile(times, 99):.2f} ({np.percentile(cpu, 99):.2f})"]


HEADER = ["controller", "plants", "return", "success", "time to upright (s)",
          "largest abs(θ) (°), mean / worst", "energy ∫V·i dt (J)", "ms per step: p50 / p99 (CPU p99)"]


def table(results: Mapping[tuple[str, str], Sequence[Episode]], controllers: Sequence[str]) -> str:
    """Markdown table of one task: a row per (controller, plants) that was run."""
    lines = ["| " + " | ".join(HEADER) + " |", "|---" * len(HEADER) + "|"]
    for name in controllers:
        for plants in PLANTS:
            if (name, plants) in results:
                lines.append("| " + " | ".join([f"{LABELS.get(name, name)} (`{name}`)", plants,
                                                *cell(results[name, plants])]) + " |")
    return "\n".join(lines)


def run_task(task: str, controllers: Sequence[str], episodes: int, plants: Sequence[dict[str, float]],
             calibrations: Sequence[Any], plant_episodes: int) -> dict[tuple[str, str], list[Episode]]:
    """Every cell of one task; prints a line per cell."""
    results: dict[tuple[str, str], list[Episode]] = {}
    for name in controllers:
        jobs = {"nominal simulation": [("qube", seed, None, None) for seed in range(episodes)],
                "substitute": [("qube_hardware", seed, None, None) for seed in range(episodes)],
                "held-out, nominal": [
                    ("qube_hardware", seed, {"plant": episode_plant(plant, seed)}, None)
                    for plant in plants for seed in range(plant_episodes)]}
        if name in baselines.names():
            jobs["held-out, calibrated"] = [
                ("qube_hardware", seed, {"plant": episode_plant(plant, seed)}, calibrated)
                for plant, calibrated in zip(plants, calibrations, strict=True)
                for seed in range(plant_episodes)]
        for plant_set, runs in jobs.items():
            results[name, plant_set] = [run_episode(name, domain, task, seed, kwargs, parameters)
                                        for domain, seed, kwargs, parameters in runs]
            print(f"{task:8s} {name:12s} {plant_set:21s} " + " | ".join(cell(results[name, plant_set])),
                  flush=True)
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=30,
                        help="seeds 0 .. episodes-1 on the nominal simulation and the substitute")
    parser.add_argument("--plants", type=int, default=10, help="held-out plants")
    parser.add_argument("--plant-episodes", type=int, default=3, help="episodes on each held-out plant")
    parser.add_argument("--plant-seed", type=int, default=2026, help="seed of the plant draws")
    parser.add_argument("--tasks", nargs="*", default=list(ROWS), choices=list(ROWS))
    parser.add_argument("--controllers", nargs="*", default=None, help="only these rows")
    parser.add_argument("--quick", action="store_true", help="one episode per cell, one held-out plant")
    parser.add_argument("--page", type=pathlib.Path, default=None,
                        help="write the tables between the results markers of this file")
    args = parser.parse_args()
    if args.quick:
        args.episodes, args.plants, args.plant_episodes = 1, 1, 1
    for value, flag in ((args.episodes, "--episodes"), (args.plants, "--plants"),
                        (args.plant_episodes, "--plant-episodes")):
        if value < 1:
            raise SystemExit(f"{flag} must be a positive integer, got {value}")

    started = time.perf_counter()
    plants = draw_plants(args.plants, args.plant_seed)
    calibrations = [calibration.calibrate("qube_hardware", {"plant": plant}, seed=0) for plant in plants]
    sections = []
    for task in args.tasks:
        controllers = [c for c in ROWS[task] if args.controllers is None or c in args.controllers]
        results = run_task(task, controllers, args.episodes, plants, calibrations, args.plant_episodes)
        sections.append(f"**{task}**\n\n{table(results, controllers)}")
    minutes = (time.perf_counter() - started) / 60
    text = "\n\n".join(sections)
    print(text)
    print(f"{minutes:.1f} min")
    if args.page is not None:
        command = " ".join(["python", "benchmarks/optimal_control.py", *sys.argv[1:]])
        held = args.plants * args.plant_episodes
        note = (f"Generated by `{command}` ({minutes:.0f} min): {args.episodes} episodes per cell on the "
                f"nominal simulation and the substitute (seeds 0 to {args.episodes - 1}), {held} on the "
                f"held-out plants ({args.plants} plants, {args.plant_episodes} episodes each), 250 Hz, 3 V.")
        write_between_markers(args.page, "\n".join([note, "", text]))
        print(f"tables written to {args.page}")


if __name__ == "__main__":
    main()
