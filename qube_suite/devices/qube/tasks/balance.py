"""Balance: keep the pendulum upright from a start near upright."""

from __future__ import annotations

import math

from qube_suite.devices.qube.tasks.goal import FollowsTarget, GoalTask
from qube_suite.tasks.registry import register
from qube_suite.tasks.starts import ClippedNormalStart

PENDULUM_LIMIT = math.radians(20.0)
"""The pendulum leaving +-20 degrees of upright ends the episode."""

START_ANGLE_STD = 0.03
"""Start: theta and alpha ~ N(0, 0.03 rad) ..."""
START_VELOCITY_STD = 0.05
"""... dtheta and dalpha ~ N(0, 0.05 rad/s), all truncated at 3 standard deviations."""


class Balance(GoalTask):
    """Keep the pendulum balanced upright, arm centred.

    ## Action
    Motor voltage (V), shape (1,), in [-voltage_limit, voltage_limit] (3 V by
    default); larger values are clipped, NaN/inf or a wrong shape raise ValueError.

    ## Observation
    `state` = [theta, alpha, dtheta, dalpha] (rad, rad/s), alpha = 0 upright; or
    the `trig` layout. See `Swingup`.

    ## Reward
    max(0, 1 - (0.8 |alpha| + 0.2 |theta|) / pi) per step. Sparse: 1 when
    |alpha| <= 10 and |theta| <= 20 degrees, else 0.

    ## Start
    Near upright: theta, alpha ~ N(0, 0.03) rad, velocities ~ N(0, 0.05) rad/s,
    truncated at 3 standard deviations.

    ## Episode end
    Terminates (discount 0) when |theta| > 90 degrees or |alpha| > 20 degrees;
    truncated (discount 1) at the time limit (2048 steps at 250 Hz).

    ## Arguments
    `sparse`, `voltage_limit`, `observation`, `random`.

    ## Version history
    v0: first release.
    """

    start = ClippedNormalStart((START_ANGLE_STD, START_ANGLE_STD, START_VELOCITY_STD, START_VELOCITY_STD),
                               3.0)

    def pendulum_error(self, physics):
        return physics.pendulum_angle()

    def in_safe_set(self, physics):
        return super().in_safe_set(physics) & (abs(physics.pendulum_angle()) <= PENDULUM_LIMIT)


class BalanceFollow(FollowsTarget, Balance):
    """Balance while the arm follows a moving target.

    As `Balance`, with the arm's goal theta_target following a schedule (`target`):
    by default ("jump") theta_target ~ U(-80, 80) degrees, redrawn at random
    moments (about twice a second) and at every reset, as in the original
    toolkit, which nothing follows closely; "steps", "sine", "fixed" or a file
    make the task a tracking benchmark.

    ## Observation
    `state` as `Balance`, plus `target` = [theta_target] (rad, within +-80 degrees);
    flattened for Gymnasium as [theta, alpha, dtheta, dalpha, theta_target].

    ## Reward
    As `Balance` with theta - theta_target in place of theta (dense and sparse).

    ## Start
    Near upright, as `Balance`; the target is drawn at reset.

    ## Episode end
    As `Balance`: the arm's +-90 degree limit is absolute, not relative to the target.

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
def balance(**kwargs) -> Balance:
    return Balance(**kwargs)


@register("sparse")
def balance_sparse(**kwargs) -> Balance:
    return Balance(sparse=True, **kwargs)


@register("benchmarking", "follow")
def balance_follow(**kwargs) -> BalanceFollow:
    return BalanceFollow(**kwargs)


@register("sparse", "follow")
def balance_follow_sparse(**kwargs) -> BalanceFollow:
    return BalanceFollow(sparse=True, **kwargs)
