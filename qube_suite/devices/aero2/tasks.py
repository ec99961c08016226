"""The Aero 2's tasks.

Tasks use only the Aero's domain interface (`Aero2Physics`), so they run unchanged on the
simulation and on a board.
"""

from __future__ import annotations

import contextlib
from collections.abc import Sequence
from typing import Protocol

import numpy as np


class Aero2Physics(Protocol):
    """What every Aero 2 domain provides (the simulation and the board alike).

    State entries are `conventions.STATE_NAMES`; voltages are (front, back) in V. A domain is made
    with `configuration="2dof"` (default) or `"pitch_only"` (yaw locked), `conventions.CONFIGURATIONS`.
    """

    latency_steps: int
    """Control periods between a `set_voltage` and its first effect on the state."""

    state_names: tuple[str, ...]
    """The entries of `qube_state()`: `conventions.STATE_NAMES`."""

    physics_error: str | None
    """Why the last step failed (the domain stopped it), or None."""

    configuration: str
    """"2dof" or "pitch_only"."""

    def pitch(self) -> float:
        """Pitch (rad), positive front up, 0 level."""

    def yaw(self) -> float:
        """Yaw (rad), positive counter-clockwise seen from above, not wrapped."""

    def pitch_velocity(self) -> float:
        """Pitch rate (rad/s)."""

    def yaw_velocity(self) -> float:
        """Yaw rate (rad/s)."""

    def rotor_speeds(self) -> np.ndarray:
        """Front and back rotor speeds (rad/s), shape (2,)."""

    def qube_state(self) -> np.ndarray:
        """[pitch, yaw, pitch rate, yaw rate, front rotor speed, back rotor speed], a new array."""

    def voltage(self) -> np.ndarray:
        """The (front, back) voltages (V) commanded by the last `set_voltage`, shape (2,)."""

    def set_voltage(self, volts: np.ndarray) -> None:
        """Command the (front, back) voltages (V), shape (2,), until the next call."""

    def set_led(self, rgb: Sequence[float]) -> None:
        """Colour the LED, (r, g, b) in [0, 1]."""

    def led(self) -> tuple[float, float, float]:
        """The LED's (r, g, b)."""

    def reset_to(self, state: Sequence[float]) -> None:
        """Start an episode from a state of `STATE_NAMES` (the board: brought there as closely as it can)."""

    def reset_context(self) -> contextlib.AbstractContextManager:
        """Time, state and voltages reset (0 V); the caller sets the start inside (`reset_to`)."""

    def time(self) -> float:
        """Time since the episode started (s)."""

    def step(self, nstep: int = 1) -> None:
        """Advance with the voltages held."""

    def end_episode(self) -> None:
        """An episode ended: the board sets both motors to 0 V."""

    def drawable(self):
        """Something a renderer can draw (the simulation itself)."""

    def close(self) -> None:
        """Release the domain; both motors at 0 V on a board."""
