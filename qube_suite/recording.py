"""Episode recordings: every step streamed to disk so that a crash loses at most one, and read back.

    from qube_suite import recording, suite
    env = suite.load("qube", "swingup", task_kwargs={"random": 0})
    with recording.Recorder("swingup.jsonl", env, metadata={"policy": "mine"}):
        timestep = env.reset(seed=0)
        while not timestep.last():
            timestep = env.step([1.0])
    episode = recording.load_recording("swingup.jsonl").episodes[0]
    episode["time"], episode["alpha"], episode["reward"]           # arrays, one row per reading

The recorder observes an `Environment` (or the Gymnasium `QubeEnv` around one):
a row after each reset and after every step, with the columns of `COLUMNS`, the
measured state (the pendulum's `theta`, `alpha`, `dtheta`, `dalpha`, or the names another
device's domain gives, `capabilities.NamedState`), the observation as the policy saw it
(`obs_<key>_<i>`) and, on hardware, the board's raw readings (`raw_<name>`: motor current
in A, encoder counts, tachometer in counts/s, missed samples; board signs).

Format: JSON Lines (UTF-8, one JSON value per line, standard JSON: no NaN).

    {"format": "qube_suite.recording", "version": 1, ...metadata}            the file's header
    {"episode": {"index": 0, "seed": 0, "randomization": {...}, "columns": [...]}}
    [0, 0.0, null, 0.0, ...]                                                  a row: values in column order
    ...
    {"end": {"steps": 2048, "terminated": false, "truncated": true, "physics_error": null}}

Why: a recording is appended to line by line, and each line is written whole and
flushed to the operating system before the step returns, so a process that is
killed or crashes leaves every finished step on disk and at most a cut-off last
line, which `load_recording` ignores (an episode without its "end" line was
interrupted). CSV cannot hold the nested header (randomization draws) without a
second file; npy chunks or one npz per episode are written whole at their end and
lose everything since the last one. JSON lines are read by any language, and a
row costs tens of microseconds to write and flush, far less than a 4 ms control period.
A power failure can still lose what the operating system had not yet written;
`close()` syncs the file to the disk.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from qube_suite import files
from qube_suite.capabilities import HasBoard, NamedState

FORMAT = "qube_suite.recording"
VERSION = 1

COLUMNS = ("step", "time", "action", "voltage", "applied_voltage", "reward", "discount", "last",
           "led_r", "led_g", "led_b")
"""Columns of every row: step number; time since the episode started (s); the action as given
(V, before clipping); the voltage commanded (V, clipped to the task's limit) and applied to the
motor (V, after actuator effects; on hardware, as written to the board); reward and discount of
the step (null in the reset's row); last (1 in the episode's final row); LED colour. The measured
state follows (`state_columns`). A device with several motors has one column of each voltage per
motor instead (`voltage_columns`)."""

VOLTAGE_COLUMNS = ("action", "voltage", "applied_voltage")
"""The columns that hold a voltage: one each for one motor, else suffixed `_0`, `_1`, ... per motor."""

PENDULUM_STATE = ("theta", "alpha", "dtheta", "dalpha")
"""The pendulum's measured state [theta, alpha, dtheta, dalpha] (rad, rad/s): the state columns of a
domain that does not name its own (`capabilities.NamedState`)."""


def state_columns(physics: Any) -> tuple[str, ...]:
    """The names of the measured state's columns for `physics`."""
    return physics.state_names if isinstance(physics, NamedState) else PENDULUM_STATE


def voltage_columns(motors: int) -> tuple[str, ...]:
    """`COLUMNS` for a device with `motors` motors: the voltage columns once per motor when several."""
    if motors == 1:
        return COLUMNS
    return tuple(column for name in COLUMNS for column in (
        [f"{name}_{motor}" for motor in range(motors)] if name in VOLTAGE_COLUMNS else [name]))


def _finite(value: float) -> float | None:
    """`value` as a float, or None (JSON null) if it is not finite."""
    value = float(value)
    return value if math.isfinite(value) else None


def _plain(value: Any) -> Any:
    """`value` with numpy numbers and arrays, tuples and non-finite floats made JSON-ready."""
    if isinstance(value, Mapping):
        return {str(key): _plain(item) for key, item in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_plain(item) for item in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return _finite(value)
    return value


class Recorder:
    """Streams the episodes of an environment to a JSON-lines file (see the module docstring).

    Args:
        path: the file to write (replaced if it exists).
        environment: a qube_suite `Environment` or `QubeEnv` to observe now; or call `attach`.
        metadata: JSON-ready values for the file's header (e.g. domain, task, policy).
    """

    def __init__(self, path: str | os.PathLike, environment: Any = None,
                 metadata: Mapping[str, Any] | None = None):
        self.path = os.fspath(path)
        self.episodes = 0
        self._file = open(self.path, "w", encoding="utf-8")  # noqa: SIM115  (closed by close())
        self._environment = None
        self._steps = 0
        self._raw = False
        self._motors = 1
        self._write({"format": FORMAT, "version": VERSION, **_plain(dict(metadata or {}))})
        if environment is not None:
            self.attach(environment)

    def attach(self, environment: Any) -> None:
        """Record `environment`'s episodes from its next reset on."""
        environment = getattr(getattr(environment, "unwrapped", environment), "environment", environment)
        if self._environment is not None:
            raise RuntimeError("this recorder already observes an environment; make one per environment")
        environment.observers.append(self)
        self._environment = environment

    def close(self) -> None:
        """Stop observing, sync the file to the disk and close it."""
        if self._environment is not None:
            self._environment.observers.remove(self)
            self._environment = None
        if not self._file.closed:
            self._file.flush()
            os.fsync(self._file.fileno())
            self._file.close()

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, exc_type, exc, traceback) -> None:
        self.close()

    # -- the environment's observer interface ------------------------------------------------

    def episode_started(self, environment: Any) -> None:
        """Write the episode's header and its first row."""
        physics, task = environment.physics, environment.task
        observation = [(key, spec.shape[0]) for key, spec in task.observation_spec(physics).items()]
        self._raw = isinstance(physics, HasBoard)
        self._motors = int(np.prod(getattr(task, "action_shape", (1,))))
        columns = [*voltage_columns(self._motors), *state_columns(physics),
                   *(f"obs_{key}_{i}" for key, size in observation for i in range(size))]
        if self._raw:
            columns += [f"raw_{name}" for name in physics.raw_readings()]
        drawn = environment.randomization_sample
        randomization = None if drawn is None else {"parameters": drawn.parameters, "effects": drawn.effects,
                                                    "seed": drawn.seed}
        header = {"index": self.episodes, "seed": environment.episode_seed, "randomization": randomization,
                  "task": type(task).__name__, "control_frequency": environment.control_frequency,
                  "voltage_limit": task.voltage_limit, "columns": columns}
        self._write({"episode": _plain(header)})
        self.episodes += 1
        self._steps = 0
        self._row(environment, None, None, None, False)

    def step_done(self, environment: Any, action: Any, reward: float, discount: float | None) -> None:
        """Write the step's row, and the episode's end once it is over."""
        self._steps += 1
        last = discount is not None
        action = float(np.ravel(action)[0]) if self._motors == 1 else np.ravel(action).astype(float)
        self._row(environment, action, reward, 1.0 if discount is None else discount, last)
        if last:
            error = environment.physics_error
            self._write({"end": {"steps": self._steps, "terminated": discount == 0.0,
                                 "truncated": discount == 1.0, "physics_error": error}})

    # -- writing -----------------------------------------------------------------------------

    def _row(self, environment: Any, action: Any, reward: float | None, discount: float | None,
             last: bool) -> None:
        physics = environment.physics
        if self._motors == 1:
            volts = [action, physics.voltage(), physics.applied_voltage()]
        else:
            volts = [*([None] * self._motors if action is None else action), *physics.voltage(),
                     *physics.applied_voltage()]
        values = [self._steps, physics.time(), *volts, reward, discount, int(last), *physics.led(),
                  *physics.qube_state().tolist(), *environment.task.observation_values(physics)]
        if self._raw:
            values += physics.raw_readings().values()
        self._write([None if value is None else _finite(value) for value in values])

    def _write(self, value: Any) -> None:
        self._file.write(json.dumps(value, allow_nan=False, separators=(",", ":")) + "\n")
        self._file.flush()


@dataclasses.dataclass(frozen=True)
class RecordedEpisode:
    """One recorded episode: its header, one array per column (NaN where a value is null), and
    its end record (None if the recording stopped before the episode ended, e.g. a crash)."""

    header: dict[str, Any]
    data: dict[str, np.ndarray]
    end: dict[str, Any] | None

    def __getitem__(self, column: str) -> np.ndarray:
        return self.data[column]

    @property
    def steps(self) -> int:
        """Steps recorded (rows after the reset's)."""
        return len(self.data["step"]) - 1


@dataclasses.dataclass(frozen=True)
class Recording:
    """A recording file read back: its header's metadata, its episodes, and whether its last line
    was cut off (the writing process was killed or crashed mid-line)."""

    metadata: dict[str, Any]
    episodes: list[RecordedEpisode]
    truncated: bool


def load_recording(path: str | os.PathLike) -> Recording:
    """Read a recording, also one a crash cut short: a last line that is incomplete is ignored.

    Raises ValueError if the file is not a qube_suite recording or a line before the last one is
    damaged.
    """
    lines = files.read_bytes(path, "recording").split(b"\n")
    truncated = lines[-1] != b""  # a complete file ends with a newline
    values = []
    for number, line in enumerate(lines[:-1], start=1):
        try:
            values.append(json.loads(line))
        except ValueError as error:
            raise ValueError(f"{os.fspath(path)}, line {number}: not JSON ({error}); the file is damaged") \
                from None
    if not values or not isinstance(values[0], dict) or values[0].get("format") != FORMAT:
        raise ValueError(f"{os.fspath(path)} is not a qube_suite recording (its first line must be a "
                         f"{FORMAT!r} header)")
    metadata = values[0]
    episodes: list[RecordedEpisode] = []
    header, columns, rows, end = None, [], [], None

    def damaged(number: int, what: str) -> ValueError:
        return ValueError(f"{os.fspath(path)}, line {number}: {what}; the file is damaged")

    def finish() -> None:
        if header is not None:
            data = np.array(rows, dtype=float).reshape(len(rows), len(columns))
            episodes.append(RecordedEpisode(header, dict(zip(columns, data.T, strict=True)), end))

    for number, value in enumerate(values[1:], start=2):
        if isinstance(value, list):
            if header is None:
                raise damaged(number, "a row before any episode header")
            if len(value) != len(columns):
                raise damaged(number, f"a row of {len(value)} values where the episode has "
                                      f"{len(columns)} columns")
            if not all(x is None or (isinstance(x, (int, float)) and not isinstance(x, bool)) for x in value):
                raise damaged(number, "a row with a value that is not a number or null")
            rows.append(value)
        elif isinstance(value, dict) and isinstance(value.get("episode"), dict):
            finish()
            header, rows, end = value["episode"], [], None
            columns = header.get("columns")
            if not (isinstance(columns, list) and columns and all(isinstance(c, str) for c in columns)):
                raise damaged(number, "an episode header without its list of column names")
        elif isinstance(value, dict) and "end" in value:
            end = value["end"]
        else:
            raise damaged(number, f"neither a row, an episode header nor an end record ({str(value)[:60]})")
    finish()
    return Recording(metadata, episodes, truncated)
