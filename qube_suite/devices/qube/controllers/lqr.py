"""Balance: LQR about upright, with gains computed from the simulated model."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import scipy.linalg

from qube_suite.conventions import DEFAULT_VOLTAGE_LIMIT
from qube_suite.devices.qube import parameters as params
from qube_suite.devices.qube import simulation as qube
from qube_suite.devices.qube.controllers.base import Controller
from qube_suite.devices.qube.controllers.linearization import linearize

STATE_WEIGHTS = (2.0, 20.0, 0.05, 0.5)
"""Default LQR state weights on [theta, alpha, dtheta, dalpha] (rad, rad/s)."""
VOLTAGE_WEIGHT = 1.0
"""Default LQR weight on the voltage (V)."""
COULOMB = ("arm_friction", "pendulum_friction")
"""Parameters the linearisation leaves out."""


def lqr_design(control_frequency: float, parameters: Mapping[str, float] | None = None,
               state_weights: Sequence[float] = STATE_WEIGHTS, voltage_weight: float = VOLTAGE_WEIGHT,
               pendulum_angle: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(K, S): discrete LQR gain (1 x 4), V = -K x, and cost-to-go matrix, x^T S x.

    For the model linearised at rest with the pendulum at `pendulum_angle` (rad; 0
    upright, pi hanging) over one control period at `control_frequency` (Hz), with
    the given physical `parameters`; S solves the discrete Riccati equation. Coulomb friction
    is left out: it has no derivative at rest (the `Controller`'s observer cancels it instead).
    """
    smooth = {name: value for name, value in params.values_of(parameters).items() if name not in COULOMB}
    physics = qube.make_physics(control_frequency, smooth)
    nstep = qube.substeps_per_control_period(control_frequency)
    a, b = linearize(physics, np.array([0.0, pendulum_angle, 0.0, 0.0]), 0.0, nstep)
    q, r = np.diag(state_weights), np.array([[voltage_weight]])
    s = scipy.linalg.solve_discrete_are(a, b, q, r)
    return np.linalg.solve(r + b.T @ s @ b, b.T @ s @ a), s


def lqr_gain(control_frequency: float, parameters: Mapping[str, float] | None = None,
             state_weights: Sequence[float] = STATE_WEIGHTS, voltage_weight: float = VOLTAGE_WEIGHT
             ) -> np.ndarray:
    """Discrete LQR gain K (1 x 4), V = -K x, for the model linearised at upright (see `lqr_design`)."""
    return lqr_design(control_frequency, parameters, state_weights, voltage_weight)[0]


class BalanceLQR(Controller):
    """Holds the pendulum upright and the arm at its target with an LQR.

    Args: as `Controller`.
    """

    name = "balance"
    tasks = ("balance", "balance_sparse", "balance_follow", "balance_follow_sparse")

    def __init__(self, control_frequency: float = 250.0, voltage_limit: float = DEFAULT_VOLTAGE_LIMIT,
                 parameters: Mapping[str, float] | None = None, latency_steps: int = 0):
        super().__init__(control_frequency, voltage_limit, parameters, latency_steps)
        gain, self.cost_matrix = lqr_design(control_frequency, parameters)
        self.gain = gain[0]

    def voltage_for(self, state: np.ndarray, target: float = 0.0) -> float:
        """-K (x - x_target), clipped; `state` is [theta, alpha, dtheta, dalpha]."""
        error = state - np.array([target, 0.0, 0.0, 0.0])
        volts = -float(self.gain @ error)
        return min(max(volts, -self.voltage_limit), self.voltage_limit)

    def cost_to_go(self, state: np.ndarray, target: float = 0.0) -> float:
        """x^T S x of the error from upright at `target`: the LQR's predicted cost."""
        error = state - np.array([target, 0.0, 0.0, 0.0])
        return float(error @ self.cost_matrix @ error)

    def level_for_voltage(self, volts: float) -> float:
        """The largest cost-to-go level whose ellipsoid keeps the unsaturated LQR within +-`volts` (V).

        On the ellipsoid x^T S x = c the largest |K x| is sqrt(c K S^-1 K^T).
        """
        return volts**2 / float(self.gain @ np.linalg.solve(self.cost_matrix, self.gain))
