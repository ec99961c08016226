"""The moving arm target of the follow tasks."""

from __future__ import annotations

import math

import numpy as np

TARGET_LIMIT = math.radians(80.0)
"""Targets are drawn uniformly from +-80 degrees."""

MEAN_HOLD_TIME = 0.5
"""Mean time (s) between redraws: a Poisson process, about twice a second."""


class TargetProcess:
    """theta_target ~ U(-80, 80) degrees, redrawn at exponentially distributed moments.

    Draws from the random state it is given (the task's), so a seeded task replays
    the same targets.
    """

    def __init__(self):
        self.value = 0.0
        self._next_draw = 0.0

    def reset(self, time: float, random: np.random.RandomState) -> None:
        """Draw a fresh target at the start of an episode at `time` (s)."""
        self._draw(time, random)

    def update(self, time: float, random: np.random.RandomState) -> None:
        """Redraw the target if its moment has come by `time` (s)."""
        if time >= self._next_draw:
            self._draw(time, random)

    def _draw(self, time: float, random: np.random.RandomState) -> None:
        self.value = random.uniform(-TARGET_LIMIT, TARGET_LIMIT)
        self._next_draw = time + random.exponential(MEAN_HOLD_TIME)
