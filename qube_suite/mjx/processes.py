"""The tasks' own processes on JAX: a rotor's revolution count, carried in the environment's state.

A task's rules read its processes' state (`QubeTask.process`); the numpy tasks keep
it themselves, the JAX environment carries it in its state and applies the task's
rules to it with `task.with_process`. How the state starts and advances is the
task's own definition (`RevolutionCount.started` and `advanced`), run on JAX arrays.
"""

from __future__ import annotations

import jax

from qube_suite.devices.qube.tasks.rotor import RevolutionCount


def first_process(task, physics, key: jax.Array):
    """The state of `task`'s processes at an episode's start, `physics` its first measured state
    (`environment.MeasuredQube`); `key` for the draws of random processes."""
    process = task.process
    if process is None:
        return None
    if isinstance(process, RevolutionCount):
        return RevolutionCount.started(physics.pendulum_angle())
    raise TypeError(f"no JAX process for {type(task).__name__}'s {type(process).__name__}")


def next_process(task, process, physics, key: jax.Array):
    """The state of `task`'s processes after a control step, `physics` the step's measured state."""
    if process is None:
        return None
    if isinstance(process, RevolutionCount):
        return process.advanced(physics.pendulum_angle())
    raise TypeError(f"no JAX process for {type(task).__name__}'s {type(process).__name__}")
