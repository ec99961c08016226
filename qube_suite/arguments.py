"""Checking keyword arguments by name, so that a misspelt one is a ValueError listing the valid ones."""

from __future__ import annotations

import inspect
from collections.abc import Callable, Iterable


def keywords_of(function: Callable, skip: Iterable[str] = ()) -> tuple[str, ...]:
    """Names of the arguments `function` (or a class's constructor) takes by keyword, less `skip`."""
    kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    skipped = set(skip) | {"self"}
    return tuple(name for name, parameter in inspect.signature(function).parameters.items()
                 if parameter.kind in kinds and name not in skipped)


def check_keywords(given: Iterable[str], valid: Iterable[str], what: str) -> None:
    """Raise ValueError naming the keys of `given` that are not `valid`, and listing the valid ones.

    `what` names the arguments in the message, e.g. "task_kwargs".
    """
    valid = tuple(valid)
    unknown = sorted(set(given) - set(valid))
    if unknown:
        raise ValueError(f"unknown {what}: {', '.join(map(repr, unknown))}; valid: {', '.join(valid)}")
