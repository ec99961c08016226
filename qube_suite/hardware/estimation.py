"""State estimation on hardware: angles from encoder counts, velocities by Quanser's filter.

Quanser's Qube models estimate velocities by passing the angle through the
high-pass-filtered differentiator H(s) = wc s / (s + wc) with wc = 50 rad/s: a
derivative below wc, flat gain wc above it (the encoders' quantisation noise is
not amplified further).

Discretisation: ramp-invariant (first-order hold on the sampled angle),

    v[k] = p v[k-1] + (1 - p) / T (x[k] - x[k-1]),    p = exp(-wc T),

which is exact whenever the angle is piecewise linear between samples, as a
smoothly moving, sampled angle nearly is: its pole is exactly the continuous one
and the velocity of a ramp comes out exact after the transient. A zero-order
hold would treat the angle as a staircase and overestimate every velocity by
wc T / (1 - p) (10 % at 250 Hz); forward Euler (the 2019 Blue River toolkit) puts
the pole at 1 - wc T (0.8 instead of 0.819 at 250 Hz). Tustin also gets a
ramp's steady velocity right but moves the pole (0.8182 instead of 0.8187), so
its transients are not the continuous filter's.

Lag: for slow motions the estimate is the true velocity delayed by 1/wc = 20 ms;
at angular frequency w the estimate is the true velocity times
1 / (1 + j w / wc): magnitude 1 / sqrt(1 + (w / wc)^2), phase lag atan(w / wc)
(12 degrees, 2 % low, for the hanging pendulum's 1.7 Hz swing).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from qube_suite.angles import wrap_angle
from qube_suite.hardware import conventions

VELOCITY_FILTER_CUTOFF = 50.0
"""wc of Quanser's velocity filter 50 s / (s + 50) (rad/s)."""


class VelocityFilter:
    """Velocities of sampled angles through wc s / (s + wc), discretised ramp-invariantly."""

    def __init__(self, frequency: float, cutoff: float = VELOCITY_FILTER_CUTOFF, channels: int = 2):
        if not (math.isfinite(frequency) and frequency > 0 and math.isfinite(cutoff) and cutoff > 0):
            raise ValueError(f"frequency and cutoff must be positive, got {frequency}, {cutoff}")
        self.frequency = float(frequency)
        self.cutoff = float(cutoff)
        self.pole = math.exp(-cutoff / frequency)
        self._gain = (1.0 - self.pole) * frequency
        self._channels = channels
        self._previous: list[float] | None = None
        self._velocity = [0.0] * channels

    @property
    def lag(self) -> float:
        """Delay (s) of the estimate behind the true velocity for slow motions: 1 / wc."""
        return 1.0 / self.cutoff

    def reset(self) -> None:
        """Forget the past: the next angles start the filter at zero velocity."""
        self._previous = None
        self._velocity = [0.0] * self._channels

    def __call__(self, angles: Sequence[float]) -> np.ndarray:
        """Velocity estimates (rad/s) after the next sample of `angles` (rad, unwrapped)."""
        x = [float(a) for a in angles]
        if len(x) != self._channels:
            raise ValueError(f"expected {self._channels} angles, got {len(x)}")
        if self._previous is not None:
            pole, gain = self.pole, self._gain
            self._velocity = [pole * v + gain * (a - b)
                              for v, a, b in zip(self._velocity, x, self._previous, strict=True)]
        self._previous = x
        return np.array(self._velocity)

    def frequency_response(self, omega: float) -> complex:
        """The discrete filter's response to a derivative input: H(e^{j w T}) / (j w)."""
        z = np.exp(1j * omega / self.frequency)
        return complex(self._gain * (1 - 1 / z) / (1 - self.pole / z) / (1j * omega))


class StateEstimator:
    """[theta, alpha, dtheta, dalpha] from encoder counts, sample by sample.

    Angles follow `conventions` (the pendulum's encoder zeroed while hanging);
    velocities come from the `VelocityFilter` of the unwrapped angles, so a
    pendulum passing +-pi gives no velocity spike.
    """

    def __init__(self, frequency: float, cutoff: float = VELOCITY_FILTER_CUTOFF):
        self.filter = VelocityFilter(frequency, cutoff, channels=2)

    def reset(self) -> None:
        """Start over: the next sample's velocities are zero."""
        self.filter.reset()

    def __call__(self, encoder_counts: Sequence[int]) -> np.ndarray:
        """The state (rad, rad/s; angles wrapped to (-pi, pi]) from [arm counts, pendulum counts]."""
        theta = conventions.arm_angle(encoder_counts[0])
        alpha = conventions.pendulum_angle_unwrapped(encoder_counts[1])
        dtheta, dalpha = self.filter((theta, alpha))
        return np.array([wrap_angle(theta), wrap_angle(alpha), dtheta, dalpha])
