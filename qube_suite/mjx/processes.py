"""The tasks' own processes on JAX: a rotor's revolution count and a follow task's target, carried in
the environment's state.

A task's rules read its processes' state (`QubeTask.process`); the numpy tasks keep
it themselves, the JAX environment carries it in its state and applies the task's
rules to it with `task.with_process`. How the state starts and advances is the
task's own definition, run on JAX arrays: `RevolutionCount.started` and `advanced`;
a schedule's `at(time)`, or for a random one its `due`, `target_from` and
`change_after`, fed with `jax.random` variates of the distributions numpy draws
(uniform in [0, 1), standard exponential). Only the random stream differs: a world
draws its targets from its JAX key, as it draws its start.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from qube_suite.devices.qube.tasks.rotor import RevolutionCount
from qube_suite.tasks.follow import RandomTargets, TargetState, TimedTargets


def check(task) -> None:
    """ValueError unless this module advances `task`'s processes."""
    process = task.process
    if process is None or isinstance(process, RevolutionCount) or (
            isinstance(process, TargetState) and isinstance(task.schedule, (TimedTargets, RandomTargets))):
        return
    raise ValueError(f"the JAX backend has no transition for {type(task).__name__}'s processes "
                     f"({type(process).__name__})")


def first_process(task, physics, key: jax.Array):
    """The state of `task`'s processes at an episode's start (time 0), `physics` its first measured state
    (`environment.MeasuredQube`); `key` for the draws of random processes."""
    process = task.process
    if process is None:
        return None
    if isinstance(process, RevolutionCount):
        return RevolutionCount.started(physics.pendulum_angle())
    if isinstance(process, TargetState):
        schedule, time = task.schedule, jnp.zeros_like(physics.arm_angle())
        if isinstance(schedule, TimedTargets):
            return _timed_target(schedule, time)
        if isinstance(schedule, RandomTargets):
            return _drawn_target(schedule, time, time, key)
    raise TypeError(f"no JAX process for {type(task).__name__}'s {type(process).__name__}")


def next_process(task, process, physics, key: jax.Array):
    """The state of `task`'s processes after a control step, `physics` the step's measured state and
    episode time."""
    if process is None:
        return None
    if isinstance(process, RevolutionCount):
        return process.advanced(physics.pendulum_angle())
    if isinstance(process, TargetState):
        schedule, time = task.schedule, physics.time()
        if isinstance(schedule, TimedTargets):
            return _timed_target(schedule, time)
        if isinstance(schedule, RandomTargets):
            drawn = _drawn_target(schedule, process.next_change, time, key)
            due = schedule.due(time, process.next_change)
            return jax.tree.map(lambda new, kept: jnp.where(due, new, kept), drawn, process)
    raise TypeError(f"no JAX process for {type(task).__name__}'s {type(process).__name__}")


def _timed_target(schedule: TimedTargets, time: jax.Array) -> TargetState:
    """A schedule's target at `time` (s), as an array of the time's dtype (a fixed target's is a number)."""
    time = jnp.asarray(time)
    return TargetState(jnp.asarray(schedule.at(time), time.dtype))


def _drawn_target(schedule: RandomTargets, due: jax.Array, time: jax.Array, key: jax.Array) -> TargetState:
    """A random schedule's target drawn at `time` (s), which was due at `due`, and its next change."""
    time = jnp.asarray(time)
    uniform_key, exponential_key = jax.random.split(key)
    value = schedule.target_from(jax.random.uniform(uniform_key, dtype=time.dtype))
    exponential = jax.random.exponential(exponential_key, dtype=time.dtype) if schedule.random_hold else None
    return TargetState(value, schedule.change_after(due, time, exponential))
