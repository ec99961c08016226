"""Balance: LQR about upright, with gains computed from the simulated model."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import scipy.linalg

from qube_suite.baselines.base import Controller, split_observation
from qube_suite.baselines.linearization import linearize
from qube_suite.domains import qube
from qube_suite.tasks.base import DEFAULT_VOLTAGE_LIMIT

STATE_WEIGHTS = (2.0, 20.0, 0.05, 0.5)
"""Default LQR state weights on [theta, alpha, dtheta, dalpha] (rad, rad/s)."""
VOLTAGE_WEIGHT = 1.0
"""Default LQR weight on the voltage (V)."""


def lqr_gain(control_frequency: float, parameters: Mapping[str, float] | None = None,
             state_weights=STATE_WEIGHTS, voltage_weight: float = VOLTAGE_WEIGHT) -> np.ndarray:
    """Discrete LQR gain K (1 x 4), V = -K x, for the model linearised at upright.

    The linearisation covers one control period at `control_frequency` (Hz) with
    the given physical `parameters`; the gain solves the discrete Riccati equation.
    """
    physics = qube.make_physics(control_frequency, parameters)
    nstep = qube.substeps_per_control_period(control_frequency)
    a, b = linearize(physics, np.zeros(4), 0.0, nstep)
    q, r = np.diag(state_weights), np.array([[voltage_weight]])
    s = scipy.linalg.solve_discrete_are(a, b, q, r)
    return np.linalg.solve(r + b.T @ s @ b, b.T @ s @ a)


class BalanceLQR(Controller):
    """Holds the pendulum upright and the arm at its target with an LQR.

    Args:
        control_frequency: control steps per second (Hz) the gain is designed for.
        voltage_limit: output clip (V).
        parameters: physical parameters of the model to design for (nominal by default).
    """

    name = "balance"
    tasks = ("balance", "balance_sparse", "balance_follow", "balance_follow_sparse")

    def __init__(self, control_frequency: float = 250.0, voltage_limit: float = DEFAULT_VOLTAGE_LIMIT,
                 parameters: Mapping[str, float] | None = None):
        self.gain = lqr_gain(control_frequency, parameters)[0]
        self.voltage_limit = voltage_limit

    def voltage_for(self, state: np.ndarray, target: float = 0.0) -> float:
        """-K (x - x_target), clipped; `state` is [theta, alpha, dtheta, dalpha]."""
        error = state - np.array([target, 0.0, 0.0, 0.0])
        volts = -float(self.gain @ error)
        return min(max(volts, -self.voltage_limit), self.voltage_limit)

    def __call__(self, observation: Any) -> float:
        return self.voltage_for(*split_observation(observation))
