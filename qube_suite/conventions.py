"""The Qube's shared conventions: the action's limits, the arm's safe range, the goal set and
the observation layouts, defined once for the tasks, the controllers and the policies."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

DEFAULT_VOLTAGE_LIMIT = 3.0
"""Default motor voltage limit (V): the smallest in [3, 10] V that allows a swing-up
within the arm's +-90 degrees (3 V does; `benchmarks/voltage_limit.py`, docs/model.md)."""

MAX_VOLTAGE_LIMIT = 10.0
"""Largest voltage limit a task accepts (V), the range of the model's motor."""

ACTION_SHAPE = (1,)
"""Shape of an action: one motor voltage (V)."""

ARM_LIMIT = math.radians(90.0)
"""The arm leaving +-90 degrees ends the episode (the encoder cable)."""

GOAL_PENDULUM_TOLERANCE = math.radians(10.0)
"""Goal set (sparse rewards, success): pendulum within 10 degrees of its goal angle ..."""
GOAL_ARM_TOLERANCE = math.radians(20.0)
"""... and, for the sparse rewards, the arm within 20 degrees of its goal angle."""

OBSERVATION_MODES = ("state", "trig")
"""`state`: [theta, alpha, dtheta, dalpha]; `trig`: [cos theta, sin theta, cos alpha,
sin alpha, dtheta, dalpha]."""


@dataclasses.dataclass(frozen=True)
class ObservationLayout:
    """Where a task's observation keeps what: its mode (`OBSERVATION_MODES`) and whether an arm
    target follows the state. A task has one (`QubeTask.observation_layout`); controllers and
    policies read observations through it rather than guessing from their length."""

    mode: str = "state"
    target: bool = False

    def __post_init__(self):
        if self.mode not in OBSERVATION_MODES:
            raise ValueError(f"observation must be one of {OBSERVATION_MODES}, got {self.mode!r}")

    @property
    def state_size(self) -> int:
        """Values of the `state` entry: 4, or 6 in the trig mode."""
        return 6 if self.mode == "trig" else 4

    @property
    def size(self) -> int:
        """Values of the flat (Gymnasium) observation."""
        return self.state_size + self.target

    def split(self, observation: Any) -> tuple[np.ndarray, float]:
        """([theta, alpha, dtheta, dalpha] (rad, rad/s), theta_target (rad, 0 without a target)) from
        an observation of this layout: a dm_env one (mapping with `state` and, if it has one,
        `target`, read by name) or a flat Gymnasium vector of `size` values.

        Raises ValueError if the observation does not have this layout.
        """
        if isinstance(observation, Mapping):
            state = np.ravel(observation["state"])
            target = observation.get("target")
            if state.size != self.state_size or (self.target and target is None):
                raise ValueError(f"not an observation of layout {self}: state of {state.size} values"
                                 f"{'' if target is not None else ', no target'}")
            flat = state if target is None else np.concatenate([state, np.ravel(target)])
        else:
            flat = np.ravel(np.asarray(observation, dtype=np.float64))
            target = self.target or None
            if flat.size != self.size:
                raise ValueError(f"not an observation of layout {self}: {self.size} values expected, "
                                 f"got {flat.size}")
        if self.mode == "trig":
            flat = np.concatenate([[math.atan2(flat[1], flat[0]), math.atan2(flat[3], flat[2])], flat[4:]])
        return flat[:4].astype(np.float64), 0.0 if target is None else float(flat[4])

    def split_rows(self, observations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """`split` for each row of a batch of flat observations: (states, rows [theta, alpha, dtheta,
        dalpha] (rad, rad/s); arm targets (rad), zeros without a target)."""
        rows = np.asarray(observations, dtype=np.float64)
        if rows.ndim != 2 or rows.shape[1] != self.size:
            raise ValueError(f"not rows of layout {self}: shape (worlds, {self.size}) expected, "
                             f"got {rows.shape}")
        if self.mode == "trig":
            rows = np.column_stack([np.arctan2(rows[:, 1], rows[:, 0]), np.arctan2(rows[:, 3], rows[:, 2]),
                                    rows[:, 4:]])
        return rows[:, :4], rows[:, 4] if self.target else np.zeros(len(rows))
