"""Physical parameters of the Qube-Servo 2 rotary pendulum: the one table of nominal values.

Nominal values are Quanser's published Qube-Servo 2 rotary-pendulum model
(motor, arm and pendulum data of the Qube-Servo 2 user manual and the
rotary-pendulum workbook's parameter file), except where a note says otherwise.
`qube_suite/devices/qube/model.xml` carries the same numbers so that it can be used on its
own; the tests keep the two equal.

Viscous damping: published values disagree by two orders of magnitude (arm
1.5e-3 to 5e-6, pendulum 5e-4 to 1e-6 N m s/rad). Quanser's 1.5e-3 on the arm
would make the motor's steady speed gain kt / (Rm Dr + kt km) = 2.9 rad/s/V,
against 1/km = 24 rad/s/V for the nearly undamped motor that the Qube's own
speed-step experiments show; 5e-4 on the pendulum would stop a free swing within
about a second. We use the values identified on a real Qube by the TU Darmstadt
`quanser_robots` / SimuRLacra projects (arm 5e-6, pendulum 1e-6): there the
motor's back-EMF (kt km / Rm = 2.1e-4) dominates the arm's damping, as on the
hardware.

The last three entries are accuracy options that are off (zero) in the nominal
model: Coulomb friction on each joint and the spring of the encoder cable on the
arm. MuJoCo represents them natively (joint `frictionloss` and `stiffness`).
"""

from __future__ import annotations

import math
import numbers
import os
import types
from collections.abc import Mapping
from typing import Any

from qube_suite import files
from qube_suite.parameter_tables import Parameter

_TABLE = (
    Parameter("motor_resistance", "Rm", 8.4, "ohm", "motor terminal resistance"),
    Parameter("motor_torque_constant", "kt", 0.042, "N m/A", "motor current-torque constant"),
    Parameter("motor_back_emf", "km", 0.042, "V s/rad", "motor back-EMF constant"),
    Parameter("rotor_inertia", "Jm", 4.0e-6, "kg m^2", "motor rotor inertia (joint armature)"),
    Parameter("motor_inductance", "Lm", 1.16e-3, "H", "motor inductance (hardware plant only; "
              "its 0.14 ms time constant is far below the control period)"),
    Parameter("arm_mass", "mr", 0.095, "kg", "rotary arm mass"),
    Parameter("arm_length", "Lr", 0.085, "m", "rotary arm length, motor axis to pendulum pivot"),
    Parameter("arm_damping", "Dr", 5.0e-6, "N m s/rad", "viscous damping of the arm joint"),
    Parameter("pendulum_mass", "mp", 0.024, "kg", "pendulum mass"),
    Parameter("pendulum_length", "Lp", 0.129, "m", "pendulum length (uniform rod pivoting at one end)"),
    Parameter("pendulum_damping", "Dp", 1.0e-6, "N m s/rad", "viscous damping of the pendulum joint"),
    Parameter("gravity", "g", 9.81, "m/s^2", "gravitational acceleration"),
    Parameter("arm_friction", "Fr", 0.0, "N m", "Coulomb friction torque on the arm (accuracy option)"),
    Parameter("pendulum_friction", "Fp", 0.0, "N m", "Coulomb friction torque on the pendulum "
              "(accuracy option)"),
    Parameter("cable_stiffness", "kc", 0.0, "N m/rad", "spring of the encoder cable on the arm, "
              "towards theta = 0 (accuracy option)"),
)

PARAMETERS: types.MappingProxyType[str, Parameter] = types.MappingProxyType({p.name: p for p in _TABLE})
"""Every parameter by long name."""

NOMINAL: types.MappingProxyType[str, float] = types.MappingProxyType({p.name: p.nominal for p in _TABLE})
"""Nominal value of every parameter by long name."""

REAL_QUBE_SERVO2 = os.path.join(os.path.dirname(os.path.abspath(__file__)), "real_qube_servo2.yaml")
"""A calibration of a real Qube-Servo 2 (TU Darmstadt's, from ten voltage chirps it recorded;
`benchmarks/real_qube.py --save`): `domain_kwargs={"parameters": REAL_QUBE_SERVO2}` simulates it,
its latency, dead zone, cable and encoder offset included. The nominal values above stay the
defaults: the shipped policies and tuned controllers were made for them (docs/calibration.md)."""

PENDULUM_ROD_RADIUS = 0.0045
"""Radius of the pendulum rod (m); gives its small inertia about its own axis."""

ENCODER_COUNTS_PER_REVOLUTION = 2048
"""Both encoders: 512 lines in quadrature."""


def arm_inertia(arm_mass: float, arm_length: float) -> float:
    """Arm inertia about the motor axis, Jr = mr Lr^2 / 12 (Quanser's convention), kg m^2."""
    return arm_mass * arm_length**2 / 12.0


def pendulum_inertia(pendulum_mass: float, pendulum_length: float) -> float:
    """Pendulum inertia about its centre, transverse to the rod, Jp = mp Lp^2 / 12, kg m^2."""
    return pendulum_mass * pendulum_length**2 / 12.0


def may_be_zero(name: str) -> bool:
    """Whether parameter `name` may be 0 (damping and the accuracy options); none may be negative."""
    return PARAMETERS[name].nominal == 0.0 or name.endswith("damping")


def resolve(overrides: dict[str, float] | None = None) -> dict[str, float]:
    """Nominal parameters updated by `overrides`; a name that is not a parameter is a ValueError."""
    values = dict(NOMINAL)
    for name, value in (overrides or {}).items():
        if name not in PARAMETERS:
            raise ValueError(f"unknown parameter {name!r}; valid names: {', '.join(PARAMETERS)}")
        if not (isinstance(value, numbers.Real) and not isinstance(value, bool)):
            raise ValueError(f"parameter {name!r} must be a number, got {value!r}")
        value = float(value)
        if not 0.0 < value < math.inf:  # positive and finite is valid for every parameter
            _check_nonpositive(name, value)
        values[name] = value
    return values


def _check_nonpositive(name: str, value: float) -> None:
    if math.isnan(value) or math.isinf(value):
        raise ValueError(f"parameter {name!r} must be finite, got {value}")
    minimum_is_zero = may_be_zero(name)
    if value < 0.0 or (value == 0.0 and not minimum_is_zero):
        raise ValueError(f"parameter {name!r} must be {'>= 0' if minimum_is_zero else '> 0'}, got {value}")


CALIBRATED_EFFECTS = ("latency_seconds", "voltage_deadzone", "cable_rest_angle", "cable_slack",
                      "pendulum_encoder_offset")
"""What a calibration identifies beyond the parameters and a simulation reproduces (`effects_of`)."""


def effects_of(source: Mapping[str, float] | str | os.PathLike | Any | None) -> dict[str, float]:
    """The calibrated effects of `source` (as for `values_of`) by the names of CALIBRATED_EFFECTS,
    those it identified only: the latency (s, a fraction of a sample allowed) and the voltage's dead
    zone (V) of its `actuation`, the cable's rest angle (rad, minus its `arm_encoder_offset`: the
    fit cannot tell a cable at rest off the encoder's zero from an encoder zeroed off the cable's
    rest, and the simulation takes the former), the half-width of the band around that rest within
    which the cable is slack (rad, its offsets' `cable_slack`; absent: a linear spring) and the
    pendulum encoder's offset (rad; true angle = encoder angle + offset). A mapping of parameters has
    none."""
    if source is None or isinstance(source, Mapping):
        return {}
    if isinstance(source, (str, os.PathLike)):
        import yaml

        with open(source, encoding="utf-8") as file:
            content = yaml.safe_load(file) or {}
        actuation, offsets = content.get("actuation") or {}, content.get("offsets") or {}
    else:
        actuation, offsets = getattr(source, "actuation", {}) or {}, getattr(source, "offsets", {}) or {}
    effects = {name: float(actuation[name]) for name in ("latency_seconds", "voltage_deadzone")
               if actuation.get(name)}
    if offsets.get("arm_encoder_offset") is not None:
        effects["cable_rest_angle"] = -float(offsets["arm_encoder_offset"])
        if offsets.get("cable_slack"):
            effects["cable_slack"] = float(offsets["cable_slack"])
    if offsets.get("pendulum_encoder_offset"):
        effects["pendulum_encoder_offset"] = float(offsets["pendulum_encoder_offset"])
    return effects


def values_of(source: Mapping[str, float] | str | os.PathLike | Any | None) -> dict[str, float]:
    """Parameter overrides by long name from `source`: a mapping, the path of a calibration file
    (YAML with a `parameters` mapping, `qube_suite.calibration`), or an object with a `parameters`
    mapping (a `Calibration`); None gives none. Names are checked by `resolve`, not here."""
    if source is None:
        return {}
    if isinstance(source, (str, os.PathLike)):
        content = files.read_yaml(source, "calibration")
        if not isinstance(content, Mapping) or not isinstance(content.get("parameters"), Mapping):
            raise ValueError(f"{os.fspath(source)} is not a calibration file: it has no 'parameters' mapping")
        return dict(content["parameters"])
    if not isinstance(source, Mapping) and isinstance(getattr(source, "parameters", None), Mapping):
        return dict(source.parameters)
    if not isinstance(source, Mapping):
        raise TypeError(f"parameters must be a mapping, a calibration file's path or a Calibration, "
                        f"got {type(source).__name__}")
    return dict(source)
