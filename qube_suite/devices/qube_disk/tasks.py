"""The disk's tasks, `SUITE`: position (follow a schedule of target angles) and speed (hold a target
speed), each dense and sparse.

Tasks use only the disk's domain interface (`DiskPhysics`), so they run unchanged on the
simulation and on a board, and their formulas take floats (one disk) or arrays (a batch) alike.
"""

from __future__ import annotations

import collections
import math
import os
from typing import Protocol

import numpy as np
from dm_env import specs

from qube_suite.conventions import DEFAULT_VOLTAGE_LIMIT
from qube_suite.devices.qube_disk.conventions import MAX_SPEED, POSITION_LIMIT
from qube_suite.tasks.base import QubeTask
from qube_suite.tasks.batch_safety import ProbeQubes
from qube_suite.tasks.elementwise import maximum
from qube_suite.tasks.follow import TARGET_LIMIT, make_schedule
from qube_suite.tasks.registry import TaskSuite

VOLTAGE_WEIGHT = 0.1
"""Weight of the squared voltage, as a fraction of the voltage limit, in the dense rewards."""

POSITION_TOLERANCE = math.radians(3.0)
"""Goal set of the position tasks: within 3 degrees of the target (sparse reward, success)."""

SPEED_SCALE = 50.0
"""Speed error (rad/s) at which the speed task's dense reward reaches 0 (voltage aside)."""

SPEED_TOLERANCE = 2.0
"""Goal set of the speed tasks: within 2 rad/s of the target speed."""

TARGET_SPEEDS = (20.0, 60.0)
"""Without a `target_speed`, each episode draws its target's magnitude uniformly from 20 to 60 rad/s
(0.9 to 2.6 V at steady state, within the default 3 V) and its sign at random."""

SETTLED_FRACTION = 0.8
"""A position episode succeeds when the disk was within the goal set for 80 % of its steps: it settles
quickly after each change of target (the default schedule changes it every 2 s)."""

START_NOISE = 0.01
"""Position tasks start at rest with theta uniform within +-0.01 rad."""


class DiskPhysics(Protocol):
    """What a disk domain provides to its tasks (the simulation and the board alike)."""

    def disk_angle(self) -> float:
        """theta (rad), not wrapped."""

    def disk_velocity(self) -> float:
        """dtheta/dt (rad/s)."""

    def voltage(self) -> float:
        """Motor voltage (V) commanded by the last `set_voltage`."""

    def set_voltage(self, volts: float) -> None:
        """Apply a motor voltage (V)."""

    def reset_to(self, state) -> None:
        """Start an episode from [theta, dtheta]."""

    def time(self) -> float:
        """Time since the episode started (s)."""


class ProbeDisks(ProbeQubes):
    """The batch-safety check's stand-in for a disk domain (`qube_suite.tasks.batch_safety`)."""

    def disk_angle(self):
        return self._column(0)

    def disk_velocity(self):
        return self._column(1)


PROBE_STATES = np.array([[0.4, -12.0], [-7.5, 95.0]])
"""[theta, dtheta] of the batch-safety check's two worlds: one near its target, one far beyond."""

SUITE = TaskSuite(probe=ProbeDisks, probe_states=PROBE_STATES)
"""The disk's tasks; tags: benchmarking, sparse."""


def _voltage_cost(physics, limit: float):
    return VOLTAGE_WEIGHT * (physics.voltage() / limit) ** 2


class DiskTask(QubeTask):
    """Base of the disk's tasks: the voltage action and the episode rules of `QubeTask`, the disk's
    state [theta, dtheta].

    Args:
        voltage_limit: largest motor voltage (V) the action can ask for; in (0, 10].
        sparse: reward 1 inside the task's goal set, else 0; dense shaping otherwise.
        random: seed or `numpy.random.RandomState`.
        worlds: None for one disk, or the number of disks in a batch.
    """

    def __init__(self, voltage_limit: float = DEFAULT_VOLTAGE_LIMIT, sparse: bool = False,
                 random: int | np.random.RandomState | None = None, worlds: int | None = None):
        super().__init__(voltage_limit=voltage_limit, random=random, worlds=worlds)
        self._sparse = bool(sparse)

    @property
    def sparse(self) -> bool:
        return self._sparse

    def get_reward(self, physics):
        if self._sparse:
            return 1.0 * self.at_goal(physics)
        return self.dense_reward(physics)

    def dense_reward(self, physics):
        """The shaped reward (at most 1)."""
        raise NotImplementedError


class Position(DiskTask):
    """Turn the disk to a target angle that changes on a schedule.

    ## Action
    Motor voltage (V), shape (1,), in [-voltage_limit, voltage_limit] (3 V by default); larger
    values are clipped, NaN/inf or a wrong shape raise ValueError.

    ## Observation
    | key | index | value | unit | range |
    |---|---|---|---|---|
    | state | 0 | disk angle theta (not wrapped) | rad | episode ends beyond +-4 pi |
    | state | 1 | disk speed dtheta | rad/s | about +-240 |
    | target | 0 | target angle theta_target | rad | within +-80 degrees |

    ## Reward
    max(0, 1 - |theta - theta_target| / pi - 0.1 (V / voltage_limit)^2) per step, V the commanded
    voltage: 1 at the target with no voltage. Sparse: 1 within 3 degrees of the target, else 0.

    ## Start
    At rest, theta uniform in +-0.01 rad (0 is where the episode's reference is: on a board, where
    the disk rests when the episode starts).

    ## Episode end
    Terminates (discount 0) when |theta| > 4 pi (two turns off); truncated at the time limit.
    Success (`qube_suite.evaluation`): within 3 degrees of the target for 80 % of the steps.

    ## Arguments
    `voltage_limit`, `random`, and the target schedule of the follow tasks
    (`qube_suite.tasks.follow.make_schedule`): `target` ("steps" by default: a new angle in
    +-60 degrees every 2 s; "jump", "sine", "fixed" or a CSV file), `target_amplitude`,
    `target_hold_time`, `target_frequency`, `target_angle`.

    ## Version history
    v0: first release.
    """

    def __init__(self, target: str | os.PathLike = "steps", target_amplitude: float | None = None,
                 target_hold_time: float | None = None, target_frequency: float | None = None,
                 target_angle: float | None = None, **kwargs):
        super().__init__(**kwargs)
        schedule = make_schedule(target, target_amplitude=target_amplitude, target_hold_time=target_hold_time,
                                 target_frequency=target_frequency, target_angle=target_angle)
        self._schedule = schedule if self.worlds is None else schedule.batch(self.worlds)
        self._schedule_random = self.random if self.worlds is None else self.randoms

    @property
    def target(self):
        """The target angle (rad; one per world in a batch)."""
        return self._schedule.value

    def initial_state(self, random: np.random.RandomState) -> np.ndarray:
        return np.array([random.uniform(-START_NOISE, START_NOISE), 0.0])

    def initialize_episode(self, physics, world: int | None = None) -> None:
        super().initialize_episode(physics, world)
        self._schedule.reset(0.0, self.random if world is None else self.randoms[world], world)

    def after_step(self, physics) -> None:
        self._schedule.update(physics.time(), self._schedule_random)

    def error(self, physics):
        """theta - theta_target (rad)."""
        return physics.disk_angle() - self._schedule.value

    def dense_reward(self, physics):
        cost = _voltage_cost(physics, self.voltage_limit)
        return maximum(1.0 - abs(self.error(physics)) / math.pi - cost, 0.0)

    def at_goal(self, physics):
        """Whether the disk is within 3 degrees of its target."""
        return abs(self.error(physics)) <= POSITION_TOLERANCE

    def succeeded(self, at_goal, terminated: bool, control_frequency: float) -> bool:
        """Whether the finished episode did not terminate and the disk was within 3 degrees of its target
        for at least `SETTLED_FRACTION` of its steps."""
        return not terminated and len(at_goal) > 0 and float(np.mean(at_goal)) >= SETTLED_FRACTION

    def in_safe_set(self, physics):
        return abs(physics.disk_angle()) <= POSITION_LIMIT

    def observation_spec(self, physics) -> collections.OrderedDict:
        return collections.OrderedDict(
            state=specs.Array((2,), np.float64, name="state"),
            target=specs.BoundedArray((1,), np.float64, -TARGET_LIMIT, TARGET_LIMIT, name="target"))

    def observation_values(self, physics) -> list:
        return [physics.disk_angle(), physics.disk_velocity(), self._schedule.value]


class Speed(DiskTask):
    """Spin the disk at a target speed.

    ## Action
    Motor voltage (V), shape (1,), in [-voltage_limit, voltage_limit] (3 V by default); larger
    values are clipped, NaN/inf or a wrong shape raise ValueError.

    ## Observation
    | key | index | value | unit | range |
    |---|---|---|---|---|
    | state | 0 | disk speed dtheta | rad/s | about +-240 |
    | target | 0 | target speed | rad/s | the `target_speed` |

    ## Reward
    max(0, 1 - |dtheta - target_speed| / 50 - 0.1 (V / voltage_limit)^2) per step: holding
    40 rad/s (1.7 V) earns 0.97. Sparse: 1 within 2 rad/s of the target, else 0.

    ## Start
    At rest at theta = 0; the target speed drawn for the episode (see Arguments).

    ## Episode end
    Never terminates on a plausible disk (|dtheta| <= 300 rad/s); truncated at the time limit.
    Success (`qube_suite.evaluation`): within 2 rad/s of the target throughout the last 2 s.

    ## Arguments
    `voltage_limit`, `random`, `target_speed` (rad/s, |target_speed| <= 200): a fixed target; by
    default each episode draws one, 20 to 60 rad/s in either direction.

    ## Version history
    v0: first release.
    """

    def __init__(self, target_speed: float | None = None, **kwargs):
        super().__init__(**kwargs)
        number = isinstance(target_speed, (int, float)) and not isinstance(target_speed, bool)
        if target_speed is not None and not (number and abs(target_speed) <= 200.0):
            raise ValueError(f"target_speed must be None or a number of rad/s within +-200, "
                             f"got {target_speed!r}")
        self._fixed = None if target_speed is None else float(target_speed)
        self._target_speed = 0.0 if self.worlds is None else np.zeros(self.worlds)

    @property
    def target(self):
        """The episode's target speed (rad/s; one per world in a batch)."""
        return self._target_speed

    def initial_state(self, random: np.random.RandomState) -> np.ndarray:
        return np.zeros(2)

    def initialize_episode(self, physics, world: int | None = None) -> None:
        super().initialize_episode(physics, world)
        random = self.random if world is None else self.randoms[world]
        if self._fixed is None:
            target = random.uniform(*TARGET_SPEEDS) * random.choice((-1.0, 1.0))
        else:
            target = self._fixed
        if world is None:
            self._target_speed = target
        else:
            self._target_speed[world] = target

    def error(self, physics):
        """dtheta - target_speed (rad/s)."""
        return physics.disk_velocity() - self._target_speed

    def dense_reward(self, physics):
        cost = _voltage_cost(physics, self.voltage_limit)
        return maximum(1.0 - abs(self.error(physics)) / SPEED_SCALE - cost, 0.0)

    def at_goal(self, physics):
        """Whether the disk turns within 2 rad/s of its target speed."""
        return abs(self.error(physics)) <= SPEED_TOLERANCE

    def in_safe_set(self, physics):
        return abs(physics.disk_velocity()) <= MAX_SPEED

    def observation_spec(self, physics) -> collections.OrderedDict:
        return collections.OrderedDict(state=specs.Array((1,), np.float64, name="state"),
                                       target=specs.Array((1,), np.float64, name="target"))

    def observation_values(self, physics) -> list:
        velocity = physics.disk_velocity()
        return [velocity, self._target_speed]


@SUITE.register("benchmarking")
def position(**kwargs) -> Position:
    return Position(**kwargs)


@SUITE.register("sparse")
def position_sparse(**kwargs) -> Position:
    return Position(sparse=True, **kwargs)


@SUITE.register("benchmarking")
def speed(**kwargs) -> Speed:
    return Speed(**kwargs)


@SUITE.register("sparse")
def speed_sparse(**kwargs) -> Speed:
    return Speed(sparse=True, **kwargs)
