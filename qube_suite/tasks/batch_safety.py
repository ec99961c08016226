"""The batch-safety rule: a task means the same for one Qube and for a batch of Qubes.

The vector environment evaluates a task made with `worlds=N` on arrays, one value
per world; the single environments evaluate it on floats. A task is batch-safe when
every method it runs in an episode (`initialize_episode`, `before_step`,
`after_step`, `get_reward`, `in_safe_set`, `observation_values`) gives, for a batch,
world by world what it gives for one Qube in that world's state. Formulas written
with numpy functions and operators are; `math.exp`, builtin `min`/`max` or an `if`
on a value are not (docs/write-a-task.md).

`check_batch_safety(factory)` proves it on two worlds against two single Qubes, with
a stand-in for the domain (`ProbeQubes`, no simulation), and raises
`BatchSafetyError` naming the first method that differs. Registering a task
(`qube_suite.tasks.register`) runs it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

PROBE_STATES = np.array([[0.3, 2.8, 1.5, -4.0],
                         [-1.9, -0.1, -0.7, 6.0]])
"""[theta, alpha, dtheta, dalpha] (rad, rad/s) of the two probe worlds: one swinging near hanging
within the arm's range, one near upright beyond it."""
PROBE_TIMES = np.array([0.52, 1.37])
"""Time (s) of the two probe worlds, both past the start."""
PROBE_ACTIONS = np.array([[1.25], [-40.0]])
"""Actions (V) of the two probe worlds: one inside any voltage limit, one beyond (every motor of a
device with several gets the same)."""


class BatchSafetyError(TypeError):
    """A task's method gives a batch of Qubes something else than it gives each Qube alone."""


class ProbeQubes:
    """A stand-in for the domain that holds given states: one Qube (`worlds` None, floats) or a
    batch (arrays, one value per world). It has the domain interface's accessors, nothing moves."""

    latency_steps = 0
    physics_error = None

    def __init__(self, states: np.ndarray, times, worlds: int | None):
        self._states = np.array(states, dtype=np.float64)
        self._times = times
        self._worlds = worlds
        self._voltage = 0.0 if worlds is None else np.zeros(worlds)

    def _column(self, index: int):
        return float(self._states[index]) if self._worlds is None else self._states[:, index].copy()

    def arm_angle(self):
        return self._column(0)

    def pendulum_angle(self):
        return self._column(1)

    def arm_velocity(self):
        return self._column(2)

    def pendulum_velocity(self):
        return self._column(3)

    def qube_state(self) -> np.ndarray:
        return self._states.copy()

    def time(self):
        return self._times

    def voltage(self):
        return self._voltage

    def applied_voltage(self):
        return self._voltage

    def set_voltage(self, volts) -> None:
        self._voltage = volts

    def set_led(self, rgb: Sequence[float]) -> None:
        pass

    def reset_to(self, state: Sequence[float]) -> None:
        self._states = np.array(state, dtype=np.float64)

    def reset_world(self, world: int, state: Sequence[float]) -> None:
        self._states[world] = state

    def move_to(self, states: np.ndarray, times) -> None:
        """Put the Qube(s) in `states` at `times` (s)."""
        self._states, self._times = np.array(states, dtype=np.float64), times


def check_batch_safety(factory: Callable, name: str | None = None, seed: int = 0,
                       probe: type[ProbeQubes] | None = None, probe_states: np.ndarray | None = None) -> None:
    """Raise `BatchSafetyError` unless the task `factory(**kwargs)` makes is batch-safe.

    `factory` is a task class or a function taking the task keywords (`random`, `worlds`);
    `name`: the task's registered name, for the message. The batch task
    (`worlds=2`, seeded `seed`) is compared, method by method in an episode's order, with two
    single tasks seeded `seed` and `seed + 1`, each in the state of its world. `probe` and
    `probe_states`: the stand-in for another device's domain (a `ProbeQubes` subclass with that
    device's accessors) and the states of its two worlds; default: the pendulum's.
    """
    probe = ProbeQubes if probe is None else probe
    probe_states = PROBE_STATES if probe_states is None else probe_states
    worlds = len(probe_states)
    batch_task = factory(random=seed, worlds=worlds)
    singles = [factory(random=seed + world) for world in range(worlds)]
    owner = type(batch_task).__name__ if name is None else f"task {name!r}: {type(batch_task).__name__}"
    batch = probe(np.zeros(probe_states.shape), np.zeros(worlds), worlds)
    qubes = [probe(np.zeros(probe_states.shape[1]), 0.0, None) for _ in range(worlds)]

    def compare(method: str, call: Callable) -> None:
        expected = np.stack([_per_world(call(task, qube)) for task, qube in zip(singles, qubes, strict=True)])
        try:
            got = _per_world(call(batch_task, batch))
            got = np.broadcast_to(got, expected.shape)
        except Exception as error:
            raise BatchSafetyError(
                f"{owner}.{method} is not batch-safe: for a batch of {worlds} Qubes it raised "
                f"{type(error).__name__}: {error}. Write it with numpy functions and operators (np.exp, "
                "np.abs, np.where, np.maximum), which take arrays with one value per Qube; see "
                "docs/write-a-task.md, 'Batch safety'") from error
        if not np.allclose(got, expected, rtol=1e-9, atol=1e-12, equal_nan=True):
            raise BatchSafetyError(
                f"{owner}.{method} is not batch-safe: for a batch of {worlds} Qubes it gave "
                f"{got.tolist()} where each Qube alone gives {expected.tolist()}; see "
                "docs/write-a-task.md, 'Batch safety'")

    def initialize_episode(task, physics):
        if physics is batch:
            for world in range(worlds):
                task.initialize_episode(physics, world)
        else:
            task.initialize_episode(physics)
        return physics.qube_state()

    actions = np.broadcast_to(PROBE_ACTIONS, (worlds, *batch_task.action_shape)).copy()

    def before_step(task, physics):
        task.before_step(actions if physics is batch else actions[qubes.index(physics)], physics)
        return physics.voltage()

    def after_step(task, physics):  # seen through what it changes: the observation
        task.after_step(physics)
        return task.observation_values(physics)

    compare("initialize_episode", initialize_episode)
    batch.move_to(probe_states, PROBE_TIMES.copy())
    for world, qube in enumerate(qubes):
        qube.move_to(probe_states[world], float(PROBE_TIMES[world]))
    compare("observation_values", lambda task, physics: task.observation_values(physics))
    compare("before_step", before_step)
    compare("after_step", after_step)
    compare("get_reward", lambda task, physics: task.get_reward(physics))
    compare("in_safe_set", lambda task, physics: task.in_safe_set(physics))


def _per_world(result) -> np.ndarray:
    """A method's result as float64, a list of values (an observation) with the world as first axis."""
    if isinstance(result, list):
        values = (np.asarray(value, dtype=np.float64) for value in result)
        return np.stack(np.broadcast_arrays(*values), axis=-1)
    return np.asarray(result, dtype=np.float64)
