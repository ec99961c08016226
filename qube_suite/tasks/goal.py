"""Tasks that drive the pendulum and the arm to goal angles (swing-up, balance, dampen)."""

from __future__ import annotations

import collections

import numpy as np
from dm_env import specs

from qube_suite.tasks import rewards
from qube_suite.tasks.base import QubeTask
from qube_suite.tasks.follow import TARGET_LIMIT, TargetProcess


class GoalTask(QubeTask):
    """Reward for pendulum and arm near their goal angles; dense or sparse.

    Subclasses say what the pendulum's error is. The arm's goal is theta = 0, or a
    moving target in the follow variants (`follows_target = True`), which then
    observe the target too.

    Args:
        sparse: reward 1 inside the goal set (pendulum within 10 degrees, arm within
            20 degrees of their goals), else 0; dense shaping otherwise.
        **kwargs: see `QubeTask`.
    """

    follows_target = False

    def __init__(self, sparse: bool = False, **kwargs):
        super().__init__(**kwargs)
        self._sparse = bool(sparse)
        self._target = TargetProcess() if self.follows_target else None

    @property
    def sparse(self) -> bool:
        return self._sparse

    @property
    def target(self) -> float:
        """The arm's goal angle (rad): 0, or the current follow target."""
        return 0.0 if self._target is None else self._target.value

    def pendulum_error(self, physics) -> float:
        """Pendulum angle from its goal (rad)."""
        raise NotImplementedError

    def arm_error(self, physics) -> float:
        """Arm angle from its goal (rad)."""
        return physics.arm_angle() - self.target

    def get_reward(self, physics) -> float:
        pendulum_error, arm_error = self.pendulum_error(physics), self.arm_error(physics)
        if self._sparse:
            return 1.0 if rewards.in_goal(pendulum_error, arm_error) else 0.0
        return rewards.angle_reward(pendulum_error, arm_error)

    def initialize_episode(self, physics) -> None:
        super().initialize_episode(physics)
        if self._target is not None:
            self._target.reset(physics.time(), self.random)

    def after_step(self, physics) -> None:
        if self._target is not None:
            self._target.update(physics.time(), self.random)

    def observation_spec(self, physics) -> collections.OrderedDict:
        spec = super().observation_spec(physics)
        if self._target is not None:
            spec["target"] = specs.BoundedArray((1,), np.float64, -TARGET_LIMIT, TARGET_LIMIT, name="target")
        return spec

    def observation_values(self, physics) -> list[float]:
        values = super().observation_values(physics)
        if self._target is not None:
            values.append(self._target.value)
        return values
