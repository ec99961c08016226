"""Follow: swing up if needed, then balance with the arm tracking the moving target.

The arm set-point of the balance LQR is the target seen through two limits:

* at most `REFERENCE_STEP` from where the arm is. The follow targets jump by up
  to 160 degrees; fed whole, such a jump asks the LQR for tens of volts, and
  the saturated LQR drops the pendulum. Limited, the LQR walks the arm over
  at the pace the voltage allows (a saturated proportional term).
* within +-`REFERENCE_LIMIT`, well short of the +-90 degree arm limit: the arm
  overshoots its set-point while it catches the pendulum's lean, and Coulomb
  friction or the cable's spring make the LQR hunt around it (with 1e-3 N m of
  friction, 1e-3 N m/rad of cable spring, quantised and filtered velocities and
  a step of delay the arm reaches 80 degrees following a 60 degree set-point).
  Stopping 20 degrees short of an 80 degree target costs 0.2 * 20 / 180 of a
  step's reward.

Before the pendulum is caught, `SwingUp` swings it up around the arm's centre;
the catch is judged against the limited set-point, so a far target does not
keep the LQR from taking over.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from qube_suite.baselines.base import Controller
from qube_suite.baselines.swingup import SwingUp
from qube_suite.tasks.base import DEFAULT_VOLTAGE_LIMIT

REFERENCE_STEP = math.radians(20.0)
"""Largest distance (rad) of the LQR's arm set-point from the arm."""
REFERENCE_LIMIT = math.radians(60.0)
"""Largest |arm set-point| (rad)."""


class Follow(Controller):
    """Balances (swinging up first if needed) with the arm following the observed target.

    Args: as `Controller`.
    """

    name = "follow"
    tasks = ("balance_follow", "balance_follow_sparse", "swingup_follow", "swingup_follow_sparse")

    def __init__(self, control_frequency: float = 250.0, voltage_limit: float = DEFAULT_VOLTAGE_LIMIT,
                 parameters: Mapping[str, float] | None = None, latency_steps: int = 0):
        super().__init__(control_frequency, voltage_limit, parameters, latency_steps)
        self.swingup = SwingUp(control_frequency, voltage_limit, parameters)

    def reset(self) -> None:
        super().reset()
        self.swingup.reset()

    def voltage_for(self, state: np.ndarray, target: float = 0.0) -> float:
        """Voltage (V) for `state` [theta, alpha, dtheta, dalpha] with the arm's target at `target` (rad)."""
        return self.swingup.voltage_for(state, arm_set_point(state[0], target))


def arm_set_point(theta: float, target: float) -> float:
    """The balance LQR's arm set-point (rad) for the arm at `theta` and the target `target` (rad)."""
    target = min(max(target, -REFERENCE_LIMIT), REFERENCE_LIMIT)
    return theta + min(max(target - theta, -REFERENCE_STEP), REFERENCE_STEP)
