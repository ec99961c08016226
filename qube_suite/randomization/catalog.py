"""Every effect by name, in the order they are applied, and how an episode's effects are built."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from qube_suite.randomization.amplifier import DeadZone, Saturation, VoltageOffset
from qube_suite.randomization.base import SIGNALS, Effect
from qube_suite.randomization.delays import ActionDelay, ObservationDelay
from qube_suite.randomization.sensors import ObservationNoise, Quantization, VelocityFilter
from qube_suite.randomization.timing import ControlJitter

EFFECTS: dict[str, type[Effect]] = {cls.name: cls for cls in (
    Quantization, VelocityFilter, ObservationNoise, ObservationDelay,
    ActionDelay, VoltageOffset, DeadZone, Saturation,
    ControlJitter,
)}
"""Effect name -> class, in the order of application: on the exact state, quantise the
angles, filter the velocities from them, add noise, delay; on the commanded voltage,
delay, add the offset, apply the dead-zone, saturate; and jitter the control period."""


def build(settings: Mapping[str, Mapping], control_period: float,
          rng: np.random.Generator | None) -> dict[str, list[Effect]]:
    """The effects for one episode's `settings` (effect name -> settings, as sampled),
    grouped by signal ("state", "voltage", "duration") in the order of application.

    `control_period` (s) converts delays in seconds and discretises the velocity
    filter; stochastic effects draw from `rng`.
    """
    effects: dict[str, list[Effect]] = {signal: [] for signal in SIGNALS}
    for name, cls in EFFECTS.items():
        if name in settings:
            effects[cls.signal].append(cls.from_settings(settings[name], control_period, rng))
    return effects
