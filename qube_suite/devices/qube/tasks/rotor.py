"""Rotor: spin the pendulum through full revolutions."""

from __future__ import annotations

import copy
import math
from typing import Any, NamedTuple

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
        zeros = 0.0 if self.worlds is None else np.zeros(self.worlds)
        self._count = RevolutionCount.started(zeros)

    @property
    def revolutions(self):
        """Net full revolutions completed this episode (int; a float per world in a batch)."""
        revolutions = self._count.revolutions
        return revolutions if isinstance(revolutions, np.ndarray) else int(revolutions)

    start = UniformStart(-START_NOISE, START_NOISE, offset=(0.0, math.pi, 0.0, 0.0))

    def succeeded(self, at_goal, terminated: bool, control_frequency: float) -> bool:
        """Whether the finished episode made at least `SUCCESS_REVOLUTIONS` net revolutions (ended by the
        arm's limit or not)."""
        return self.revolutions >= SUCCESS_REVOLUTIONS

    def initialize_episode(self, physics, world=None) -> None:
        super().initialize_episode(physics, world)
        alpha = physics.pendulum_angle()
        if world is None:
            self._count = RevolutionCount.started(alpha)
        else:
            started = RevolutionCount.started(float(alpha[world]))
            self._count = RevolutionCount(*(np.where(np.arange(self.worlds) == world, new, kept)
                                            for new, kept in zip(started, self._count, strict=True)))

    def after_step(self, physics) -> None:
        self._count = self._count.advanced(physics.pendulum_angle())

    def get_reward(self, physics):
        return 1.0 * self._count.completed

    @property
    def process(self) -> RevolutionCount:
        return self._count

    def with_process(self, process: RevolutionCount) -> Rotor:
        task = copy.copy(self)
        task._count = process
        return task


class RevolutionCount(NamedTuple):
    """Net full turns of the pendulum since the start, counted from its angle sampled each step.

    A value: `advanced` gives the next count. Its fields are floats for one Qube, arrays with
    one value per world for a batch (numpy) or JAX arrays (`qube_suite.mjx`), with the same
    arithmetic for all.
    """

    last_alpha: Any
    """The pendulum angle (rad) last counted from."""
    turned: Any
    """Angle turned since the start (rad), signed."""
    revolutions: Any
    """Most net full turns reached so far (a whole number)."""
    completed: Any
    """Whether the last step completed a new turn."""

    @classmethod
    def started(cls, alpha) -> RevolutionCount:
        """The count at an episode's start, from pendulum angle `alpha` (rad)."""
        zero = 0.0 * alpha
        return cls(alpha, zero, zero, zero > 0.0)

    def advanced(self, alpha) -> RevolutionCount:
        """The count after the turn from the last angle to `alpha` (rad, wrapped to (-pi, pi])."""
        turned = self.turned + wrap_angle(alpha - self.last_alpha)
        revolutions = abs(turned) // TAU
        return RevolutionCount(alpha, turned, maximum(self.revolutions, revolutions),
                               revolutions > self.revolutions)


@register("benchmarking")
def rotor(**kwargs) -> Rotor:
    return Rotor(**kwargs)
