"""Swing-up: energy shaping up to the upright energy, then the balance LQR.

From any state, `EnergyShaping` pumps the total energy of arm and pendulum to a
little above that of the pendulum at rest upright (`ENERGY_MARGIN`), keeping the
arm's swing centre near 0. Near upright with the arm moving along (zero angular
momentum) the pendulum's effective inertia is less than half its own, so every
bit of excess energy arrives as speed: the margin is small, and it adapts
instead. Each swing through the upper half that had the set energy (to within
the pump's `ENERGY_BAND`) but was not caught corrects it: turning back at
alpha_peak raises it by mp g l (1 - cos alpha_peak), passing over the top at
alpha'_top lowers it by the kinetic energy there, both times `ADAPTATION`.
Friction, the cable's spring and model error thus cost a swing, not the swing-up.

The balance LQR (`BalanceLQR`) takes over inside a level set of its own
cost-to-go x^T S x, the ellipsoid on which the unsaturated LQR would ask for at
most `CATCH_VOLTAGE`, and hands back outside the larger `RELEASE_VOLTAGE` one.
Sized by the cost-to-go rather than by |alpha| alone, the switch accounts for
the arm's angle and both speeds: of random states with |alpha| < 17 degrees the
LQR catches only about half at 3 V, of those inside the catch ellipsoid 99 %.

Energy, catch and hand-back are judged on the state the `StateObserver` estimates
from the angles and predicts for the sample the voltage will act on (`Controller`):
free of the velocity filter's lag and of the loop's latency on hardware.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from qube_suite.conventions import DEFAULT_VOLTAGE_LIMIT
from qube_suite.devices.qube.controllers.base import Controller
from qube_suite.devices.qube.controllers.energy import ENERGY_BAND, EnergyShaping
from qube_suite.devices.qube.controllers.lqr import BalanceLQR

ENERGY_MARGIN = 0.03
"""Set energy above upright at rest, as a fraction of 2 mp g l: covers friction and model error."""
CATCH_VOLTAGE = 8.5
"""The LQR takes over inside the cost-to-go ellipsoid where it would ask for at most this (V) ..."""
RELEASE_VOLTAGE = 12.0
"""... and hands back to the swing-up outside this larger one (V)."""
ADAPTATION = 1.0
"""Fraction of each uncaught swing's shortfall or excess energy corrected by the next swing."""
ENERGY_MARGIN_LIMIT = 0.3
"""The adapted set energy stays within [0, 0.3] 2 mp g l above upright."""


class SwingupController(Controller):
    """Swings the pendulum up from any state and balances it, arm within +-90 degrees.

    Args: as `Controller`.
    """

    name = "swingup"
    tasks = ("swingup", "swingup_sparse", "balance", "balance_sparse")

    def __init__(self, control_frequency: float = 250.0, voltage_limit: float = DEFAULT_VOLTAGE_LIMIT,
                 parameters: Mapping[str, float] | None = None, latency_steps: int = 0):
        super().__init__(control_frequency, voltage_limit, parameters, latency_steps)
        self.balance = BalanceLQR(control_frequency, voltage_limit, parameters)
        self.shaping = EnergyShaping(self.model, voltage_limit)
        self.catch_level = self.balance.level_for_voltage(CATCH_VOLTAGE)
        self.release_level = self.balance.level_for_voltage(RELEASE_VOLTAGE)
        self.reset()

    def reset(self) -> None:
        super().reset()
        self.balancing = False
        self.energy_set = ENERGY_MARGIN * self.model.swing_up_energy
        self._upper_side = 0.0     # sign of alpha when the current swing entered the upper half, else 0
        self._peak_alpha = math.pi  # smallest |alpha| of that swing (rad) ...
        self._peak_energy = 0.0    # ... and the total energy there (J)
        self._excess: float | None = None  # kinetic energy (J) where it crossed upright, if it did

    def voltage_for(self, state: np.ndarray, target: float = 0.0) -> float:
        """Voltage (V) for `state` [theta, alpha, dtheta, dalpha]; balances with the arm at `target` (rad)."""
        level = self.release_level if self.balancing else self.catch_level
        self.balancing = self.balance.cost_to_go(state, target) < level
        self._learn_from_swing(state)
        if self.balancing:
            return self.balance.voltage_for(state, target)
        return self.shaping.voltage(state, self.energy_set)

    def _learn_from_swing(self, state: np.ndarray) -> None:
        """Adapt the set energy when a swing through the upper half ends uncaught at the set energy."""
        _, alpha, dtheta, dalpha = state
        model = self.model
        if abs(alpha) < math.pi / 2:
            if not self._upper_side:
                self._upper_side, self._peak_alpha, self._excess = math.copysign(1.0, alpha), math.pi, None
            if abs(alpha) < self._peak_alpha:
                self._peak_alpha = abs(alpha)
                self._peak_energy = model.energy(alpha, dtheta, dalpha)
            if alpha * self._upper_side < 0.0 and self._excess is None:  # crossed upright
                self._excess = 0.5 * model.upright_swing_inertia * dalpha * dalpha
        elif self._upper_side:
            settled = abs(self._peak_energy - self.energy_set) < ENERGY_BAND * model.swing_up_energy
            if settled and not self.balancing:
                shortfall = model.gravity_torque * (1.0 - math.cos(self._peak_alpha))
                change = shortfall if self._excess is None else -self._excess
                self.energy_set += ADAPTATION * change
                self.energy_set = min(max(self.energy_set, 0.0), ENERGY_MARGIN_LIMIT * model.swing_up_energy)
            self._upper_side = 0.0
