"""Dampen: energy shaping down to rest hanging, then an LQR about hanging.

From any state (swinging, revolving or upright) `EnergyShaping` drains the total
energy towards that of the pendulum at rest hanging, -2 mp g l, with the arm's
swing centre held at 0. Near rest an LQR designed on the model linearised about
hanging (`lqr_design(pendulum_angle=pi)`) damps the last small swing, which the
energy law, whose error vanishes quadratically there, would leave to the
pendulum's own friction, and centres the arm. It acts inside the ellipsoid of
its cost-to-go on which it would ask for at most `HANG_VOLTAGE`.

A pendulum at rest upright gives the energy law nothing to act on (its torque
follows the pendulum's speed), and Coulomb friction in the pendulum's bearing can
hold it there: a Qube left balanced at the end of an episode would stay up. Then
the arm is kicked with `KICK_VOLTAGE` towards its centre until the pendulum moves.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from qube_suite.angles import wrap_angle
from qube_suite.conventions import DEFAULT_VOLTAGE_LIMIT
from qube_suite.devices.qube.controllers.base import Controller
from qube_suite.devices.qube.controllers.energy import EnergyShaping
from qube_suite.devices.qube.controllers.lqr import lqr_design

STATE_WEIGHTS = (2.0, 5.0, 0.05, 0.5)
"""LQR weights on [theta, alpha - pi, dtheta, dalpha] (rad, rad/s) about hanging."""
HANG_VOLTAGE = 6.0
"""The hanging LQR acts inside its cost-to-go ellipsoid where it would ask for at most this (V)."""
KICK_VOLTAGE = 1.0
"""Voltage (V) that tips a pendulum resting upright ..."""
RESTING_UPRIGHT = (0.1, 0.2)
"""... found within this angle of upright (rad) and below this speed (rad/s)."""


class DampenController(Controller):
    """Brings the pendulum to rest hanging with the arm centred, from any state.

    Args: as `Controller`.
    """

    name = "dampen"
    tasks = ("dampen", "dampen_sparse")

    def __init__(self, control_frequency: float = 250.0, voltage_limit: float = DEFAULT_VOLTAGE_LIMIT,
                 parameters: Mapping[str, float] | None = None, latency_steps: int = 0):
        super().__init__(control_frequency, voltage_limit, parameters, latency_steps)
        self.shaping = EnergyShaping(self.model, voltage_limit)
        self.energy_set = -self.model.swing_up_energy
        gain, self.cost_matrix = lqr_design(control_frequency, parameters, STATE_WEIGHTS,
                                            pendulum_angle=math.pi)
        self.gain = gain[0]
        self.hang_level = HANG_VOLTAGE**2 / float(self.gain @ np.linalg.solve(self.cost_matrix, self.gain))

    def voltage_for(self, state: np.ndarray, target: float = 0.0) -> float:
        """Voltage (V) for `state` [theta, alpha, dtheta, dalpha]; the target is ignored."""
        error = np.array([state[0], wrap_angle(state[1] - math.pi), state[2], state[3]])
        if error @ self.cost_matrix @ error < self.hang_level:
            volts = -float(self.gain @ error)
            return min(max(volts, -self.voltage_limit), self.voltage_limit)
        if abs(wrap_angle(state[1])) < RESTING_UPRIGHT[0] and abs(state[3]) < RESTING_UPRIGHT[1]:
            return -math.copysign(min(KICK_VOLTAGE, self.voltage_limit), state[0])
        return self.shaping.voltage(state, self.energy_set)
