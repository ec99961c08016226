"""The arm target of the follow tasks: its schedules, chosen by task keywords.

| `target` | the arm's goal theta_target (rad) | keywords (defaults) |
|---|---|---|
| "jump" | U(-A, A), redrawn at exponentially distributed moments | A (80 deg), H (mean, 0.5 s) |
| "steps" | U(-A, A), redrawn every hold time H | A (60 deg), H (2 s) |
| "sine" | A sin(2 pi f t) | A (45 deg), f (0.2 Hz) |
| "fixed" | a constant angle | `target_angle` (0) |
| a file path | piecewise constant, from a CSV file (`read_target_file`) | none |

A = `target_amplitude` (rad), H = `target_hold_time` (s), f = `target_frequency` (Hz).

"jump" is the original toolkit's schedule, which nothing follows closely; the
others make the follow tasks a tracking benchmark. Random schedules draw from the
random state they are given (the task's), at every reset and at every redraw, so a
seeded task replays the same targets. Targets stay within +-80 degrees, short of
the arm's +-90 degree limit. For one Qube (`worlds=None`) `value` is a float (rad);
for a batch of `worlds` Qubes it is an array with one target per world, each world
drawing from its own random state and following its own episode time.
"""

from __future__ import annotations

import copy
import csv
import math
import os
import pathlib
from typing import Any, NamedTuple

import numpy as np

from qube_suite.tasks.elementwise import array_namespace, sin

TARGET_LIMIT = math.radians(80.0)
"""Every schedule keeps its targets within +-80 degrees."""

MEAN_HOLD_TIME = 0.5
"""Mean time (s) between the "jump" schedule's redraws: about twice a second."""

SCHEDULES = ("jump", "steps", "sine", "fixed")
"""Named schedules; `target` may also be the path of a CSV file."""

_TIME_TOLERANCE = 1e-9
"""Slack (s) for comparing the episode's time with a scheduled change."""


class TargetState(NamedTuple):
    """A schedule's state as a value: the target `value` (rad) and, for a random schedule, when it is
    next redrawn (`next_change`, s; None for a schedule that is a function of time). Floats for one
    Qube, arrays for a batch or JAX arrays (`qube_suite.mjx`)."""

    value: Any
    next_change: Any = None


class TargetSchedule:
    """Base of the schedules: `value` (rad, one per world in a batch), set by `reset` and `update`."""

    def __init__(self, worlds: int | None = None):
        self.worlds = worlds
        self.value = 0.0 if worlds is None else np.zeros(worlds)

    @property
    def state(self) -> TargetState:
        """The schedule's current state."""
        return TargetState(self.value)

    def with_state(self, state: TargetState) -> TargetSchedule:
        """A copy of this schedule in `state` (of `state`'s form, e.g. JAX arrays)."""
        schedule = copy.copy(self)
        schedule.value = state.value
        return schedule

    def batch(self, worlds: int) -> TargetSchedule:
        """The same schedule for a batch of `worlds` Qubes."""
        raise NotImplementedError

    def reset(self, time: float, random: np.random.RandomState, world: int | None = None) -> None:
        """Start the schedule at `time` (s), the start of an episode (of `world` in a batch)."""
        raise NotImplementedError

    def update(self, time, random) -> None:
        """Advance to `time` (s, or one per world). `random`: the random state, or in a batch the
        sequence of per-world ones."""
        raise NotImplementedError


class RandomTargets(TargetSchedule):
    """theta_target ~ U(-amplitude, amplitude), redrawn at moments drawn by `_next_change`."""

    def __init__(self, amplitude: float, hold_time: float, worlds: int | None = None):
        super().__init__(worlds)
        self.amplitude, self.hold_time = amplitude, hold_time
        self._next_change = 0.0 if worlds is None else np.zeros(worlds)

    random_hold = False
    """Whether a target is held for a random time: each redraw then draws a standard exponential
    variate after the target's uniform one."""

    def batch(self, worlds: int) -> RandomTargets:
        return type(self)(self.amplitude, self.hold_time, worlds)

    @property
    def state(self) -> TargetState:
        return TargetState(self.value, self._next_change)

    def with_state(self, state: TargetState) -> RandomTargets:
        schedule = super().with_state(state)
        schedule._next_change = state.next_change
        return schedule

    @staticmethod
    def due(time, next_change):
        """Whether the target is to be redrawn at `time` (s, float or array)."""
        raise NotImplementedError

    def target_from(self, uniform):
        """The target (rad) for a uniform variate in [0, 1): U(-amplitude, amplitude), as
        `RandomState.uniform` computes it."""
        return -self.amplitude + 2.0 * self.amplitude * uniform

    def change_after(self, due, time, exponential):
        """When (s) the target drawn at `time`, which was due at `due`, changes next; `exponential`: a
        standard exponential variate (None unless `random_hold`)."""
        raise NotImplementedError

    def _draw(self, due: float, time: float, random: np.random.RandomState, world: int | None) -> None:
        value = self.target_from(random.random_sample())
        exponential = random.standard_exponential() if self.random_hold else None
        next_change = self.change_after(due, time, exponential)
        if world is None:
            self.value, self._next_change = value, next_change
        else:
            self.value[world], self._next_change[world] = value, next_change

    def reset(self, time: float, random: np.random.RandomState, world: int | None = None) -> None:
        self._draw(time, time, random, world)

    def update(self, time, random) -> None:
        if not isinstance(time, np.ndarray):
            if self.due(time, self._next_change):
                self._draw(self._next_change, time, random, None)
            return
        for world in np.flatnonzero(self.due(time, self._next_change)).tolist():
            self._draw(float(self._next_change[world]), float(time[world]), random[world], world)


class JumpTargets(RandomTargets):
    """Redrawn at exponentially distributed moments, mean `hold_time` apart (a Poisson process)."""

    random_hold = True

    @staticmethod
    def due(time, next_change):
        return time > next_change

    def change_after(self, due, time, exponential):
        return time + self.hold_time * exponential


class StepTargets(RandomTargets):
    """Redrawn every `hold_time` seconds exactly."""

    @staticmethod
    def due(time, next_change):
        return time >= next_change - _TIME_TOLERANCE

    def change_after(self, due, time, exponential):
        return due + self.hold_time


class TimedTargets(TargetSchedule):
    """A target that is a function of the episode's time only (`at`), drawing nothing."""

    def reset(self, time: float, random: np.random.RandomState, world: int | None = None) -> None:
        if world is None:
            self.value = self.at(time)
        else:
            self.value[world] = self.at(time)

    def update(self, time, random) -> None:
        self.value = self.at(time)

    def at(self, time):
        """The target (rad) at `time` (s, float or array)."""
        raise NotImplementedError


class SineTarget(TimedTargets):
    """amplitude sin(2 pi frequency t), t the episode's time."""

    def __init__(self, amplitude: float, frequency: float, worlds: int | None = None):
        super().__init__(worlds)
        self.amplitude, self.frequency = amplitude, frequency

    def batch(self, worlds: int) -> SineTarget:
        return SineTarget(self.amplitude, self.frequency, worlds)

    def at(self, time):
        return self.amplitude * sin(2.0 * math.pi * self.frequency * time)


class FixedTarget(TimedTargets):
    """A constant `angle` (rad)."""

    def __init__(self, angle: float, worlds: int | None = None):
        super().__init__(worlds)
        self.angle = angle

    def batch(self, worlds: int) -> FixedTarget:
        return FixedTarget(self.angle, worlds)

    def at(self, time):
        return np.full(np.shape(time), self.angle) if isinstance(time, np.ndarray) else self.angle


class SequenceTargets(TimedTargets):
    """Piecewise constant: `angles[i]` (rad) from `times[i]` (s) on, the last held to the episode's end."""

    def __init__(self, times: np.ndarray, angles: np.ndarray, worlds: int | None = None):
        super().__init__(worlds)
        self.times, self.angles = times, angles

    def batch(self, worlds: int) -> SequenceTargets:
        return SequenceTargets(self.times, self.angles, worlds)

    def at(self, time):
        namespace = array_namespace(time)
        if namespace not in (None, np):  # JAX arrays: the table looked up in their own namespace
            times = namespace.asarray(self.times)
            index = namespace.searchsorted(times, time + _TIME_TOLERANCE, side="right") - 1
            return namespace.asarray(self.angles)[index]
        index = np.searchsorted(self.times, np.asarray(time) + _TIME_TOLERANCE, side="right") - 1
        return self.angles[index] if isinstance(time, np.ndarray) else float(self.angles[index])


def read_target_file(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """(times (s), angles (rad)) of a target sequence file.

    Format: CSV with the header `time,target` and one row per change: the time (s)
    from the episode's start at which the target (rad) takes effect. Times start at
    0 and increase strictly; targets are finite and within +-80 degrees (1.396 rad).
    Lines starting with `#` are comments. Raises ValueError naming the file and line.
    """
    path = pathlib.Path(path)
    try:
        text = path.read_text()
    except OSError as error:
        raise ValueError(f"target file {path}: cannot be read ({error.strerror or error})") from None
    rows = [(number, line) for number, line in enumerate(text.splitlines(), start=1)
            if line.strip() and not line.lstrip().startswith("#")]
    if not rows or [cell.strip() for cell in rows[0][1].split(",")] != ["time", "target"]:
        raise ValueError(f"target file {path}: the first line must be the header 'time,target'")
    times, angles = [], []
    for number, cells in zip((n for n, _ in rows[1:]), csv.reader(line for _, line in rows[1:]), strict=True):
        try:
            time, angle = (float(cell) for cell in cells)
        except ValueError:
            raise ValueError(f"target file {path}, line {number}: expected two numbers 'time,target', "
                             f"got {','.join(cells)!r}") from None
        if not (math.isfinite(time) and math.isfinite(angle)):
            raise ValueError(f"target file {path}, line {number}: values must be finite")
        if abs(angle) > TARGET_LIMIT:
            raise ValueError(f"target file {path}, line {number}: target {angle} rad is beyond "
                             f"+-{TARGET_LIMIT:.4f} rad (80 degrees)")
        if (times and time <= times[-1]) or (not times and time != 0.0):
            raise ValueError(f"target file {path}, line {number}: times must start at 0 and increase, "
                             f"got {time}")
        times.append(time)
        angles.append(angle)
    if not times:
        raise ValueError(f"target file {path}: no rows after the header")
    return np.array(times), np.array(angles)


def _positive(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.0 < value < math.inf:
        raise ValueError(f"{name} must be a positive number, got {value!r}")
    return float(value)


def _angle(name: str, value: Any, allow_zero: bool = True) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not abs(value) <= TARGET_LIMIT \
            or (not allow_zero and value == 0.0):
        bound = "(0, " if not allow_zero else "[-"
        raise ValueError(f"{name} must be a number of radians in {bound}{TARGET_LIMIT:.4f}] "
                         f"(80 degrees), got {value!r}")
    return float(value)


_APPLIES = {"jump": ("target_amplitude", "target_hold_time"),
            "steps": ("target_amplitude", "target_hold_time"),
            "sine": ("target_amplitude", "target_frequency"),
            "fixed": ("target_angle",)}
"""Which shaping keywords each named schedule takes."""


def make_schedule(target: str | os.PathLike = "jump", target_amplitude: float | None = None,
                  target_hold_time: float | None = None, target_frequency: float | None = None,
                  target_angle: float | None = None) -> TargetSchedule:
    """The schedule `target` names (see the module's table), shaped by the keywords it takes.

    Raises ValueError for an unknown schedule (listing the valid ones), a missing or
    malformed file, a keyword the schedule does not take or a value out of range.
    """
    given = {"target_amplitude": target_amplitude, "target_hold_time": target_hold_time,
             "target_frequency": target_frequency, "target_angle": target_angle}
    given = {key: value for key, value in given.items() if value is not None}
    if isinstance(target, str) and target in SCHEDULES:
        extra = sorted(set(given) - set(_APPLIES[target]))
        if extra:
            raise ValueError(f"target={target!r} does not take {', '.join(extra)}; it takes "
                             f"{', '.join(_APPLIES[target])}")
    elif isinstance(target, (str, os.PathLike)) and (pathlib.Path(target).suffix == ".csv"
                                                     or pathlib.Path(target).exists()):
        if given:
            raise ValueError(f"a target file takes no other target keywords, got {', '.join(sorted(given))}")
        return SequenceTargets(*read_target_file(target))
    else:
        raise ValueError(f"unknown target schedule {target!r}; valid: {', '.join(SCHEDULES)}, "
                         "or the path of a CSV file with the header 'time,target'")
    if target == "fixed":
        return FixedTarget(_angle("target_angle", given.get("target_angle", 0.0)))
    default = {"jump": TARGET_LIMIT, "steps": math.radians(60.0), "sine": math.radians(45.0)}[target]
    amplitude = _angle("target_amplitude", given.get("target_amplitude", default), allow_zero=False)
    if target == "sine":
        return SineTarget(amplitude, _positive("target_frequency", given.get("target_frequency", 0.2)))
    default_hold = MEAN_HOLD_TIME if target == "jump" else 2.0
    hold_time = _positive("target_hold_time", given.get("target_hold_time", default_hold))
    return JumpTargets(amplitude, hold_time) if target == "jump" else StepTargets(amplitude, hold_time)
