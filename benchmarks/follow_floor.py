"""How closely a steps schedule can be followed at a voltage limit: each crossing flown as planned offline.

A controller that follows a steps schedule cannot know the next target, so the
best it can do after each jump is the best crossing from rest at the old target
to rest at the new one. For each step size (every 5 degrees up to twice the
amplitude) this script plans that crossing offline on the closed-form model of
the nominal Qube with the iLQR kernel (`qube_suite.devices.qube.controllers.ilqr`):

* 1.6 s of knots from rest upright with the arm at -size/2, reference +size/2;
* cost: arm weight 200 (a large weight, close to a shortest crossing), no arm
  speed term, pendulum speed 0.05, voltage 0.01, the lean from upright paying
  1e5 per rad^2 beyond 19 degrees (the balance tasks end at 20);
* the voltage within the task's limit (all of it: the plan keeps none back for friction);
* warm-started from the `ilqr` controller's own closed loop on the model, 150 iterations.

It then runs a controller through `qube_suite.evaluate` on the steps schedule and
replays the targets it met (read from the observations) with each jump's crossing
as planned: the error of those plans, over the steps `evaluate` counts (after the
first 2 s), is the floor printed beside the controller's follow error. The first
target is crossed to from the arm at 0 at the start; the target at the last step
is taken to be the one observed before it (a steps schedule changes every hold
time, never at an episode's last step here). The plans are local optima of a
quadratic cost, not proof of a bound: the figure says how close the best known
crossings get, flown exactly, without latency, friction or estimation error.

    nice -n 10 .venv/bin/python benchmarks/follow_floor.py [--hold-time 2] [--amplitude 60]
        [--voltage-limit 3] [--episodes 30] [--controllers ilqr follow] [--tasks balance_follow]
        [--domains qube qube_hardware]
"""

from __future__ import annotations

import argparse
import math

import numpy as np
from qube_suite.devices.qube.controllers._ilqr import Kernel

from qube_suite import baselines, suite
from qube_suite.devices.qube.controllers.ilqr import Cost
from qube_suite.evaluation import evaluate
from qube_suite.tasks.base import success_steps

CONTROL_FREQUENCY = 250.0
H = 1 / CONTROL_FREQUENCY
KNOTS = 400
SIZE_STEP = math.radians(5.0)
PLAN_COST = Cost(arm=200.0, arm_speed=0.0, pendulum_speed=0.05, voltage=0.01,
                 lean_limit=math.radians(19.0), lean_weight=1e5)


def plan_crossing(size: float, voltage_limit: float, iterations: int = 150) -> tuple[np.ndarray, np.ndarray]:
    """The offline plan of a crossing of `size` (rad) from rest upright: (|theta - target| (rad) and
    the states [theta, alpha, dtheta, dalpha], one per control period from the jump)."""
    start, target = np.array([-size / 2, 0.0, 0.0, 0.0]), size / 2
    controller = baselines.make("ilqr", control_frequency=CONTROL_FREQUENCY, voltage_limit=voltage_limit)
    state, voltages = start.copy(), []
    for _ in range(KNOTS):  # the controller's closed loop on its own model: the warm start
        voltages.append(controller.voltage_for(state, target))
        state = controller.kernel.step(state, voltages[-1], H)[0]
    kernel = Kernel(controller.model, PLAN_COST, KNOTS, H, voltage_limit)
    kernel.lean_limit = PLAN_COST.lean_limit
    kernel.U[:] = voltages
    reference = np.full(KNOTS + 1, target)
    for _ in range(iterations):
        kernel.iterate(start, reference, np.zeros(KNOTS + 1))
    states = np.array(kernel.X)
    return np.abs(states[:, 0] - target), states


class CrossingTable:
    """Planned crossings every `SIZE_STEP` up to `largest` (rad); `error(size)` interpolates between them."""

    def __init__(self, largest: float, voltage_limit: float):
        self.sizes = np.arange(1, math.ceil(largest / SIZE_STEP - 1e-9) + 1) * SIZE_STEP
        self.plans = [plan_crossing(size, voltage_limit) for size in self.sizes]
        self.relative = np.array([error for error, _ in self.plans]) / self.sizes[:, None]
        self.largest_lean = max(float(np.abs(states[:, 1]).max()) for _, states in self.plans)

    def error(self, size: float) -> np.ndarray:
        """|theta - target| (rad) along the crossing of `size` (rad), one per control period, `KNOTS` + 1."""
        size = abs(size)
        if size > self.sizes[-1] + 1e-9:
            raise ValueError(f"a crossing of {math.degrees(size):.1f} degrees is beyond the table's "
                             f"{math.degrees(self.sizes[-1]):.0f}")
        upper = min(int(np.searchsorted(self.sizes, size)), len(self.sizes) - 1)
        if upper == 0:  # up to the smallest size: its shape, scaled
            return size * self.relative[0]
        weight = (size - self.sizes[upper - 1]) / (self.sizes[upper] - self.sizes[upper - 1])
        return size * ((1 - weight) * self.relative[upper - 1] + weight * self.relative[upper])


def planned_error(targets: np.ndarray, table: CrossingTable) -> np.ndarray:
    """|theta - target| (rad) after each step if every jump of `targets` (rad, the target after each
    step) is crossed as planned; the arm starts at 0."""
    error = np.zeros(len(targets))
    previous = 0.0
    for step, target in enumerate(targets):
        if target != previous:
            crossing = table.error(target - previous)[: len(targets) - step]
            error[step:step + len(crossing)] = crossing
            previous = target
    return error


class TargetRecorder:
    """A controller that also keeps the targets it observes: one list per episode, the target after
    each step (the last step's taken as the one before it)."""

    def __init__(self, controller):
        self.controller, self.name, self.episodes = controller, controller.name, []

    def reset(self) -> None:
        self.controller.reset()
        self.episodes.append([])

    def __call__(self, observation):
        self.episodes[-1].append(float(observation["target"][0]))
        return self.controller(observation)

    def targets(self) -> list[np.ndarray]:
        """The target after each step of each episode (rad)."""
        return [np.append(seen[1:], seen[-1]) for seen in self.episodes]


def measure(name: str, domain: str, task: str, task_kwargs: dict, episodes: int,
            table: CrossingTable) -> tuple[float, float]:
    """(the controller's follow error, the planned crossings' error on the same steps) (rad)."""
    environment = suite.load(domain, task, task_kwargs={"random": 0, **task_kwargs})
    recorder = TargetRecorder(baselines.for_environment(name, environment))
    environment.close()  # it only told the controller its settings; `evaluate` makes its own
    result = evaluate(recorder, domain, task, episodes=episodes, task_kwargs=task_kwargs)
    settled = success_steps(CONTROL_FREQUENCY)
    floor = np.concatenate([planned_error(targets, table)[settled:] for targets in recorder.targets()])
    return result.follow_error, float(floor.mean())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hold-time", type=float, default=2.0, help="s")
    parser.add_argument("--amplitude", type=float, default=60.0, help="degrees")
    parser.add_argument("--voltage-limit", type=float, default=3.0, help="V")
    parser.add_argument("--episodes", type=int, default=30)
    parser.add_argument("--controllers", nargs="+", default=["ilqr", "follow"])
    parser.add_argument("--tasks", nargs="+", default=["balance_follow", "swingup_follow"])
    parser.add_argument("--domains", nargs="+", default=["qube", "qube_hardware"])
    args = parser.parse_args()
    if args.hold_time < KNOTS * H:
        parser.error(f"--hold-time must be at least the plans' {KNOTS * H:g} s: each crossing starts at rest")
    table = CrossingTable(2 * math.radians(args.amplitude), args.voltage_limit)
    print(f"{len(table.sizes)} crossings planned at {args.voltage_limit:g} V (largest lean "
          f"{math.degrees(table.largest_lean):.1f} deg); integral of |theta - target| over each (rad s):",
          ", ".join(f"{math.degrees(table.sizes[i]):.0f} deg {table.plans[i][0].sum() * H:.3f}"
                    for i in range(3, len(table.sizes), 4)), flush=True)
    task_kwargs = {"target": "steps", "target_hold_time": args.hold_time,
                   "target_amplitude": math.radians(args.amplitude), "voltage_limit": args.voltage_limit}
    print(f"steps held {args.hold_time:g} s within +-{args.amplitude:g} deg, {args.episodes} episodes, "
          "follow error after the first 2 s (rad):")
    for task in args.tasks:
        for domain in args.domains:
            for name in args.controllers:
                error, floor = measure(name, domain, task, task_kwargs, args.episodes, table)
                print(f"  {name:7s} {task:15s} {domain:14s} {error:.3f}   planned crossings on the same "
                      f"steps {floor:.3f}   ratio {error / floor:.2f}", flush=True)


if __name__ == "__main__":
    main()
