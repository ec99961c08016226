"""What the Qube's sensors do to the state: encoder quantisation, filtered velocities, noise.

Each is an `Effect` on the state [theta, alpha, dtheta, dalpha] (rad, rad/s).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from qube_suite.angles import TAU, wrap_angle
from qube_suite.devices.qube.parameters import ENCODER_COUNTS_PER_REVOLUTION
from qube_suite.randomization.base import (
    Effect,
    Field,
    components,
    generator_of,
    number_or_array,
    per_env,
    rint,
    shape,
    with_rows,
)
from qube_suite.velocity_filter import VELOCITY_FILTER_CUTOFF, VelocityFilter, filtered_velocity


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
        self.resolution = number_or_array(TAU / np.asarray(counts_per_revolution, dtype=np.float64))

    def output(self, x, rows: np.ndarray | None):
        q = per_env(self.resolution, rows)
        theta, alpha, dtheta, dalpha = x
        return [wrap_angle(q * rint(theta / q)), wrap_angle(q * rint(alpha / q)), dtheta, dalpha]


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

    per_env_settings = ("pole", "gain")

    @classmethod
    def from_settings(cls, settings: Mapping, control_period: float, rng) -> FilteredVelocity:
        return cls(settings["cutoff"], control_period)

    def __init__(self, cutoff: float | np.ndarray, control_period: float):
        discrete = VelocityFilter(control_period, cutoff)
        self.pole, self.gain = number_or_array(discrete.pole), number_or_array(discrete.gain)

    def start(self, x, rows: np.ndarray | None):
        if rows is None:
            self._memory = list(x)  # last angles and velocity estimates
        else:
            self._memory = [with_rows(kept, rows, new) for kept, new in zip(self._memory, x, strict=True)]
        return x

    def advance(self, x):
        theta, alpha, _, _ = x
        last_theta, last_alpha, dtheta, dalpha = self._memory
        self._memory = y = [theta, alpha,
                            filtered_velocity(dtheta, theta, last_theta, self.pole, self.gain),
                            filtered_velocity(dalpha, alpha, last_alpha, self.pole, self.gain)]
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
        std = np.asarray(std, dtype=np.float64)
        self.std = std.tolist() if std.ndim == 1 else std  # shared (or one Qube's), or (n, 4)
        self._rng = rng

    def output(self, x, rows: np.ndarray | None):
        theta, alpha, dtheta, dalpha = x
        n0, n1, n2, n3 = components(generator_of(self._rng, rows).standard_normal(shape(theta) + (4,)))
        s0, s1, s2, s3 = components(per_env(self.std, rows))
        return [wrap_angle(theta + s0 * n0), wrap_angle(alpha + s1 * n1), dtheta + s2 * n2, dalpha + s3 * n3]
