"""What every Qube task shares: the voltage action, the observation, the safe set.

Tasks use only the domain interface (`qube_suite.domains.interface.QubePhysics`),
so they run unchanged in simulation and on hardware. Their formulas (reward,
safe set, observation, task processes) take floats from one Qube or arrays from a
batch of Qubes alike (`qube_suite.domains.qube_batch.QubeBatch`, used by the vector
environment after `use_batch`), so each is written once.
"""

from __future__ import annotations

import collections
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from dm_control.suite import base
from dm_env import specs

from qube_suite.arguments import check_seed, is_number
from qube_suite.tasks.elementwise import cos, sin

DEFAULT_VOLTAGE_LIMIT = 3.0
"""Default motor voltage limit (V): the smallest in [3, 10] V that allows a swing-up
within the arm's +-90 degrees (3 V does; `benchmarks/voltage_limit.py`, docs/model.md)."""

MAX_VOLTAGE_LIMIT = 10.0
"""Largest voltage limit a task accepts (V), the range of the model's motor."""

ARM_LIMIT = math.radians(90.0)
"""The arm leaving +-90 degrees ends the episode (the encoder cable)."""

OBSERVATION_MODES = ("state", "trig")
"""`state`: [theta, alpha, dtheta, dalpha]; `trig`: [cos theta, sin theta, cos alpha,
sin alpha, dtheta, dalpha]."""


ACTION_SHAPE = (1,)
"""Shape of an action: one motor voltage (V)."""


def voltage_from_action(action: Any, limit: float, allow_number: bool = True) -> float:
    """The motor voltage for `action`: one finite number, clipped to +-`limit` (V).

    Takes an array-like of shape (1,), or, if `allow_number` (dm_env, where
    controllers return a float), also a plain number (shape ()). A wrong shape
    raises ValueError("Action dimension mismatch ...", Gymnasium's wording), as do
    NaN, inf and non-numbers. See docs/conventions.md.
    """
    if type(action) is np.ndarray and action.shape == ACTION_SHAPE and action.dtype.kind == "f":
        volts = action.item()  # the usual action: checked by the comparison below
        if -limit <= volts <= limit:  # False for NaN
            return volts
    else:
        try:
            action = np.asarray(action)
        except Exception as error:  # ragged sequences and other oddities
            raise ValueError(f"Action dimension mismatch: an action is one number (V) of shape (1,), "
                             f"got {action!r}") from error
        if action.shape != ACTION_SHAPE and not (allow_number and action.shape == ()):
            raise ValueError(f"Action dimension mismatch: an action has shape (1,), got shape {action.shape} "
                             f"({action!r})")
        if action.dtype.kind not in "fiu":
            raise ValueError(f"action must be one number (V), got {action!r} with dtype {action.dtype}")
        volts = float(action.item())
    if not math.isfinite(volts):
        raise ValueError(f"action must be finite, got {volts}")
    return min(max(volts, -limit), limit)


class QubeTask(base.Task):
    """Base of the Qube tasks.

    Args:
        voltage_limit: largest motor voltage (V) the action can ask for; actions
            beyond it are clipped. In (0, 10].
        observation: "state" ([theta, alpha, dtheta, dalpha]) or "trig"
            ([cos theta, sin theta, cos alpha, sin alpha, dtheta, dalpha]).
        random: seed or `numpy.random.RandomState` for everything random in the task.
    """

    def __init__(self, voltage_limit: float = DEFAULT_VOLTAGE_LIMIT, observation: str = "state",
                 random: int | np.random.RandomState | None = None):
        if not (is_number(voltage_limit) and 0.0 < voltage_limit <= MAX_VOLTAGE_LIMIT):
            raise ValueError(f"voltage_limit must be in (0, {MAX_VOLTAGE_LIMIT:g}] V, got {voltage_limit!r}")
        if observation not in OBSERVATION_MODES:
            raise ValueError(f"observation must be one of {OBSERVATION_MODES}, got {observation!r}")
        check_seed(random)
        super().__init__(random=random)
        self._voltage_limit = float(voltage_limit)
        self._trig = observation == "trig"
        limit = np.full(ACTION_SHAPE, self._voltage_limit)
        self._action_spec = specs.BoundedArray(ACTION_SHAPE, np.float64, -limit, limit, name="voltage")
        self._layout: list[tuple[str, int]] | None = None

    @property
    def voltage_limit(self) -> float:
        """Largest motor voltage (V)."""
        return self._voltage_limit

    # -- episode ----------------------------------------------------------------

    def initialize_episode(self, physics) -> None:
        """Start from a state drawn by `initial_state` from `self.random`."""
        self.start_episode(physics, self.random)

    def start_episode(self, physics, random: np.random.RandomState, world: int | None = None) -> None:
        """Reset the Qube to a start drawn from `random` and restart the task's processes.

        `world`: which Qube of a batch starts (the others go on); None for one Qube.
        """
        state = self.initial_state(random)
        if world is None:
            physics.reset_to(state)
        else:
            physics.reset_world(world, state)

    def initial_state(self, random: np.random.RandomState) -> np.ndarray:
        """[theta, alpha, dtheta, dalpha] (rad, rad/s) to start an episode from, drawn from `random`."""
        raise NotImplementedError

    def use_batch(self, randoms: Sequence[np.random.RandomState]) -> None:
        """Evaluate a batch of `len(randoms)` Qubes from now on, world i drawing from `randoms[i]`.

        The task's processes then hold one value per world, `self.random` is the
        sequence of per-world random states, and `get_reward`, `in_safe_set`,
        `observation_values` and `after_step` take a `QubeBatch` and return arrays.
        """
        self._random = tuple(randoms)

    def before_step(self, action, physics) -> None:
        """Validate and limit `action`, then apply it; a bad action raises and changes nothing."""
        physics.set_voltage(voltage_from_action(action, self._voltage_limit))

    def after_step(self, physics) -> None:
        """Advance the task's own processes (none by default)."""

    def in_safe_set(self, physics):
        """Whether the Qube may go on (bool, or one per world): the arm within +-90 degrees."""
        return abs(physics.arm_angle()) <= ARM_LIMIT

    def get_termination(self, physics) -> float | None:
        """0.0 (terminal, discount 0) once the Qube leaves the safe set, else None."""
        return None if self.in_safe_set(physics) else 0.0

    # -- specs and observations ---------------------------------------------------

    def action_spec(self, physics) -> specs.BoundedArray:
        """Motor voltage (V), shape (1,), within +-voltage_limit."""
        return self._action_spec

    def observation_spec(self, physics) -> collections.OrderedDict:
        return collections.OrderedDict(state=specs.Array((6 if self._trig else 4,), np.float64, name="state"))

    def observation_values(self, physics) -> list:
        """The observation as one flat list (of floats, or of arrays over worlds), in the order of
        `observation_spec`'s keys."""
        theta, alpha = physics.arm_angle(), physics.pendulum_angle()
        if self._trig:
            return [cos(theta), sin(theta), cos(alpha), sin(alpha),
                    physics.arm_velocity(), physics.pendulum_velocity()]
        return [theta, alpha, physics.arm_velocity(), physics.pendulum_velocity()]

    def get_observation(self, physics) -> collections.OrderedDict:
        values = self.observation_values(physics)
        observation = collections.OrderedDict()
        start = 0
        for key, size in self._observation_layout():
            observation[key] = np.array(values[start:start + size])
            start += size
        return observation

    def _observation_layout(self) -> list[tuple[str, int]]:
        if self._layout is None:
            self._layout = [(key, spec.shape[0]) for key, spec in self.observation_spec(None).items()]
        return self._layout
