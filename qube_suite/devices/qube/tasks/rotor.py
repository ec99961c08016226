"""Rotor: spin the pendulum through full revolutions."""

from __future__ import annotations

import math

import numpy as np

from qube_suite.angles import TAU, wrap_angle
from qube_suite.tasks.base import QubeTask
from qube_suite.tasks.elementwise import maximum
from qube_suite.tasks.registry import register
from qube_suite.tasks.starts import UniformStart

SUCCESS_REVOLUTIONS = 5
"""An episode succeeds with at least 5 net revolutions."""

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
        self._counter = RevolutionCounter(self.worlds)

    @property
    def revolutions(self):
        """Net full revolutions completed this episode (int; a float per world in a batch)."""
        revolutions = self._counter.revolutions
        return revolutions if isinstance(revolutions, np.ndarray) else int(revolutions)

    start = UniformStart(-START_NOISE, START_NOISE, offset=(0.0, math.pi, 0.0, 0.0))

    def succeeded(self, at_goal, terminated: bool, control_frequency: float) -> bool:
        """Whether the finished episode made at least `SUCCESS_REVOLUTIONS` net revolutions (ended by the
        arm's limit or not)."""
        return self.revolutions >= SUCCESS_REVOLUTIONS

    def initialize_episode(self, physics, world=None) -> None:
        super().initialize_episode(physics, world)
        alpha = physics.pendulum_angle()
        self._counter.reset(alpha if world is None else float(alpha[world]), world)

    def after_step(self, physics) -> None:
        self._counter.update(physics.pendulum_angle())

    def get_reward(self, physics):
        return 1.0 * self._counter.completed


class RevolutionCounter:
    """Net full turns of the pendulum since the start, from its angle sampled each step.

    For one Qube (`worlds=None`) its values are floats, for a batch arrays with one
    value per world; `update` is the same arithmetic for both.
    """

    def __init__(self, worlds: int | None = None):
        def zeros():
            return 0.0 if worlds is None else np.zeros(worlds)

        self.last_alpha = zeros()
        self.turned = zeros()
        """Angle turned since the start (rad), signed."""
        self.revolutions = zeros()
        """Most net full turns reached so far (a whole number)."""
        self.completed = zeros() > 0.0
        """Whether the last update completed a new turn."""

    def reset(self, alpha: float, world: int | None = None) -> None:
        """Start counting from pendulum angle `alpha` (rad) (in `world` of a batch)."""
        if world is None:
            self.last_alpha, self.turned, self.revolutions, self.completed = alpha, 0.0, 0.0, False
        else:
            self.last_alpha[world], self.turned[world], self.revolutions[world] = alpha, 0.0, 0.0
            self.completed[world] = False

    def update(self, alpha) -> None:
        """Count the turn from the last angle to `alpha` (rad, wrapped to (-pi, pi])."""
        self.turned = self.turned + wrap_angle(alpha - self.last_alpha)
        self.last_alpha = alpha
        revolutions = abs(self.turned) // TAU
        self.completed = revolutions > self.revolutions
        self.revolutions = maximum(self.revolutions, revolutions)


@register("benchmarking")
def rotor(**kwargs) -> Rotor:
    return Rotor(**kwargs)
