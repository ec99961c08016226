"""Recordings from any logger: CSV or NumPy `.npz` files of a Qube's encoders and voltage.

The format (that of Quanser's own scopes exported to CSV, of Simulink or LabVIEW logs
renamed, and of `qube-suite recording export`): one row per sample, a header line with

    time            s     sample time; any constant period (timestamps with jitter are fine)
    voltage         V     voltage applied to the motor over the interval that starts at the sample
    arm_angle       rad   theta, 0 = arm centred, counter-clockwise from above positive
    pendulum_angle  rad   alpha, 0 = upright, +-pi hanging (wrapped or not)

and optionally `motor_current` (A), `arm_velocity`, `pendulum_velocity` (rad/s, ignored by the
fit, which differentiates the angles without lag) and `voltage_commanded` (V, before the
amplifier's clipping). Other columns are ignored. A `.npz`, or a MATLAB `.mat` of separate
variables (`save('run.mat', 'time', 'voltage', 'arm_angle', 'pendulum_angle')`), holds the
same names as arrays. (QUARC's To File blocks write one unnamed matrix: save its rows under
these names first.)

Recordings in other conventions are read with `Conventions`: angles in degrees, the pendulum's
zero hanging rather than upright, either angle's sign reversed.

`read` refuses, with a ValueError of one line naming the file and the problem, files that
cannot calibrate: a missing column, a value that is not a finite number, time that does not
increase or has gaps, a recording too short, the arm beyond its limit, the voltage saturated
for most of the recording.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import os

import numpy as np

from qube_suite.calibration.measurements import Measurements
from qube_suite.hardware.plant import plant_parameters

REQUIRED = ("time", "voltage", "arm_angle", "pendulum_angle")
"""Columns every recording must have."""
OPTIONAL = ("motor_current", "voltage_commanded", "arm_velocity", "pendulum_velocity")
"""Columns used where present."""
DEVICES = {"qube_servo2": "qube_servo2_usb", "qube_servo3": "qube_servo3_usb"}
"""Devices a recording may come from, and the board type whose motor data they assume."""
ARM_LIMIT = np.radians(120.0)
"""Largest arm angle (rad) a recording may reach. The tasks stop at +-90 degrees but open-loop
recordings go further (TU Darmstadt's chirps on a Qube-Servo 2 reach 100 degrees); beyond 120 the
encoder cable pulls hard on the arm, and a larger value usually means angles in degrees."""
MIN_SECONDS = 2.0
"""Shortest recording (s): ten of the fit's 0.2 s momentum-balance windows."""
MAX_JITTER = 0.25
"""Largest deviation of a sample interval from the median one, as a fraction of it."""
SMOOTHING_WINDOW = 11
"""Samples in the Savitzky-Golay window for these recordings (44 ms at 250 Hz): shorter than the
experiment's 21, because recordings from elsewhere move faster (TU Darmstadt's chirps start at
10 Hz, which a 21-sample quintic window attenuates); with 11 the held-out chirps' 0.5 s-ahead
error was 0.028 rad against 0.035 with 21 (benchmarks/real_qube.py's fit, this machine)."""
SATURATED_FRACTION = 0.5
"""A recording whose voltage sits at its clipping limit for more than this fraction of the samples
is refused: clipped, the voltage no longer shows what the controller asked for, and the motion
is mostly the amplifier's limit rather than the plant's response."""


@dataclasses.dataclass(frozen=True)
class Conventions:
    """How a recording's angles differ from the suite's (all False / +1: they are the suite's)."""

    degrees: bool = False
    """Angles (and velocities) in degrees."""
    pendulum_zero_hanging: bool = False
    """alpha = 0 with the pendulum hanging (the suite's 0 is upright)."""
    arm_sign: int = 1
    """-1 if the recording's theta is clockwise from above."""
    pendulum_sign: int = 1
    """-1 if the recording's alpha turns the other way."""

    def __post_init__(self):
        if self.arm_sign not in (1, -1) or self.pendulum_sign not in (1, -1):
            raise ValueError(f"signs must be +1 or -1, got arm {self.arm_sign}, "
                             f"pendulum {self.pendulum_sign}")


def read(path: str | os.PathLike, device: str = "qube_servo2",
         conventions: Conventions | None = None) -> Measurements:
    """The measurements recorded in the CSV or `.npz` file at `path` from a Qube `device`
    (a key of `DEVICES`), its angles converted from `conventions` (None: the suite's).

    Raises ValueError (one line, naming the file) for a file that cannot calibrate (see the module).
    """
    name = os.fspath(path)
    if device not in DEVICES:
        raise ValueError(f"unknown device {device!r}; valid: {', '.join(DEVICES)}")
    conventions = conventions or Conventions()
    columns = _columns(name)
    missing = [column for column in REQUIRED if column not in columns]
    if missing:
        raise ValueError(f"{name}: no column {', '.join(map(repr, missing))} (it has: {', '.join(columns)}); "
                         f"a recording needs {', '.join(REQUIRED)}")
    used = [column for column in REQUIRED + OPTIONAL if column in columns]
    for column in used:
        bad = np.flatnonzero(~np.isfinite(columns[column]))
        if bad.size:
            raise ValueError(f"{name}: column {column!r} has {bad.size} value(s) that are not finite "
                             f"numbers, the first in data row {bad[0] + 1}")
    time = columns["time"]
    sample_time = _sample_time(name, time)
    if time[-1] - time[0] < MIN_SECONDS:
        raise ValueError(f"{name} is too short: {time[-1] - time[0]:.2f} s recorded, calibration needs at "
                         f"least {MIN_SECONDS:g} s")
    scale = np.pi / 180.0 if conventions.degrees else 1.0
    theta = conventions.arm_sign * scale * columns["arm_angle"]
    alpha = conventions.pendulum_sign * scale * columns["pendulum_angle"]
    if conventions.pendulum_zero_hanging:
        alpha = alpha + np.pi
    if np.max(np.abs(theta)) > ARM_LIMIT:
        raise ValueError(f"{name}: the arm reaches {np.degrees(np.max(np.abs(theta))):.0f} degrees, beyond "
                         f"{np.degrees(ARM_LIMIT):.0f}: it hit its stop (or the angles are in degrees: "
                         "--degrees)")
    voltage = columns["voltage"]
    _check_saturation(name, voltage, columns.get("voltage_commanded"))
    current = columns.get("motor_current")
    board_type = DEVICES[device]
    if current is not None:
        limit = plant_parameters(board_type)["current_limit"]
        if np.mean(np.abs(current) >= 0.98 * limit) > 0.01:
            current = None  # saturated current says nothing of the circuit: fit from the voltage alone
    metadata = {"board_type": board_type, "device": device, "recording": os.path.abspath(name),
                "format": os.path.splitext(name)[1].lstrip(".").lower() or "csv",
                "conventions": dataclasses.asdict(conventions)}
    return Measurements(time=time - time[0], theta=theta, alpha=np.unwrap(alpha), voltage=voltage,
                        current=current, sample_time=sample_time, metadata=metadata,
                        smoothing_window=SMOOTHING_WINDOW)


def _columns(name: str) -> dict[str, np.ndarray]:
    """Every column of the file by name, as float arrays. ValueError if it cannot be read."""
    try:
        if name.endswith(".npz"):
            with np.load(name, allow_pickle=False) as archive:
                return {key: np.asarray(archive[key], dtype=float).ravel() for key in archive.files}
        if name.endswith(".mat"):
            from scipy.io import loadmat

            variables = loadmat(name)
            return {key: np.asarray(value, dtype=float).ravel() for key, value in variables.items()
                    if not key.startswith("__") and np.asarray(value).dtype.kind in "iuf"}
        with open(name, newline="", encoding="utf-8") as file:
            rows = list(csv.reader(row for row in file if not row.startswith("#")))
    except (OSError, ValueError) as error:
        raise ValueError(f"{name}: cannot be read ({error})") from None
    if len(rows) < 2:
        raise ValueError(f"{name}: no data rows under a header line")
    header = [column.strip() for column in rows[0]]
    width = len(header)
    short = next((i for i, row in enumerate(rows[1:], 1) if len(row) != width), None)
    if short is not None:
        raise ValueError(f"{name}: data row {short} has {len(rows[short])} values, the header {width}")
    values = np.full((len(rows) - 1, width), np.nan)
    for i, row in enumerate(rows[1:]):
        for j, text in enumerate(row):
            with contextlib.suppress(ValueError):  # not a number: NaN, refused if the column is used
                values[i, j] = float(text)
    return {column: values[:, j] for j, column in enumerate(header)}


def _sample_time(name: str, time: np.ndarray) -> float:
    """The recording's constant sample period (s), the mean interval (jitter averages out). ValueError
    if time does not increase or an interval is further than MAX_JITTER from the median one."""
    if len(time) < 3:
        raise ValueError(f"{name} is too short: {len(time)} samples")
    steps = np.diff(time)
    backwards = np.flatnonzero(steps <= 0.0)
    if backwards.size:
        raise ValueError(f"{name}: time does not increase at data row {backwards[0] + 2} "
                         f"({time[backwards[0]]:g} s, then {time[backwards[0] + 1]:g} s)")
    period = float(np.median(steps))
    uneven = np.flatnonzero(np.abs(steps - period) > MAX_JITTER * period)
    if uneven.size:
        raise ValueError(f"{name}: the sample period is not constant: {steps[uneven[0]]:g} s between "
                         f"data rows {uneven[0] + 1} and {uneven[0] + 2} against {period:g} s typically "
                         "(a gap or a change of rate)")
    return float((time[-1] - time[0]) / (len(time) - 1))


def _check_saturation(name: str, voltage: np.ndarray, commanded: np.ndarray | None) -> None:
    """ValueError if the voltage is clipped for more than SATURATED_FRACTION of the samples."""
    if commanded is not None:
        clipped = np.abs(commanded - voltage) > 1e-6 + 1e-3 * np.abs(commanded)
    else:
        peak = np.max(np.abs(voltage))
        clipped = np.abs(voltage) >= 0.999 * peak if peak > 0.0 else np.zeros(len(voltage), dtype=bool)
    if np.mean(clipped) > SATURATED_FRACTION:
        raise ValueError(f"{name}: the voltage is saturated in {100 * np.mean(clipped):.0f} % of the "
                         "samples; a recording at its voltage limit most of the time cannot calibrate")


def export(source: str | os.PathLike, destination: str | os.PathLike, episode: int = 0) -> str:
    """Write episode `episode` of the suite's recording at `source` (JSON lines) to `destination`
    in this module's CSV format; return its path. Raises ValueError if there is no such episode."""
    from qube_suite.recording import load_recording

    recording = load_recording(source)
    if not 0 <= episode < len(recording.episodes):
        raise ValueError(f"{os.fspath(source)} has {len(recording.episodes)} episode(s); "
                         f"no episode {episode}")
    data = recording.episodes[episode]
    columns = {"time": data["time"], "voltage": data["applied_voltage"], "arm_angle": data["theta"],
               "pendulum_angle": data["alpha"], "voltage_commanded": data["voltage"],
               "arm_velocity": data["dtheta"], "pendulum_velocity": data["dalpha"]}
    if "raw_current" in data.data:
        from qube_suite.hardware import conventions

        columns["motor_current"] = conventions.ARM_SIGN * data["raw_current"]
    names = list(columns)
    table = np.column_stack([columns[name] for name in names])
    destination = os.fspath(destination)
    np.savetxt(destination, table, delimiter=",", header=",".join(names), comments="", fmt="%.9g")
    return destination
