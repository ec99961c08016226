"""Follow: swing up if needed, then balance with the arm tracking the moving target.

Balanced, the arm is driven by a tracking LQR: the state's error from the
reference [r, 0, r', 0], r the arm set-point and r' the target's own speed. The
speed term matters for a moving target: an LQR about [r, 0, 0, 0] treats the
arm's speed as an error and lags a 0.2 Hz +-45 degree sine by 0.45 s (0.39 rad
mean error); fed the target's speed, 0.03 rad. r' is estimated from the target's
change over the last control period; a change faster than `TARGET_JUMP_SPEED`
is a jump of the schedule, not a motion, and counts as 0.

Its weights (`TRACKING_WEIGHTS`) are stiffer on the arm than the balance LQR's.
Steps of up to 120 degrees held 2 s are followed to a mean error of 0.24 to 0.25
rad over 30 episodes (docs/optimal_control.md). A set-point further ahead follows
them closer (0.18 rad at 20 degrees, 0.10 at 60) but drops the pendulum of a real
Qube: on the calibrated real Qube-Servo 2 (8 times the rotor inertia, 6 ms
latency) the default "jump" targets, which keep the arm's error saturated, ended
with the pendulum down in 9, 10 and 10 of 20 episodes at 20 degrees (simulated
exactly, as its board measures it, on its substitute), in none at 12.5.

The set-point is the target seen through two limits:

* at most `REFERENCE_STEP` from where the arm is: a jump of the target asks the
  LQR for no more than it can do at the voltage limit, so the saturated LQR does
  not drop the pendulum; the LQR walks the arm over (a saturated proportional
  term).
* within +-`REFERENCE_LIMIT`, well short of the +-90 degree arm limit: the arm
  overshoots its set-point while it catches the pendulum's lean, and Coulomb
  friction or the cable's spring make the LQR hunt around it.

Before the pendulum is caught, `SwingupController` swings it up around the arm's centre;
the catch is judged against the limited set-point, so a far target does not
keep the LQR from taking over.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from qube_suite.conventions import DEFAULT_VOLTAGE_LIMIT
from qube_suite.devices.qube.controllers.base import Controller
from qube_suite.devices.qube.controllers.lqr import lqr_design
from qube_suite.devices.qube.controllers.swingup import SwingupController

REFERENCE_STEP = math.radians(12.5)
"""Largest distance (rad) of the arm set-point from the arm."""
REFERENCE_LIMIT = math.radians(60.0)
"""Largest |arm set-point| (rad)."""
TRACKING_WEIGHTS = (300.0, 100.0, 1.0, 2.0)
"""LQR weights on the error of [theta, alpha, dtheta, dalpha] (rad, rad/s) from the reference."""
TARGET_JUMP_SPEED = 5.0
"""A target moving faster than this (rad/s) between two calls jumped: its speed counts as 0."""



class TargetSpeed:
    """The arm target's speed (rad/s), from its change over the last control period; a change faster
    than `TARGET_JUMP_SPEED` is a jump, which reads as 0."""

    def __init__(self, control_frequency: float):
        self.control_frequency = control_frequency
        self.reset()

    def reset(self) -> None:
        self._last: float | None = None

    def __call__(self, target: float) -> float:
        speed = 0.0
        if self._last is not None:
            speed = (target - self._last) * self.control_frequency
            speed = speed if abs(speed) < TARGET_JUMP_SPEED else 0.0
        self._last = target
        return speed

class FollowController(Controller):
    """Balances (swinging up first if needed) with the arm following the observed target.

    Args: as `Controller`.
    """

    name = "follow"
    tasks = ("balance_follow", "balance_follow_sparse", "swingup_follow", "swingup_follow_sparse")
    follows_target = True

    def __init__(self, control_frequency: float = 250.0, voltage_limit: float = DEFAULT_VOLTAGE_LIMIT,
                 parameters: Mapping[str, float] | None = None, latency_steps: int = 0):
        super().__init__(control_frequency, voltage_limit, parameters, latency_steps)
        self.swingup = SwingupController(control_frequency, voltage_limit, parameters)
        self.gain = lqr_design(control_frequency, parameters, TRACKING_WEIGHTS)[0][0]
        self.target_speed = TargetSpeed(control_frequency)
        self.reset()

    def reset(self) -> None:
        super().reset()
        self.swingup.reset()
        self.target_speed.reset()

    def voltage_for(self, state: np.ndarray, target: float = 0.0) -> float:
        """Voltage (V) for `state` [theta, alpha, dtheta, dalpha] with the arm's target at `target` (rad)."""
        speed = self.target_speed(target)
        set_point = arm_set_point(state[0], target)
        volts = self.swingup.voltage_for(state, set_point)
        if not self.swingup.balancing:
            return volts
        error = state - np.array([set_point, 0.0, speed, 0.0])
        return min(max(-float(self.gain @ error), -self.voltage_limit), self.voltage_limit)


def arm_set_point(theta: float, target: float, step: float = REFERENCE_STEP) -> float:
    """The arm set-point (rad) for the arm at `theta` and the target `target` (rad), at most `step`
    (rad) from the arm."""
    target = min(max(target, -REFERENCE_LIMIT), REFERENCE_LIMIT)
    return theta + min(max(target - theta, -step), step)
