"""A device's own plant inside the substitute board: the protocol and where the board finds one.

The substitute board (`_hil_sim.HIL`) carries the Qube's compiled Furuta plant by default
(`plant.py`: a dict of overrides by long name). A device whose physics is not a Qube's brings
its own plant, an object with the small protocol `BoardPlant` below: the board keeps the
clock, the watchdog, the task buffers, the encoder offsets and the faults, and asks the plant
only to move and to be read. A plant is passed as `HIL(plant=...)` /
`QuanserWrapper(..., plant=...)`, or found by card type when a board of that card is opened
without one (`substitute_plant`): each device's `substitute` module (registry field
`qube_suite.devices.Device.substitute`) declares `CARD_TYPE` and `make_plant()`.
"""

from __future__ import annotations

import dataclasses
import importlib
from typing import Protocol, runtime_checkable

import numpy as np

LED_OUTPUTS = (11000, 11001, 11002)
"""Other outputs of the LED (red, green, blue), the same on every Quanser USB device."""


@dataclasses.dataclass(frozen=True)
class PlantChannels:
    """The channels a board with this plant offers; channel numbers as the device's card numbers them.

    Attributes:
        card_type: the QUARC card type the board answers to (the device's own card).
        analog_outputs: one per motor (V).
        digital_outputs: amplifier enables, one per motor (or one for all).
        analog_inputs: e.g. motor currents (A).
        encoder_inputs: encoders (counts).
        other_inputs: e.g. tachometers (counts/s).
        voltage_limit: the amplifier's range (V): it applies at most this much, whatever is written.
    """

    card_type: str
    analog_outputs: tuple[int, ...]
    digital_outputs: tuple[int, ...]
    analog_inputs: tuple[int, ...]
    encoder_inputs: tuple[int, ...]
    other_inputs: tuple[int, ...]
    voltage_limit: float

    def __post_init__(self):
        if len(self.digital_outputs) not in (1, len(self.analog_outputs)):
            raise ValueError("digital_outputs: one amplifier enable for all motors or one per motor")


@runtime_checkable
class BoardPlant(Protocol):
    """A plant the substitute board integrates: it moves under the applied voltages and is read.

    Every method gets and returns numpy arrays in board units and signs, one entry per channel of
    `channels`, in that order.
    """

    channels: PlantChannels

    def advance(self, seconds: float, volts: np.ndarray, enabled: np.ndarray) -> None:
        """Move the plant on by `seconds` (s) with `volts` (V, one per analog output, already within
        the amplifier's range) applied to the motors whose amplifier is `enabled` (bool, one per
        analog output); a disabled amplifier leaves its motor open-circuit (no current)."""

    def encoder_positions(self) -> np.ndarray:
        """Where each encoder is, in counts (real numbers: the board floors them and adds its
        offsets)."""

    def analog_inputs(self) -> np.ndarray:
        """The analog inputs now (e.g. motor currents, A)."""

    def other_inputs(self) -> np.ndarray:
        """The other inputs now (e.g. tachometers, counts/s)."""

    def true_state(self) -> np.ndarray:
        """The plant's true state, in its device's terms (for tests and the sim-to-real gap)."""

    def set_true_state(self, state: np.ndarray) -> None:
        """Put the plant in `state` (as `true_state` gives it); the encoders count the move."""


def substitute_plant(card_type: str) -> BoardPlant | None:
    """A new plant for a board of `card_type` from the device that declares that card, or None if no
    device's `substitute` module does (the Qubes' cards: the board's own Furuta plant)."""
    from qube_suite import devices

    for device in devices.devices().values():
        if device.substitute is None:
            continue
        module = importlib.import_module(device.substitute)
        if card_type == module.CARD_TYPE:
            return module.make_plant()
    return None
