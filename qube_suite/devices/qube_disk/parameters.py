"""Physical parameters of the Qube-Servo 2/3 with the inertia-disk module: the disk's table.

The motor rows are the Qube's own, read from `qube_suite.devices.qube.parameters` (the one table of the
motor's nominal values, shared with the pendulum); the module rows are new here. Sources:

- Disk mass 0.053 kg and radius 0.0248 m, attachment hub mass 0.0106 kg, radius 0.0111 m and
  moment of inertia 0.6e-6 kg m^2: Quanser, Qube-Servo 3 user manual, table 2.2 "Qube-Servo 3
  System Parameters", rows "Inertia Disc Module" and "Module attachment hub" (the same disk
  ships with the Qube-Servo 2).
- The disk is a uniform solid disc: its inertia about the motor axis is m r^2 / 2 = 1.63e-5 kg m^2
  (Quanser's workbooks use the same formula), so the load's inertia is four times the rotor's.
- `disk_damping` = 5e-6 N m s/rad: the pendulum table's arm damping (the same bearings and motor);
  the back-EMF term kt km / Rm = 2.1e-4 N m s/rad dominates it.
- `disk_friction` (Coulomb, N m): 0 in the nominal model, an accuracy option as on the pendulum;
  the substitute board's plant uses the pendulum's `arm_friction` estimate (the same motor).
"""

from __future__ import annotations

import types
from collections.abc import Mapping
from typing import Any

from qube_suite import parameter_tables
from qube_suite.devices.qube import parameters as shared
from qube_suite.parameter_tables import Parameter

MOTOR_NAMES = ("motor_resistance", "motor_torque_constant", "motor_back_emf", "rotor_inertia",
               "motor_inductance")
"""The motor's parameters: the Qube's, read from `qube_suite.devices.qube.parameters`."""

_MODULE = (
    Parameter("disk_mass", "md", 0.053, "kg", "inertia disk mass"),
    Parameter("disk_radius", "rd", 0.0248, "m", "inertia disk radius"),
    Parameter("hub_inertia", "Jh", 0.6e-6, "kg m^2", "module attachment hub moment of inertia"),
    Parameter("disk_damping", "Dd", 5.0e-6, "N m s/rad", "viscous damping of the motor shaft"),
    Parameter("disk_friction", "Fd", 0.0, "N m", "Coulomb friction torque on the motor shaft "
                     "(accuracy option)"),
)

PARAMETERS: types.MappingProxyType[str, Parameter] = types.MappingProxyType(
    {**{name: shared.PARAMETERS[name] for name in MOTOR_NAMES}, **{p.name: p for p in _MODULE}})
"""Every parameter of the disk-loaded Qube by long name: the motor's, then the module's."""

NOMINAL: types.MappingProxyType[str, float] = types.MappingProxyType(
    {name: p.nominal for name, p in PARAMETERS.items()})
"""Nominal value of every parameter by long name."""

_MAY_BE_ZERO = frozenset({"disk_damping", "disk_friction", "hub_inertia", "motor_inductance"})


def disk_inertia(disk_mass: float, disk_radius: float) -> float:
    """Inertia of the uniform disk about the motor axis, md rd^2 / 2 (kg m^2)."""
    return 0.5 * disk_mass * disk_radius**2


def shaft_inertia(values: Mapping[str, float]) -> float:
    """Everything that turns with the shaft: rotor, hub and disk (kg m^2)."""
    return values["rotor_inertia"] + values["hub_inertia"] + disk_inertia(values["disk_mass"],
                                                                          values["disk_radius"])


def resolve(overrides: Mapping[str, Any] | None = None) -> dict[str, float]:
    """Nominal parameters updated by `overrides` (by long name); see `qube_suite.parameter_tables.resolve`."""
    return parameter_tables.resolve(PARAMETERS, _MAY_BE_ZERO, overrides)
