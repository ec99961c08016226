"""The Aero 2 on a Quanser board (the substitute or a real one), in the Aero's terms.

The board's channels (card `quanser_aero2_usb`; Quanser's own Aero 2 Python class in its academic
resources' library, public copies of which declare the channels below and convert counts the same
way, and the first Aero's map in the original Quanser Gym toolkit's `quanser_wrapper.pyx`, which has
the same channel numbers):

| channel | what | units |
|---|---|---|
| analog output 0, 1 | front (motor 0) and back (motor 1) thruster voltage | V |
| digital output 0, 1 | their amplifier enables | 1 = on |
| analog input 0, 1 | their motor currents | A |
| encoder 0, 1 | the motors' shafts (2048 counts/rev) | counts |
| encoder 2, 3 | pitch (`conventions.PITCH_COUNTS_PER_REVOLUTION`), yaw (`..._YAW_...`) | counts |
| other input 3000-3002, 4000-4002 | gyroscope (rad/s), accelerometer (g) of the body | |
| other input 14000, 14001 | the motors' tachometers | counts/s |
| other input 14002, 14003 | the pitch and yaw tachometers | counts/s |
| other output 11000-11002 | LED red, green, blue | 0..1 |

Read every sample: both currents, the four encoders, the four tachometers (not the inertial unit).
The wrapper's glitch check holds every encoder to `max_encoder_speed` (500 rad/s, above the rotors'
414 rad/s at 24 V). Board signs are taken as the package's:
positive counts with pitch up and yaw counter-clockwise, positive voltage spinning a rotor positive
(Quanser's Aero 2 class converts every count with a positive factor).

Safety is the shared wrapper's (`qube_suite.hardware.quanser.QuanserWrapper`) on both outputs: each
voltage clipped to +-`max_voltage` (at most the amplifier's 24 V), NaN, inf or a wrong shape refused
with both motors at 0 V, the watchdog zeroing both outputs and disabling both amplifiers, and every
exit (close, an exception, Ctrl-C inside a board call, garbage collection, a truncated or finished
episode) writing 0 V to both with both amplifiers off. The Qube's arm limit has no counterpart: the
beam's pitch stops are mechanical and the yaw turns freely on its slip ring.

An episode starts level and at rest at the yaw it asks for (a board holds no other pitch at rest: a
start's pitch, rates and rotor speeds are not reached): `reset_to(state)` drives both thrusters
(`reset_controller`, at most `RESET_VOLTAGE`, LED yellow) until the beam is level within
`PITCH_TOLERANCE`, the yaw within `YAW_TOLERANCE` of the start's (2-DOF), then holds 0 V until the
body and the rotors have rested for `REST_TIME`. One that does not get there within
`reset_timeout` raises `ResetError` with both motors stopped. Pitch and yaw count from where the
board was powered up (the beam rests level there: its centre of mass hangs below the pivot).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from dm_control.rl import control

from qube_suite.arguments import is_number, keywords_of
from qube_suite.devices.aero2 import conventions, substitute
from qube_suite.devices.qube.parameters import values_of
from qube_suite.devices.qube.simulation import check_control_frequency
from qube_suite.domains.effects import Effects
from qube_suite.domains.interface import BoardClockAndLed, BoardLifecycle
from qube_suite.hardware.errors import ResetError
from qube_suite.hardware.quanser import SIMULATED, Device, QuanserWrapper

AERO2 = Device(
    board_type=substitute.CARD_TYPE, analog_outputs=(0, 1), digital_outputs=(0, 1), analog_inputs=(0, 1),
    encoder_inputs=(0, 1, 2, 3), other_inputs=(14000, 14001, 14002, 14003), led_outputs=(11000, 11001, 11002),
    amplifier_fault_inputs=(), stall_warning_inputs=(), stall_error_inputs=(), arm_encoder=None,
    radians_per_count=(conventions.TACHOMETER_TO_RAD_PER_S, conventions.TACHOMETER_TO_RAD_PER_S,
                       1.0 / conventions.PITCH_COUNTS_PER_RADIAN, 1.0 / conventions.YAW_COUNTS_PER_RADIAN),
    amplifier_range=conventions.VOLTAGE_LIMIT)
"""The Aero 2's channels as the wrapper reads them (see the module docstring)."""

RESET_VOLTAGE = 6.0
"""Largest voltage (V) of the reset controller on either thruster: a third of the nominal 18 V."""

PITCH_TOLERANCE = math.radians(2.0)
"""An episode starts with the beam within 2 degrees of level ..."""

YAW_TOLERANCE = math.radians(3.0)
"""... the yaw within 3 degrees of the start's (2-DOF) ..."""

REST_RATE = 0.05
"""... pitch and yaw rates below 0.05 rad/s ..."""

REST_ROTOR_SPEED = 5.0
"""... and both rotors below 5 rad/s ..."""

REST_TIME = 0.2
"""... for 0.2 s."""

DEFAULT_RESET_TIMEOUT = 15.0
"""Longest a reset may take (s): the passive beam alone needs about 20 s to settle from 30 degrees."""

RESET_LED = (1.0, 0.8, 0.0)
"""Yellow while the Aero is brought to its start."""

RESET_GAINS = {"pitch": (40.0, 20.0, 0.0), "yaw": (60.0, 40.0, 5.0)}
"""The reset controller's (proportional V/rad, derivative V s/rad, integral V/(rad s)) per axis: the
pitch is a stable pendulum and needs damping only to settle fast; the yaw has nothing to hold it
but its friction, which the integral overcomes. On substitute Aeros they bring the Aero from 2 s of
random voltages to its start in 0.3 to 3 s."""


class ResetController:
    """Voltages that bring the beam level and the yaw to a target, at most `RESET_VOLTAGE` each.

    Args:
        configuration: "2dof" (the front thruster holds pitch, the back one yaw) or "pitch_only"
            (both lift: their difference holds pitch).
        sample_time: the control period (s).
    """

    def __init__(self, configuration: str, sample_time: float):
        self.configuration = configuration
        self.sample_time = sample_time
        self._integral = 0.0

    def __call__(self, pitch: float, yaw: float, pitch_rate: float, yaw_rate: float,
                 target_yaw: float) -> np.ndarray:
        """(front, back) voltages (V) for the measured state."""
        kp, kd, _ = RESET_GAINS["pitch"]
        lift = float(np.clip(-kp * pitch - kd * pitch_rate, -RESET_VOLTAGE, RESET_VOLTAGE))
        if self.configuration == "pitch_only":
            return np.array([0.5 * lift, -0.5 * lift])
        kp, kd, ki = RESET_GAINS["yaw"]
        error = target_yaw - yaw
        self._integral = float(np.clip(self._integral + error * self.sample_time,
                                       -RESET_VOLTAGE / ki, RESET_VOLTAGE / ki))
        turn = float(np.clip(kp * error - kd * yaw_rate + ki * self._integral, -RESET_VOLTAGE, RESET_VOLTAGE))
        return np.array([lift, turn])


class Physics(BoardClockAndLed, BoardLifecycle, control.Physics):
    """An Aero 2 on a board, through the Aero's domain interface (`tasks.Aero2Physics`).

    Args:
        control_frequency: sample rate of the board (Hz); one `step` is one sample.
        board: "simulated" (the substitute) or "quanser_aero2_usb" (a real Aero 2).
        parameters: the substitute's plant parameters by long name (`substitute.plant_values`: the
            table and the plant's own), or a calibration file's path; None: the default substitute,
            whose parameters are hidden. A real board has its own physics.
        plant_seed: draw the substitute's hidden parameters with this seed instead of the default's.
        configuration: "2dof" (default) or "pitch_only" (yaw locked).
        realtime: pace the substitute by the wall clock (a real board always is).
        max_voltage: the wrapper's voltage clip on each thruster (V).
        reset_timeout: longest a reset may take (s).
        identifier: the board's number.
    """

    latency_steps = 1
    """A step reads the next sample, then writes: the voltages act one sample after their observation."""

    paced_by_board = True
    physics_error = None
    state_names = conventions.STATE_NAMES
    """The entries of `qube_state()`: what recordings name their state columns."""

    def __init__(self, control_frequency: float = 250.0, board: str = SIMULATED,
                 parameters: Mapping[str, float] | Any = None, plant_seed: int | None = None,
                 configuration: str = "2dof", realtime: bool | None = None,
                 max_voltage: float = conventions.RECOMMENDED_VOLTAGE,
                 reset_timeout: float = DEFAULT_RESET_TIMEOUT, identifier: str = "0"):
        if configuration not in conventions.CONFIGURATIONS:
            raise ValueError(f"unknown configuration {configuration!r}; valid configurations: "
                             f"{', '.join(conventions.CONFIGURATIONS)}")
        if not (is_number(reset_timeout) and 0.0 < reset_timeout < math.inf):
            raise ValueError(f"reset_timeout must be a positive number of seconds, got {reset_timeout!r}")
        if board != SIMULATED and (parameters is not None or plant_seed is not None):
            raise ValueError("parameters and plant_seed set the substitute board's plant; a real board has "
                             "its own physics")
        plant = None
        if board == SIMULATED:
            given = values_of(parameters) if parameters is not None else None
            plant = substitute.make_plant(given, configuration, plant_seed)
        self.configuration = configuration
        self.qube = QuanserWrapper(AERO2, board, identifier, frequency=control_frequency,
                                   max_voltage=max_voltage, plant=plant, realtime=realtime,
                                   arm_limit=None)
        self._frequency = float(control_frequency)
        self._reset_timeout = float(reset_timeout)
        self._closed = False
        self._voltage = np.zeros(2)
        self._applied = np.zeros(2)
        self._effects = Effects()
        self._led: tuple[float, float, float] = RESET_LED
        self._state = np.zeros(6)
        self._samples = 0
        self._episode_start = 0
        self._twin = None
        self.currents, self.encoders, self.others = np.zeros(2), np.zeros(4, dtype=np.int32), np.zeros(4)

    # -- the Aero's interface -------------------------------------------------------------

    def pitch(self) -> float:
        """Pitch (rad) from encoder 2, positive front up, 0 level (where the board was powered up)."""
        return float(self._state[0])

    def yaw(self) -> float:
        """Yaw (rad) from encoder 3, positive counter-clockwise seen from above, not wrapped."""
        return float(self._state[1])

    def pitch_velocity(self) -> float:
        """Pitch rate (rad/s), the board's pitch tachometer."""
        return float(self._state[2])

    def yaw_velocity(self) -> float:
        """Yaw rate (rad/s), the board's yaw tachometer."""
        return float(self._state[3])

    def rotor_speeds(self) -> np.ndarray:
        """Front and back rotor speeds (rad/s), the motors' tachometers, as a new array."""
        return self._state[4:].copy()

    def qube_state(self) -> np.ndarray:
        """[pitch, yaw, pitch rate, yaw rate, front rotor speed, back rotor speed] (rad, rad/s), as a new
        array: what episode traces record (`conventions.STATE_NAMES`)."""
        return self._state.copy()

    def voltage(self) -> np.ndarray:
        """(front, back) voltages (V) commanded by the last `set_voltage`, as a new array."""
        return self._voltage.copy()

    def set_voltage(self, volts: Sequence[float] | np.ndarray) -> None:
        """Command the (front, back) voltages (V), written at the next `step`. Raises ValueError, both
        motors at 0 V, unless `volts` is two finite numbers."""
        volts = np.array(volts, dtype=np.float64)
        if volts.shape != (2,) or not np.isfinite(volts).all():
            self.stop_motor()
            raise ValueError(f"the Aero takes two finite voltages (front, back), got {volts!r}")
        self._voltage = volts

    def applied_voltage(self) -> np.ndarray:
        """(front, back) voltages (V) written at the last sample, after actuator effects and the clip."""
        return self._applied.copy()

    @property
    def max_voltage(self) -> float:
        """The board wrapper's voltage clip (V)."""
        return self.qube.max_voltage

    def raw_readings(self) -> dict[str, float]:
        """The last sample in board units: motor currents (A), encoder counts, tachometers (counts/s)."""
        return {"current_front": float(self.currents[0]), "current_back": float(self.currents[1]),
                "encoder_front": int(self.encoders[0]), "encoder_back": int(self.encoders[1]),
                "encoder_pitch": int(self.encoders[2]), "encoder_yaw": int(self.encoders[3]),
                "tachometer_front": float(self.others[0]), "tachometer_back": float(self.others[1]),
                "tachometer_pitch": float(self.others[2]), "tachometer_yaw": float(self.others[3]),
                "missed_samples": self.qube.missed_samples}

    def set_actuator_model(self, actuator_model) -> None:
        """Write `actuator_model(volts)` (arrays of shape (2,)) to the board instead of the commanded
        voltages; None: as commanded. A `reset(volts)` method, if present, is called with 0 V when an
        episode starts."""
        self._effects.actuator = actuator_model

    def stop_motor(self) -> None:
        """Write 0 V to both motors at once, while an episode drives (an action was refused); the
        watchdog disables the amplifiers if no valid action follows within its timeout."""
        if self.qube.is_open and not self.qube.is_idle:
            try:
                self.qube.zero_voltage()
            except BaseException:
                self._stop()
                raise

    # -- episodes -----------------------------------------------------------------------------

    def _start_sampling(self) -> None:
        """An episode's first sample, at 0 V on both motors."""
        self._sample(np.zeros(2))
        self._voltage = np.zeros(2)

    def after_reset(self) -> None:
        """Nothing to do: `reset_to` leaves the Aero at the episode's start."""

    def reset_to(self, state: Sequence[float]) -> None:
        """Bring the Aero level and at rest at yaw `state[1]` (see the module docstring): as close to
        `state` as a board gets, which holds no other pitch at rest (the start's pitch, rates and rotor
        speeds are taken as 0). Raises ValueError for anything but six finite numbers, or a yaw other
        than 0 when it is locked (pitch-only)."""
        state = np.asarray(state, dtype=np.float64)
        if state.shape != (len(conventions.STATE_NAMES),) or not np.isfinite(state).all():
            raise ValueError(f"an Aero state is {len(conventions.STATE_NAMES)} finite numbers "
                             f"{conventions.STATE_NAMES}, got {state!r}")
        if self.configuration == "pitch_only" and state[1] != 0.0:
            raise ValueError(f"the pitch-only Aero's yaw is locked: the start's yaw must be 0, "
                             f"got {state[1]}")
        self._led = RESET_LED
        controller = ResetController(self.configuration, 1.0 / self._frequency)
        needed, rested = max(1, round(REST_TIME * self._frequency)), 0
        try:
            for _ in range(round(self._reset_timeout * self._frequency)):
                pitch, yaw, pitch_rate, yaw_rate = self._state[:4]
                near = abs(pitch) <= PITCH_TOLERANCE and (self.configuration == "pitch_only"
                                                          or abs(yaw - state[1]) <= YAW_TOLERANCE)
                still = abs(pitch_rate) < REST_RATE and abs(yaw_rate) < REST_RATE
                if near and still:
                    rested = rested + 1 if np.abs(self._state[4:]).max() < REST_ROTOR_SPEED else 0
                    if rested >= needed:
                        break
                    self._sample(np.zeros(2))
                else:
                    rested = 0
                    self._sample(controller(pitch, yaw, pitch_rate, yaw_rate, state[1]))
            else:
                raise ResetError(f"reset failed: the Aero did not come level and to rest within "
                                 f"{self._reset_timeout:g} s (state {np.round(self._state, 3).tolist()})")
        except BaseException:
            self._stop()
            raise
        self._voltage = np.zeros(2)
        self._effects.restart_actuation(np.zeros(2))
        self._episode_start = self._samples

    def drawable(self):
        """The simulated Aero put in the measured state with the LED's colour: a digital twin."""
        if self._twin is None:
            from qube_suite.devices.aero2.simulation import make_physics

            self._twin = make_physics(self._frequency, configuration=self.configuration)
        state = self.qube_state()
        if self.configuration == "pitch_only":
            state[1] = state[3] = 0.0
        self._twin.reset_to(state)
        self._twin.set_led(self._led)
        return self._twin.drawable()

    @property
    def model(self):
        """The digital twin's `MjModel` (what `drawable()` draws)."""
        return self.drawable().model

    # -- helpers ----------------------------------------------------------------------------

    def _sample(self, volts: np.ndarray) -> None:
        self.currents, self.encoders, self.others = self.qube.action([float(volts[0]), float(volts[1])],
                                                                      led=self._led)
        self._applied = np.clip(volts, -self.qube.max_voltage, self.qube.max_voltage)
        pitch = self.encoders[2] / conventions.PITCH_COUNTS_PER_RADIAN
        yaw = self.encoders[3] / conventions.YAW_COUNTS_PER_RADIAN
        self._state = np.array([pitch, yaw, self.others[2] / conventions.PITCH_COUNTS_PER_RADIAN,
                                self.others[3] / conventions.YAW_COUNTS_PER_RADIAN,
                                self.others[0] * conventions.TACHOMETER_TO_RAD_PER_S,
                                self.others[1] * conventions.TACHOMETER_TO_RAD_PER_S])
        self._samples += 1


def make_physics(control_frequency: float = 250.0, **options: Any) -> Physics:
    """An Aero 2 on a board for control at `control_frequency` (Hz); `options`: see `Physics`."""
    check_control_frequency(control_frequency)
    return Physics(control_frequency, **options)


DOMAIN_KWARGS = keywords_of(Physics, skip=("control_frequency",))
"""Keys `suite.load`'s `domain_kwargs` may hold for this domain."""
