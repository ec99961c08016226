"""Every controller on every task it is meant for: return, success rate and compute per step.

Runs each controller of `qube_suite.baselines.CONTROLLERS` on each task in its
`tasks` on the nominal simulated Qube (`qube` domain, 250 Hz, 3 V), one seeded
episode per seed, and prints per (controller, task):

* return: mean and standard deviation over the episodes;
* success: the fraction of episodes that end without termination with the
  pendulum within 10 degrees of its goal (upright, or hanging for dampen) for
  the final 2 s; for rotor, with at least 5 net revolutions;
* compute per control step (ms), timed around the controller call only, over all
  steps and over the steps with the pendulum more than 20 degrees from upright
  (swinging, where the MPC plans; upright it hands over to its LQR): the median
  and 99th percentile of wall-clock time, and the 99th percentile of the
  thread's CPU time. On a shared machine the wall-clock tail includes the time
  other processes hold the CPU; the CPU time does not.

    python benchmarks/controllers.py [--episodes 20] [--controllers swingup mpc] [--tasks swingup]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from qube_suite import baselines, suite

SETTLE_TIME = 2.0
"""Success needs the pendulum at its goal for the final 2 s ..."""
GOAL_ANGLE = math.radians(10.0)
"""... within 10 degrees."""
ROTOR_REVOLUTIONS = 5
"""Success on rotor: at least this many net revolutions."""
SWINGING = math.radians(20.0)
"""Steps with |alpha| beyond this count as swinging for the last compute column."""


def episode(controller, task: str, seed: int) -> tuple[float, bool, np.ndarray, np.ndarray]:
    """(return, success, [wall-clock, CPU] time of each step's call (s, N x 2), whether swinging (N))."""
    env = suite.load("qube", task, task_kwargs={"random": seed})
    controller.reset()
    timestep = env.reset()
    episode_return, at_goal_since, times, swinging = 0.0, None, [], []
    while not timestep.last():
        wall, cpu = time.perf_counter(), time.thread_time()
        volts = controller(timestep.observation)
        times.append((time.perf_counter() - wall, time.thread_time() - cpu))
        swinging.append(abs(timestep.observation["state"][1]) > SWINGING)
        timestep = env.step(volts)
        episode_return += timestep.reward
        if task != "rotor" and abs(env.task.pendulum_error(env.physics)) >= GOAL_ANGLE:
            at_goal_since = None
        elif task != "rotor" and at_goal_since is None:
            at_goal_since = env.physics.time()
    completed = env.step_count == env.episode_steps
    if task == "rotor":
        success = completed and env.task.revolutions >= ROTOR_REVOLUTIONS
    else:
        success = completed and at_goal_since is not None and \
            env.physics.time() - at_goal_since >= SETTLE_TIME - 1e-9
    return episode_return, success, np.array(times), np.array(swinging)


def statistics(times: np.ndarray) -> str:
    """Median and p99 wall-clock and p99 CPU time (ms) of [wall, cpu] rows, formatted."""
    if not times.size:
        return f"{'-':>9s} {'-':>7s} {'-':>7s}"
    return (f"{np.median(times[:, 0]):9.3f} {np.percentile(times[:, 0], 99):7.3f} "
            f"{np.percentile(times[:, 1], 99):7.3f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=20,
                        help="seeds 0 .. episodes-1 per controller and task")
    parser.add_argument("--controllers", nargs="*", default=list(baselines.CONTROLLERS))
    parser.add_argument("--tasks", nargs="*", default=None, help="only these tasks")
    args = parser.parse_args()

    print(f"{'compute per step (ms):':>57s} {'all steps':^25s}   {'while swinging':^25s}")
    print(f"{'controller':10s} {'task':22s} {'return':>15s} {'success':>7s} {'median':>9s} {'p99':>7s} "
          f"{'p99 cpu':>7s}   {'median':>7s} {'p99':>7s} {'p99 cpu':>7s}")
    for name in args.controllers:
        controller = baselines.make(name)
        for task in controller.tasks:
            if args.tasks and task not in args.tasks:
                continue
            results = [episode(controller, task, seed) for seed in range(args.episodes)]
            returns = np.array([r[0] for r in results])
            times = np.concatenate([r[2] for r in results]) * 1e3
            swinging = times[np.concatenate([r[3] for r in results])]
            print(f"{name:10s} {task:22s} {returns.mean():7.1f} ± {returns.std():5.1f} "
                  f"{np.mean([r[1] for r in results]):7.2f} {statistics(times)}   {statistics(swinging)}",
                  flush=True)
        controller.close()


if __name__ == "__main__":
    main()
