"""The effect interface: a sensor or actuator imperfection that any Qube domain can apply to n Qubes.

An effect transforms one signal once per control step: states [theta, alpha,
dtheta, dalpha] (rad, rad/s; angles wrapped to (-pi, pi]), motor voltages (V) or
step durations (s), of one Qube as Python floats (4 for a state, 1 otherwise) or of
n Qubes as float64 arrays with one row per Qube, (n, 4) or (n,):

    y = effect.reset(x, rows=None)   # start afresh from x (the initial state, or 0 V); the output for x
    y = effect(x)                    # the output one control step later

Each effect's maths is written once, elementwise: it computes on a state's four
components (`inward`), each a float for one Qube or a column of n values,
and on a voltage or duration as a float or an array, so the same lines serve one
Qube (fast Python arithmetic) and a batch (numpy).

Settings are numbers shared by every Qube (one Qube's are numbers), or arrays
with one entry per Qube along their first axis; memory (delay lines, filter
states) takes the form of the signal given to `reset`. `effect.reset(x, rows)`
restarts only the Qubes `rows` (integer indices) from their signals `x` (first
axis len(rows)) and returns their outputs; the others keep their memory. A caller
that redraws the settings of some Qubes gives them to those rows first with
`effect.set_rows(rows, fresh)`, where `fresh` is the same effect built for
len(rows) Qubes (for one Qube: built with its numbers). Stochastic effects draw
from one generator, or from `Streams`, one generator per Qube, so that each Qube
draws the numbers it would alone. Effects never modify their input. `Chain`
applies several effects in order.
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
    memory, or `start` and `advance` if they do: on the signal in the form `inward`
    gives, elementwise, so that one Qube's floats and arrays take the same lines.
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
        environments; their memory restarts at the next `reset(x, rows)`. Settings held as
        numbers (one Qube's) are replaced."""
        for attribute in self.per_env_settings:
            setting = getattr(self, attribute)
            if type(setting) is np.ndarray:
                setting[rows] = getattr(fresh, attribute)
            else:
                setattr(self, attribute, getattr(fresh, attribute))

    def reset(self, x, rows: np.ndarray | None = None):
        return outward(self.start(inward(x, self.signal), rows), x, self.signal)

    def __call__(self, x):
        return outward(self.advance(inward(x, self.signal)), x, self.signal)

    def start(self, x, rows: np.ndarray | None):
        """`reset` on the signal in the form effects compute on (`inward`)."""
        return self.output(x, rows)

    def advance(self, x):
        """`__call__` on the signal in the form effects compute on (`inward`)."""
        return self.output(x, None)

    def output(self, x, rows: np.ndarray | None):
        """Output of a memoryless effect for the signal `x` (`inward`'s form); `rows` selects
        per-environment settings."""
        raise NotImplementedError


def inward(x, signal: str):
    """A signal in the form effects compute on: one Qube's floats as they are; arrays copied, a
    state's split into its four components (`components`)."""
    if type(x) is not np.ndarray:
        return x
    if signal != "state":
        return np.array(x, dtype=np.float64)
    return x.tolist() if x.ndim == 1 else list(np.array(x.T, dtype=np.float64))  # (4, n), C order


def outward(y, x, signal: str):
    """The output `y` of effects on the signal `x` in the form of `x` (inverse of `inward`)."""
    if type(x) is not np.ndarray:
        return y
    if signal != "state":
        return np.array(y, dtype=np.float64)
    return np.stack(y, axis=-1) if x.ndim > 1 else np.array(y, dtype=np.float64)


def components(values):
    """The four components of a state-shaped setting or draw: floats from a list or a 1-D array
    (one Qube's, or shared), columns from an (n, 4) array."""
    if type(values) is not np.ndarray:
        return values
    return values.tolist() if values.ndim == 1 else list(values.T)


def number_or_array(value, dtype=np.float64):
    """A setting as effects hold it: a Python number if it is one (shared by every Qube, or one
    Qube's), else an array with one entry per Qube."""
    array = np.asarray(value, dtype=dtype)
    return array.item() if array.ndim == 0 else array


def shape(x) -> tuple[int, ...]:
    """The shape of a signal's value: () for one Qube's float, (n,) for n Qubes' array."""
    return x.shape if type(x) is np.ndarray else ()


def per_env(setting, rows: np.ndarray | None):
    """`setting`, or its entries for `rows` when it holds one per environment (an array)."""
    return setting[rows] if rows is not None and type(setting) is np.ndarray else setting


def with_rows(memory, rows: np.ndarray, values):
    """A copy of the per-environment `memory` (an array) with `values` at `rows`; copying keeps
    outputs that share the old array unchanged."""
    memory = memory.copy()
    memory[rows] = values
    return memory


# Elementwise arithmetic on one Qube's floats (Python's, the fast path) or on arrays (numpy's).

def rint(x):
    """x rounded to the nearest integer, halves to even (as a float for arrays, an int for floats)."""
    return np.rint(x) if type(x) is np.ndarray else round(x)


def maximum(x, y):
    """The larger of `x` and `y`, elementwise for arrays."""
    if type(x) is np.ndarray or type(y) is np.ndarray:
        return np.maximum(x, y)
    return max(x, y)


def copysign(x, y):
    """|x| with the sign of `y`."""
    if type(x) is np.ndarray or type(y) is np.ndarray:
        return np.copysign(x, y)
    return math.copysign(x, y)


def clip(x, low, high):
    """`x` limited to [low, high]."""
    if type(x) is np.ndarray or type(low) is np.ndarray:
        return np.clip(x, low, high)
    return min(max(x, low), high)


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
    """Effects on one signal applied in order: a domain's sensor, actuator or step-duration model;
    itself an effect, on one Qube's floats (the hook contract of one-Qube domains,
    `set_sensor_model`, ...) or on arrays with one row per Qube (a batch's)."""

    def __init__(self, effects: Iterable[Effect]):
        self.effects = tuple(effects)
        self.signal = self.effects[0].signal if self.effects else None

    def reset(self, x, rows: np.ndarray | None = None):
        one = type(x) is not np.ndarray  # one Qube's floats, the form effects compute on
        y = x if one else inward(x, self.signal)
        for effect in self.effects:
            y = effect.start(y, rows)
        return y if one else outward(y, x, self.signal)

    def __call__(self, x):
        one = type(x) is not np.ndarray
        y = x if one else inward(x, self.signal)
        for effect in self.effects:
            y = effect.advance(y)
        return y if one else outward(y, x, self.signal)
