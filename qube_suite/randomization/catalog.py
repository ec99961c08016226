"""Every effect by name, in the order they are applied."""

from __future__ import annotations

from qube_suite.randomization.amplifier import DeadZone, Saturation, VoltageOffset
from qube_suite.randomization.base import Effect
from qube_suite.randomization.delays import ActionDelay, ObservationDelay
from qube_suite.randomization.sensors import FilteredVelocity, ObservationNoise, Quantization
from qube_suite.randomization.timing import ControlJitter

EFFECTS: dict[str, type[Effect]] = {cls.name: cls for cls in (
    Quantization, FilteredVelocity, ObservationNoise, ObservationDelay,
    ActionDelay, VoltageOffset, DeadZone, Saturation,
    ControlJitter,
)}
"""Effect name -> class, in the order of application: on the exact state, quantise the
angles, filter the velocities from them, add noise, delay; on the commanded voltage,
delay, add the offset, apply the dead-zone, saturate; and jitter the control period."""

