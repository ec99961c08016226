"""Which simulator details matter? A classical controller's success as each effect grows.

Runs the LQR balance controller (`baselines.make("balance")`, designed on the
nominal model) on the `balance` task, and a controller named "swingup" on the
`swingup` task when `qube_suite.devices.qube.controllers.CONTROLLERS` has one, with one
sensor/actuator effect or plant detail at a time at increasing strength; the
first level of every row is the nominal simulation. An episode succeeds when it
runs to the time limit with the pendulum within 10 degrees of upright over its
last second; its return is reported as a fraction of the largest possible (one
per step). Prints a table and, with matplotlib (the `media` extra), saves a
plot.

    python benchmarks/effect_sensitivity.py [--episodes 10] [--plot docs/effect_sensitivity.png]
"""

from __future__ import annotations

import argparse
import math
import pathlib

import numpy as np

from qube_suite import baselines, suite

STUDIES = {
    # name: (what, unit, levels, config at a level)
    "quantization": ("encoder counts per revolution", "counts/rev", [None, 2048, 256, 64, 32, 16],
                     lambda n: {"effects": {"quantization": {"counts_per_revolution": n}}}),
    "velocity_filter": ("velocity filter bandwidth", "rad/s", [None, 100.0, 50.0, 10.0, 2.0],
                        lambda a: {"effects": {"velocity_filter": {"cutoff": a}}}),
    "observation_noise": ("angle noise std (velocity std 10x)", "rad", [0.0, 0.01, 0.03, 0.05, 0.1],
                          lambda s: {"effects": {"observation_noise": {"std": [s, s, 10 * s, 10 * s]}}}),
    "observation_delay": ("observation delay", "steps of 4 ms", [0, 2, 4, 8, 12],
                          lambda k: {"effects": {"observation_delay": {"steps": k}}}),
    "action_delay": ("action delay", "steps of 4 ms", [0, 2, 4, 8, 12],
                     lambda k: {"effects": {"action_delay": {"steps": k}}}),
    "dead_zone": ("voltage dead-zone", "V", [0.0, 0.2, 0.5, 1.0, 1.5],
                  lambda v: {"effects": {"dead_zone": {"voltage": v}}}),
    "voltage_offset": ("voltage offset", "V", [0.0, 0.25, 0.5, 1.0, 2.0],
                       lambda v: {"effects": {"voltage_offset": {"voltage": v}}}),
    "saturation": ("amplifier saturation", "V", [None, 1.0, 0.25, 0.1, 0.05],
                   lambda v: {"effects": {"saturation": {"voltage": v}}}),
    "control_jitter": ("control-period jitter", "of the period", [0.0, 0.1, 0.2, 0.3, 0.5],
                       lambda f: {"effects": {"control_jitter": {"fraction": f}}}),
    "arm_friction": ("Coulomb friction on the arm", "N m", [0.0, 1e-3, 4e-3, 8e-3, 1.5e-2],
                     lambda f: {"parameters": {"arm_friction": f}}),
    "pendulum_friction": ("Coulomb friction on the pendulum", "N m", [0.0, 1e-4, 5e-4, 1e-3, 2e-3],
                          lambda f: {"parameters": {"pendulum_friction": f}}),
    "cable_stiffness": ("encoder cable spring", "N m/rad", [0.0, 2e-3, 6e-3, 1.2e-2, 2e-2],
                        lambda k: {"parameters": {"cable_stiffness": k}}),
}
"""Effect or plant detail -> (description, unit, strengths, randomization at a strength);
a strength of None or 0 is the nominal simulation."""

HELD_ANGLE = math.radians(10.0)
"""Success: the pendulum within this of upright (rad) ..."""
HELD_TIME = 1.0
"""... over the episode's last this many seconds, and no termination."""


def randomization_at(study: str, level):
    """The randomization config of `study` at `level` (None: the nominal simulation)."""
    return None if not level else STUDIES[study][3](level)


def episode(task: str, controller_name: str, randomization, seed: int) -> tuple[bool, float]:
    """(success, return as a fraction of the largest possible) of one seeded episode."""
    env = suite.load("qube", task, task_kwargs={"random": seed}, randomization=randomization)
    controller = baselines.make(controller_name)
    controller.reset()
    timestep = env.reset()
    held_steps = round(HELD_TIME * env.control_frequency)
    episode_return, recent = 0.0, []
    while not timestep.last():
        timestep = env.step(controller(timestep.observation))
        episode_return += timestep.reward
        recent = (recent + [abs(env.physics.true_state()[1]) <= HELD_ANGLE])[-held_steps:]
    controller.close()
    success = timestep.discount == 1.0 and len(recent) == held_steps and all(recent)
    return success, episode_return / env.episode_steps


def run(task: str, controller_name: str, episodes: int) -> dict[str, list[tuple[float, float]]]:
    """Study -> [(success rate, mean return fraction) at each level]; the nominal level is run once."""
    nominal = [episode(task, controller_name, None, seed) for seed in range(episodes)]
    results = {}
    for study, (_, _, levels, _) in STUDIES.items():
        rows = []
        for level in levels:
            randomization = randomization_at(study, level)
            outcomes = nominal if randomization is None else [
                episode(task, controller_name, randomization, seed) for seed in range(episodes)]
            rows.append((float(np.mean([s for s, _ in outcomes])), float(np.mean([r for _, r in outcomes]))))
        results[study] = rows
    return results


def print_table(task: str, results: dict) -> None:
    print(f"\n{task}: success rate (mean return / largest) at each strength; the first column is nominal")
    for study, rows in results.items():
        _, unit, levels, _ = STUDIES[study]
        cells = [f"{'nominal' if not level else f'{level:g}':>8s}: {rate:4.0%} ({ret:4.2f})"
                 for level, (rate, ret) in zip(levels, rows, strict=True)]
        print(f"{study:18s} [{unit}]".ljust(36) + " | ".join(cells))


def plot(all_results: dict[str, dict], path: pathlib.Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    columns = 4
    rows = math.ceil(len(STUDIES) / columns)
    figure, axes = plt.subplots(rows, columns, figsize=(3.2 * columns, 2.6 * rows), sharey=True)
    for axis, (study, (what, unit, levels, _)) in zip(axes.flat, STUDIES.items(), strict=False):
        labels = ["nominal" if not level else f"{level:g}" for level in levels]
        for (task, results), colour in zip(all_results.items(), ("C0", "C1"), strict=False):
            axis.plot(range(len(levels)), [rate for rate, _ in results[study]], marker="o", color=colour,
                      label=f"{task}: success rate")
            axis.plot(range(len(levels)), [ret for _, ret in results[study]], linestyle="--", color=colour,
                      label=f"{task}: return / largest")
        axis.set_xticks(range(len(levels)), labels, fontsize=7)
        axis.set_title(f"{what}\n[{unit}]", fontsize=8)
        axis.set_ylim(-0.05, 1.05)
        axis.grid(alpha=0.3)
    for axis in axes[:, 0]:
        axis.set_ylabel("fraction")
    for axis in axes.flat[len(STUDIES):]:
        axis.remove()
    axes.flat[0].legend(fontsize=7)
    figure.suptitle("Classical controllers on the simulated Qube as one simulator detail grows", fontsize=10)
    figure.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=110)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=10, help="seeded episodes per strength")
    parser.add_argument("--plot", type=pathlib.Path, default=None, help="save the plot here (PNG)")
    args = parser.parse_args()

    tasks = {"balance": "balance"}
    if "swingup" in baselines.names():
        tasks["swingup"] = "swingup"
    all_results = {}
    for task, controller_name in tasks.items():
        all_results[task] = run(task, controller_name, args.episodes)
        print_table(task, all_results[task])
    if args.plot is not None:
        plot(all_results, args.plot)
        print(f"\nplot written to {args.plot}")


if __name__ == "__main__":
    main()
