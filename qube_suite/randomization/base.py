"""The effect interface: a sensor or actuator imperfection that any Qube domain can apply, to one or n Qubes.

An effect transforms one signal once per control step:

    y = effect.reset(x)    # start afresh from x (the initial state, or 0 V); the output for x
    y = effect(x)          # the output one control step later

Signals are float64 arrays: a state [theta, alpha, dtheta, dalpha] (rad, rad/s;
angles wrapped to (-pi, pi]) of shape (4,), or (n, 4) for n environments; a motor
voltage (V) or a step duration (s) of shape (), or (n,). Settings are numbers
shared by all environments, or arrays with one entry per environment along their
first axis. Memory (delay lines, filter states) lives in arrays shaped by the
signal given to `reset`. `effect.reset(x, rows)` restarts only the environments
`rows` (integer indices) from their signals `x` (first axis len(rows)) and returns
their outputs; the others keep their memory (a caller that redraws per-environment
settings writes them into the setting arrays first). Effects never modify their
input.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping
from typing import ClassVar

import numpy as np

SIGNALS = ("state", "voltage", "duration")
"""What an effect transforms: the measured state, the motor voltage, the control period."""


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

    Subclasses set `name` (their key in a config's `effects`), `signal` (one of
    SIGNALS), `fields` and `stochastic` (whether they draw from a generator), and
    implement `output` if they have no memory, or `reset` and `__call__` if they do.
    """

    name: ClassVar[str]
    signal: ClassVar[str]
    fields: ClassVar[dict[str, Field]]
    stochastic: ClassVar[bool] = False

    @classmethod
    def complete(cls, settings: dict) -> dict:
        """Settings with what depends on several fields resolved; ValueError if inconsistent."""
        return settings

    @classmethod
    def from_settings(cls, settings: Mapping, control_period: float,
                      rng: np.random.Generator | None) -> Effect:
        """The effect for one episode's `settings` at `control_period` (s), drawing from `rng`."""
        return cls(**settings)

    def reset(self, x: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        return self.output(x, rows)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return self.output(x, None)

    def output(self, x: np.ndarray, rows: np.ndarray | None) -> np.ndarray:
        """Output for `x` of a memoryless effect; `rows` selects per-environment settings."""
        raise NotImplementedError


def per_env(setting: np.ndarray, rows: np.ndarray | None, shared_ndim: int = 0) -> np.ndarray:
    """`setting`, or its entries for `rows` when it holds one per environment (ndim > `shared_ndim`)."""
    return setting if rows is None or setting.ndim == shared_ndim else setting[rows]


class Chain:
    """Effects applied in order, itself an effect; a domain's sensor or actuator model.

    Takes any array-like signal (a tuple of 4 floats, a float) and returns a float64 array.
    """

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
