"""Swing-up: from hanging, bring the pendulum upright and keep it there."""

from __future__ import annotations

import math

from qube_suite.devices.qube.tasks.goal import FollowsTarget, GoalTask
from qube_suite.tasks.registry import register
from qube_suite.tasks.starts import UniformStart

START_NOISE = 0.05
"""Start: angles (rad) and velocities (rad/s) uniform within +-0.05 of hanging at rest."""


class Swingup(GoalTask):
    """Swing the pendulum up from hanging and balance it, arm centred.

    ## Action
    Motor voltage (V), shape (1,), in [-voltage_limit, voltage_limit] (3 V by
    default); larger values are clipped, NaN/inf or a wrong shape raise ValueError.

    ## Observation
    | key | index | value | unit | range |
    |---|---|---|---|---|
    | state | 0 | arm angle theta | rad | (-pi, pi], episode ends beyond +-pi/2 |
    | state | 1 | pendulum angle alpha, 0 upright | rad | (-pi, pi] |
    | state | 2 | arm velocity | rad/s | unbounded |
    | state | 3 | pendulum velocity | rad/s | unbounded |
    With `observation="trig"`, `state` is [cos theta, sin theta, cos alpha, sin
    alpha, dtheta, dalpha].

    ## Reward
    max(0, 1 - (0.8 |alpha| + 0.2 |theta|) / pi) per step: 1 upright with the arm
    centred, 0.2 hanging. Sparse: 1 when |alpha| <= 10 and |theta| <= 20 degrees,
    else 0.

    ## Start
    Hanging at rest: theta, alpha - pi, dtheta, dalpha each uniform in +-0.05.

    ## Episode end
    Terminates (discount 0) when |theta| > 90 degrees; truncated (discount 1) at the
    time limit (2048 steps at 250 Hz).

    ## Arguments
    `sparse`, `voltage_limit`, `observation`, `random` (see `GoalTask`, `QubeTask`).

    ## Version history
    v0: first release.
    """

    start = UniformStart(-START_NOISE, START_NOISE, offset=(0.0, math.pi, 0.0, 0.0))

    def pendulum_error(self, physics):
        return physics.pendulum_angle()


class SwingupFollow(FollowsTarget, Swingup):
    """Swing up and balance while the arm follows a moving target.

    As `Swingup`, with the arm's goal theta_target following a schedule (`target`):
    by default ("jump") theta_target ~ U(-80, 80) degrees, redrawn at random
    moments (about twice a second) and at every reset, as in the original
    toolkit, which nothing follows closely; "steps", "sine", "fixed" or a file
    make the task a tracking benchmark.

    ## Observation
    `state` as `Swingup`, plus `target` = [theta_target] (rad, within +-80 degrees);
    flattened for Gymnasium as [theta, alpha, dtheta, dalpha, theta_target].

    ## Reward
    As `Swingup` with theta - theta_target in place of theta (dense and sparse).

    ## Start
    Hanging at rest, as `Swingup`; the target is drawn at reset.

    ## Episode end
    As `Swingup`: the arm's +-90 degree limit is absolute, not relative to the target.

    ## Arguments
    `sparse`, `voltage_limit`, `observation`, `random`, and the target schedule:
    `target` ("jump" by default, "steps", "sine", "fixed" or a CSV file's path) with
    `target_amplitude`, `target_hold_time`, `target_frequency`, `target_angle`; their
    table, defaults and file format are in `qube_suite.tasks.follow`. A keyword the
    schedule does not take, an amplitude beyond 80 degrees or a malformed file is a
    ValueError. The sparse variant follows the same schedule.

    ## Version history
    v0: first release; the target schedule keywords were added later in v0, with
    "jump" (the first release's targets, draw for draw) the default.
    """


@register("benchmarking")
def swingup(**kwargs) -> Swingup:
    return Swingup(**kwargs)


@register("sparse")
def swingup_sparse(**kwargs) -> Swingup:
    return Swingup(sparse=True, **kwargs)


@register("benchmarking", "follow")
def swingup_follow(**kwargs) -> SwingupFollow:
    return SwingupFollow(**kwargs)


@register("sparse", "follow")
def swingup_follow_sparse(**kwargs) -> SwingupFollow:
    return SwingupFollow(sparse=True, **kwargs)
