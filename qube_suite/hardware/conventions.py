"""How a Qube's board signals relate to the package's angles and voltage.

The package's coordinates (`qube_suite/domains/interface.py`): arm angle theta
positive counter-clockwise seen from above, 0 = arm centred; pendulum angle
alpha with 0 = upright and +-pi = hanging; the motor voltage V is positive when
it drives theta positive.

The board's signals, as in Quanser's own Qube-Servo 2 rotary-pendulum QUARC
models (their "Arm: counts to rad" gain is -2*pi/2048, their "Pendulum: counts to
rad" gain is +2*pi/2048 followed by mod 2*pi and a -pi bias, and their "For +ve
CCW" gain of -1 sits before the analog output):

| board signal                      | package quantity                                  |
|-----------------------------------|---------------------------------------------------|
| encoder 0 (counts)                | theta = ARM_SIGN * 2*pi/2048 * counts             |
| encoder 1 (counts)                | alpha = wrap(pi + PENDULUM_SIGN * 2*pi/2048 * counts) |
| analog output 0 (V)               | V = ARM_SIGN * volts                              |
| analog input 0 (A)                | motor current = ARM_SIGN * amperes                |
| other input 14000 (counts/s)      | dtheta/dt = ARM_SIGN * 2*pi/2048 * counts_per_s   |

Both encoders are incremental: they read 0 where they were at power-up or at the
last `set_encoder_counts`. The pendulum mapping therefore assumes the pendulum
hung at rest when its encoder was zeroed (a real Qube is switched on with the
pendulum hanging), and the arm mapping assumes the arm was centred.
The substitute board (`_hil_sim`) wires its plant by these same constants.
"""

from __future__ import annotations

import math

from qube_suite.devices.qube.parameters import ENCODER_COUNTS_PER_REVOLUTION

RADIANS_PER_COUNT = 2.0 * math.pi / ENCODER_COUNTS_PER_REVOLUTION
"""Both encoders: 2048 counts per revolution (512 lines in quadrature)."""

ARM_SIGN = -1
"""The board's positive motor direction (voltage, current, encoder 0, tachometer) is -theta."""

PENDULUM_SIGN = 1
"""Encoder 1 counts up with alpha."""


def arm_angle(counts: float) -> float:
    """theta (rad) from encoder 0 counts (not wrapped)."""
    return ARM_SIGN * RADIANS_PER_COUNT * counts


def pendulum_angle_unwrapped(counts: float) -> float:
    """alpha (rad) from encoder 1 counts, not wrapped: pi at the count of zero (hanging)."""
    return math.pi + PENDULUM_SIGN * RADIANS_PER_COUNT * counts


def board_voltage(voltage: float) -> float:
    """Analog output (V) that applies the package's motor voltage `voltage` (V)."""
    return ARM_SIGN * voltage


def motor_current(board_current: float) -> float:
    """Motor current (A) in the package's sign from analog input 0 (A)."""
    return ARM_SIGN * board_current


def arm_velocity(tachometer: float) -> float:
    """dtheta/dt (rad/s) from the tachometer, other input 14000 (counts/s)."""
    return ARM_SIGN * RADIANS_PER_COUNT * tachometer
