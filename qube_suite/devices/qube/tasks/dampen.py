"""Dampen: bring a swinging pendulum to rest hanging, arm centred."""

from __future__ import annotations

import math

from qube_suite.angles import wrap_angle
from qube_suite.devices.qube.tasks.goal import GoalTask
from qube_suite.tasks.registry import register
from qube_suite.tasks.starts import UniformStart

START_ARM_RANGE = 0.1
"""Start: theta uniform in +-0.1 rad, ..."""
START_ARM_SPEED = 0.1
"""... dtheta uniform in +-0.1 rad/s, ..."""
START_PENDULUM_SPEED = 1.0
"""... alpha uniform in (-pi, pi] and dalpha uniform in +-1 rad/s."""


class Dampen(GoalTask):
    """Stop the pendulum's swing: bring it to rest hanging with the arm centred.

    ## Action
    Motor voltage (V), shape (1,), in [-voltage_limit, voltage_limit] (3 V by
    default); larger values are clipped, NaN/inf or a wrong shape raise ValueError.

    ## Observation
    `state` = [theta, alpha, dtheta, dalpha] (rad, rad/s), alpha = 0 upright; or
    the `trig` layout. See `Swingup`.

    ## Reward
    max(0, 1 - (0.8 |alpha_down| + 0.2 |theta|) / pi), alpha_down = alpha measured
    from hanging. Sparse: 1 when |alpha_down| <= 10 and |theta| <= 20 degrees.

    ## Start
    Any pendulum angle with a small speed: alpha ~ U(-pi, pi], dalpha ~ U(-1, 1)
    rad/s, theta ~ U(-0.1, 0.1) rad, dtheta ~ U(-0.1, 0.1) rad/s.

    ## Episode end
    Terminates (discount 0) when |theta| > 90 degrees; truncated (discount 1) at
    the time limit (2048 steps at 250 Hz).

    ## Arguments
    `sparse`, `voltage_limit`, `observation`, `random`.

    ## Version history
    v0: first release.
    """

    start = UniformStart(-1.0, 1.0, scale=(START_ARM_RANGE, math.pi, START_ARM_SPEED, START_PENDULUM_SPEED))

    def pendulum_error(self, physics):
        return wrap_angle(physics.pendulum_angle() - math.pi)


@register("benchmarking")
def dampen(**kwargs) -> Dampen:
    return Dampen(**kwargs)


@register("sparse")
def dampen_sparse(**kwargs) -> Dampen:
    return Dampen(sparse=True, **kwargs)
