"""What the amplifier does to the commanded voltage: offset, dead-zone, saturation.

Applied in that order, after any action delay: the motor receives
clip(dead_zone(v + offset), -limit, limit).
"""

from __future__ import annotations

import numpy as np

from qube_suite.randomization.base import Effect, Field, clip, copysign, maximum, number_or_array, per_env


class VoltageOffset(Effect):
    """A constant `voltage` (V) added to every command."""

    name = "voltage_offset"
    signal = "voltage"
    fields = {"voltage": Field("V", "offset added to the command")}
    per_env_settings = ("voltage",)

    def __init__(self, voltage: float | np.ndarray):
        self.voltage = number_or_array(voltage)

    def output(self, x, rows: np.ndarray | None):
        return x + per_env(self.voltage, rows)


class DeadZone(Effect):
    """Commands within +-`voltage` (V) give 0 V; larger ones are reduced by it:
    sign(v) max(|v| - voltage, 0), continuous like a motor's static friction."""

    name = "dead_zone"
    signal = "voltage"
    fields = {"voltage": Field("V", "half-width of the dead band", minimum=0.0)}
    per_env_settings = ("voltage",)

    def __init__(self, voltage: float | np.ndarray):
        self.voltage = number_or_array(voltage)

    def output(self, x, rows: np.ndarray | None):
        return copysign(maximum(abs(x) - per_env(self.voltage, rows), 0.0), x)


class Saturation(Effect):
    """The amplifier's output limited to +-`voltage` (V); acts when below the task's voltage limit."""

    name = "saturation"
    signal = "voltage"
    fields = {"voltage": Field("V", "largest output", minimum=0.0, exclusive_minimum=True)}
    per_env_settings = ("voltage",)

    def __init__(self, voltage: float | np.ndarray):
        self.voltage = number_or_array(voltage)

    def output(self, x, rows: np.ndarray | None):
        limit = per_env(self.voltage, rows)
        return clip(x, -limit, limit)
