"""Physical parameters of the Quanser Aero 2: the table, by long name, with units and sources.

Sources (Quanser's own teaching material for the Aero 2 and its user manual):

- [L4] Quanser Academic Resources, `6_teaching/1_Controls/Aero_2/l4_system_block_diagram_modeling/
  digital_twin/aero2_parameters.m` (public copy: github.com/vanshs64/quanser-qarm): thrust arm
  Dt = 0.16743 m, body mass 1.07 kg, centre-of-mass offset 2.7 mm, pitch inertia 0.0231 kg m^2 (CAD:
  23188500.45 g mm^2), propeller thrust constant 0.0006 N s/rad, pitch damping 0.008 N m s/rad, and the
  thrusters' Rm = 8.4 ohm, kt = km = 0.042, propeller drag 8e-5 N m s/rad, Lm = 1.16 mH, rotor inertia
  4e-6 kg m^2, propeller inertia 4e-5 kg m^2, hub mass 3 g and radius 4.5 mm.
- [L3] the same resources, `l3_pitch_parameter_estimation/hardware/aero2_parameters.m`: the same arm
  and mass, centre-of-mass offset 2.4 mm, pitch inertia 23188500.45 g mm^2 and yaw inertia
  23810415.95 g mm^2 from CAD.
- [UM] Quanser Aero 2 user manual, table 2 "Quanser Aero 2 System Parameters": motor 18 V nominal,
  Rm 8.4 ohm, kt = km = 0.042, rotor inertia 4.0e-6 kg m^2, Lm 1.16 mH; body mass 1.07 kg, centre of
  mass -2.42 mm along z (below the pivot), Jp 2.32e-2 and Jy 2.38e-2 kg m^2, thrust displacement 0.168 m;
  amplifier +-18 V recommended, +-24 V maximum.
- [AERO] Quanser's parameter file for the first Aero (its 2-DOF LQR lab): yaw viscous damping
  Dy = 0.0220 N m s/rad, found experimentally. No Aero 2 source gives a yaw damping; the yoke and
  bearing of the yaw axis are alike, so the predecessor's value is used.

Where they disagree:
- centre-of-mass offset: 2.42 mm [UM] and 2.4 mm [L3] against 2.7 mm [L4]. The table takes the manual's
  2.42 mm, which two sources agree on; [L4]'s digital twin is the outlier. Its weight makes the beam a
  pendulum: Mb g Dm = 0.0254 N m/rad of restoring torque at small pitch.
- inertias: the CAD figures ([L3], [L4]) rather than the manual's rounded ones.
- thrust arm: [L4]/[L3]'s 0.16743 m rather than the manual's rounded 0.168 m.

The thrust and drag model is [L4]'s, linear in rotor speed: thrust kf w (N), aerodynamic drag torque
kd w (N m) on the propeller, so each thruster is a first-order system from voltage to speed,
J w' = kt (V - km w) / Rm - kd w, with time constant J / (kd + kt km / Rm) = 0.15 s and gain
17.2 rad/s per volt (`rotor_time_constant`, `rotor_speed_gain`).
"""

from __future__ import annotations

import types
from collections.abc import Mapping
from typing import Any

from qube_suite import parameter_tables
from qube_suite.parameter_tables import Parameter

_TABLE = (
    # The body (beam, thruster shrouds, yoke) about the pivot.
    Parameter("thrust_arm", "Dt", 0.16743, "m", "pivot to each rotor's centre [L4, L3]"),
    Parameter("body_mass", "Mb", 1.07, "kg", "mass of the moving body [L4, L3, UM]"),
    Parameter("center_of_mass_offset", "Dm", 2.42e-3, "m", "centre of mass below the pitch axis [UM, L3]"),
    Parameter("pitch_inertia", "Jp", 0.02318850045, "kg m^2", "pitch-axis inertia, CAD [L3, L4]"),
    Parameter("yaw_inertia", "Jy", 0.02381041595, "kg m^2", "yaw-axis inertia, CAD [L3]"),
    Parameter("pitch_damping", "Dp", 0.008, "N m s/rad", "viscous damping of the pitch pivot [L4]"),
    Parameter("yaw_damping", "Dy", 0.022, "N m s/rad", "viscous damping of the yaw axis [AERO]"),
    Parameter("gravity", "g", 9.81, "m/s^2", "gravitational acceleration [L4]"),
    # Each thruster: a DC motor, hub and propeller.
    Parameter("motor_resistance", "Rm", 8.4, "ohm", "thruster motor terminal resistance [L4, UM]"),
    Parameter("motor_torque_constant", "kt", 0.042, "N m/A", "thruster motor torque constant [L4, UM]"),
    Parameter("motor_back_emf", "km", 0.042, "V s/rad", "thruster motor back-EMF constant [L4, UM]"),
    Parameter("motor_inductance", "Lm", 1.16e-3, "H", "thruster motor inductance (board plant only; its "
              "0.14 ms time constant is neglected in simulation) [L4, UM]"),
    Parameter("rotor_inertia", "Jr", 4.0e-6, "kg m^2", "thruster motor rotor inertia [L4, UM]"),
    Parameter("propeller_inertia", "Jprop", 4.0e-5, "kg m^2", "propeller inertia about its axis [L4]"),
    Parameter("hub_mass", "mh", 3.0e-3, "kg", "propeller hub mass [L4]"),
    Parameter("hub_radius", "rh", 4.5e-3, "m", "propeller hub radius [L4]"),
    Parameter("thrust_constant", "kf", 6.0e-4, "N s/rad", "propeller thrust per rotor speed [L4]"),
    Parameter("propeller_drag", "kd", 8.0e-5, "N m s/rad", "aerodynamic drag torque per rotor speed [L4]"),
)

PARAMETERS: types.MappingProxyType[str, Parameter] = types.MappingProxyType({p.name: p for p in _TABLE})
"""Every parameter of the Aero 2 by long name."""

NOMINAL: types.MappingProxyType[str, float] = types.MappingProxyType(
    {name: p.nominal for name, p in PARAMETERS.items()})
"""Nominal value of every parameter by long name."""

_MAY_BE_ZERO = frozenset({"center_of_mass_offset", "pitch_damping", "yaw_damping", "motor_inductance",
                          "hub_mass", "hub_radius", "propeller_drag"})


def rotor_assembly_inertia(values: Mapping[str, float]) -> float:
    """Everything that turns with a thruster's shaft: rotor, propeller and hub (mh rh^2 / 2), kg m^2."""
    hub = 0.5 * values["hub_mass"] * values["hub_radius"] ** 2
    return values["rotor_inertia"] + values["propeller_inertia"] + hub


def rotor_damping(values: Mapping[str, float]) -> float:
    """Total speed-proportional torque on a rotor: drag plus back-EMF, kd + kt km / Rm (N m s/rad)."""
    return values["propeller_drag"] + values["motor_torque_constant"] * values["motor_back_emf"] / \
        values["motor_resistance"]


def rotor_time_constant(values: Mapping[str, float]) -> float:
    """Time constant (s) of a thruster's speed after a voltage step."""
    return rotor_assembly_inertia(values) / rotor_damping(values)


def rotor_speed_gain(values: Mapping[str, float]) -> float:
    """Steady rotor speed per volt (rad/s/V): kt / (Rm (kd + kt km / Rm))."""
    return values["motor_torque_constant"] / (values["motor_resistance"] * rotor_damping(values))


def gravity_stiffness(values: Mapping[str, float]) -> float:
    """Restoring pitch torque per radian at small pitch, Mb g Dm (N m/rad)."""
    return values["body_mass"] * values["gravity"] * values["center_of_mass_offset"]


def resolve(overrides: Mapping[str, Any] | None = None) -> dict[str, float]:
    """Nominal parameters updated by `overrides` (by long name); see `qube_suite.parameter_tables.resolve`."""
    return parameter_tables.resolve(PARAMETERS, _MAY_BE_ZERO, overrides)
