"""Checking keyword arguments by name, so that a misspelt one is an error listing the valid ones."""

from __future__ import annotations

import inspect
import numbers
from collections.abc import Callable, Iterable, Mapping

import numpy as np


class UnknownKeywordError(TypeError, ValueError):
    """An unknown keyword argument: a TypeError, as Python raises for one (clients such as TorchRL's
    `GymEnv` retry without an optional keyword on TypeError), and a ValueError, as qube_suite raises
    for every other bad argument."""


def is_number(value) -> bool:
    """Whether `value` is a real number: int, float or a numpy scalar of either, not a bool."""
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def check_seed(random) -> None:
    """Raise ValueError unless `random` is None, a non-negative integer or a numpy RandomState."""
    if random is None or isinstance(random, np.random.RandomState):
        return
    if not (isinstance(random, numbers.Integral) and not isinstance(random, (bool, np.bool_))
            and 0 <= random < 2**32):
        raise ValueError(f"random must be None, an integer seed in [0, 2**32) or a numpy RandomState, "
                         f"got {random!r}")


def keywords_of(function: Callable, skip: Iterable[str] = ()) -> tuple[str, ...]:
    """Names of the arguments `function` (or a class's constructor) takes by keyword, less `skip`."""
    kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    skipped = set(skip) | {"self"}
    return tuple(name for name, parameter in inspect.signature(function).parameters.items()
                 if parameter.kind in kinds and name not in skipped)


def check_keywords(given: Iterable[str], valid: Iterable[str], what: str) -> None:
    """Raise UnknownKeywordError (a TypeError and a ValueError) naming the keys of `given` that are
    not `valid`, and listing the valid ones.

    `what` names what takes the arguments in the message, e.g. "task_kwargs".
    """
    valid = tuple(valid)
    unknown = sorted(set(given) - set(valid))
    if unknown:
        # Python's wording ("got an unexpected keyword argument 'x'"), which clients match on.
        names = "an unexpected keyword argument" if len(unknown) == 1 else "unexpected keyword arguments"
        raise UnknownKeywordError(f"{what} got {names} {', '.join(map(repr, unknown))}; "
                                  f"valid: {', '.join(valid)}")


def checked_controller(controllers: Mapping[str, type], name: str, kwargs: Iterable[str]) -> type:
    """The class called `name` in a device's `controllers` (name -> class), once `name` and the keyword
    arguments `kwargs` are known to it; ValueError listing the valid ones otherwise."""
    if name not in controllers:
        raise ValueError(f"unknown controller {name!r}; valid controllers: {', '.join(controllers)}")
    cls = controllers[name]
    check_keywords(kwargs, keywords_of(cls), f"keyword arguments of controller {name!r}")
    return cls
