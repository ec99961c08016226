"""Angle helpers shared by domains, tasks and controllers."""

from __future__ import annotations

import math

TAU = 2.0 * math.pi


def wrap_angle(angle: float) -> float:
    """`angle` (rad) wrapped to (-pi, pi]."""
    return math.pi - (math.pi - angle) % TAU
