"""Start-state distributions of the tasks, as data that every backend draws from.

A task says where its episodes start with one of these; the numpy domains draw
with `draw(random)` (a `numpy.random.RandomState`), the JAX backend
(`qube_suite.mjx`) draws from the same numbers with `jax.random`. States are
[theta, alpha, dtheta, dalpha] (rad, rad/s).
"""

from __future__ import annotations

import dataclasses

import numpy as np


@dataclasses.dataclass(frozen=True)
class UniformStart:
    """scale * U(low, high) + offset, componentwise: `low`, `high` numbers, `scale` and `offset`
    four numbers each (units of the state)."""

    low: float
    high: float
    scale: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0)
    offset: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)

    def draw(self, random: np.random.RandomState) -> np.ndarray:
        """One start state drawn from `random`."""
        return np.asarray(self.scale) * random.uniform(self.low, self.high, 4) + np.asarray(self.offset)


@dataclasses.dataclass(frozen=True)
class ClippedNormalStart:
    """N(0, std) componentwise, clipped at +-`clip` standard deviations; `std` four numbers."""

    std: tuple[float, float, float, float]
    clip: float

    def draw(self, random: np.random.RandomState) -> np.ndarray:
        """One start state drawn from `random`."""
        std = np.asarray(self.std)
        return np.clip(random.normal(0.0, std), -self.clip * std, self.clip * std)
