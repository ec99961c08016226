"""A calibration experiment's recording, checked and turned into the signals the fit uses.

Angles come from the raw encoder counts (the pendulum's unwrapped, so a swing over the
top is no jump), the motor current from the board's analog input, the voltage from
the `applied_voltage` column (as written to the board at each sample: it acts until
the next one). Velocities and accelerations are estimated offline by a zero-phase
Savitzky-Golay filter (`SMOOTHING_WINDOW` samples, quintic), which has no lag, unlike
the 50 rad/s filter the controllers must use online.

`load` refuses, with a ValueError naming the problem, recordings that cannot give a
trustworthy calibration: cut off, too short, without motor currents, from an
unknown board type, with the arm at its limit, or with the motor current saturated.
"""

from __future__ import annotations

import dataclasses
import math
import os
from typing import Any

import numpy as np
from scipy.signal import savgol_filter

from qube_suite.hardware import conventions
from qube_suite.hardware.plant import BOARD_MOTORS, plant_parameters
from qube_suite.recording import load_recording

SMOOTHING_WINDOW = 21
"""Samples in the Savitzky-Golay window (84 ms at 250 Hz)."""
SMOOTHING_ORDER = 5
"""Order of its polynomial. Of windows 11 to 51 samples and orders 3 to 7, 21 and 5 gave the
smallest velocity error on the substitute (0.05 rad/s RMS against its true state): longer windows
smooth the motion itself, shorter ones keep more of the encoders' quantisation."""
MIN_SECONDS = 20.0
"""Shortest recording (s) that calibrates: every phase of the experiment needs several seconds."""
ARM_LIMIT = np.radians(85.0)
"""An arm angle beyond this (rad) means the arm hit the tasks' +-90 degree limit."""
SATURATION_FRACTION = 0.01
"""More than this fraction of samples with the current at the amplifier's limit is saturation."""
BOARD_TYPES = tuple(BOARD_MOTORS)
"""Board types a calibration can come from."""


@dataclasses.dataclass(frozen=True)
class Encoders:
    """Where a device's angles are in a recording: the raw encoder column of the motor's shaft (read
    with the arm's sign), of the pendulum (None: the device has none), and the shaft's largest
    angle in a usable recording (rad; None: it turns freely)."""

    shaft: str = "raw_encoder_arm"
    pendulum: str | None = "raw_encoder_pendulum"
    shaft_limit: float | None = ARM_LIMIT


PENDULUM_ENCODERS = Encoders()
"""The Qube pendulum's: the arm on encoder 0, the pendulum on encoder 1, the arm within 85 degrees."""


@dataclasses.dataclass(frozen=True)
class Measurements:
    """The signals of one recorded experiment, one row per sample (package signs, SI units)."""

    time: np.ndarray
    """Board time (s)."""
    theta: np.ndarray
    """Arm angle (the motor shaft's) from encoder 0 (rad)."""
    alpha: np.ndarray | None
    """Pendulum angle from encoder 1, unwrapped, pi = hanging at the encoder's zero (rad); None for a
    device without a pendulum."""
    voltage: np.ndarray
    """Voltage written at each sample (V); it acts until the next sample."""
    current: np.ndarray | None
    """Motor current read at each sample (A); None where the recording has none."""
    sample_time: float
    """Time between samples (s)."""
    metadata: dict[str, Any]
    """The recording's header (board type, identifier, date, ...) and its path."""
    smoothing_window: int = SMOOTHING_WINDOW
    """Samples in the Savitzky-Golay window of `derivatives`."""

    def __len__(self) -> int:
        return len(self.time)

    @property
    def board_type(self) -> str:
        """The board type the recording came from."""
        return self.metadata["board_type"]

    def derivatives(self, signal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(value, derivative) of `signal`, smoothed without lag (per s)."""
        window, h = self.smoothing_window, self.sample_time
        order = SMOOTHING_ORDER
        return savgol_filter(signal, window, order), savgol_filter(signal, window, order, deriv=1, delta=h)


def load(path: str | os.PathLike, board_type: str | None = None,
         encoders: Encoders = PENDULUM_ENCODERS) -> Measurements:
    """The measurements of the experiment recorded at `path` (its first episode).

    `board_type`: the board type (or board, e.g. "simulated") the recording must come from (None:
    any supported one). `encoders`: the device's encoder columns (the pendulum's by default).
    Raises ValueError naming the problem for a recording that cannot be calibrated from.
    """
    path = os.fspath(path)
    recording = load_recording(path)
    if recording.truncated or not recording.episodes or recording.episodes[0].end is None:
        raise ValueError(f"{path} is truncated: the recording stopped before the experiment ended "
                         "(run the experiment again)")
    metadata = {**recording.metadata, "recording": os.path.abspath(path)}
    recorded_type = metadata.get("board_type")
    if recorded_type not in BOARD_TYPES:
        raise ValueError(f"{path} comes from board type {recorded_type!r}; calibration needs a recording "
                         f"from one of: {', '.join(BOARD_TYPES)}")
    if board_type is not None and board_type not in (recorded_type, metadata.get("board")):
        raise ValueError(f"{path} comes from board type {recorded_type!r} (board {metadata.get('board')!r}), "
                         f"not {board_type!r}")
    episode = recording.episodes[0]
    if "raw_current" not in episode.data or not np.all(np.isfinite(episode["raw_current"])):
        raise ValueError(f"{path} has no motor currents (column raw_current): record the experiment on "
                         "a hardware domain, whose recordings carry the board's raw readings")
    missing = [column for column in (encoders.shaft, encoders.pendulum)
               if column is not None and column not in episode.data]
    if missing:
        raise ValueError(f"{path} has no encoder column {', '.join(missing)}: it is a recording of another "
                         "device than the one calibrated")
    sample_time = 1.0 / float(episode.header["control_frequency"])
    time = episode["time"]
    if time[-1] - time[0] < MIN_SECONDS:
        raise ValueError(f"{path} is too short: {time[-1] - time[0]:.1f} s recorded, calibration needs at "
                         f"least {MIN_SECONDS:g} s")
    theta = conventions.ARM_SIGN * conventions.RADIANS_PER_COUNT * episode[encoders.shaft]
    alpha = None
    if encoders.pendulum is not None:
        counts = episode[encoders.pendulum]
        alpha = np.pi + conventions.PENDULUM_SIGN * conventions.RADIANS_PER_COUNT * counts
    limit = math.inf if encoders.shaft_limit is None else encoders.shaft_limit
    if episode.end.get("terminated") or np.max(np.abs(theta)) > limit:
        raise ValueError(f"{path}: the arm reached its limit ({np.degrees(np.max(np.abs(theta))):.0f} "
                         "degrees); the experiment must stay well inside +-90 degrees")
    current = conventions.ARM_SIGN * episode["raw_current"]
    limit = plant_parameters(recorded_type)["current_limit"]
    if np.mean(np.abs(current) >= 0.98 * limit) > SATURATION_FRACTION:
        raise ValueError(f"{path}: the motor current is saturated at the amplifier's {limit:g} A limit in "
                         f"{100 * np.mean(np.abs(current) >= 0.98 * limit):.0f} % of the samples; lower the "
                         "experiment's voltage")
    return Measurements(time=time, theta=theta, alpha=alpha, voltage=episode["applied_voltage"],
                        current=current, sample_time=sample_time, metadata=metadata)
