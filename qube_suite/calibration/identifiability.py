"""Which of the Qube's parameters its two encoders and its motor current can identify.

The fit (`qube_suite.calibration.fit`) uses three equations, each linear in what it
identifies:

* the motor's circuit, V = Rm i + km theta' (inductance negligible: Lm / Rm = 0.14 ms):
  the current against the voltage and the arm's speed gives the **resistance** and
  the **back-EMF constant** on their own (angles alone give only kt / Rm);
* the pendulum's equation has no input, so it fixes ratios only: of its inertia to
  its gravity torque, which with g known is its **length** (the swing frequency),
  and of its damping and friction to its mass;
* the arm's equation, kt i = M11 theta'' + M12 alpha'' + ... + Dr theta' + Fr sign(theta')
  + kc (theta - theta_0), gives every arm-side coefficient relative to kt: the
  pendulum's reaction on the arm gives its **mass** / kt, the arm's own inertia
  (Jr + Jm) / kt, and likewise damping, Coulomb friction and the cable's spring.

What no recording of these signals can tell apart is the torque scale: doubling kt
and every mass and inertia gives the same motion for the same current. The anchor
is the arm's inertia about the motor axis, Jr + Jm, of which the arm's part
Jr = mr Lr^2 / 12 is known from its mass and length (fixed at nominal) and the
rotor's Jm, about 2 % of the arm-axis inertia with the pendulum attached, is not
separable from it. We fix Jm at nominal and carry its tolerance (`FIXED`) into the
intervals of every torque-scaled estimate (kt, mp, Dr, Fr, kc and, through mp, the
pendulum's damping and friction): a rotor 30 % off moves them by about 2 %.
The identified combination is reported as `arm_acceleration_per_ampere` = kt / (Jr + Jm).
"""

from __future__ import annotations

import dataclasses
import types

from qube_suite.devices.qube import parameters


@dataclasses.dataclass(frozen=True)
class Fitted:
    """A quantity the fit estimates: its long name, the scale that makes it near 1, its unit."""

    name: str
    scale: float
    unit: str
    absolute_tolerance: float = 0.0
    """Smallest 95 % half-width (its unit): friction-like parameters, whose truth may be 0."""
    relative_tolerance: float = 0.0
    """Smallest 95 % half-width as a fraction of the estimate: what the model leaves out (the motor's
    inductance, the amplifier's and the current sensor's own errors) is not in the residual's spread."""


FITTED: tuple[Fitted, ...] = (
    Fitted("motor_resistance", parameters.NOMINAL["motor_resistance"], "ohm", relative_tolerance=0.005),
    Fitted("motor_back_emf", parameters.NOMINAL["motor_back_emf"], "V s/rad", relative_tolerance=0.005),
    Fitted("motor_torque_constant", parameters.NOMINAL["motor_torque_constant"], "N m/A",
           relative_tolerance=0.005),
    Fitted("pendulum_mass", parameters.NOMINAL["pendulum_mass"], "kg", relative_tolerance=0.005),
    Fitted("pendulum_length", parameters.NOMINAL["pendulum_length"], "m", relative_tolerance=0.005),
    Fitted("arm_damping", 1.0e-5, "N m s/rad", 2.0e-5),
    Fitted("arm_friction", 1.0e-3, "N m", 1.5e-4),
    Fitted("cable_stiffness", 1.0e-3, "N m/rad", 1.5e-4),
    Fitted("pendulum_damping", 1.0e-6, "N m s/rad", 1.0e-6),
    Fitted("pendulum_friction", 1.0e-4, "N m", 1.5e-5),
)
"""The identified parameters (long names of `qube_suite.devices.qube.parameters`), in the fit's order."""

OFFSETS: tuple[Fitted, ...] = (
    Fitted("arm_torque_offset", 1.0e-4, "N m", 1.0e-5),
    Fitted("pendulum_encoder_offset", 0.01, "rad", 1.0e-3),
)
"""Offsets: a constant torque on the arm (the cable's spring relaxed off the encoder's zero, or
an amplifier offset): -kc theta_0, so the arm encoder's offset theta_0 follows where the cable's
stiffness is identified; and the pendulum encoder's offset (true angle = encoder angle + offset,
0 if it was zeroed hanging at rest)."""

FIXED: types.MappingProxyType[str, float] = types.MappingProxyType({
    "rotor_inertia": 0.30,
    "arm_mass": 0.0,
    "arm_length": 0.0,
    "gravity": 0.0,
    "motor_inductance": 0.0,
})
"""Parameters fixed at nominal, with the relative tolerance (uniform, +-) assumed for each: the
rotor's inertia cannot be told from the arm's; the arm's mass and length anchor the torque scale
(Quanser's published values); gravity is known; the inductance acts far below the sample time."""

TORQUE_SCALED = ("motor_torque_constant", "pendulum_mass", "arm_damping", "arm_friction", "cable_stiffness",
                 "pendulum_damping", "pendulum_friction")
"""Estimates proportional to the assumed arm-axis inertia (they all scale with the torque)."""

