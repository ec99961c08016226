"""The effect interface: a sensor or actuator imperfection that any Qube domain can apply to n Qubes.

An effect transforms one signal once per control step, for n Qubes at once, on
float64 arrays with one row per Qube: states of shape (n, 4), each
[theta, alpha, dtheta, dalpha] (rad, rad/s; angles wrapped to (-pi, pi]), and
motor voltages (V) or step durations (s) of shape (n,). A single Qube is a batch
of one (`OneRow` applies effects to one Qube's floats):

    y = effect.reset(x, rows=None)   # start afresh from x (the initial state, or 0 V); the output for x
    y = effect(x)                    # the output one control step later

Settings are numbers shared by every Qube, or arrays with one entry per Qube
along their first axis; memory (delay lines, filter states) lives in arrays
shaped by the signal given to `reset`. `effect.reset(x, rows)` restarts only the
Qubes `rows` (integer indices) from their signals `x` (first axis len(rows)) and
returns their outputs; the others keep their memory. A caller that redraws the
settings of some Qubes gives them to those rows first with
`effect.set_rows(rows, fresh)`, where `fresh` is the same effect built for
len(rows) Qubes. Stochastic effects draw from one generator, or from `Streams`,
one generator per Qube, so that each Qube draws the numbers it would alone.
Effects never modify their input. `Chain` applies several effects in order.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import ClassVar

import numpy as np


@dataclasses.dataclass(frozen=True)
class Field:
    """One setting of an effect as a config gives it: unit, default and allowed values.

    `default` None means required, unless `optional` (the effect's `complete`
    decides then). `size` > 0: a list of that many fixed numbers; otherwise one
    number or, per episode, a distribution (integers: a uniform integer range).
    """

    unit: str
    description: str
    default: float | None = None
    optional: bool = False
    minimum: float = -math.inf
    maximum: float = math.inf
    exclusive_minimum: bool = False
    integer: bool = False
    size: int = 0

    def allows(self, lower: float, upper: float) -> bool:
        """Whether every value in [lower, upper] is allowed."""
        above = lower > self.minimum if self.exclusive_minimum else lower >= self.minimum
        return above and upper <= self.maximum

    def describe_range(self) -> str:
        """The allowed values in words, e.g. `> 0` or `in [0, 0.5]`."""
        if self.maximum < math.inf:
            return f"in [{self.minimum:g}, {self.maximum:g}]"
        return f"{'>' if self.exclusive_minimum else '>='} {self.minimum:g}"


class Effect:
    """Base of the effects (see the module docstring for the interface).

    Subclasses set `name` (their key in a config's `effects`), `signal` (what they
    transform: "state", "voltage" or "duration"), `fields` and `stochastic`
    (whether they draw from a generator), and implement `output` if they have no
    memory, or `reset` and `__call__` if they do.
    """

    name: ClassVar[str]
    signal: ClassVar[str]
    fields: ClassVar[dict[str, Field]]
    stochastic: ClassVar[bool] = False
    per_env_settings: ClassVar[tuple[str, ...]] = ()
    """Attributes holding the settings, one entry per environment along their first axis on n Qubes."""

    @classmethod
    def complete(cls, settings: dict) -> dict:
        """Settings with what depends on several fields resolved; ValueError if inconsistent."""
        return settings

    @classmethod
    def from_settings(cls, settings: Mapping, control_period: float, rng) -> Effect:
        """The effect for one episode's `settings` at `control_period` (s); stochastic effects
        draw from `rng` (a numpy Generator or RandomState)."""
        return cls(**settings)

    def set_rows(self, rows: np.ndarray, fresh: Effect) -> None:
        """Give environments `rows` the settings of `fresh`, this effect built for len(rows)
        environments; their memory restarts at the next `reset(x, rows)`."""
        for attribute in self.per_env_settings:
            getattr(self, attribute)[rows] = getattr(fresh, attribute)

    def reset(self, x: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        return self.output(x, rows)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return self.output(x, None)

    def output(self, x: np.ndarray, rows: np.ndarray | None) -> np.ndarray:
        """Output for the arrays `x` of a memoryless effect; `rows` selects per-environment settings."""
        raise NotImplementedError


def per_env(setting: np.ndarray, rows: np.ndarray | None, shared_ndim: int = 0) -> np.ndarray:
    """`setting`, or its entries for `rows` when it holds one per environment (ndim > `shared_ndim`)."""
    return setting if rows is None or setting.ndim == shared_ndim else setting[rows]


class Streams:
    """One random generator per environment, drawn from as one generator by effects on n Qubes.

    Row i of every draw comes from generator i, so each environment gets the numbers
    its own generator gives the one-Qube path (`standard_normal(4)`, `random()`).
    """

    def __init__(self, generators: Sequence[np.random.RandomState]):
        self.generators = tuple(generators)

    def rows(self, rows: np.ndarray) -> Streams:
        """The generators of environments `rows`."""
        return Streams([self.generators[row] for row in rows.tolist()])

    def standard_normal(self, shape: tuple[int, ...]) -> np.ndarray:
        """Standard normal draws of `shape`, (environments, ...)."""
        size = shape[1:] or None
        return _stacked([generator.standard_normal(size) for generator in self.generators], shape)

    def random(self, shape: tuple[int, ...]) -> np.ndarray:
        """Uniform draws in [0, 1) of `shape`, (environments, ...)."""
        size = shape[1:] or None
        return _stacked([generator.random(size) for generator in self.generators], shape)


def _stacked(draws: list, shape: tuple[int, ...]) -> np.ndarray:
    """Each environment's draw (a float, or an array of shape[1:]) in one array of `shape`."""
    if len(shape) == 1 or not draws:
        return np.array(draws, dtype=np.float64).reshape(shape)
    return np.concatenate(draws).reshape(shape)  # far faster than np.array of many small arrays


def generator_of(rng, rows: np.ndarray | None):
    """`rng`, or the generators of `rows` when it holds one per environment (`Streams`)."""
    return rng.rows(rows) if rows is not None and isinstance(rng, Streams) else rng


class Chain:
    """Effects applied in order to the signals of n Qubes (float64 arrays, one row per Qube): a
    domain's sensor, actuator or step-duration model; itself an effect."""

    def __init__(self, effects: Iterable[Effect]):
        self.effects = tuple(effects)

    def reset(self, x, rows: np.ndarray | None = None) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        for effect in self.effects:
            x = effect.reset(x, rows)
        return x

    def __call__(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        for effect in self.effects:
            x = effect(x)
        return x


class OneRow:
    """A `Chain` applied to one Qube's signal as a batch of one: Python floats in and out (4 for a
    state, 1 for a voltage or a duration), the hook contract of one-Qube domains (`set_sensor_model`,
    `set_actuator_model`, `set_step_duration_model`)."""

    def __init__(self, chain: Chain):
        self.chain = chain

    def reset(self, x):
        return self.chain.reset(np.array([x], dtype=np.float64))[0].tolist()

    def __call__(self, x):
        return self.chain(np.array([x], dtype=np.float64))[0].tolist()
