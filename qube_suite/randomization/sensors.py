"""What the Qube's sensors do to the state: encoder quantisation, filtered velocities, noise.

Each is an `Effect` on the state [theta, alpha, dtheta, dalpha] (rad, rad/s).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from qube_suite.angles import TAU, wrap_angle
from qube_suite.parameters import ENCODER_COUNTS_PER_REVOLUTION
from qube_suite.randomization.base import Effect, Field, generator_of, per_env
from qube_suite.velocity_filter import VELOCITY_FILTER_CUTOFF, VelocityFilter


class Quantization(Effect):
    """Encoders of `counts_per_revolution`: both angles rounded to the nearest multiple of
    2 pi / counts_per_revolution (rad), kept in (-pi, pi]. Velocities are untouched."""

    name = "quantization"
    signal = "state"
    fields = {"counts_per_revolution": Field("counts/rev", "encoder counts per revolution",
                                             default=ENCODER_COUNTS_PER_REVOLUTION, minimum=1,
                                             maximum=2**32, integer=True)}
    per_env_settings = ("resolution",)

    def __init__(self, counts_per_revolution: int | np.ndarray = ENCODER_COUNTS_PER_REVOLUTION):
        self.resolution = TAU / np.asarray(counts_per_revolution, dtype=np.float64)

    def output(self, x: np.ndarray, rows: np.ndarray | None) -> np.ndarray:
        resolution = per_env(self.resolution, rows)[..., None]
        y = x.copy()
        y[..., :2] = wrap_angle(resolution * np.rint(x[..., :2] / resolution))
        return y


class FilteredVelocity(Effect):
    """Velocities estimated from the measured angles by Quanser's filter a s / (s + a)
    (a = `cutoff`, 50 rad/s on the Qube) instead of exact: the hardware domain's
    `qube_suite.velocity_filter.VelocityFilter`, discretised ramp-invariantly at the control
    period. Angle differences are wrapped, so a full turn is no jump. At reset the filter
    is settled: it starts from the exact velocities.
    """

    name = "velocity_filter"
    signal = "state"
    fields = {"cutoff": Field("rad/s", "filter bandwidth a", default=VELOCITY_FILTER_CUTOFF,
                              minimum=0.0, exclusive_minimum=True)}

    @classmethod
    def from_settings(cls, settings: Mapping, control_period: float, rng) -> FilteredVelocity:
        return cls(settings["cutoff"], control_period)

    def __init__(self, cutoff: float | np.ndarray, control_period: float):
        self.filter = VelocityFilter(control_period, cutoff)

    def set_rows(self, rows: np.ndarray, fresh: FilteredVelocity) -> None:
        for attribute in ("cutoff", "pole", "gain"):
            getattr(self.filter, attribute)[rows] = getattr(fresh.filter, attribute)

    def reset(self, x: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        self.filter.reset(x[..., :2], x[..., 2:], rows)
        return x

    def __call__(self, x: np.ndarray) -> np.ndarray:
        y = x.copy()
        y[..., 2:] = self.filter(x[..., :2])
        return y


class ObservationNoise(Effect):
    """Gaussian noise added to each measurement, standard deviations `std` =
    [theta, alpha, dtheta, dalpha] (rad, rad/s); angles re-wrapped to (-pi, pi]."""

    name = "observation_noise"
    signal = "state"
    stochastic = True
    fields = {"std": Field("rad, rad, rad/s, rad/s", "standard deviation of each component",
                           minimum=0.0, size=4)}
    per_env_settings = ("std",)

    @classmethod
    def from_settings(cls, settings: Mapping, control_period: float, rng) -> ObservationNoise:
        return cls(settings["std"], rng)

    def __init__(self, std, rng):
        self.std = np.asarray(std, dtype=np.float64)
        self._rng = rng

    def output(self, x: np.ndarray, rows: np.ndarray | None) -> np.ndarray:
        noise = generator_of(self._rng, rows).standard_normal(x.shape)
        y = x + per_env(self.std, rows, shared_ndim=1) * noise
        y[..., :2] = wrap_angle(y[..., :2])
        return y
