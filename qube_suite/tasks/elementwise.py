"""Arithmetic that works alike on one Qube (Python floats), a batch of Qubes (numpy arrays) and
Qubes simulated with JAX (JAX arrays, `qube_suite.mjx`).

Task formulas use these where Python's builtins or `math` would not accept arrays,
so that one definition of a reward or a termination serves the single environments,
the vector environment and the JAX backend. Floats take the builtin path, which is the
fast one; numpy arrays the numpy path; any other array its own namespace by the array
API standard (`x.__array_namespace__()`), which JAX arrays provide.
"""

from __future__ import annotations

import math

import numpy as np


def array_namespace(*values):
    """The array API namespace of the first array among `values` (numpy for numpy arrays,
    `jax.numpy` for JAX arrays), or None when all are Python or numpy scalars."""
    for value in values:
        namespace = getattr(value, "__array_namespace__", None)
        if namespace is not None:
            return namespace()
    return None


def maximum(x, y):
    """The larger of `x` and `y`, elementwise for arrays."""
    if type(x) is float and type(y) is float:  # one Qube: the hot path, checked first
        return x if x >= y else y
    if type(x) is np.ndarray or type(y) is np.ndarray:  # type(), not isinstance: the float path is hot
        return np.maximum(x, y)
    namespace = array_namespace(x, y)
    if namespace is not None:
        return namespace.maximum(x, y)
    return x if x >= y else y


def cos(x):
    """cos(x), x in rad."""
    return math.cos(x) if type(x) is float else _elementwise("cos", x)


def sin(x):
    """sin(x), x in rad."""
    return math.sin(x) if type(x) is float else _elementwise("sin", x)


def _elementwise(name: str, x):
    """`math.<name>` of a number, or the array namespace's `<name>` of an array, elementwise."""
    if isinstance(x, np.ndarray):
        return getattr(np, name)(x)
    namespace = array_namespace(x)
    return getattr(math if namespace is None else namespace, name)(x)


def where(condition, x, y):
    """`x` where `condition` holds, else `y`, elementwise for arrays."""
    if type(condition) is bool:
        return x if condition else y
    if type(condition) is np.ndarray:
        return np.where(condition, x, y)
    namespace = array_namespace(condition)
    if namespace is not None:
        return namespace.where(condition, x, y)
    return x if condition else y
