"""What the Qube's sensors do to the state: encoder quantisation, filtered velocities, noise.

Each is an `Effect` on the state [theta, alpha, dtheta, dalpha] (rad, rad/s).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from qube_suite.angles import TAU, wrap_angle
from qube_suite.parameters import ENCODER_COUNTS_PER_REVOLUTION
from qube_suite.randomization.base import Effect, Field, generator_of, per_env


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
        y[..., :2] = wrap_angle(resolution * np.round(x[..., :2] / resolution))
        return y


class VelocityFilter(Effect):
    """Velocities estimated from the measured angles by Quanser's filter a s / (s + a)
    (a = `cutoff`, 50 rad/s on the Qube) instead of exact.

    Discretised ramp-invariantly (exact for an angle varying linearly between
    samples, i.e. a first-order hold) at the control period T:
    v_k = p v_(k-1) + (1 - p) / T (angle_k - angle_(k-1)), p = exp(-a T).
    Its pole is the continuous filter's and a constant speed comes out exact; the
    zero-order-hold equivalent would overestimate every speed by aT / (1 - p) (10%
    at 250 Hz), Tustin's moves the pole (0.8182 instead of 0.8187). The hardware
    domain's estimator uses the same discretisation. Angle differences are
    wrapped, so a full turn is no jump. At reset the filter is settled: it starts
    from the exact velocities.
    """

    name = "velocity_filter"
    signal = "state"
    fields = {"cutoff": Field("rad/s", "filter bandwidth a", default=50.0,
                              minimum=0.0, exclusive_minimum=True)}
    per_env_settings = ("pole", "gain")

    @classmethod
    def from_settings(cls, settings: Mapping, control_period: float, rng) -> VelocityFilter:
        return cls(settings["cutoff"], control_period)

    def __init__(self, cutoff: float | np.ndarray, control_period: float):
        self.pole = np.exp(-np.asarray(cutoff, dtype=np.float64) * control_period)
        self.gain = (1.0 - self.pole) / control_period

    def reset(self, x: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        if rows is None:
            self._angles = x[..., :2].copy()
            self._velocities = x[..., 2:].copy()
        else:
            self._angles[rows] = x[..., :2]
            self._velocities[rows] = x[..., 2:]
        return x

    def __call__(self, x: np.ndarray) -> np.ndarray:
        y = x.copy()
        self._velocities = (self.pole[..., None] * self._velocities
                            + self.gain[..., None] * wrap_angle(y[..., :2] - self._angles))
        self._angles = x[..., :2].copy()
        y[..., 2:] = self._velocities
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
