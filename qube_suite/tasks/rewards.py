"""Reward shaping shared by the angle-based tasks."""

from __future__ import annotations

import math

PENDULUM_WEIGHT = 0.8
ARM_WEIGHT = 0.2

GOAL_PENDULUM_TOLERANCE = math.radians(10.0)
"""Sparse goal set: pendulum within 10 degrees of its goal angle ..."""
GOAL_ARM_TOLERANCE = math.radians(20.0)
"""... and arm within 20 degrees of its goal angle."""


def angle_reward(pendulum_error: float, arm_error: float) -> float:
    """max(0, 1 - (0.8 |pendulum_error| + 0.2 |arm_error|) / pi), errors in rad; 1 at the goal."""
    return max(0.0, 1.0 - (PENDULUM_WEIGHT * abs(pendulum_error) + ARM_WEIGHT * abs(arm_error)) / math.pi)


def in_goal(pendulum_error: float, arm_error: float) -> bool:
    """Whether both errors (rad) are inside the sparse tasks' goal set."""
    return abs(pendulum_error) <= GOAL_PENDULUM_TOLERANCE and abs(arm_error) <= GOAL_ARM_TOLERANCE
