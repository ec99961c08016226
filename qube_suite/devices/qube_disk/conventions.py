"""The disk-loaded Qube's conventions: state, action, signs, counts to SI, limits.

State [theta, dtheta]: theta (rad) the disk's angle, positive counter-clockwise seen from
above, *not* wrapped (the disk turns freely; 0 where its episode's reference is), dtheta
(rad/s) its speed. Action: the motor voltage (V), shape (1,), positive driving theta positive,
as on the pendulum (`qube_suite.conventions`).

On a board the disk is the motor's shaft, so it reads as the pendulum's arm does: encoder 0
(2048 counts per revolution) and the motor voltage with the arm's sign
(`qube_suite.hardware.conventions.arm_angle` and `board_voltage`, which the substitute board also
follows); the pendulum's encoder is absent (channel 1 is not read).
"""

from __future__ import annotations

import math

STATE_NAMES = ("disk_angle", "disk_velocity")
"""The state's entries: theta (rad), dtheta (rad/s)."""

ACTION_NAMES = ("voltage",)
"""The action's entry: the motor voltage (V)."""

ENCODER = 0
"""The board's encoder channel on the motor shaft."""

MAX_SPEED = 300.0
"""Largest |dtheta| (rad/s) of a plausible disk: above the motor's no-load 238 rad/s at 10 V."""

POSITION_LIMIT = 4.0 * math.pi
"""The position tasks end (terminate) when the disk is more than two turns from its reference."""

