"""The Aero 2's tasks, `SUITE`: pitch (1-DOF: hold and step the pitch), hover (2-DOF: hold level at a
yaw target) and track (2-DOF: follow pitch and yaw schedules), each dense and sparse.

Tasks use only the Aero's domain interface (`Aero2Physics`), so they run unchanged on the
simulation and on a board, and their formulas take floats (one Aero) or arrays (a batch) alike.
The action is the two thruster voltages (front, back), shape (2,).
"""

from __future__ import annotations

import collections
import contextlib
import math
import os
from collections.abc import Sequence
from typing import Protocol

import numpy as np
from dm_env import specs

from qube_suite.devices.aero2.conventions import (
    ACTION_NAMES,
    PITCH_LIMIT,
    RECOMMENDED_VOLTAGE,
    STATE_NAMES,
    VOLTAGE_LIMIT,
)
from qube_suite.tasks.base import QubeTask
from qube_suite.tasks.batch_safety import ProbeQubes
from qube_suite.tasks.elementwise import maximum
from qube_suite.tasks.follow import TARGET_LIMIT, StepTargets, make_schedule
from qube_suite.tasks.registry import TaskSuite

VOLTAGE_WEIGHT = 0.1
"""Weight of the mean squared voltage, as a fraction of the voltage limit, in the dense rewards."""

PITCH_SCALE = math.radians(30.0)
"""Pitch error (rad) at which a dense reward's pitch term has taken all of it."""

YAW_SCALE = math.radians(90.0)
"""Yaw error (rad) at which a dense reward's yaw term has taken all of it: a quarter turn."""

PITCH_TOLERANCE = math.radians(3.0)
"""Goal set: pitch within 3 degrees of its target."""

YAW_TOLERANCE = math.radians(5.0)
"""Goal set: yaw within 5 degrees of its target."""

SAFE_PITCH = PITCH_LIMIT - math.radians(5.0)
"""Episodes terminate when the beam comes within 5 degrees of its stops."""

SAFE_YAW = 2.0 * math.pi
"""The 2-DOF episodes terminate when the Aero has turned a whole turn away from its reference."""

PITCH_TARGET_LIMIT = math.radians(45.0)
"""Pitch targets stay within +-45 degrees, short of the stops."""

PITCH_AMPLITUDE = math.radians(30.0)
"""Default amplitude of the pitch task's schedules."""

TRACK_PITCH_AMPLITUDE = math.radians(20.0)
"""Default amplitude of the track task's pitch schedule."""

YAW_AMPLITUDE = math.radians(60.0)
"""Default amplitude of the track task's yaw schedule and range of the hover task's yaw targets."""

HOLD_TIME = 4.0
"""Default hold time (s) of the "steps" schedules: a new target every 4 s (twice an 8.192 s episode)."""

SETTLED_FRACTION = 0.6
"""A pitch or track episode succeeds when the Aero was within the goal set for 60 % of its steps: it
settles within about 1.5 s after each change of target."""

START_PITCH = math.radians(2.0)
"""Episodes start at rest with the pitch uniform within +-2 degrees (yaw 0)."""

HOVER_START_PITCH = math.radians(10.0)
"""Hover episodes start at rest with the pitch uniform within +-10 degrees (yaw 0)."""


class Aero2Physics(Protocol):
    """What every Aero 2 domain provides (the simulation and the board alike).

    State entries are `conventions.STATE_NAMES`; voltages are (front, back) in V. A domain is made
    with `configuration="2dof"` (default) or `"pitch_only"` (yaw locked), `conventions.CONFIGURATIONS`.
    """

    latency_steps: int
    """Control periods between a `set_voltage` and its first effect on the state."""

    state_names: tuple[str, ...]
    """The entries of `qube_state()`: `conventions.STATE_NAMES`."""

    physics_error: str | None
    """Why the last step failed (the domain stopped it), or None."""

    configuration: str
    """"2dof" or "pitch_only"."""

    def pitch(self) -> float:
        """Pitch (rad), positive front up, 0 level."""

    def yaw(self) -> float:
        """Yaw (rad), positive counter-clockwise seen from above, not wrapped; 0 when locked."""

    def pitch_velocity(self) -> float:
        """Pitch rate (rad/s)."""

    def yaw_velocity(self) -> float:
        """Yaw rate (rad/s); 0 when locked."""

    def rotor_speeds(self) -> np.ndarray:
        """Front and back rotor speeds (rad/s), shape (2,)."""

    def qube_state(self) -> np.ndarray:
        """[pitch, yaw, pitch rate, yaw rate, front rotor speed, back rotor speed], a new array."""

    def voltage(self) -> np.ndarray:
        """The (front, back) voltages (V) commanded by the last `set_voltage`, shape (2,)."""

    def set_voltage(self, volts: np.ndarray) -> None:
        """Command the (front, back) voltages (V), shape (2,), until the next call."""

    def stop_motor(self) -> None:
        """Both motors to 0 V now (a refused action); nothing to do in simulation."""

    def set_led(self, rgb: Sequence[float]) -> None:
        """Colour the LED, (r, g, b) in [0, 1]."""

    def led(self) -> tuple[float, float, float]:
        """The LED's (r, g, b)."""

    def reset_to(self, state: Sequence[float]) -> None:
        """Start an episode from a state of `STATE_NAMES` (a board: brought there as closely as it can)."""

    def reset_context(self) -> contextlib.AbstractContextManager:
        """Time, state and voltages reset (0 V); the caller sets the start inside (`reset_to`)."""

    def time(self) -> float:
        """Time since the episode started (s)."""

    def step(self, nstep: int = 1) -> None:
        """Advance with the voltages held."""

    def end_episode(self) -> None:
        """An episode ended: a board sets both motors to 0 V."""

    def drawable(self):
        """Something a renderer can draw (the simulation itself)."""

    def close(self) -> None:
        """Release the domain; both motors at 0 V on a board."""


class ProbeAeros(ProbeQubes):
    """The batch-safety check's stand-in for an Aero domain (`qube_suite.tasks.batch_safety`), in the
    2-DOF configuration."""

    configuration = "2dof"

    def __init__(self, states: np.ndarray, times, worlds: int | None):
        super().__init__(states, times, worlds)
        self._voltage = np.zeros(len(ACTION_NAMES) if worlds is None else (worlds, len(ACTION_NAMES)))

    def pitch(self):
        return self._column(0)

    def yaw(self):
        return self._column(1)

    def pitch_velocity(self):
        return self._column(2)

    def yaw_velocity(self):
        return self._column(3)

    def rotor_speeds(self):
        return self._states[..., 4:6].copy()


PROBE_STATES = np.array([[0.1, 0.4, -0.3, 0.2, 80.0, -20.0],
                         [-1.2, -7.0, 2.0, -1.5, 300.0, 150.0]])
"""States of the batch-safety check's two worlds: one near level, one beyond the safe pitch and yaw."""

SUITE = TaskSuite(probe=ProbeAeros, probe_states=PROBE_STATES)
"""The Aero's tasks; tags: benchmarking, sparse."""


def _voltage_cost(physics, limit: float):
    """VOLTAGE_WEIGHT times the mean over the thrusters of (V / limit)^2 (one per world in a batch)."""
    return VOLTAGE_WEIGHT * np.mean((physics.voltage() / limit) ** 2, axis=-1)


def _schedule(target, amplitude: float, limit: float, name: str, **keywords):
    """`make_schedule(target, ...)` with `amplitude` as the default amplitude of the named random and
    sine schedules; raises ValueError if its targets may go beyond +-`limit` (rad)."""
    if target in ("steps", "jump", "sine") and keywords["target_amplitude"] is None:
        keywords["target_amplitude"] = amplitude
    if target in ("steps", "jump") and keywords["target_hold_time"] is None:
        keywords["target_hold_time"] = HOLD_TIME
    schedule = make_schedule(target, **keywords)
    reach = max(abs(getattr(schedule, "amplitude", 0.0)), abs(getattr(schedule, "angle", 0.0)),
                float(np.max(np.abs(getattr(schedule, "angles", 0.0)))))
    if reach > limit + 1e-12:
        raise ValueError(f"the {name} targets reach {math.degrees(reach):.1f} degrees, beyond the "
                         f"{math.degrees(limit):.0f} degrees the Aero's {name} targets keep within")
    return schedule


class Aero2Task(QubeTask):
    """Base of the Aero's tasks: two thruster voltages as the action, the episode rules of `QubeTask`.

    Args:
        voltage_limit: largest voltage (V) the action can ask of either thruster; in (0, 24], 18 by
            default (the amplifier's recommended range).
        sparse: reward 1 inside the task's goal set, else 0; dense shaping otherwise.
        random: seed or `numpy.random.RandomState`.
        worlds: None for one Aero, or the number of Aeros in a batch.
    """

    action_shape = (len(ACTION_NAMES),)
    max_voltage_limit = VOLTAGE_LIMIT
    needs_yaw = False
    """Whether the task needs the 2-DOF configuration (a yaw that turns)."""

    def __init__(self, voltage_limit: float = RECOMMENDED_VOLTAGE, sparse: bool = False,
                 random: int | np.random.RandomState | None = None, worlds: int | None = None):
        super().__init__(voltage_limit=voltage_limit, random=random, worlds=worlds)
        self._sparse = bool(sparse)

    @property
    def sparse(self) -> bool:
        return self._sparse

    def initialize_episode(self, physics, world: int | None = None) -> None:
        if self.needs_yaw and physics.configuration != "2dof":
            raise ValueError(f"the {type(self).__name__.lower()} task turns the yaw: it needs the Aero in "
                             f"its 2-DOF configuration, got configuration {physics.configuration!r}")
        super().initialize_episode(physics, world)

    def get_reward(self, physics):
        if self._sparse:
            return 1.0 * self.at_goal(physics)
        return self.dense_reward(physics)

    def dense_reward(self, physics):
        """The shaped reward (at most 1)."""
        raise NotImplementedError

    def in_safe_set(self, physics):
        """Whether the beam is clear of its stops by 5 degrees (and, in 2-DOF tasks, within a turn of its
        yaw reference)."""
        safe = abs(physics.pitch()) <= SAFE_PITCH
        if self.needs_yaw:
            safe = safe & (abs(physics.yaw()) <= SAFE_YAW)
        return safe

    def action_spec(self, physics) -> specs.BoundedArray:
        """(front, back) thruster voltages (V), shape (2,), within +-voltage_limit."""
        return self._action_spec


class Pitch(Aero2Task):
    """Hold the beam's pitch at a target that changes on a schedule (1-DOF).

    Meant for the pitch-only configuration (`domain_kwargs={"configuration": "pitch_only"}`: yaw
    locked, both thrusters lifting); in the 2-DOF configuration the yaw turns freely and is ignored.

    ## Action
    (front, back) thruster voltages (V), shape (2,), each in [-voltage_limit, voltage_limit] (18 V
    by default); larger values are clipped, NaN/inf or a wrong shape raise ValueError.

    ## Observation
    | key | index | value | unit | range |
    |---|---|---|---|---|
    | state | 0 | pitch theta (front up) | rad | episode ends beyond +-55 degrees |
    | state | 1 | pitch rate | rad/s | a few rad/s |
    | state | 2, 3 | front, back rotor speeds | rad/s | +-414 at 24 V |
    | target | 0 | target pitch | rad | within +-45 degrees |

    ## Reward
    max(0, 1 - |theta - theta_target| / 30 deg - 0.1 mean((V / voltage_limit)^2)) per step.
    Sparse: 1 within 3 degrees of the target, else 0.

    ## Start
    At rest, rotors stopped, pitch uniform in +-2 degrees.

    ## Episode end
    Terminates (discount 0) when |pitch| > 55 degrees (near the stops); truncated at the time limit.
    Success (`qube_suite.evaluation`): within 3 degrees of the target for 60 % of the steps.

    ## Arguments
    `voltage_limit`, `random`, and the target schedule of the follow tasks
    (`qube_suite.tasks.follow.make_schedule`): `target` ("steps" by default: a new pitch in
    +-30 degrees every 4 s; "jump", "sine", "fixed" or a CSV file), `target_amplitude`,
    `target_hold_time`, `target_frequency`, `target_angle`; targets within +-45 degrees.

    ## Version history
    v0: first release.
    """


    def __init__(self, target: str | os.PathLike = "steps", target_amplitude: float | None = None,
                 target_hold_time: float | None = None, target_frequency: float | None = None,
                 target_angle: float | None = None, **kwargs):
        super().__init__(**kwargs)
        schedule = _schedule(target, PITCH_AMPLITUDE, PITCH_TARGET_LIMIT, "pitch",
                             target_amplitude=target_amplitude, target_hold_time=target_hold_time,
                             target_frequency=target_frequency, target_angle=target_angle)
        self._pitch_schedule = schedule if self.worlds is None else schedule.batch(self.worlds)
        self._schedule_random = self.random if self.worlds is None else self.randoms

    @property
    def target(self):
        """The target pitch (rad; one per world in a batch)."""
        return self._pitch_schedule.value

    def initial_state(self, random: np.random.RandomState) -> np.ndarray:
        return np.array([random.uniform(-START_PITCH, START_PITCH), 0.0, 0.0, 0.0, 0.0, 0.0])

    def initialize_episode(self, physics, world: int | None = None) -> None:
        super().initialize_episode(physics, world)
        self._pitch_schedule.reset(0.0, self.random if world is None else self.randoms[world], world)

    def after_step(self, physics) -> None:
        self._pitch_schedule.update(physics.time(), self._schedule_random)

    def pitch_error(self, physics):
        """theta - theta_target (rad)."""
        return physics.pitch() - self._pitch_schedule.value

    def dense_reward(self, physics):
        cost = _voltage_cost(physics, self.voltage_limit)
        return maximum(1.0 - abs(self.pitch_error(physics)) / PITCH_SCALE - cost, 0.0)

    def at_goal(self, physics):
        """Whether the pitch is within 3 degrees of its target."""
        return abs(self.pitch_error(physics)) <= PITCH_TOLERANCE

    def succeeded(self, at_goal, terminated: bool, control_frequency: float) -> bool:
        """Whether the finished episode did not terminate and the Aero was at its goal for at least
        `SETTLED_FRACTION` of its steps."""
        return not terminated and len(at_goal) > 0 and float(np.mean(at_goal)) >= SETTLED_FRACTION

    def observation_spec(self, physics) -> collections.OrderedDict:
        return collections.OrderedDict(
            state=specs.Array((4,), np.float64, name="state"),
            target=specs.BoundedArray((1,), np.float64, -PITCH_TARGET_LIMIT, PITCH_TARGET_LIMIT,
                                      name="target"))

    def observation_values(self, physics) -> list:
        speeds = physics.rotor_speeds()
        return [physics.pitch(), physics.pitch_velocity(), speeds[..., 0], speeds[..., 1],
                self._pitch_schedule.value]


class Track(Aero2Task):
    """Follow a pitch schedule and a yaw schedule at once (2-DOF helicopter).

    ## Action
    (front, back) thruster voltages (V), shape (2,), each in [-voltage_limit, voltage_limit] (18 V
    by default); larger values are clipped, NaN/inf or a wrong shape raise ValueError.

    ## Observation
    | key | index | value | unit | range |
    |---|---|---|---|---|
    | state | 0, 1 | pitch theta (front up), yaw psi (counter-clockwise from above) | rad | see Episode end |
    | state | 2, 3 | pitch rate, yaw rate | rad/s | a few rad/s |
    | state | 4, 5 | front, back rotor speeds | rad/s | +-414 at 24 V |
    | target | 0, 1 | target pitch, target yaw | rad | +-45, +-80 degrees |

    ## Reward
    max(0, 1 - |theta - theta_target| / 30 deg - |psi - psi_target| / 90 deg
    - 0.1 mean((V / voltage_limit)^2)) per step. Sparse: 1 with the pitch within 3 degrees and the
    yaw within 5 degrees of their targets, else 0.

    ## Start
    At rest, rotors stopped, yaw 0, pitch uniform in +-2 degrees.

    ## Episode end
    Terminates (discount 0) when |pitch| > 55 degrees or |yaw| > 360 degrees; truncated at the
    time limit. Success: at the goal (both tolerances) for 60 % of the steps.

    ## Arguments
    `voltage_limit`, `random`; each axis's schedule with the follow tasks' keywords
    (`qube_suite.tasks.follow.make_schedule`) prefixed by the axis: `pitch_target` ("steps": a new
    pitch in +-20 degrees every 4 s), `pitch_target_amplitude`, `pitch_target_hold_time`,
    `pitch_target_frequency`, `pitch_target_angle`; `yaw_target` ("steps": a new yaw in +-60
    degrees every 4 s), `yaw_target_amplitude`, `yaw_target_hold_time`, `yaw_target_frequency`,
    `yaw_target_angle`. Pitch targets stay within +-45 degrees, yaw targets within +-80.

    ## Version history
    v0: first release.
    """

    needs_yaw = True

    def __init__(self, pitch_target: str | os.PathLike = "steps", pitch_target_amplitude: float | None = None,
                 pitch_target_hold_time: float | None = None, pitch_target_frequency: float | None = None,
                 pitch_target_angle: float | None = None, yaw_target: str | os.PathLike = "steps",
                 yaw_target_amplitude: float | None = None, yaw_target_hold_time: float | None = None,
                 yaw_target_frequency: float | None = None, yaw_target_angle: float | None = None,
                 **kwargs):
        super().__init__(**kwargs)
        pitch = _schedule(pitch_target, TRACK_PITCH_AMPLITUDE, PITCH_TARGET_LIMIT, "pitch",
                          target_amplitude=pitch_target_amplitude, target_hold_time=pitch_target_hold_time,
                          target_frequency=pitch_target_frequency, target_angle=pitch_target_angle)
        yaw = _schedule(yaw_target, YAW_AMPLITUDE, TARGET_LIMIT, "yaw",
                        target_amplitude=yaw_target_amplitude, target_hold_time=yaw_target_hold_time,
                        target_frequency=yaw_target_frequency, target_angle=yaw_target_angle)
        self._pitch_schedule = pitch if self.worlds is None else pitch.batch(self.worlds)
        self._yaw_schedule = yaw if self.worlds is None else yaw.batch(self.worlds)
        self._schedule_random = self.random if self.worlds is None else self.randoms

    @property
    def target(self):
        """The (pitch, yaw) targets (rad), as an array of shape (2,) (or (worlds, 2) in a batch)."""
        return np.stack([np.asarray(self._pitch_schedule.value), np.asarray(self._yaw_schedule.value)],
                        axis=-1)

    def initial_state(self, random: np.random.RandomState) -> np.ndarray:
        return np.array([random.uniform(-START_PITCH, START_PITCH), 0.0, 0.0, 0.0, 0.0, 0.0])

    def initialize_episode(self, physics, world: int | None = None) -> None:
        super().initialize_episode(physics, world)
        random = self.random if world is None else self.randoms[world]
        self._pitch_schedule.reset(0.0, random, world)
        self._yaw_schedule.reset(0.0, random, world)

    def after_step(self, physics) -> None:
        self._pitch_schedule.update(physics.time(), self._schedule_random)
        self._yaw_schedule.update(physics.time(), self._schedule_random)

    def pitch_error(self, physics):
        """theta - theta_target (rad)."""
        return physics.pitch() - self._pitch_schedule.value

    def yaw_error(self, physics):
        """psi - psi_target (rad), not wrapped."""
        return physics.yaw() - self._yaw_schedule.value

    def dense_reward(self, physics):
        cost = _voltage_cost(physics, self.voltage_limit)
        return maximum(1.0 - abs(self.pitch_error(physics)) / PITCH_SCALE
                       - abs(self.yaw_error(physics)) / YAW_SCALE - cost, 0.0)

    def at_goal(self, physics):
        """Whether the pitch is within 3 degrees and the yaw within 5 degrees of their targets."""
        pitch_close = abs(self.pitch_error(physics)) <= PITCH_TOLERANCE
        return pitch_close & (abs(self.yaw_error(physics)) <= YAW_TOLERANCE)

    def succeeded(self, at_goal, terminated: bool, control_frequency: float) -> bool:
        """Whether the finished episode did not terminate and the Aero was at its goal for at least
        `SETTLED_FRACTION` of its steps."""
        return not terminated and len(at_goal) > 0 and float(np.mean(at_goal)) >= SETTLED_FRACTION

    def observation_spec(self, physics) -> collections.OrderedDict:
        limit = np.array([PITCH_TARGET_LIMIT, TARGET_LIMIT])
        return collections.OrderedDict(
            state=specs.Array((len(STATE_NAMES),), np.float64, name="state"),
            target=specs.BoundedArray((2,), np.float64, -limit, limit, name="target"))

    def observation_values(self, physics) -> list:
        speeds = physics.rotor_speeds()
        return [physics.pitch(), physics.yaw(), physics.pitch_velocity(), physics.yaw_velocity(),
                speeds[..., 0], speeds[..., 1], self._pitch_schedule.value, self._yaw_schedule.value]


class Hover(Track):
    """Hold the beam level and turn it to a yaw target (2-DOF helicopter).

    ## Action
    (front, back) thruster voltages (V), shape (2,), each in [-voltage_limit, voltage_limit] (18 V
    by default); larger values are clipped, NaN/inf or a wrong shape raise ValueError.

    ## Observation
    As the track task's: state [pitch, yaw, pitch rate, yaw rate, front and back rotor speeds]
    (rad, rad/s), target [0, psi_target] (rad).

    ## Reward
    max(0, 1 - |theta| / 30 deg - |psi - psi_target| / 90 deg - 0.1 mean((V / voltage_limit)^2))
    per step. Sparse: 1 with the pitch within 3 degrees of level and the yaw within 5 degrees of its
    target, else 0.

    ## Start
    At rest, rotors stopped, yaw 0, pitch uniform in +-10 degrees; the yaw target drawn for the
    episode (see Arguments).

    ## Episode end
    Terminates (discount 0) when |pitch| > 55 degrees or |yaw| > 360 degrees; truncated at the
    time limit. Success (`qube_suite.evaluation`): at the goal throughout the last 2 s.

    ## Arguments
    `voltage_limit`, `random`, `target_yaw` (rad, within +-80 degrees): a fixed yaw target; by
    default each episode draws one uniformly within +-60 degrees.

    ## Version history
    v0: first release.
    """

    def __init__(self, target_yaw: float | None = None, voltage_limit: float = RECOMMENDED_VOLTAGE,
                 sparse: bool = False, random: int | np.random.RandomState | None = None,
                 worlds: int | None = None):
        fixed_yaw = 0.0 if target_yaw is None else target_yaw
        super().__init__(pitch_target="fixed", pitch_target_angle=0.0, yaw_target="fixed",
                         yaw_target_angle=fixed_yaw, voltage_limit=voltage_limit, sparse=sparse,
                         random=random, worlds=worlds)
        if target_yaw is None:  # one target per episode: drawn at the start, never redrawn
            drawn = StepTargets(YAW_AMPLITUDE, math.inf)
            self._yaw_schedule = drawn if self.worlds is None else drawn.batch(self.worlds)

    def initial_state(self, random: np.random.RandomState) -> np.ndarray:
        return np.array([random.uniform(-HOVER_START_PITCH, HOVER_START_PITCH), 0.0, 0.0, 0.0, 0.0, 0.0])

    def succeeded(self, at_goal, terminated: bool, control_frequency: float) -> bool:
        """Whether the finished episode did not terminate and the Aero was at its goal throughout its
        last 2 s (`QubeTask.succeeded`)."""
        return QubeTask.succeeded(self, at_goal, terminated, control_frequency)


@SUITE.register("benchmarking")
def pitch(**kwargs) -> Pitch:
    return Pitch(**kwargs)


@SUITE.register("sparse")
def pitch_sparse(**kwargs) -> Pitch:
    return Pitch(sparse=True, **kwargs)


@SUITE.register("benchmarking")
def hover(**kwargs) -> Hover:
    return Hover(**kwargs)


@SUITE.register("sparse")
def hover_sparse(**kwargs) -> Hover:
    return Hover(sparse=True, **kwargs)


@SUITE.register("benchmarking")
def track(**kwargs) -> Track:
    return Track(**kwargs)


@SUITE.register("sparse")
def track_sparse(**kwargs) -> Track:
    return Track(sparse=True, **kwargs)
