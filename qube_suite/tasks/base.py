"""What every Qube task shares: the voltage action, the observation, the safe set.

Tasks use only the domain interface (`qube_suite.domains.interface.QubePhysics`),
so they run unchanged in simulation and on hardware. Their formulas (reward,
safe set, observation, task processes) take floats from one Qube or arrays from a
batch of Qubes alike (`qube_suite.devices.qube.batch.QubeBatch`, used by the vector
environment through a task made with `worlds=N`), so each is written once; a
registered task is checked for that (`qube_suite.tasks.batch_safety`).
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
from qube_suite.conventions import (
    ACTION_SHAPE,
    ARM_LIMIT,
    DEFAULT_VOLTAGE_LIMIT,
    MAX_VOLTAGE_LIMIT,
    OBSERVATION_MODES,
    ObservationLayout,
)
from qube_suite.tasks.elementwise import cos, sin
from qube_suite.tasks.starts import ClippedNormalStart, UniformStart

SUCCESS_TIME = 2.0
"""An episode succeeds if its Qube is at the task's goal throughout its final 2 s (`QubeTask.succeeded`)."""


def success_steps(control_frequency: float) -> int:
    """Control steps in SUCCESS_TIME at `control_frequency` (Hz); at least 1."""
    return max(1, round(SUCCESS_TIME * control_frequency))


def voltage_from_action(action: Any, limit: float, worlds: int | None = None, allow_number: bool = True,
                        shape: tuple[int, ...] = ACTION_SHAPE):
    """The motor voltage for `action`, finite and clipped to +-`limit` (V).

    One Qube (`worlds` None): an array-like of shape (1,), or, if `allow_number`
    (dm_env, where controllers return a float), a plain number; returns a float.
    A batch of `worlds` Qubes: shape (worlds, 1); returns a new float64 array of shape
    (worlds,). A wrong shape raises ValueError("Action dimension mismatch ...",
    Gymnasium's wording), as do NaN, inf and non-numbers. See docs/conventions.md.

    A device with several motors passes its action's `shape` (two motors: (2,)): the voltages are then a
    new float64 array of that shape, or of (worlds, *shape) for a batch, each clipped to +-`limit`.
    """
    if shape != ACTION_SHAPE:
        return _voltage_array_from_action(action, limit, shape if worlds is None else (worlds, *shape))
    if worlds is not None:
        return _voltages_from_actions(action, limit, worlds)
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


def _voltages_from_actions(actions: Any, limit: float, worlds: int) -> np.ndarray:
    try:
        actions = np.asarray(actions)
    except Exception as error:  # ragged sequences and other oddities
        raise ValueError(f"actions must be {worlds} numbers (V), got {actions!r}") from error
    if actions.shape != (worlds, *ACTION_SHAPE):
        raise ValueError(f"Action dimension mismatch: actions have shape ({worlds}, 1), got shape "
                         f"{actions.shape}")
    if actions.dtype.kind not in "fiu":
        raise ValueError(f"actions must be numbers (V), got dtype {actions.dtype}")
    volts = actions.reshape(worlds).astype(np.float64)
    if not np.isfinite(volts).all():
        raise ValueError(f"actions must be finite, got {actions.reshape(-1)[~np.isfinite(volts)][:5]}")
    return np.minimum(np.maximum(volts, -limit, out=volts), limit, out=volts)


def _voltage_array_from_action(action: Any, limit: float, shape: tuple[int, ...]) -> np.ndarray:
    try:
        array = np.asarray(action)
    except Exception as error:  # ragged sequences and other oddities
        raise ValueError(f"Action dimension mismatch: an action has shape {shape}, got {action!r}") from error
    if array.shape != shape:
        raise ValueError(f"Action dimension mismatch: an action has shape {shape}, got shape {array.shape} "
                         f"({action!r})")
    if array.dtype.kind not in "fiu":
        raise ValueError(f"an action is numbers (V), got {action!r} with dtype {array.dtype}")
    volts = array.astype(np.float64)
    if not np.isfinite(volts).all():
        raise ValueError(f"action must be finite, got {volts}")
    return np.clip(volts, -limit, limit, out=volts)


class QubeTask(base.Task):
    """Base of the Qube tasks.

    A task made with `worlds=N` evaluates a batch of N Qubes (the vector
    environment's): its accessors' arrays go in, arrays with one value per world
    come out, and world i draws from `randoms[i]`. The episode ends by
    `in_safe_set`, for one Qube and a batch alike (`qube_suite.episode_rules`);
    `get_termination`, dm_control's view of it, is not to be overridden.

    Args:
        voltage_limit: largest motor voltage (V) the action can ask for; actions
            beyond it are clipped. In (0, 10].
        observation: "state" ([theta, alpha, dtheta, dalpha]) or "trig"
            ([cos theta, sin theta, cos alpha, sin alpha, dtheta, dalpha]).
        random: seed or `numpy.random.RandomState` for everything random in the task;
            with `worlds`, an integer seed s (world i is seeded s + i) or None.
        worlds: None for one Qube, or the number of Qubes in a batch.
    """

    follows_target = False
    """Whether the arm follows a target that the observation includes."""

    action_shape: tuple[int, ...] = ACTION_SHAPE
    """The action's shape: one voltage per motor of the device (the Qube's one)."""

    max_voltage_limit: float = MAX_VOLTAGE_LIMIT
    """Largest `voltage_limit` (V) the device's tasks accept."""

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if cls.get_termination is not QubeTask.get_termination:
            raise TypeError(f"{cls.__name__} overrides get_termination: a Qube task says when its episode "
                            "terminates with in_safe_set (for one Qube and for a batch), from which "
                            "get_termination follows; see docs/write-a-task.md")

    def __init__(self, voltage_limit: float = DEFAULT_VOLTAGE_LIMIT, observation: str = "state",
                 random: int | np.random.RandomState | None = None, worlds: int | None = None):
        if not (is_number(voltage_limit) and 0.0 < voltage_limit <= self.max_voltage_limit):
            raise ValueError(f"voltage_limit must be in (0, {self.max_voltage_limit:g}] V, "
                             f"got {voltage_limit!r}")
        if observation not in OBSERVATION_MODES:
            raise ValueError(f"observation must be one of {OBSERVATION_MODES}, got {observation!r}")
        check_seed(random)
        if worlds is not None:
            if not (type(worlds) is int and worlds >= 1):
                raise ValueError(f"worlds must be None or a positive integer, got {worlds!r}")
            if not (random is None or isinstance(random, int)):
                raise ValueError(f"random must be an integer seed or None for a batch of Qubes, "
                                 f"got {random!r}")
        super().__init__(random=random)
        self._worlds = worlds
        self._randoms = None if worlds is None else (self.random, *(
            np.random.RandomState(None if random is None else random + world) for world in range(1, worlds)))
        self._voltage_limit = float(voltage_limit)
        self._trig = observation == "trig"
        limit = np.full(self.action_shape, self._voltage_limit)
        self._action_spec = specs.BoundedArray(self.action_shape, np.float64, -limit, limit, name="voltage")
        self._layout: list[tuple[str, int]] | None = None

    @property
    def voltage_limit(self) -> float:
        """Largest motor voltage (V)."""
        return self._voltage_limit

    @property
    def worlds(self) -> int | None:
        """Qubes in the batch this task evaluates, or None for one Qube."""
        return self._worlds

    @property
    def randoms(self) -> tuple[np.random.RandomState, ...] | None:
        """A batch's per-world random states (world 0's is `random`), or None for one Qube."""
        return self._randoms

    # -- episode ----------------------------------------------------------------

    def initialize_episode(self, physics, world: int | None = None) -> None:
        """Reset the Qube to a start drawn by `initial_state` and restart the task's processes.

        `world`: which Qube of a batch starts, drawing from `randoms[world]` (the others go
        on); None for one Qube, drawing from `random`.
        """
        state = self.initial_state(self.random if world is None else self._randoms[world])
        if world is None:
            physics.reset_to(state)
        else:
            physics.reset_world(world, state)

    start: UniformStart | ClippedNormalStart | None = None
    """Where episodes start, as data every backend draws from (`qube_suite.tasks.starts`); a task
    without one overrides `initial_state`."""

    def initial_state(self, random: np.random.RandomState) -> np.ndarray:
        """[theta, alpha, dtheta, dalpha] (rad, rad/s) to start an episode from, drawn from `random`."""
        if self.start is None:
            raise NotImplementedError(f"{type(self).__name__} has no start distribution: set `start` or "
                                      "override initial_state")
        return self.start.draw(random)

    def before_step(self, action, physics) -> None:
        """Validate and limit `action` (shape `action_shape`, or (worlds, *action_shape) in a batch), then
        apply it; a bad action raises and changes nothing."""
        physics.set_voltage(voltage_from_action(action, self._voltage_limit, self._worlds,
                                                shape=self.action_shape))

    def after_step(self, physics) -> None:
        """Advance the task's own processes (none by default)."""

    @property
    def process(self):
        """The state of the task's own processes (a rotor's revolution count, a follow task's target),
        which its rules read: None for a task without any, else a value (a NamedTuple) whose fields
        are floats for one Qube and arrays for a batch."""
        return None

    def with_process(self, process) -> QubeTask:
        """This task with its rules reading `process` (of `process`'s form, e.g. JAX arrays) in place of
        its own: how a backend that carries the processes in its own state (`qube_suite.mjx`) applies
        the task's rules. The task itself is left as it was."""
        if process is not None:
            raise ValueError(f"{type(self).__name__} has no processes, got {process!r}")
        return self

    def in_safe_set(self, physics):
        """Whether the Qube may go on (bool, or one per world): the arm within +-90 degrees."""
        return abs(physics.arm_angle()) <= ARM_LIMIT

    def get_termination(self, physics) -> float | None:
        """dm_control's termination of one Qube: 0.0 (terminal, discount 0) once it leaves the safe set,
        else None."""
        return None if self.in_safe_set(physics) else 0.0

    # -- success (scored by qube_suite.evaluation) ----------------------------------

    def at_goal(self, physics):
        """Whether the Qube is at the task's goal (bool, or one per world), as success counts it.

        True by default: a task without a goal set succeeds by not terminating."""
        return True

    def succeeded(self, at_goal: Sequence[bool], terminated: bool, control_frequency: float) -> bool:
        """Whether a finished episode succeeded: it did not terminate, and `at_goal` (one per step of
        the episode) held throughout its final `SUCCESS_TIME` at `control_frequency` (Hz)."""
        settled = success_steps(control_frequency)
        return not terminated and len(at_goal) >= settled and bool(np.all(at_goal[-settled:]))

    # -- specs and observations ---------------------------------------------------

    def action_spec(self, physics) -> specs.BoundedArray:
        """Motor voltage (V), shape (1,), within +-voltage_limit."""
        return self._action_spec

    def observation_spec(self, physics) -> collections.OrderedDict:
        return collections.OrderedDict(state=specs.Array((6 if self._trig else 4,), np.float64, name="state"))

    @property
    def observation_layout(self) -> ObservationLayout:
        """Where the observation keeps the state and the target: what controllers and policies read
        it with."""
        return ObservationLayout("trig" if self._trig else "state", self.follows_target)

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
        layout = self._observation_layout()
        observation = collections.OrderedDict()
        if len(layout) == 1 and len(values) == layout[0][1]:  # the state alone: no slicing
            observation[layout[0][0]] = np.array(values)
            return observation
        start = 0
        for key, size in layout:
            observation[key] = np.array(values[start:start + size])
            start += size
        return observation

    def _observation_layout(self) -> list[tuple[str, int]]:
        if self._layout is None:
            self._layout = [(key, spec.shape[0]) for key, spec in self.observation_spec(None).items()]
        return self._layout
