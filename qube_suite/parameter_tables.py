"""A device's table of physical parameters: rows by long name, and values checked against it.

Each device's `parameters.py` holds its rows (`Parameter`: long name, symbol, nominal value,
unit, description) and the names that may be zero; `resolve` gives its nominal values with
overrides by long name, refusing a misspelt name by listing the valid ones.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Collection, Mapping
from typing import Any


@dataclasses.dataclass(frozen=True)
class Parameter:
    """One named physical parameter."""

    name: str
    symbol: str
    nominal: float
    unit: str
    description: str


def resolve(table: Mapping[str, Parameter], may_be_zero: Collection[str],
            overrides: Mapping[str, Any] | None = None) -> dict[str, float]:
    """The nominal values of `table` updated by `overrides` (by long name).

    Raises ValueError for an unknown name (listing the valid ones), a non-number, or a value that is
    not finite, negative, or zero where zero is impossible (names outside `may_be_zero`).
    """
    values = {name: row.nominal for name, row in table.items()}
    for name, value in (overrides or {}).items():
        if name not in table:
            raise ValueError(f"unknown parameter {name!r}; valid names: {', '.join(table)}")
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise ValueError(f"parameter {name!r} must be a number, got {value!r}")
        value = float(value)
        zero_allowed = name in may_be_zero
        if not math.isfinite(value) or value < 0.0 or (value == 0.0 and not zero_allowed):
            raise ValueError(f"parameter {name!r} must be finite and {'>= 0' if zero_allowed else '> 0'}, "
                             f"got {value}")
        values[name] = value
    return values
