"""State estimation on hardware: angles from encoder counts, velocities by Quanser's filter
(`qube_suite.velocity_filter`: 50 s / (s + 50), discretised ramp-invariantly, lagging by 20 ms)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from qube_suite.angles import wrap_angle
from qube_suite.hardware import conventions
from qube_suite.velocity_filter import VELOCITY_FILTER_CUTOFF, VelocityFilter

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
        self.filter = VelocityFilter(1.0 / frequency, cutoff, channels=2)

    def reset(self) -> None:
        """Start over: the next sample's velocities are zero."""
        self.filter.reset()

    def __call__(self, encoder_counts: Sequence[int]) -> np.ndarray:
        """The state (rad, rad/s; angles wrapped to (-pi, pi]) from [arm counts, pendulum counts]."""
        theta = conventions.arm_angle(encoder_counts[0])
        alpha = conventions.pendulum_angle_unwrapped(encoder_counts[1])
        dtheta, dalpha = self.filter((theta, alpha))
        return np.array([wrap_angle(theta), wrap_angle(alpha), dtheta, dalpha])
