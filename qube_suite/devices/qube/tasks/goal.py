"""Tasks that drive the pendulum and the arm to goal angles (swing-up, balance, dampen)."""

from __future__ import annotations

import collections
import copy

import numpy as np
from dm_env import specs

from qube_suite.conventions import GOAL_PENDULUM_TOLERANCE
from qube_suite.devices.qube.tasks import rewards
from qube_suite.tasks.base import QubeTask
from qube_suite.tasks.follow import TARGET_LIMIT, TargetSchedule, TargetState, make_schedule


class GoalTask(QubeTask):
    """Reward for pendulum and arm near their goal angles; dense or sparse.

    Subclasses say what the pendulum's error is. The arm's goal is theta = 0, or a
    moving target in the follow variants (`FollowsTarget`), which then observe the
    target too.

    Args:
        sparse: reward 1 inside the goal set (pendulum within 10 degrees, arm within
            20 degrees of their goals), else 0; dense shaping otherwise.
        **kwargs: see `QubeTask`.
    """

    def __init__(self, sparse: bool = False, **kwargs):
        super().__init__(**kwargs)
        self._sparse = bool(sparse)
        self._target = None
        self._target_random = self.random if self.worlds is None else self.randoms

    @property
    def sparse(self) -> bool:
        return self._sparse

    @property
    def target(self):
        """The arm's goal angle (rad): 0, or the current follow target (one per world in a batch)."""
        return 0.0 if self._target is None else self._target.value

    @property
    def schedule(self) -> TargetSchedule | None:
        """The follow target's schedule (`qube_suite.tasks.follow`), or None for a fixed goal."""
        return self._target

    @property
    def process(self) -> TargetState | None:
        """The follow target's state, or None for a fixed goal."""
        return None if self._target is None else self._target.state

    def with_process(self, process: TargetState | None) -> GoalTask:
        if self._target is None:
            return super().with_process(process)
        task = copy.copy(self)
        task._target = self._target.with_state(process)
        return task

    def pendulum_error(self, physics):
        """Pendulum angle from its goal (rad)."""
        raise NotImplementedError

    def arm_error(self, physics):
        """Arm angle from its goal (rad)."""
        return physics.arm_angle() - self.target

    def get_reward(self, physics):
        pendulum_error, arm_error = self.pendulum_error(physics), self.arm_error(physics)
        if self._sparse:
            return rewards.goal_reward(pendulum_error, arm_error)
        return rewards.angle_reward(pendulum_error, arm_error)

    def at_goal(self, physics):
        """Whether the pendulum is within 10 degrees of its goal (the arm may be anywhere)."""
        return abs(self.pendulum_error(physics)) <= GOAL_PENDULUM_TOLERANCE

    def initialize_episode(self, physics, world=None) -> None:
        super().initialize_episode(physics, world)
        if self._target is not None:  # episodes start at time 0
            self._target.reset(0.0, self.random if world is None else self.randoms[world], world)

    def after_step(self, physics) -> None:
        if self._target is not None:
            self._target.update(physics.time(), self._target_random)

    def observation_spec(self, physics) -> collections.OrderedDict:
        spec = super().observation_spec(physics)
        if self._target is not None:
            spec["target"] = specs.BoundedArray((1,), np.float64, -TARGET_LIMIT, TARGET_LIMIT, name="target")
        return spec

    def observation_values(self, physics) -> list:
        values = super().observation_values(physics)
        if self._target is not None:
            values.append(self._target.value)
        return values


class FollowsTarget(GoalTask):
    """A goal task whose arm follows a moving target, chosen by the schedule keywords.

    Put first among a follow task's bases (`class SwingupFollow(FollowsTarget, Swingup)`).

    Args:
        target, target_amplitude, target_hold_time, target_frequency, target_angle:
            the target schedule (`qube_suite.tasks.follow.make_schedule`).
        **kwargs: see `GoalTask`.
    """

    follows_target = True

    def __init__(self, target="jump", target_amplitude: float | None = None,
                 target_hold_time: float | None = None, target_frequency: float | None = None,
                 target_angle: float | None = None, **kwargs):
        super().__init__(**kwargs)
        self._target = make_schedule(target, target_amplitude=target_amplitude,
                                     target_hold_time=target_hold_time, target_frequency=target_frequency,
                                     target_angle=target_angle)
        if self.worlds is not None:
            self._target = self._target.batch(self.worlds)
