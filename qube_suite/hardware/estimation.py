"""State estimation on hardware: angles from encoder counts, velocities by Quanser's filter
(`qube_suite.velocity_filter`: 50 s / (s + 50), discretised ramp-invariantly, lagging by 20 ms)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from qube_suite.angles import TAU as _TAU
from qube_suite.hardware import conventions
from qube_suite.velocity_filter import VELOCITY_FILTER_CUTOFF, VelocityFilter

_PI = math.pi

__all__ = ["VELOCITY_FILTER_CUTOFF", "StateEstimator", "VelocityFilter"]


class StateEstimator:
    """[theta, alpha, dtheta, dalpha] from encoder counts, sample by sample.

    Angles follow `conventions` (the pendulum's encoder zeroed while hanging);
    velocities come from the `VelocityFilter` of the unwrapped angles, so a
    pendulum passing +-pi gives no velocity spike.
    """

    def __init__(self, frequency: float, cutoff: float = VELOCITY_FILTER_CUTOFF):
        if not frequency > 0:
            raise ValueError(f"frequency must be positive, got {frequency}")
        velocity_filter = VelocityFilter(1.0 / frequency, cutoff, channels=2)
        self._pole, self._gain = float(velocity_filter.pole), float(velocity_filter.gain)
        self._last: tuple[float, float, float, float] | None = None  # theta, alpha (unwrapped), velocities

    def reset(self) -> None:
        """Start over: the next sample's velocities are zero."""
        self._last = None

    def __call__(self, encoder_counts: Sequence[int]) -> np.ndarray:
        """The state (rad, rad/s; angles wrapped to (-pi, pi]) from [arm counts, pendulum counts]."""
        return np.array(self.estimate(encoder_counts))

    def estimate(self, encoder_counts: Sequence[int]) -> tuple[float, float, float, float]:
        """`self(encoder_counts)` as a tuple of floats (what a control loop reads fastest).

        `filtered_velocity` and `wrap_angle` are written out here (six calls fewer per sample);
        the tests hold them to those functions' numbers bit for bit."""
        arm, pendulum = (encoder_counts.tolist() if isinstance(encoder_counts, np.ndarray)
                         else encoder_counts)[:2]
        theta = conventions.arm_angle(arm)
        alpha = conventions.pendulum_angle_unwrapped(pendulum)
        last = self._last
        if last is None:
            dtheta = dalpha = 0.0
        else:  # the filter's step in floats, which gives the same numbers as on its arrays
            pole, gain = self._pole, self._gain
            dtheta = pole * last[2] + gain * (_PI - (_PI - (theta - last[0])) % _TAU)
            dalpha = pole * last[3] + gain * (_PI - (_PI - (alpha - last[1])) % _TAU)
        self._last = (theta, alpha, dtheta, dalpha)
        return _PI - (_PI - theta) % _TAU, _PI - (_PI - alpha) % _TAU, dtheta, dalpha
