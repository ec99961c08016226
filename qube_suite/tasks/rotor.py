"""Rotor: spin the pendulum through full revolutions."""

from __future__ import annotations

import math

import numpy as np

from qube_suite.angles import TAU, wrap_angle
from qube_suite.tasks.base import QubeTask
from qube_suite.tasks.registry import SUITE

START_NOISE = 0.01
"""Start: hanging at rest, each state variable uniform within +-0.01 (rad, rad/s)."""


class Rotor(QubeTask):
    """Spin the pendulum round and round, without the arm leaving +-90 degrees.

    ## Action
    Motor voltage (V), shape (1,), in [-voltage_limit, voltage_limit] (3 V by
    default); larger values are clipped, NaN/inf or a wrong shape raise ValueError.

    ## Observation
    `state` = [theta, alpha, dtheta, dalpha] (rad, rad/s); or the `trig` layout.

    ## Reward
    1 on the step that completes a full 360 degree revolution of the pendulum,
    else 0. Revolutions are net, counted from the start in either direction:
    swinging back over a counted turn earns nothing until a new turn is made.

    ## Start
    Hanging at rest (noise within +-0.01).

    ## Episode end
    Terminates (discount 0) when |theta| > 90 degrees; truncated (discount 1) at
    the time limit (2048 steps at 250 Hz).

    ## Arguments
    `voltage_limit`, `observation`, `random`.

    ## Version history
    v0: first release.
    """

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._last_alpha = 0.0
        self._turned = 0.0
        self._revolutions = 0
        self._completed_revolution = False

    @property
    def revolutions(self) -> int:
        """Net full revolutions completed this episode."""
        return self._revolutions

    def initial_state(self) -> np.ndarray:
        return self.random.uniform(-START_NOISE, START_NOISE, 4) + np.array([0.0, math.pi, 0.0, 0.0])

    def initialize_episode(self, physics) -> None:
        super().initialize_episode(physics)
        self._last_alpha = physics.pendulum_angle()
        self._turned = 0.0
        self._revolutions = 0
        self._completed_revolution = False

    def after_step(self, physics) -> None:
        alpha = physics.pendulum_angle()
        self._turned += wrap_angle(alpha - self._last_alpha)
        self._last_alpha = alpha
        revolutions = int(abs(self._turned) // TAU)
        self._completed_revolution = revolutions > self._revolutions
        self._revolutions = max(self._revolutions, revolutions)

    def get_reward(self, physics) -> float:
        return 1.0 if self._completed_revolution else 0.0


@SUITE.add("benchmarking")
def rotor(**kwargs) -> Rotor:
    return Rotor(**kwargs)
