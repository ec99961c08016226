"""Quanser's velocity filter: velocities of sampled angles through wc s / (s + wc).

Quanser's Qube models estimate velocities by passing the angle through the
high-pass-filtered differentiator H(s) = wc s / (s + wc) with wc = 50 rad/s: a
derivative below wc, flat gain wc above it (the encoders' quantisation noise is
not amplified further). The hardware domain estimates its velocities with it
(`qube_suite.hardware.estimation`), and randomization's `velocity_filter` effect
gives a simulated Qube the same estimates.

Discretisation: ramp-invariant (first-order hold on the sampled angle), at the
sample period T,

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

import numpy as np

from qube_suite.angles import wrap_angle

VELOCITY_FILTER_CUTOFF = 50.0
"""wc of Quanser's velocity filter 50 s / (s + 50) (rad/s)."""


def filtered_velocity(velocity, angle, last_angle, pole, gain):
    """The filter's next estimate (rad/s) from its last `velocity` when the angle moved from
    `last_angle` to `angle` (rad): p v + (1 - p) / T wrap(x - x_last), with `pole` p and `gain`
    (1 - p) / T (1/s). Floats (one angle) or arrays, elementwise."""
    return pole * velocity + gain * wrap_angle(angle - last_angle)


class VelocityFilter:
    """Velocities (rad/s) of angles (rad) sampled every `period` (s), through wc s / (s + wc).

    Angles come as arrays whose last axis holds `channels` angles, e.g. (n, 2) for
    the arm and pendulum of n Qubes; `cutoff` (wc, rad/s) is one number or one per
    row. Differences of consecutive angles are wrapped to (-pi, pi], so angles
    wrapped at +-pi give no velocity spike.
    """

    def __init__(self, period: float, cutoff: float | np.ndarray = VELOCITY_FILTER_CUTOFF, channels: int = 2):
        cutoff = np.asarray(cutoff, dtype=np.float64)
        if not (math.isfinite(period) and period > 0 and np.isfinite(cutoff).all() and (cutoff > 0).all()):
            raise ValueError(f"period and cutoff must be positive, got {period}, {cutoff}")
        self.period = float(period)
        self.channels = channels
        self.cutoff = cutoff
        self.pole = np.exp(-cutoff * period)
        self.gain = (1.0 - self.pole) / period
        self._angles: np.ndarray | None = None
        self._velocities: np.ndarray | None = None

    @property
    def lag(self) -> float | np.ndarray:
        """Delay (s) of the estimate behind the true velocity for slow motions: 1 / wc."""
        return 1.0 / self.cutoff if self.cutoff.ndim else 1.0 / float(self.cutoff)

    def reset(self, angles=None, velocities=None, rows: np.ndarray | None = None) -> None:
        """Start afresh: settled at `velocities` with the last angles `angles`, for all rows or for
        `rows` (integer indices); without angles, the next angles start it at zero velocity."""
        if angles is None:
            self._angles = self._velocities = None
        elif rows is None:
            self._angles = np.array(angles, dtype=np.float64)
            self._velocities = np.array(velocities, dtype=np.float64)
        else:
            self._angles[rows] = angles
            self._velocities[rows] = velocities

    def __call__(self, angles) -> np.ndarray:
        """Velocity estimates (rad/s) after the next sample of `angles` (rad)."""
        angles = np.array(angles, dtype=np.float64)
        if angles.shape[-1:] != (self.channels,):
            raise ValueError(f"expected {self.channels} angles, got {angles.shape[-1:] or 'a number'}")
        if self._angles is None:
            self._velocities = np.zeros_like(angles)
        else:
            self._velocities = filtered_velocity(self._velocities, angles, self._angles,
                                                 self.pole[..., None], self.gain[..., None])
        self._angles = angles
        return self._velocities

    def frequency_response(self, omega: float) -> complex:
        """The discrete filter's response to a derivative input: H(e^{j w T}) / (j w), one cutoff."""
        z = np.exp(1j * omega * self.period)
        return complex(self.gain * (1 - 1 / z) / (1 - self.pole / z) / (1j * omega))
