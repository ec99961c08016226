"""Rotor: energy shaping above the upright energy, so the pendulum goes round and round.

`EnergyShaping` holds the total energy at `ROTOR_ENERGY` above that of the
pendulum at rest upright, with the arm's swing centre at 0. With more energy
than it takes to reach upright the pendulum never turns back, so every
revolution counts in the same direction. At the set energy a revolution takes
about 0.26 s (27 in an 8.192 s episode of the nominal model at 3 V), and the
arm, whose reaction torques grow with the pendulum's speed squared, stays
within about +-50 degrees; more energy spins faster but swings the arm wider.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from qube_suite.conventions import DEFAULT_VOLTAGE_LIMIT
from qube_suite.devices.qube.controllers.base import Controller
from qube_suite.devices.qube.controllers.energy import EnergyShaping

ROTOR_ENERGY = 0.5
"""Set energy above upright at rest, as a fraction of 2 mp g l."""


class RotorController(Controller):
    """Keeps the pendulum revolving, arm within +-90 degrees.

    Args: as `Controller` (the law itself is continuous-time).
    """

    name = "rotor"
    tasks = ("rotor",)

    def __init__(self, control_frequency: float = 250.0, voltage_limit: float = DEFAULT_VOLTAGE_LIMIT,
                 parameters: Mapping[str, float] | None = None, latency_steps: int = 0):
        super().__init__(control_frequency, voltage_limit, parameters, latency_steps)
        self.shaping = EnergyShaping(self.model, voltage_limit)
        self.energy_set = ROTOR_ENERGY * self.model.swing_up_energy

    def voltage_for(self, state: np.ndarray, target: float = 0.0) -> float:
        """Voltage (V) for `state` [theta, alpha, dtheta, dalpha]; the target is ignored."""
        return self.shaping.voltage(state, self.energy_set)
