"""Arithmetic that works alike on one Qube (Python floats) and on a batch of Qubes (numpy arrays).

Task formulas use these where Python's builtins or `math` would not accept arrays,
so that one definition of a reward or a termination serves the single environments
and the vector environment. Floats take the builtin path, which is the fast one.
"""

from __future__ import annotations

import math

import numpy as np


def maximum(x, y):
    """The larger of `x` and `y`, elementwise for arrays."""
    if type(x) is np.ndarray or type(y) is np.ndarray:  # type(), not isinstance: the float path is hot
        return np.maximum(x, y)
    return x if x >= y else y


def cos(x):
    """cos(x), x in rad."""
    return np.cos(x) if isinstance(x, np.ndarray) else math.cos(x)


def sin(x):
    """sin(x), x in rad."""
    return np.sin(x) if isinstance(x, np.ndarray) else math.sin(x)


def where(condition, x, y):
    """`x` where `condition` holds, else `y`, elementwise for arrays."""
    if type(condition) is np.ndarray:
        return np.where(condition, x, y)
    return x if condition else y
