"""The Aero 2's conventions: state, action, signs, limits, and board counts to SI units.

State (`STATE_NAMES`): pitch and yaw (rad), their rates (rad/s), and the two rotor speeds (rad/s of
the motor shaft). Action (`ACTION_NAMES`): the front and back thruster voltages (V), shape (2,).

Signs. The beam lies along the body's x axis, the front thruster at +x. Pitch is positive when the
front rises; yaw is positive counter-clockwise seen from above; both are 0 with the beam level and
pointing where the episode's reference is (yaw is not wrapped: the Aero 2's yaw turns freely on
its slip ring). A rotor's speed is positive when a positive voltage drives it.

Thrusters, by configuration (`CONFIGURATIONS`):
- "2dof", the helicopter: the front thruster lifts (thrust along the body's z axis: positive front
  voltage raises the front, pitch up); the back thruster pushes sideways (thrust horizontal,
  perpendicular to the beam: positive back voltage turns yaw positive). Each motor's reaction torque
  acts about its own axis: the front motor's turns yaw (negative for a positive voltage), the back
  motor's turns pitch (positive for a positive voltage), as the signs of the cross-coupling gains
  Quanser identifies for the Aero 2's 2-DOF LQR lab (thrust acting on yaw from the pitch rotor
  negative, on pitch from the yaw rotor positive).
- "pitch_only", the 1-DOF configuration: yaw locked, both thrusters lift; the front's raises the
  front (pitch up), the back's raises the back (pitch down), as in Quanser's 1-DOF labs.

Board counts (the channel map of the first Aero in the original Quanser Gym toolkit's wrapper,
`quanser_wrapper.pyx` of github.com/BlueRiverTech/quanser-openai-driver: analog outputs 0 and 1
the two motors, encoders 0 and 1 the motors, 2 the pitch, 3 the yaw, other channels 3000-3002 the
gyroscope, 4000-4002 the accelerometer, 14000-14003 the tachometers in counts/s of the encoders): the
pitch encoder gives 2048 counts per revolution and the yaw encoder 4096 (the toolkit's Aero
environment converts them so). The motors' tachometers read counts/s of 2048-count motor encoders
(assumed like the pitch encoder; no source read here states the Aero 2 motor encoder's resolution).
The board domain owns the channel numbers; this module holds the scales.
"""

from __future__ import annotations

import math

STATE_NAMES = ("pitch", "yaw", "pitch_velocity", "yaw_velocity", "front_rotor_speed", "back_rotor_speed")
"""The state's entries: pitch, yaw (rad), their rates (rad/s), front and back rotor speeds (rad/s)."""

ACTION_NAMES = ("front_voltage", "back_voltage")
"""The action's entries: the front and back thruster voltages (V)."""

CONFIGURATIONS = ("2dof", "pitch_only")
"""The Aero 2's configurations: the 2-DOF helicopter, and the 1-DOF pitch with yaw locked."""


def check_configuration(configuration: str) -> None:
    """Raise ValueError unless `configuration` is one of `CONFIGURATIONS`."""
    if configuration not in CONFIGURATIONS:
        raise ValueError(f"unknown configuration {configuration!r}; valid configurations: "
                         f"{', '.join(CONFIGURATIONS)}")


VOLTAGE_LIMIT = 24.0
"""The Aero 2 amplifier's maximum output voltage (V), Quanser Aero 2 user manual, table 2."""

RECOMMENDED_VOLTAGE = 18.0
"""The amplifier's recommended output range (V) and the thrusters' nominal voltage (user manual):
the tasks' default voltage limit."""

PITCH_LIMIT = math.radians(60.0)
"""The beam's mechanical pitch stop (rad). Assumed: no source read here states the Aero 2's pitch
travel; the board side confirms it. The simulation stops the beam there."""

MAX_ROTOR_SPEED = 600.0
"""Largest |rotor speed| (rad/s) of a plausible rotor: above the 414 rad/s a 24 V step settles at."""

MAX_BODY_SPEED = 50.0
"""Largest |pitch or yaw rate| (rad/s) of a plausible body; faster means the simulation diverged."""

PITCH_COUNTS_PER_REVOLUTION = 2048
"""Pitch encoder counts per revolution (in quadrature)."""

YAW_COUNTS_PER_REVOLUTION = 4096
"""Yaw encoder counts per revolution (in quadrature)."""

MOTOR_COUNTS_PER_REVOLUTION = 2048
"""Thruster motor encoder counts per revolution (assumed, see the module's docstring)."""

PITCH_COUNTS_PER_RADIAN = PITCH_COUNTS_PER_REVOLUTION / (2.0 * math.pi)
"""Pitch encoder counts per radian."""

YAW_COUNTS_PER_RADIAN = YAW_COUNTS_PER_REVOLUTION / (2.0 * math.pi)
"""Yaw encoder counts per radian."""

TACHOMETER_TO_RAD_PER_S = 2.0 * math.pi / MOTOR_COUNTS_PER_REVOLUTION
"""A thruster tachometer's reading (counts/s) times this is its rotor speed (rad/s)."""
