"""Observation history: a policy's inputs extended by its last k feature vectors and actions.

An adaptive policy sees, besides the features of the current observation, those
of the previous `length` observations and the voltages it applied after them,
so that it can tell the plant it is on (a heavier pendulum swings slower, more
friction answers a voltage less). Inputs are laid out as

    [features(t), features(t-1), ..., features(t-k), voltage(t-1), ..., voltage(t-k)]

with the current features first, so that a network trained without history
extends to one with history by zero weights on the new inputs
(`qube_suite.training.warm_start`). At an episode's first step the history is
the first features repeated, with zero voltages (the Qube at rest before it).
Training (`qube_suite.training.environments.VecHistory`) and inference
(`qube_suite.policies.mlp`) use this one class, so both see the same inputs.
"""

from __future__ import annotations

import numpy as np


def input_size(feature_size: int, length: int) -> int:
    """Network inputs for `feature_size` features per observation and a history of `length` steps."""
    return feature_size * (1 + length) + length


class History:
    """The last `length` feature vectors and voltages of each of `worlds` worlds (newest first)."""

    def __init__(self, length: int, worlds: int, feature_size: int, dtype: type = np.float64):
        if not (isinstance(length, int) and length >= 0):
            raise ValueError(f"history length must be an integer >= 0, got {length!r}")
        self.length = length
        self.features = np.zeros((worlds, length, feature_size), dtype=dtype)
        self.voltages = np.zeros((worlds, length), dtype=dtype)

    def start(self, features: np.ndarray, worlds: np.ndarray | slice = slice(None)) -> None:
        """Begin new episodes in `worlds` (indices or a mask) whose first features are `features`
        (one row per world started)."""
        self.features[worlds] = np.asarray(features)[:, None, :]
        self.voltages[worlds] = 0.0

    def push(self, features: np.ndarray, voltages: np.ndarray) -> None:
        """Record one step of every world: the features it acted on and the voltage (V) it applied."""
        if self.length == 0:
            return
        self.features[:, 1:] = self.features[:, :-1]
        self.voltages[:, 1:] = self.voltages[:, :-1]
        self.features[:, 0] = features
        self.voltages[:, 0] = voltages

    def inputs(self, features: np.ndarray, worlds: np.ndarray | slice = slice(None)) -> np.ndarray:
        """The network inputs of `worlds` whose current features are `features` (one row each)."""
        past = self.features[worlds]
        return np.concatenate([features, past.reshape(len(past), -1), self.voltages[worlds]], axis=1)
