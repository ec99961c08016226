"""Control-period jitter: each control step lasts a randomly perturbed time."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from qube_suite.randomization.base import Effect, Field, generator_of, number_or_array, per_env, shape


class ControlJitter(Effect):
    """Each control step lasts T (1 + u), u ~ U(-fraction, fraction), instead of the
    nominal period T; the voltage is held throughout. The signal is the step's
    nominal duration (s). At most 0.5, so a step lasts between T/2 and 3T/2."""

    name = "control_jitter"
    signal = "duration"
    stochastic = True
    fields = {"fraction": Field("of the period", "largest relative change of a step's duration",
                                minimum=0.0, maximum=0.5)}
    per_env_settings = ("fraction",)

    @classmethod
    def from_settings(cls, settings: Mapping, control_period: float, rng) -> ControlJitter:
        return cls(settings["fraction"], rng)

    def __init__(self, fraction: float | np.ndarray, rng):
        self.fraction = number_or_array(fraction)
        self._rng = rng

    def output(self, x, rows: np.ndarray | None):
        draws = generator_of(self._rng, rows).random(shape(x) or None)  # a float for one Qube
        return self.jittered(x, per_env(self.fraction, rows), draws)

    @staticmethod
    def jittered(duration, fraction, uniform):
        """The duration (s) of a step of nominal `duration` for a uniform variate in [0, 1): duration
        (1 + u), u = fraction (2 uniform - 1); numbers or arrays (numpy's, or JAX's for `qube_suite.mjx`)."""
        return duration * (1.0 + fraction * (2.0 * uniform - 1.0))
