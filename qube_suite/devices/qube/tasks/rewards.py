"""Reward shaping shared by the angle-based tasks.

Errors are floats for one Qube or arrays for a batch of Qubes; the result has the
same kind.
"""

from __future__ import annotations

import math

from qube_suite.conventions import GOAL_ARM_TOLERANCE, GOAL_PENDULUM_TOLERANCE
from qube_suite.tasks.elementwise import maximum

PENDULUM_WEIGHT = 0.8
ARM_WEIGHT = 0.2


def angle_reward(pendulum_error, arm_error):
    """max(0, 1 - (0.8 |pendulum_error| + 0.2 |arm_error|) / pi), errors in rad; 1 at the goal."""
    return maximum(1.0 - (PENDULUM_WEIGHT * abs(pendulum_error) + ARM_WEIGHT * abs(arm_error)) / math.pi, 0.0)


def in_goal(pendulum_error, arm_error):
    """Whether both errors (rad) are inside the sparse tasks' goal set (bool, or bool array)."""
    return (abs(pendulum_error) <= GOAL_PENDULUM_TOLERANCE) & (abs(arm_error) <= GOAL_ARM_TOLERANCE)


def goal_reward(pendulum_error, arm_error):
    """1.0 inside the goal set (see `in_goal`), else 0.0."""
    return 1.0 * in_goal(pendulum_error, arm_error)
