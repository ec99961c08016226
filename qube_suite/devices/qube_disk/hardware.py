"""The disk-loaded Qube on a Quanser board (the substitute or a real one), in the disk's terms.

The board is the Qube's own (`qube_suite.hardware.quanser.QuanserWrapper`, with every safety
check and exit path of the pendulum's), read on the motor's channels only: encoder 0 and the
tachometer; the pendulum's encoder is absent. On the substitute board its plant is the
disk-loaded Qube (`substitute.py`).

An episode starts where the disk comes to rest: `reset_to([theta, dtheta])` holds 0 V with the
amplifier on (the motor's back-EMF brakes the disk, time constant J Rm / (kt km) = 0.1 s) until
the disk has rested for `REST_TIME`, then takes that position as theta (the disk has no absolute
reference: its angle counts from where its episode starts). A disk that does not come to rest
within `reset_timeout` raises `ResetError` with the motor stopped.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from dm_control.rl import control

from qube_suite.arguments import is_number, keywords_of
from qube_suite.devices.qube.simulation import check_control_frequency
from qube_suite.devices.qube_disk import conventions
from qube_suite.devices.qube_disk.substitute import plant_overrides
from qube_suite.domains.effects import Effects
from qube_suite.domains.interface import BoardClockAndLed, BoardLifecycle
from qube_suite.hardware import conventions as board_conventions
from qube_suite.hardware.errors import ResetError
from qube_suite.hardware.quanser import DEVICES, SIMULATED, QuanserWrapper
from qube_suite.velocity_filter import VelocityFilter

BOARDS = {name: dataclasses.replace(device, encoder_inputs=(conventions.ENCODER,), other_inputs=(14000,),
                                    arm_encoder=None)
          for name, device in DEVICES.items()}
"""The Qube-Servo 2 and 3 channel declarations on the motor's channels only (encoder 0, tachometer
14000): no pendulum encoder, no arm limit (the disk turns freely)."""

REST_SPEED = 0.5
"""The disk rests when its estimated speed stays below 0.5 rad/s ..."""

REST_TIME = 0.1
"""... for 0.1 s."""

DEFAULT_RESET_TIMEOUT = 5.0
"""Longest a reset may wait for the disk to rest (s)."""

RESET_LED = (1.0, 0.8, 0.0)
"""Yellow while the disk is brought to rest."""


class Physics(BoardClockAndLed, BoardLifecycle, control.Physics):
    """A disk-loaded Qube on a board, through the disk's domain interface (`tasks.DiskPhysics`).

    Args:
        control_frequency: sample rate of the board (Hz); one `step` is one sample.
        board: "simulated" (the substitute) or the device's card type (a real Qube).
        device: "qube_servo2" or "qube_servo3" (default: the one `board` names, else "qube_servo2").
        parameters: the disk's parameters by long name for the substitute's plant (on top of the
            device's motor); a real board has its own physics.
        realtime: pace the substitute by the wall clock (a real board always is).
        max_voltage: the wrapper's voltage clip (V).
        reset_timeout: longest a reset may wait for the disk to rest (s).
        identifier: the board's number.
    """

    latency_steps = 1
    """A step reads the next sample, then writes: the voltage acts one sample after its observation."""

    paced_by_board = True
    physics_error = None
    state_names = conventions.STATE_NAMES
    """The entries of `qube_state()`: what recordings name their state columns."""

    def __init__(self, control_frequency: float = 250.0, board: str = SIMULATED, device: str | None = None,
                 parameters: dict[str, float] | None = None, realtime: bool | None = None,
                 max_voltage: float = 10.0, reset_timeout: float = DEFAULT_RESET_TIMEOUT,
                 identifier: str = "0"):
        if device is None:
            device = next((name for name, d in BOARDS.items() if d.board_type == board), "qube_servo2")
        if device not in BOARDS:
            raise ValueError(f"unknown device {device!r}; valid: {', '.join(BOARDS)}")
        if not (is_number(reset_timeout) and 0.0 < reset_timeout < math.inf):
            raise ValueError(f"reset_timeout must be a positive number of seconds, got {reset_timeout!r}")
        if parameters is not None and board != SIMULATED:
            raise ValueError("parameters set the substitute board's plant; a real board has its own physics")
        plant = plant_overrides(BOARDS[device].board_type, parameters) if board == SIMULATED else None
        self.device = device
        self.qube = QuanserWrapper(BOARDS[device], board, identifier, frequency=control_frequency,
                                   max_voltage=max_voltage, plant=plant, realtime=realtime)
        self._frequency = float(control_frequency)
        self._filter = VelocityFilter(1.0 / self._frequency, channels=1)
        self._reset_timeout = float(reset_timeout)
        self._closed = False
        self._voltage = 0.0
        self._applied = 0.0
        self._effects = Effects()
        self._led: tuple[float, float, float] = RESET_LED
        self._offset = 0.0      # theta of encoder count 0 (rad)
        self._angle = 0.0       # theta of the last sample, from the encoder (rad)
        self._speed = 0.0       # its filtered derivative (rad/s)
        self._samples = 0
        self._episode_start = 0
        self._twin = None
        self.currents, self.encoders, self.others = np.zeros(1), np.zeros(1, dtype=np.int32), np.zeros(1)

    # -- the disk's interface -------------------------------------------------------------

    def disk_angle(self) -> float:
        """theta (rad) from encoder 0, counted from the episode's start position."""
        return self._angle

    def disk_velocity(self) -> float:
        """dtheta/dt (rad/s), by Quanser's velocity filter (lags 20 ms)."""
        return self._speed

    def qube_state(self) -> np.ndarray:
        """The disk-loaded Qube's state [theta, dtheta] (rad, rad/s), as a new array: what episode traces
        record (`conventions.STATE_NAMES`)."""
        return np.array([self._angle, self._speed])

    def voltage(self) -> float:
        """Motor voltage (V) commanded by the last `set_voltage`."""
        return self._voltage

    def set_voltage(self, volts: float) -> None:
        """Command `volts` (V); written to the board at the next `step`."""
        self._voltage = volts

    def applied_voltage(self) -> float:
        """Motor voltage (V) written at the last sample, after actuator effects and the wrapper's clip."""
        return self._applied

    @property
    def max_voltage(self) -> float:
        """The board wrapper's voltage clip (V)."""
        return self.qube.max_voltage

    def raw_readings(self) -> dict[str, float]:
        """The last sample in board units: motor current (A), encoder counts, tachometer (counts/s)."""
        return {"current": float(self.currents[0]), "encoder_disk": int(self.encoders[0]),
                "tachometer": float(self.others[0]), "missed_samples": self.qube.missed_samples}

    def set_actuator_model(self, actuator_model) -> None:
        """Write `actuator_model(volts)` to the board instead of the commanded voltage; None: as
        commanded. A `reset(volts)` method, if present, is called with 0 V when an episode starts."""
        self._effects.actuator = actuator_model

    # -- episodes -----------------------------------------------------------------------------

    def _start_sampling(self) -> None:
        """An episode's first sample, at 0 V, the velocity filter started again."""
        self._filter.reset()
        self._sample(0.0)
        self._voltage = 0.0

    def after_reset(self) -> None:
        """Nothing to do: `reset_to` leaves the disk at the episode's start."""

    def reset_to(self, state: Sequence[float]) -> None:
        """Wait at 0 V for the disk to rest, then count theta = state[0] from there (state[1] must be 0:
        a board starts its episodes at rest)."""
        if float(state[1]) != 0.0:
            raise ValueError(f"the disk's episodes start at rest on a board; got dtheta = {state[1]}")
        self._led = RESET_LED
        needed, rested = max(1, round(REST_TIME * self._frequency)), 0
        try:
            for _ in range(round(self._reset_timeout * self._frequency)):
                rested = rested + 1 if abs(self._speed) < REST_SPEED else 0
                if rested >= needed:
                    break
                self._sample(0.0)
            else:
                raise ResetError(f"reset failed: the disk did not come to rest within "
                                 f"{self._reset_timeout:g} s "
                                 f"(speed {self._speed:.2f} rad/s)")
        except BaseException:
            self._stop()
            raise
        self._offset += float(state[0]) - self._angle
        self._angle, self._speed = float(state[0]), 0.0
        self._filter.reset(np.array([self._angle]), np.zeros(1))
        self._voltage = 0.0
        self._effects.restart_actuation()
        self._episode_start = self._samples

    def drawable(self):
        """The simulated disk put in the measured state with the LED's colour: a digital twin."""
        if self._twin is None:
            from qube_suite.devices.qube_disk.simulation import make_physics

            self._twin = make_physics(self._frequency)
        self._twin.reset_to(self.qube_state())
        self._twin.set_led(self._led)
        return self._twin.drawable()

    @property
    def model(self):
        """The digital twin's `MjModel` (what `drawable()` draws), for dm_control tools that read a
        physics' model (element names, cameras)."""
        return self.drawable().model

    # -- helpers ----------------------------------------------------------------------------

    def _sample(self, volts: float) -> None:
        self.currents, self.encoders, self.others = self.qube.action([board_conventions.board_voltage(volts)],
                                                                      led=self._led)
        limit = self.qube.max_voltage
        self._applied = -limit if volts < -limit else limit if volts > limit else volts
        self._angle = board_conventions.arm_angle(int(self.encoders[0])) + self._offset
        self._speed = float(self._filter(np.array([self._angle]))[0])
        self._samples += 1


def make_physics(control_frequency: float = 250.0, **options: Any) -> Physics:
    """A disk-loaded Qube on a board for control at `control_frequency` (Hz); `options`: see `Physics`."""
    check_control_frequency(control_frequency)
    return Physics(control_frequency, **options)


DOMAIN_KWARGS = keywords_of(Physics, skip=("control_frequency",))
"""Keys `suite.load`'s `domain_kwargs` may hold for this domain."""
