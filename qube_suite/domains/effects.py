"""What a domain's measurement and motor voltage pass through: its sensor chain and actuator chain.

Every domain that takes effects (one simulated Qube, a batch of them, a Qube on a board)
holds one `Effects` and says only where its voltage goes in and where its exact state
comes out: it sends the commanded voltage through `actuate` before the motor, the
exact state (or the board's estimate) through `measure` after each step, and restarts
both chains when an episode starts (`restart_actuation`, then `restart` from the
start's state).

Each chain has two stages, applied in this order:

* the calibrated stage: what a calibration found on the real Qube and the simulation
  reproduces (the encoders' reading of the exact state; latency and dead zone before
  the motor), set by the device from the calibration's effects;
* the randomized stage: randomization's effects (`qube_suite.randomization.Chain`) or any
  model, set through the domain's `set_sensor_model` / `set_actuator_model`.

A stage is a callable `stage(x) -> x`: on one Qube's floats, or on a batch's arrays with
one row per world. It may have `reset(x, rows=None) -> x`, which restarts its memory from
`x` for the worlds `rows` (None: every world, or the one Qube) and returns what it makes of
`x`; a sensor stage without `reset` is restarted by calling it, an actuator stage without
`reset` has nothing to restart.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

Stage = Callable[[Any], Any]
"""One stage of a chain: `stage(x) -> x` on floats (one Qube) or arrays (rows of a batch)."""


class Effects:
    """A domain's sensor chain and actuator chain; every stage None (the default): exact and as
    commanded. The stages are plain attributes the domain sets."""

    __slots__ = ("calibrated_sensor", "sensor", "calibrated_actuator", "actuator")

    def __init__(self) -> None:
        self.calibrated_sensor: Stage | None = None
        """The encoders' reading of the exact state, as a calibration found it."""
        self.sensor: Stage | None = None
        """Randomization's effects on the measurement (`set_sensor_model`)."""
        self.calibrated_actuator: Stage | None = None
        """The latency and dead zone between a command and the motor, as a calibration found them."""
        self.actuator: Stage | None = None
        """Randomization's effects on the voltage (`set_actuator_model`)."""

    @property
    def senses_exactly(self) -> bool:
        """Whether a measurement is the exact state itself (no sensor stage)."""
        return self.calibrated_sensor is None and self.sensor is None

    def measure(self, exact):
        """The measurement of the `exact` state (one Qube's floats, or rows) after a step."""
        if self.calibrated_sensor is not None:
            exact = self.calibrated_sensor(exact)
        return exact if self.sensor is None else self.sensor(exact)

    def actuate(self, volts):
        """The voltage (V) that reaches the motor when `volts` are commanded now."""
        if self.calibrated_actuator is not None:
            volts = self.calibrated_actuator(volts)
        return volts if self.actuator is None else self.actuator(volts)

    def restart(self, exact, rows: np.ndarray | None = None):
        """Restart the sensor chain from the `exact` state of the worlds `rows` (None: every world, or
        the one Qube), whose state was set directly; returns their measurement."""
        for stage in (self.calibrated_sensor, self.sensor):
            if stage is None:
                continue
            reset = getattr(stage, "reset", None)
            if reset is None:
                exact = stage(exact)
            elif rows is None:
                exact = reset(exact)
            else:
                exact = reset(exact, rows)
        return exact

    def restart_actuation(self, volts: Any = 0.0, rows: np.ndarray | None = None) -> None:
        """Restart the actuator chain of the worlds `rows` (None: every world, or the one Qube) as if
        `volts` (V; one per row) had always been commanded."""
        for stage in (self.calibrated_actuator, self.actuator):
            reset = getattr(stage, "reset", None)
            if reset is None:
                continue
            if rows is None:
                reset(volts)
            else:
                reset(volts, rows)
