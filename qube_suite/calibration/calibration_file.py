"""A Qube's calibration: its estimates with their intervals and where they came from, as a YAML file.

    format: qube_suite.calibration
    version: 1
    board_type: qube_servo2_usb          # the experiment's metadata
    board: qube_servo2_usb
    identifier: '0'
    date: '2026-11-24T08:10:23+00:00'
    recording: /home/lab/my_qube.jsonl
    parameters:                          # every model parameter by long name: estimates and fixed ones
      motor_resistance: 8.41
      ...
    intervals:                           # 95 % intervals of the estimates
      motor_resistance: [8.40, 8.42]
      ...
    fixed: [rotor_inertia, arm_mass, ...]   # at nominal: not identifiable from this Qube's signals
    combinations: {arm_acceleration_per_ampere: 686.3, arm_axis_inertia: 6.12e-05}
    offsets: {arm_torque_offset: ..., pendulum_encoder_offset: ..., arm_encoder_offset: ..., cable_slack: ...}
    latency_steps: 0                     # samples between a recorded voltage and its action
    actuation: {latency_seconds: 0.0052, voltage_deadzone: 0.06}   # recordings without current
    prediction: {horizon: 0.5, nominal_rms: 0.12, calibrated_rms: 0.015}   # held-out segments, rad

The `parameters` mapping is what `suite.load("qube", ..., domain_kwargs={"parameters": path})`
and the controllers (`parameters=path`) read (`qube_suite.devices.qube.parameters.values_of`).
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping
from typing import Any

from qube_suite import files
from qube_suite.calibration.fit import VOLTAGE_NAMES
from qube_suite.calibration.identifiability import FITTED, FIXED
from qube_suite.devices.qube import parameters as params

FORMAT = "qube_suite.calibration"
VERSION = 1
METADATA = ("board_type", "board", "identifier", "date", "recording", "domain", "seconds", "seed")
"""Keys of the experiment's metadata that a calibration keeps."""


@dataclasses.dataclass(frozen=True)
class Calibration:
    """A calibrated Qube (see the module docstring for the fields)."""

    parameters: dict[str, float]
    """Every parameter of `qube_suite.devices.qube.parameters` by long name: estimates, and nominal values of
    the fixed ones."""
    intervals: dict[str, tuple[float, float]]
    """95 % interval (low, high) of every estimated parameter."""
    metadata: dict[str, Any]
    """Board type, board, identifier, date, recording, ..."""
    offsets: dict[str, float] = dataclasses.field(default_factory=dict)
    """arm_torque_offset (N m), pendulum_encoder_offset (rad), arm_encoder_offset (rad, or None
    where the cable's stiffness is too small to tell) and, from recordings without current,
    cable_slack (rad): the half-width of the band around the cable's rest where it does not pull."""
    latency_steps: float = 0
    prediction: dict[str, float] = dataclasses.field(default_factory=dict)
    actuation: dict[str, float] = dataclasses.field(default_factory=dict)
    """What acts between the recorded voltage and the motor, where identified: latency_seconds (s,
    a fraction of a sample allowed) and voltage_deadzone (V). The simulation applies both."""
    held: tuple[str, ...] | None = None
    """Parameters held at nominal, where they differ from the current-based fit's `FIXED`."""
    identified: dict[str, float] | None = None
    """Identified combinations, where they differ from the current-based fit's."""

    @property
    def fixed(self) -> tuple[str, ...]:
        """Parameters held at nominal."""
        return tuple(FIXED) if self.held is None else tuple(self.held)

    @property
    def combinations(self) -> dict[str, float]:
        """What the recording identifies where single parameters are not: the arm's acceleration
        per ampere of motor current with the pendulum at the pivot, kt / (Jr + Jm) (rad/s^2/A),
        and the arm-axis inertia Jr + Jm (kg m^2) assumed for it (nominal)."""
        if self.identified is not None:
            return dict(self.identified)
        p = self.parameters
        inertia = params.arm_inertia(p["arm_mass"], p["arm_length"]) + p["rotor_inertia"]
        return {"arm_acceleration_per_ampere": p["motor_torque_constant"] / inertia,
                "arm_axis_inertia": inertia}

    def randomization(self, width: float = 1.0) -> dict[str, Any]:
        """A randomization config (`qube_suite.randomization`) drawing every estimated parameter
        uniformly from its interval, widened `width` times about the estimate (never below 0)."""
        config = {}
        for name, (low, high) in self.intervals.items():
            if name not in params.PARAMETERS:
                continue  # an effect (the dead zone) rather than a parameter
            value = self.parameters[name]
            low, high = value - width * (value - low), value + width * (high - value)
            low = max(low, 0.0) if params.may_be_zero(name) else max(low, 0.05 * value)
            config[name] = {"distribution": "uniform", "low": low, "high": high, "relative": False}
        return {"parameters": config}

    def save(self, path: str | os.PathLike) -> str:
        """Write the calibration to `path` (YAML) and the randomization config beside it
        (`<stem>.randomization.yaml`); return the calibration's path."""
        import yaml

        path = os.fspath(path)
        data = {"format": FORMAT, "version": VERSION,
                **{key: self.metadata.get(key) for key in METADATA},
                "parameters": dict(self.parameters),
                "intervals": {name: [low, high] for name, (low, high) in self.intervals.items()},
                "fixed": list(self.fixed), "combinations": self.combinations, "offsets": dict(self.offsets),
                "latency_steps": self.latency_steps, "actuation": dict(self.actuation),
                "prediction": dict(self.prediction)}
        with open(path, "w", encoding="utf-8") as file:
            yaml.safe_dump(_plain(data), file, sort_keys=False)
        with open(randomization_path(path), "w", encoding="utf-8") as file:
            yaml.safe_dump(_plain(self.randomization()), file, sort_keys=False)
        return path


def randomization_path(path: str | os.PathLike) -> str:
    """Where `Calibration.save` puts the randomization config for a calibration saved at `path`."""
    root, _ = os.path.splitext(os.fspath(path))
    return root + ".randomization.yaml"


def load(path: str | os.PathLike) -> Calibration:
    """The calibration saved at `path`. Raises ValueError if it is not a calibration file."""
    data = files.read_yaml(path, "calibration")
    if not isinstance(data, Mapping) or data.get("format") != FORMAT:
        raise ValueError(f"{os.fspath(path)} is not a qube_suite calibration (format {FORMAT!r})")
    parameters = params.resolve({name: float(value) for name, value in data["parameters"].items()})
    intervals = {name: (float(low), float(high)) for name, (low, high) in data["intervals"].items()}
    unknown = set(intervals) - {q.name for q in FITTED} - set(VOLTAGE_NAMES)
    if unknown:
        raise ValueError(f"{os.fspath(path)}: intervals of unknown parameters {sorted(unknown)}")
    return Calibration(parameters=parameters, intervals=intervals,
                       metadata={key: data.get(key) for key in METADATA},
                       offsets=dict(data.get("offsets") or {}),
                       latency_steps=float(data.get("latency_steps", 0)),
                       prediction=dict(data.get("prediction") or {}),
                       actuation=dict(data.get("actuation") or {}),
                       held=None if data.get("fixed") is None else tuple(data["fixed"]),
                       identified=dict(data.get("combinations") or {}) or None)


def _plain(value: Any) -> Any:
    """`value` with numpy numbers and tuples as plain YAML values."""
    if isinstance(value, Mapping):
        return {str(key): _plain(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(item) for item in value]
    if hasattr(value, "item"):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
