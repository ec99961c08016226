"""A new task on the Qube, in one file: turn the arm to a goal angle, the pendulum hanging still.

Subclass `QubeTask` (the voltage action, the observation and the arm's safe set
come with it), say where episodes start and what earns reward, and register a
factory for it with `qube_suite.tasks.register`: it then loads by name like the
suite's own tasks, on both domains (`suite.load("qube", "arm_to_angle")`,
`"qube_hardware"`), under its Gymnasium ids (`QubeSuite/ArmToAngle-v0`, also with
`gymnasium.make_vec`), in `evaluate` and `train`, with the LED, randomization and
rendering. Its own keyword (`goal`) goes through `task_kwargs` and Gymnasium's
keywords. Its formulas use numpy (`np.exp`, not `math.exp`), so it is batch-safe,
which registering checks.

    python examples/custom_task.py [--goal 45] [--short]
"""

from __future__ import annotations

import argparse
import math

import gymnasium
import numpy as np

import qube_suite  # noqa: F401  (registers the suite's Gymnasium ids)
from qube_suite import suite
from qube_suite.angles import wrap_angle
from qube_suite.tasks import QubeTask, register

ARM_TOLERANCE = 0.1
"""Width (rad) of the reward's bell around the arm's goal."""


class ArmToAngle(QubeTask):
    """Turn the arm to `goal` and hold it there without swinging the pendulum.

    ## Action
    Motor voltage (V), shape (1,), within +-voltage_limit (3 V by default).

    ## Observation
    `state` = [theta, alpha, dtheta, dalpha] (rad, rad/s), alpha = 0 upright.

    ## Reward
    exp(-((theta - goal) / 0.1)^2) * (1 - |alpha_down| / pi) per step, alpha_down
    the pendulum's angle from hanging: 1 with the arm at its goal and the pendulum
    hanging still.

    ## Start
    Hanging at rest, the arm within +-0.05 rad of centre.

    ## Episode end
    Terminates when |theta| > 90 degrees; truncated at the time limit.

    ## Arguments
    goal: the arm's goal angle (rad), within +-80 degrees; `voltage_limit`,
    `observation`, `random` as `QubeTask`.
    """

    def __init__(self, goal: float = math.radians(45.0), **kwargs):
        if abs(goal) > math.radians(80.0):
            raise ValueError(f"goal must be within +-80 degrees, got {math.degrees(goal):.0f}")
        super().__init__(**kwargs)
        self.goal = goal

    def initial_state(self, random: np.random.RandomState) -> np.ndarray:
        return np.array([random.uniform(-0.05, 0.05), math.pi, 0.0, 0.0])

    def get_reward(self, physics):
        arm = np.exp(-(((physics.arm_angle() - self.goal) / ARM_TOLERANCE) ** 2))
        swing = abs(wrap_angle(physics.pendulum_angle() - math.pi)) / math.pi
        return arm * (1.0 - swing)


@register("custom")
def arm_to_angle(**kwargs) -> ArmToAngle:
    """The task's factory: its name is the task's, its keywords are `ArmToAngle`'s."""
    return ArmToAngle(**kwargs)


def arm_controller(goal: float, observation) -> float:
    """A PD controller on the arm (V): enough for this task, blind to the pendulum."""
    theta, _, dtheta, _ = observation["state"]
    return -6.0 * (theta - goal) - 0.3 * dtheta


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--goal", type=float, default=45.0, help="the arm's goal (degrees)")
    parser.add_argument("--short", action="store_true", help="a 1 s episode")
    args = parser.parse_args(argv)
    goal = math.radians(args.goal)
    time_limit = 1.0 if args.short else 4.0

    # dm_env, by name, with the task's own keyword.
    env = suite.load("qube", "arm_to_angle", task_kwargs={"goal": goal, "random": 0},
                     environment_kwargs={"time_limit": time_limit})
    timestep, episode_return = env.reset(), 0.0
    while not timestep.last():
        timestep = env.step(np.array([arm_controller(goal, timestep.observation)]))
        episode_return += timestep.reward
    theta = timestep.observation["state"][0]
    print(f"arm at {math.degrees(theta):.1f} deg (goal {args.goal:g}), return {episode_return:.1f} "
          f"of {env.step_count} steps, LED {np.round(env.physics.led(), 2).tolist()}")
    env.close()

    # Gymnasium: the id registering gave it.
    gym_env = gymnasium.make("QubeSuite/ArmToAngle-v0", goal=goal, time_limit=time_limit)
    observation, info = gym_env.reset(seed=0)
    observation, reward, terminated, truncated, info = gym_env.step(gym_env.action_space.sample())
    print(f"Gymnasium: observation {observation.shape}, first reward {reward:.3f}")
    gym_env.close()


if __name__ == "__main__":
    main()
