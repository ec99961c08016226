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
    the same targets. For one Qube (`worlds=None`) `value` is a float (rad); for a
    batch of `worlds` Qubes it is an array with one target per world, each world
    drawing from its own random state.
    """

    def __init__(self, worlds: int | None = None):
        self.value = 0.0 if worlds is None else np.zeros(worlds)
        self._next_draw = 0.0 if worlds is None else np.zeros(worlds)

    def reset(self, time: float, random: np.random.RandomState, world: int | None = None) -> None:
        """Draw a fresh target at `time` (s), the start of an episode (of `world` in a batch)."""
        value = random.uniform(-TARGET_LIMIT, TARGET_LIMIT)
        next_draw = time + random.exponential(MEAN_HOLD_TIME)
        if world is None:
            self.value, self._next_draw = value, next_draw
        else:
            self.value[world], self._next_draw[world] = value, next_draw

    def update(self, time, random) -> None:
        """Redraw the targets whose moment has passed by `time` (s, or one per world).

        `random`: the random state, or in a batch the sequence of per-world ones.
        """
        if not isinstance(time, np.ndarray):
            if time > self._next_draw:
                self.reset(time, random)
            return
        for world in np.flatnonzero(time > self._next_draw).tolist():
            self.reset(float(time[world]), random[world], world)
