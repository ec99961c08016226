"""Distributions of randomized values: uniform, normal or log-uniform; relative or absolute; clipped.

As data (a mapping in a config):

    {distribution: uniform, low: 0.9, high: 1.1}               # U(low, high)
    {distribution: normal, mean: 1.0, std: 0.05, clip: [0.8, 1.2]}
    {distribution: loguniform, low: 0.5, high: 2.0}            # exp U(ln low, ln high), 0 < low
    {distribution: uniform, low: 0.0, high: 1e-3, relative: false}

A relative draw scales the nominal value (value = nominal x draw); an absolute
draw is the value itself. `clip: [lower, upper]` bounds every draw (either may
be null), in the units of the draw.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping

import numpy as np

KINDS: dict[str, tuple[str, str]] = {
    "uniform": ("low", "high"),
    "normal": ("mean", "std"),
    "loguniform": ("low", "high"),
}
"""Distribution name -> its two numbers."""

def finite_number(value, where: str) -> float:
    """`value` as a float; a ValueError naming `where` unless it is a finite real number."""
    try:
        number = float(value) if isinstance(value, numbers.Real) and not isinstance(value, bool) else math.nan
    except OverflowError:  # an int beyond a float's range
        number = math.nan
    if not math.isfinite(number):
        shown = f"an integer of {len(str(value))} digits" if isinstance(value, int) else repr(value)
        raise ValueError(f"{where} must be a finite number, got {shown}")
    return number


def is_list(value, length: int) -> bool:
    """Whether `value` is a list (or tuple, array) of `length` entries."""
    return not isinstance(value, (str, bytes, Mapping)) and hasattr(value, "__len__") and len(value) == length


@dataclasses.dataclass(frozen=True)
class Distribution:
    """A distribution of one value (see the module docstring for the config form).

    `low`/`high` are set for uniform and loguniform, `mean`/`std` for normal;
    `clip` is (lower, upper), None where unbounded.
    """

    kind: str
    low: float | None = None
    high: float | None = None
    mean: float | None = None
    std: float | None = None
    clip: tuple[float | None, float | None] = (None, None)
    relative: bool = False
    integer: bool = False

    @classmethod
    def parse(cls, spec: Mapping, where: str, relative_default: bool | None,
              integer: bool = False) -> Distribution:
        """Validate a config mapping; `relative_default` None forbids the `relative` key;
        `integer`: only a uniform range of integers (both included) is allowed.

        Raises ValueError naming `where` for unknown keys or impossible ranges
        (low > high, negative std, log-uniform bounds <= 0, lower clip > upper clip,
        a clip that excludes the whole range).
        """
        if integer and not (spec.get("distribution") == "uniform" and "clip" not in spec
                            and all(isinstance(spec.get(key), int) for key in ("low", "high"))):
            raise ValueError(f"{where} takes an integer or {{distribution: uniform, low: <integer>, "
                             f"high: <integer>}} (both included), got {dict(spec)!r}")
        kind = spec.get("distribution")
        if kind not in KINDS:
            raise ValueError(f"{where}: 'distribution' must be one of {', '.join(KINDS)}, got {kind!r}")
        first, second = KINDS[kind]
        valid = ("distribution", first, second, "clip") + (() if relative_default is None else ("relative",))
        unknown = [key for key in spec if key not in valid]
        if unknown:
            raise ValueError(f"{where}: unknown key {unknown[0]!r} for a {kind} distribution; "
                             f"valid keys: {', '.join(valid)}")
        missing = [key for key in (first, second) if key not in spec]
        if missing:
            raise ValueError(f"{where}: a {kind} distribution needs {first!r} and {second!r}")
        a = finite_number(spec[first], f"{where}.{first}")
        b = finite_number(spec[second], f"{where}.{second}")
        if kind == "normal" and b < 0.0:
            raise ValueError(f"{where}: std must be >= 0, got {b:g}")
        if kind != "normal" and a > b:
            raise ValueError(f"{where}: low ({a:g}) must not exceed high ({b:g})")
        if kind == "loguniform" and a <= 0.0:
            raise ValueError(f"{where}: a loguniform distribution needs 0 < low, got low = {a:g}")
        clip = _parse_clip(spec.get("clip"), f"{where}.clip")
        relative = spec.get("relative", relative_default)
        if relative_default is not None and not isinstance(relative, bool):
            raise ValueError(f"{where}.relative must be true or false, got {relative!r}")
        values = {"mean": a, "std": b} if kind == "normal" else {"low": a, "high": b}
        distribution = cls(kind, clip=clip, relative=bool(relative), integer=integer, **values)
        lower, upper = clip
        if kind != "normal" and ((lower is not None and lower > b) or (upper is not None and upper < a)):
            raise ValueError(f"{where}: clip [{lower}, {upper}] excludes the whole range [{a:g}, {b:g}]")
        return distribution

    def bounds(self, nominal: float = 1.0) -> tuple[float, float]:
        """Smallest and largest value a draw can give (relative draws scaled by `nominal` >= 0)."""
        lower, upper = (-math.inf, math.inf) if self.kind == "normal" else (self.low, self.high)
        clip_lower, clip_upper = self.clip
        lower = lower if clip_lower is None else max(lower, clip_lower)
        upper = upper if clip_upper is None else min(upper, clip_upper)
        return (lower * nominal, upper * nominal) if self.relative else (lower, upper)

    def sample(self, random: np.random.RandomState, nominal: float = 1.0) -> float | int:
        """One draw from `random`: the value itself, or `nominal` times the draw if relative."""
        if self.kind == "normal":
            value = self.mean + self.std * random.standard_normal()
        else:
            u = random.random_sample()
            if self.integer:
                return int(self.low + math.floor(u * (self.high - self.low + 1.0)))
            if self.kind == "uniform":
                value = self.low + (self.high - self.low) * u
            else:
                value = math.exp(math.log(self.low) + (math.log(self.high) - math.log(self.low)) * u)
        lower, upper = self.clip
        if lower is not None and value < lower:
            value = lower
        if upper is not None and value > upper:
            value = upper
        return float(value * nominal if self.relative else value)

    def __str__(self) -> str:
        """Compact form, e.g. `x U(0.9, 1.1)` (x: relative to nominal) or `N(0, 0.1) in [-0.2, 0.2]`."""
        if self.kind == "normal":
            text = f"N({self.mean:g}, {self.std:g})"
        elif self.low == self.high:
            text = f"{self.low:g}"
        elif self.integer:
            text = f"U{{{self.low:g}..{self.high:g}}}"
        else:
            text = f"{'logU' if self.kind == 'loguniform' else 'U'}({self.low:g}, {self.high:g})"
        if self.clip != (None, None):
            lower, upper = ("" if bound is None else f"{bound:g}" for bound in self.clip)
            text += f" in [{lower}, {upper}]"
        return f"x {text}" if self.relative else text


def fixed(value: float) -> Distribution:
    """The distribution that always gives `value` (absolute)."""
    return Distribution("uniform", low=value, high=value)


def _parse_clip(clip, where: str) -> tuple[float | None, float | None]:
    if clip is None:
        return None, None
    if not is_list(clip, 2):
        raise ValueError(f"{where} must be [lower, upper] (either may be null), got {clip!r}")
    lower, upper = (None if bound is None else finite_number(bound, where) for bound in clip)
    if lower is not None and upper is not None and lower > upper:
        raise ValueError(f"{where}: lower bound {lower:g} exceeds upper bound {upper:g}")
    return lower, upper
