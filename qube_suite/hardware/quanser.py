"""Quanser boards behind a safe context manager: `QuanserWrapper`, `QubeServo2`, `QubeServo3`.

    with QubeServo2(frequency=250) as qube:             # the substitute board
        currents, encoders, others = qube.action([0.5])  # volts in, raw board readings out

A device is a channel declaration (`Device`); the wrapper is the same for all
devices and for the substitute board (`board="simulated"`, the default) and a
real one (`board="qube_servo2_usb"`), which it drives through Quanser's Python HIL
API (`quanser.hardware`, imported only then). Nothing is opened before
`__enter__`/`open()`.

Entering clears a watchdog left expired by an earlier run, writes 0 V with the
amplifier off, starts a reader task at `frequency`, sets the watchdog to zero the
voltage and disable the amplifier on expiry, enables the amplifier and starts the
watchdog. It keeps the board's encoder counts: a board counts from 0 where the
Qube was at power-up and goes on counting while it is powered, across opens and
closes (QUARC's own models set encoder counts only by an explicit
`hil_set_encoder_counts`, which their HIL Initialize block makes at model start
when its "set initial encoder counts" option is chosen), so a Qube powered up
with the pendulum hanging at rest and the arm centred is zeroed for as long as it
stays powered, whatever earlier runs left it doing. `zero_encoders=True` zeroes
them at open instead, where the Qube is then (it must be at rest: no count moving
by more than one over 0.2 s, else `NotAtRestError`); `reset_encoders()` at any
time. `action(voltages, led=None)`
waits for the next sample, reloads the watchdog, checks safety, writes the
voltages and returns (currents in A, encoder counts, other inputs) as the board
reports them: raw board units and signs (`conventions.py` maps them to the
package's angles and voltage; `estimation.StateEstimator` gives the state).
Leaving, also after an exception or KeyboardInterrupt, writes 0 V, turns the LED
red, disables the amplifier, stops the watchdog, stops and deletes the task and
closes the board; `idle()` and leaving write 0 V and the amplifier off whatever a
board query answers (only an expired watchdog, which has done so already, refuses
them). While a board is open, SIGTERM unwinds the program like Ctrl-C (exit code
143) where its handler was Python's default. `watchdog_timeout` is at most
`MAX_WATCHDOG_TIMEOUT` (0.15 s).

Safety: voltages are clipped to +-`max_voltage`. NaN, inf, a wrong shape or a
non-number, and an invalid LED colour, make the wrapper write 0 V and raise
ValueError without reading a sample (the next valid action drives again). After
each sample, in this order, each of these stops the motor (0 V, amplifier
disabled, watchdog stopped: the board idles, `resume()` drives again) and raises
(`errors.py`): the watchdog expired (`WatchdogExpiredError`), more than
`max_missed_samples` samples passed since the last action (`MissedSamplesError`;
`missed_samples` counts them all, samples before the first action excepted), an
amplifier fault (`AmplifierFaultError`; raised again after `resume()` while it
lasts), a stall error (`MotorStallError`; disabling the amplifier clears it), an
encoder count that moved farther since the last sample than `max_encoder_speed`
allows (`EncoderGlitchError`; the position reference is lost: close, put the Qube
at its start position and open again), the arm farther than `arm_limit` from
its zero (`ArmLimitError`; raised again after `resume()` and at the next open
until the arm is back: `return_arm()` may bring it back, towards the centre only,
gently, and not against whatever holds it). A board that cannot be opened raises `BoardOpenError`. The
stall warning (digital input 1) is reported by `stall_warning`.

On the substitute board in fast mode (`realtime` False) a plain action (a list of one
float, the LED None or a tuple of floats) is checked and clipped, its sample read, the
watchdog reloaded and, if none of these checks could stop at that sample, the voltage and
LED written in one compiled call (`_hil_sim.ClearSamples`); any other action or sample goes
through the checks one by one. Both give the same readings, refusals and stops, bit for bit
(`tests/test_hardware_compiled_samples.py`).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import signal
import threading
import weakref
from collections.abc import Sequence
from typing import Any, NoReturn

import numpy as np

from qube_suite.hardware import conventions
from qube_suite.hardware.board_plant import BoardPlant
from qube_suite.hardware.errors import (
    AmplifierFaultError,
    ArmLimitError,
    BoardIOError,
    BoardOpenError,
    EncoderGlitchError,
    HardwareError,
    MissedSamplesError,
    MotorStallError,
    NotAtRestError,
    QuanserSDKNotFoundError,
    WatchdogExpiredError,
)
from qube_suite.hardware.plant import plant_parameters

SIMULATED = "simulated"

MAX_ENCODER_SPEED = 500.0
"""Default `max_encoder_speed` (rad/s): twice the motor's no-load speed at 10 V (238 rad/s); at
250 Hz a jump of more than 652 counts between two samples is a glitch."""

SDK_HELP = (
    "Quanser's Python HIL API (the `quanser` package) is not installed. It comes with the Quanser SDK "
    "(https://github.com/quanser/quanser_sdk; on Ubuntu: configure Quanser's apt repository as in "
    "https://github.com/quanser/quanser_sdk_linux, then `sudo apt-get install quanser-sdk`); install its "
    "Python wheels into this environment with `python -m pip install --find-links <SDK>/python quanser_api` "
    "(on Windows <SDK> is %QSDK_DIR%). Without a Qube, use board='simulated'.")


AMPLIFIER_RANGE = 15.0
"""Largest `max_voltage` (V) on a Qube: its amplifier range, +-15 V (see `plant.py`); a device declares
its own (`Device.amplifier_range`)."""


@dataclasses.dataclass(frozen=True)
class Device:
    """A Quanser device's channels, as the wrapper uses them."""

    board_type: str                             # QUARC card type, e.g. "qube_servo2_usb"
    analog_outputs: tuple[int, ...]             # motor voltages (V)
    digital_outputs: tuple[int, ...]            # amplifier enables
    analog_inputs: tuple[int, ...]              # read every sample, e.g. motor currents (A)
    encoder_inputs: tuple[int, ...]             # read every sample (counts)
    other_inputs: tuple[int, ...]               # read every sample, e.g. tachometers (counts/s)
    led_outputs: tuple[int, ...]                # LED red, green, blue (0..1)
    amplifier_fault_inputs: tuple[int, ...]     # digital inputs: 1 = amplifier fault
    stall_warning_inputs: tuple[int, ...]       # digital inputs: 1 = stall detected
    stall_error_inputs: tuple[int, ...]         # digital inputs: 1 = stall error (amplifier disabled)
    arm_encoder: int | None = 0                 # encoder channel watched by `arm_limit`
    card_options: str = ""                      # set by set_card_specific_options at open ("" = none)
    radians_per_count: tuple[float, ...] | None = None  # per encoder input; None: a Qube's, 2 pi / 2048 each
    amplifier_range: float = AMPLIFIER_RANGE    # the amplifier's largest output (V): the largest max_voltage

    @property
    def encoder_scales(self) -> tuple[float, ...]:
        """Radians per count of each encoder input, in `encoder_inputs` order."""
        if self.radians_per_count is None:
            return (conventions.RADIANS_PER_COUNT,) * len(self.encoder_inputs)
        return self.radians_per_count

    @property
    def digital_inputs(self) -> tuple[int, ...]:
        """All digital inputs read every sample."""
        return tuple(sorted(set(self.amplifier_fault_inputs + self.stall_warning_inputs
                                + self.stall_error_inputs)))


QUBE_SERVO_2 = Device(
    board_type="qube_servo2_usb", analog_outputs=(0,), digital_outputs=(0,), analog_inputs=(0,),
    encoder_inputs=(0, 1), other_inputs=(14000,), led_outputs=(11000, 11001, 11002),
    amplifier_fault_inputs=(0,), stall_warning_inputs=(1,), stall_error_inputs=(2,), arm_encoder=0)
"""Quanser Qube-Servo 2 (QUARC card qube_servo2_usb)."""

QUBE_SERVO_3 = dataclasses.replace(
    QUBE_SERVO_2, board_type="qube_servo3_usb", other_inputs=(14000, 14001),
    card_options=("deadband_compensation=0.3;pwm_en=0;enc0_velocity=3.0;enc1_velocity=3.0;"
                  "min_diode_compensation=0.3;max_diode_compensation=1.5"))
"""Quanser Qube-Servo 3 (QUARC card qube_servo3_usb): the Qube-Servo 2's channels plus the pendulum
tachometer (other input 14001, counts/s), and the card options Quanser's own Python library sets on
it (`QubeServo3(boardSpecificOptions=...)` default in Quanser_Academic_Resources,
0_libraries/python/pal/products/qube.py; QUARC's generated Qube-Servo 3 models set the same
`deadband_compensation`, `pwm_en=0` and `enc*_velocity` options)."""

DEVICES = {"qube_servo2": QUBE_SERVO_2, "qube_servo3": QUBE_SERVO_3}
"""Qubes by name, as `device=` takes them."""

MAX_FREQUENCY = 10000.0
"""Highest sample rate (Hz) the wrapper accepts: the substitute's plant integrates at 10 kHz."""

REST_CHECK_TIME = 0.2
"""With zero_encoders=True, open() zeroes the encoders only after no count moved by more than one from
where it was over this long (s): a Qube at rest (a count may flicker at its edge), not one moving."""

MAX_WATCHDOG_TIMEOUT = 0.15
"""Largest `watchdog_timeout` (s). The watchdog is what stops the motor when the process driving it
dies or hangs; it must expire before an arm driven from rest at its centre reaches the 120 degree
arm limit: 0.16 s at 10 V on the substitute's estimated plant (0.23 s at 5 V, 0.37 s at 2 V), 0.18 s on
the real Qube's (0.25 s, 0.41 s)."""

RETURN_VOLTAGE = 3.0
"""Largest voltage (V) `return_arm` lets through while the arm is beyond `arm_limit`."""

RETURN_CURRENT = 0.2
"""Largest motor current (A) `return_arm` allows for longer than `RETURN_HELD_TIME` while the arm is
beyond `arm_limit`: a free arm turning slowly draws a few tens of mA, a held one (the end of its
travel, a tangled cable, a hand) what the voltage drives through the motor's 8.4 ohm, 0.36 A at
`RETURN_VOLTAGE`."""

RETURN_HELD_TIME = 0.1
"""Seconds of current above `RETURN_CURRENT` that mean the arm is held: the current of a start from
rest falls within a few ms, as the arm takes up speed."""

RETURN_SLACK = math.radians(5.0)
"""How much farther out (rad) than at the last sample of 0 V the arm may get while `return_arm`
pushes it inwards beyond `arm_limit` before the return stops (the motor would be driving it out)."""

LED_OFF_STATE = (1.0, 0.0, 0.0)
"""The LED's colour after `close()`: red."""


def _hil_api(simulated: bool) -> tuple[Any, Any, Any, type[Exception]]:
    """(HIL class, Clock, BufferOverflowMode, HILError) of the substitute or of Quanser's SDK."""
    if simulated:
        try:
            from qube_suite.hardware import _hil_sim
        except ImportError as error:
            raise ImportError("the substitute board is a compiled extension that is missing; reinstall "
                              "qube_suite from source (pip install -e .) to build it") from error
        return _hil_sim.HIL, _hil_sim.Clock, _hil_sim.BufferOverflowMode, _hil_sim.HILError
    try:
        from quanser.hardware import HIL, Clock, HILError
        from quanser.hardware.enumerations import BufferOverflowMode
    except ImportError as error:
        raise QuanserSDKNotFoundError(SDK_HELP) from error
    except OSError as error:  # the Python package is there, its native HIL library is not
        raise QuanserSDKNotFoundError(f"Quanser's native HIL library could not be loaded ({error}). "
                                      + SDK_HELP) from error
    return HIL, Clock, BufferOverflowMode, HILError


def error_text(error: BaseException) -> str:
    """A board error's text: Quanser's `get_error_message()` and the code where there is one."""
    message = getattr(error, "get_error_message", None)
    code = getattr(error, "error_code", None)
    if callable(message):
        try:
            text = message()
        except Exception:  # a message lookup that fails must not hide the error itself
            text = ""
        if text:
            return text if code is None else f"{text} (error {code})"
    return str(error)


def _real_number(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a number, got {value!r}")
    return float(value)


def _unwind(signum: int, frame: Any) -> NoReturn:
    raise SystemExit(128 + signum)


class _TerminationUnwinds:
    """While a board is open, SIGTERM (`kill`, a job scheduler, a closing session) raises SystemExit
    (exit code 143) in the main thread, so that the program unwinds as after Ctrl-C and stops the
    motor at once; Python's default would end the process on the spot, leaving the board to its
    watchdog. Only where SIGTERM has its default action (a program's own handler is left alone); the
    default comes back when the last board closes."""

    def __init__(self):
        self.open_boards: set[int] = set()

    def hold(self, handle: object) -> None:
        self.open_boards.add(id(handle))
        if (threading.current_thread() is threading.main_thread()
                and signal.getsignal(signal.SIGTERM) is signal.SIG_DFL):
            signal.signal(signal.SIGTERM, _unwind)

    def release(self, handle: object) -> None:
        self.open_boards.discard(id(handle))
        if (not self.open_boards and threading.current_thread() is threading.main_thread()
                and signal.getsignal(signal.SIGTERM) is _unwind):
            signal.signal(signal.SIGTERM, signal.SIG_DFL)


TERMINATION_UNWINDS = _TerminationUnwinds()


class _Handle:
    """What a finaliser needs to leave the board safe when its wrapper is collected or the
    interpreter exits: the board, the task and the channels, never the wrapper itself."""

    def __init__(self, channels: dict[str, np.ndarray]):
        self.board: Any = None
        self.task: Any = None
        self.open = False
        self.channels = channels

    def shut(self) -> list[BaseException]:
        """0 V, LED red, amplifier off, watchdog stopped (after the outputs), task deleted,
        board closed: every step tried; the failures returned."""
        if not self.open:
            return []
        board, task, c = self.board, self.task, self.channels
        errors: list[BaseException] = []

        def attempt(function, *args):
            try:
                return function(*args)
            except BaseException as error:  # a second Ctrl-C must not skip the remaining steps
                errors.append(error)
                return None

        # The writes come first, whatever the board would answer to a query: an expired watchdog
        # refuses them, its expiration states being 0 V and the amplifier off already.
        attempt(board.write_analog, c["analog_outputs"], len(c["analog_outputs"]),
                np.zeros(len(c["analog_outputs"])))
        attempt(board.write_digital, c["digital_outputs"], len(c["digital_outputs"]),
                np.zeros(len(c["digital_outputs"]), dtype=np.int8))
        attempt(board.write_other, c["led_outputs"], len(c["led_outputs"]), np.array(LED_OFF_STATE))
        if errors and attempt(board.watchdog_is_expired) is True:
            # The writes were refused by an expired watchdog: the outputs are at their expiration
            # states (0 V, amplifier off), which is what the writes were for.
            errors = [error for error in errors if isinstance(error, (KeyboardInterrupt, SystemExit))]
        attempt(board.watchdog_stop)  # only after the outputs are zeroed
        if task is not None:
            attempt(board.task_stop, task)
            attempt(board.task_delete, task)
        attempt(board.close)
        self.task, self.open = None, False
        attempt(TERMINATION_UNWINDS.release, self)
        return errors


class QuanserWrapper:
    """A Quanser device's board as a context manager that keeps the motors safe.

    device: the channel declaration. board: "simulated" (the substitute board) or
    the device's board type (a real board through Quanser's SDK). identifier: the
    board number. frequency (Hz): the sample rate that `action` follows.
    max_voltage (V): the clip. plant: parameters of the substitute's plant
    (`qube_suite.hardware.plant`) by long name, changing the board's default plant
    (`plant.DEFAULT_PLANTS`), a named plant (`plant.PLANTS`), or a device's own
    plant for it (`qube_suite.hardware.board_plant.BoardPlant`). realtime: the substitute follows the
    wall clock (default False, fast); a real board always does. watchdog_timeout (s): the
    board zeroes its outputs when no action reloads it for this long.
    arm_limit (rad, or None): the largest arm angle from the arm encoder's zero.
    max_missed_samples (or None): the largest gap between two actions, in samples.
    max_encoder_speed (rad/s, or None): the fastest any encoder may turn between two
        samples; a larger jump of the count is a glitch.
    zero_encoders: zero the encoders at every open() where the Qube rests; default False:
        keep the board's counts (see the module docstring).
    """

    def __init__(self, device: Device, board: str = SIMULATED, identifier: str = "0", *,
                 frequency: float = 250.0, max_voltage: float = 10.0,
                 plant: dict[str, float] | str | BoardPlant | None = None, realtime: bool | None = None,
                 watchdog_timeout: float = 0.1, arm_limit: float | None = math.radians(120.0),
                 max_missed_samples: int | None = 10, max_encoder_speed: float | None = MAX_ENCODER_SPEED,
                 zero_encoders: bool = False):
        if board not in (SIMULATED, device.board_type):
            cards = ", ".join(f"{d.board_type} for {name}" for name, d in DEVICES.items())
            raise ValueError(f"board must be {SIMULATED!r} or {device.board_type!r}, got {board!r} "
                             f"(the Qubes' cards: {cards})")
        simulated = board == SIMULATED
        if not simulated and plant is not None:
            raise ValueError("plant= sets the substitute board's plant; a real board has its own physics")
        if realtime is not None and not isinstance(realtime, bool):
            raise TypeError(f"realtime must be True, False or None, got {realtime!r}")
        if not simulated and realtime is False:
            raise ValueError("a real board always runs in real time")
        if not isinstance(zero_encoders, bool):
            raise TypeError(f"zero_encoders must be True or False, got {zero_encoders!r}")
        if not isinstance(identifier, str):
            raise TypeError(f"identifier must be a string such as '0', got {identifier!r}")
        frequency = _real_number("frequency", frequency)
        max_voltage = _real_number("max_voltage", max_voltage)
        watchdog_timeout = _real_number("watchdog_timeout", watchdog_timeout)
        for name, value in (("frequency", frequency), ("max_voltage", max_voltage),
                            ("watchdog_timeout", watchdog_timeout)):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be positive, got {value}")
        if watchdog_timeout > MAX_WATCHDOG_TIMEOUT:
            raise ValueError(f"watchdog_timeout must be at most {MAX_WATCHDOG_TIMEOUT:g} s "
                             "(MAX_WATCHDOG_TIMEOUT: longer leaves a dead process's motor driven too long), "
                             f"got {watchdog_timeout:g}")
        if max_voltage > device.amplifier_range:
            raise ValueError(f"max_voltage must be at most the amplifier's {device.amplifier_range:g} V, "
                             f"got {max_voltage}")
        if frequency > MAX_FREQUENCY:
            raise ValueError(f"frequency must be at most {MAX_FREQUENCY:g} Hz, got {frequency}")
        if 2.0 / frequency > watchdog_timeout:
            raise ValueError(
                f"frequency {frequency:g} Hz cannot keep the {watchdog_timeout:g} s watchdog fed (one action "
                f"per sample, at least two per timeout): use at least {2.0 / watchdog_timeout:g} Hz")
        if arm_limit is not None and not (math.isfinite(_real_number("arm_limit", arm_limit))
                                          and arm_limit > 0):
            raise ValueError(f"arm_limit must be positive or None, got {arm_limit}")
        if max_missed_samples is not None and (isinstance(max_missed_samples, bool)
                                               or not isinstance(max_missed_samples, numbers.Integral)):
            raise TypeError(f"max_missed_samples must be an int or None, got {max_missed_samples!r}")
        if max_missed_samples is not None and max_missed_samples < 0:
            raise ValueError(f"max_missed_samples must be >= 0 or None, got {max_missed_samples}")
        if max_encoder_speed is not None and not (math.isfinite(_real_number("max_encoder_speed",
                                                                             max_encoder_speed))
                                                  and max_encoder_speed > 0):
            raise ValueError(f"max_encoder_speed must be positive or None, got {max_encoder_speed}")
        scales = device.radians_per_count
        if scales is not None and len(scales) != len(device.encoder_inputs):
            raise ValueError("radians_per_count needs one scale per encoder input")
        if isinstance(plant, BoardPlant):
            if plant.channels.card_type != device.board_type:
                raise ValueError(f"the plant is a {plant.channels.card_type}'s, "
                                 f"the device a {device.board_type}")
        elif simulated:
            plant_parameters(device.board_type, plant)  # a misspelt name fails now, not at open()
        self.device = device
        self.board_name = board
        self.identifier = identifier
        self.frequency = float(frequency)
        self.max_voltage = float(max_voltage)
        self.plant = plant if plant is None or isinstance(plant, (BoardPlant, str)) else dict(plant)
        self.realtime = bool(realtime) if simulated else True
        self.watchdog_timeout = float(watchdog_timeout)
        self.arm_limit = arm_limit
        self.max_missed_samples = max_missed_samples
        self.max_encoder_speed = max_encoder_speed
        self.zero_encoders = zero_encoders
        """Zero the encoders at every open() (else keep the board's counts)."""
        self.missed_samples = 0
        self.stall_warning = False
        self.encoders_zeroed = False
        """True if the last open() zeroed the encoders."""
        self._idle = False

        d = device
        self._channels = {name: np.array(getattr(d, name), dtype=np.uint32) for name in (
            "analog_outputs", "digital_outputs", "analog_inputs", "encoder_inputs", "other_inputs",
            "led_outputs", "digital_inputs")}
        self._currents = np.zeros(len(d.analog_inputs))
        self._encoders = np.zeros(len(d.encoder_inputs), dtype=np.int32)
        self._digitals = np.zeros(len(d.digital_inputs), dtype=np.int8)
        self._others = np.zeros(len(d.other_inputs))
        self._zero_volts = np.zeros(len(d.analog_outputs))
        self._volts = np.zeros(len(d.analog_outputs))
        self._rgb = np.zeros(len(d.led_outputs))
        self._fault_at = [d.digital_inputs.index(c) for c in d.amplifier_fault_inputs]
        self._warning_at = [d.digital_inputs.index(c) for c in d.stall_warning_inputs]
        self._stall_at = [d.digital_inputs.index(c) for c in d.stall_error_inputs]
        self._arm_at = None if d.arm_encoder is None else d.encoder_inputs.index(d.arm_encoder)
        self._overflows_seen: int | None = None
        self._return_from: float | None = None  # abs(arm angle) where return_arm() began beyond the limit
        self._held_samples = 0  # samples in a row of return_arm() beyond the limit above RETURN_CURRENT
        self._last_counts: list[int] | None = None  # encoder counts of the last sample, for the glitch check
        self._board_error: type[Exception] = Exception  # the board's HILError class, set at open()
        self._clear_samples: Any = None  # the substitute's compiled sample call, set at open()
        self._handle = _Handle(self._channels)
        # Garbage collection and interpreter exit leave the board safe too (the handle, not `self`).
        self._finalizer = weakref.finalize(self, self._handle.shut)

    # The board's state lives in the handle that the finaliser shares.
    _board = property(lambda self: self._handle.board)
    _task = property(lambda self: self._handle.task)
    _open = property(lambda self: self._handle.open)

    def __getstate__(self) -> NoReturn:
        raise TypeError(f"a {type(self).__name__} drives a board, which cannot be copied or pickled: make a "
                        "new one (or a new environment) in the other process")

    # -- opening and closing ---------------------------------------------------------------

    @property
    def board(self) -> Any:
        """The HIL object in use (also after `close()`, for inspection); None before `open()`."""
        return self._board

    @property
    def is_open(self) -> bool:
        """True between `open()` and `close()`."""
        return self._open

    def __enter__(self) -> QuanserWrapper:
        self.open()
        return self

    def __exit__(self, exc_type, exc, traceback) -> None:
        self.close()

    def open(self, zero_encoders: bool | None = None) -> None:
        """Open the board, write 0 V, start the reader task, enable the amplifier, start the watchdog.

        The encoders keep the board's counts unless `zero_encoders` (default: the wrapper's
        `zero_encoders`) asks to zero them where the Qube rests (`NotAtRestError` if it moves).
        """
        if zero_encoders is None:
            zero_encoders = self.zero_encoders
        if not isinstance(zero_encoders, bool):
            raise TypeError(f"zero_encoders must be True, False or None, got {zero_encoders!r}")
        if self._open:
            raise RuntimeError("the board is already open")
        simulated = self.board_name == SIMULATED
        hil_class, clock, overflow_mode, self._board_error = _hil_api(simulated)
        board = hil_class(plant=self.plant, realtime=self.realtime) if simulated else hil_class()
        try:
            board.open(self.device.board_type, self.identifier)
        except Exception as error:
            raise BoardOpenError(
                f"could not open the {self.device.board_type} board {self.identifier!r}: "
                f"{error_text(error)}; check that it is connected and powered and that no other program has "
                "it open") from error
        handle = self._handle
        handle.board, handle.task, handle.open, self._idle = board, None, True, False
        self._clear_samples = None
        TERMINATION_UNWINDS.hold(handle)
        self.missed_samples, self.stall_warning, self._overflows_seen = 0, False, None
        self._last_counts = None
        c = self._channels
        try:
            if board.watchdog_is_expired():  # left expired by an earlier run that died: unlock the outputs
                board.watchdog_clear()
            if self.device.card_options:
                board.set_card_specific_options(self.device.card_options, len(self.device.card_options) + 1)
            board.write_analog(c["analog_outputs"], len(c["analog_outputs"]), self._zero_volts)
            board.write_digital(c["digital_outputs"], len(c["digital_outputs"]),
                                np.zeros(len(c["digital_outputs"]), dtype=np.int8))
            handle.task = board.task_create_reader(
                1, c["analog_inputs"], len(c["analog_inputs"]), c["encoder_inputs"], len(c["encoder_inputs"]),
                c["digital_inputs"], len(c["digital_inputs"]), c["other_inputs"], len(c["other_inputs"]))
            board.task_set_buffer_overflow_mode(self._task, overflow_mode.OVERWRITE_ON_OVERFLOW)
            # Quanser's older Python API has no HIL.INFINITE; -1 is its value in the C API.
            board.task_start(self._task, clock.HARDWARE_CLOCK_0, self.frequency,
                             getattr(hil_class, "INFINITE", -1))
            self.encoders_zeroed = False
            if zero_encoders:
                if not self._at_rest(board):
                    raise NotAtRestError(
                        "the Qube moved while its encoders were to be zeroed: let the pendulum hang still, "
                        "centre the arm and open again")
                board.set_encoder_counts(c["encoder_inputs"], len(c["encoder_inputs"]),
                                         np.zeros(len(c["encoder_inputs"]), dtype=np.int32))
                self.encoders_zeroed = True
            board.watchdog_set_analog_expiration_state(c["analog_outputs"], len(c["analog_outputs"]),
                                                       self._zero_volts)
            board.watchdog_set_digital_expiration_state(  # 0 = DigitalState.LOW: amplifiers disabled
                c["digital_outputs"], len(c["digital_outputs"]),
                np.zeros(len(c["digital_outputs"]), dtype=np.int32))
            board.write_digital(c["digital_outputs"], len(c["digital_outputs"]),
                                np.ones(len(c["digital_outputs"]), dtype=np.int8))
            self._overflows_seen = None
            board.watchdog_start(self.watchdog_timeout)
            self._clear_samples = self._compiled_samples(hil_class, board)
        except BaseException as error:
            self.close()
            if isinstance(error, self._board_error):
                raise BoardIOError(
                    f"could not set up the {self.device.board_type} board: {error_text(error)}") from error
            raise

    def _compiled_samples(self, hil_class: Any, board: Any) -> Any:
        """The substitute's `ClearSamples` for this wrapper's samples in fast mode (the substitute
        itself, its channels as the device declares them), else None: every sample then goes
        through the board calls and checks of `_act` one by one."""
        from qube_suite.hardware import _hil_sim

        d = self.device
        if (hil_class is not _hil_sim.HIL or type(board) is not _hil_sim.HIL or self.realtime
                or d.analog_outputs != (0,) or d.led_outputs != _hil_sim.OTHER_LED
                or d.radians_per_count is not None):
            return None
        return _hil_sim.ClearSamples(
            board, self._task, self._currents, self._encoders, self._digitals, self._others, self._volts,
            -1 if self._arm_at is None else self._arm_at,
            conventions.ARM_SIGN * conventions.RADIANS_PER_COUNT, conventions.RADIANS_PER_COUNT)

    def _at_rest(self, board: Any) -> bool:
        """True if no encoder count moved by more than one from where it was over `REST_CHECK_TIME`
        of samples (amplifier off)."""
        first = None
        for _ in range(max(2, round(REST_CHECK_TIME * self.frequency))):
            board.task_read(self._task, 1, self._currents, self._encoders, self._digitals, self._others)
            if first is None:
                first = self._encoders.astype(np.int64)
            elif np.abs(self._encoders - first).max() > 1:
                return False
        return True

    def close(self) -> None:
        """Stop the motor and close the board: every step is tried; the first failure is raised after."""
        errors = self._handle.shut()
        if errors:
            raise errors[0]

    # -- the control loop ------------------------------------------------------------------

    def action(self, voltages: float | Sequence[float] | np.ndarray, led: Sequence[float] | None = None,
               *, copy: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Wait for the next sample, check safety, apply `voltages` (V) and optionally an LED colour.

        Returns (currents, encoders, others) of that sample in board units and signs: new arrays,
        or with `copy` False the wrapper's own reading buffers, which every later sample
        overwrites (for a loop that reads them before its next action: no arrays made per sample).
        Raises ValueError after writing 0 V, or a `SafetyStopError` after stopping the motor (0 V,
        amplifier disabled: idle).
        """
        return self._act(voltages, led, False, copy)

    def return_arm(self, voltages: float | Sequence[float] | np.ndarray, led: Sequence[float] | None = None,
                   *, copy: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """`action`, for bringing back an arm that is beyond `arm_limit` (where `action` stops).

        While the arm is beyond the limit, each sample stops the motor with `ArmLimitError`
        unless its voltage drives the arm towards its zero (or is 0) and is at most
        `RETURN_VOLTAGE`, the motor current has not stayed above `RETURN_CURRENT` for
        `RETURN_HELD_TIME` (the arm is held), and the arm is no more than `RETURN_SLACK` farther
        out than it was at the last sample of 0 V (an arm still coasting outwards at 0 V is
        braked by the motor's back-EMF, not driven). Within the limit it is `action`. The device's first
        analog output drives the arm encoder's joint.
        """
        return self._act(voltages, led, True, copy)

    def _act(self, voltages, led, returning: bool, copy: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        board = self._require_open()
        if self._idle:
            raise RuntimeError("the board is idle: call resume() before action()")
        compiled, given = self._clear_samples, None  # given: (reloaded, overflows) of a sample read
        try:
            if compiled is not None:  # a plain action is checked, clipped, read, reloaded and, where no
                outcome = compiled.sample_given(  # check below could stop, written in one compiled call
                    voltages, led, self.max_voltage, self._overflows_seen, self._last_counts,
                    self.max_missed_samples, self.max_encoder_speed, self.frequency, self.arm_limit)
                if outcome is None:
                    return self._after_clear_sample(copy)
                if outcome is not False:  # read, not clear: the checks below decide
                    given = outcome
        except self._board_error as error:
            self._stop(BoardIOError(f"the board could not deliver a sample: {error_text(error)}"), error)
        if given is None:  # not read yet: the action's checks first
            volts = self._checked_voltages(voltages)
            rgb = None if led is None else self._checked_led(led)
        else:  # what the action's checks return for a plain action
            volts, rgb = self._volts, led
        try:
            if given is not None:
                reloaded, overflows = given
            elif compiled is None:
                board.task_read(self._task, 1, self._currents, self._encoders, self._digitals, self._others)
                reloaded, overflows = None, None  # asked below
            else:  # read, reload and, where no check below could stop, write in one compiled call
                outcome = compiled.sample(  # the checks' settings as they are now
                    rgb, self._overflows_seen, self._last_counts, self.max_missed_samples,
                    self.max_encoder_speed, self.frequency, self.arm_limit)
                if outcome is None:
                    return self._after_clear_sample(copy)
                reloaded, overflows = outcome
        except self._board_error as error:
            self._stop(BoardIOError(f"the board could not deliver a sample: {error_text(error)}"), error)
        if not (board.watchdog_reload() if reloaded is None else reloaded):
            self._stop(WatchdogExpiredError(
                f"the watchdog expired: no action for {self.watchdog_timeout} s, so the board zeroed its "
                "outputs; resume() drives again"))
        missed = self._check_missed_samples(board, overflows)
        self._check_amplifier()
        self._check_encoders(missed)
        self._check_arm(volts[0], returning)
        try:
            board.write_analog(self._channels["analog_outputs"], len(volts), volts)
            if rgb is not None:
                if type(rgb) is tuple:
                    self._rgb[:] = rgb
                    rgb = self._rgb
                board.write_other(self._channels["led_outputs"], len(rgb), rgb)
        except self._board_error as error:
            if board.watchdog_is_expired():  # it expired after the reload (the process was held up)
                self._stop(WatchdogExpiredError(
                    f"the watchdog expired between a sample and its action (no action for "
                    f"{self.watchdog_timeout} s), so the board zeroed its outputs; resume() drives again"),
                    error)
            self._stop(BoardIOError(f"the board refused the voltage: {error_text(error)}"), error)
        return self._readings(copy)

    def _readings(self, copy: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The last sample's (currents, encoders, others): copies, or the buffers themselves."""
        if copy:
            return self._currents.copy(), self._encoders.copy(), self._others.copy()
        return self._currents, self._encoders, self._others

    def _after_clear_sample(self, copy: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What the checks of `_act` leave after a sample that `ClearSamples` found clear and wrote:
        no sample missed, no flag set, the counts kept for the next glitch check, the arm within
        its limit; `_act`'s readings."""
        self.stall_warning = False
        self._last_counts = self._encoders.tolist()
        if self.arm_limit is not None and self._arm_at is not None:
            self._return_from, self._held_samples = None, 0
        return self._readings(copy)

    def idle(self) -> None:
        """Stop driving until `resume()`: 0 V, amplifier disabled, watchdog stopped.

        For pauses between episodes, when no action comes for longer than the
        watchdog allows; the reader task keeps sampling and the encoders keep counting.
        """
        board = self._require_open()
        c = self._channels
        self._idle = True
        refused = None
        amplifiers_off = np.zeros(len(c["digital_outputs"]), dtype=np.int8)
        for write, channels, zeros in ((board.write_analog, c["analog_outputs"], self._zero_volts),
                                       (board.write_digital, c["digital_outputs"], amplifiers_off)):
            try:  # both writes, whatever a query would answer: nothing may skip them
                write(channels, len(channels), zeros)
            except self._board_error as error:
                refused = refused or error
        if refused is not None and board.watchdog_is_expired() is not True:
            raise BoardIOError(f"could not stop the motor: {error_text(refused)}") from refused
        board.watchdog_stop()  # only now: until here the watchdog still guards the outputs

    def resume(self) -> None:
        """Drive again after `idle()`: enable the amplifier and restart the watchdog; samples
        that passed while idle do not count as missed."""
        board = self._require_open()
        if not self._idle:
            return
        c = self._channels
        self._overflows_seen = None
        try:
            if board.watchdog_is_expired():
                board.watchdog_clear()
            board.write_analog(c["analog_outputs"], len(c["analog_outputs"]), self._zero_volts)
            board.write_digital(c["digital_outputs"], len(c["digital_outputs"]),
                                np.ones(len(c["digital_outputs"]), dtype=np.int8))
            board.watchdog_start(self.watchdog_timeout)
        except self._board_error as error:
            raise BoardIOError(f"could not resume driving: {error_text(error)}") from error
        self._idle = False
        self._last_counts = None  # the Qube may have moved while idle
        self._return_from, self._held_samples = None, 0

    @property
    def is_idle(self) -> bool:
        """True between `idle()` and `resume()`."""
        return self._idle

    def reset_encoders(self, channels: Sequence[int] | None = None) -> None:
        """Make encoder `channels` (default: all read) count from 0 at their present positions."""
        board = self._require_open()
        chosen = np.array(self.device.encoder_inputs if channels is None else channels, dtype=np.uint32)
        unknown = set(chosen.tolist()) - set(self.device.encoder_inputs)
        if unknown:
            raise ValueError(f"encoder channels {sorted(unknown)} are not read; "
                             f"valid: {self.device.encoder_inputs}")
        board.set_encoder_counts(chosen, len(chosen), np.zeros(len(chosen), dtype=np.int32))
        self._last_counts = None

    # -- safety ----------------------------------------------------------------------------

    def _require_open(self) -> Any:
        handle = self._handle
        if not handle.open:
            raise RuntimeError("the board is not open: use `with QubeServo2(...) as qube:` or call open()")
        return handle.board

    def zero_voltage(self) -> None:
        """Write 0 V now (the amplifier stays enabled, the watchdog running: the next `action` drives
        again); what a refused action does. Refused only by an expired watchdog, which did it already."""
        board = self._require_open()
        try:
            board.write_analog(self._channels["analog_outputs"], len(self._zero_volts), self._zero_volts)
        except self._board_error:
            if board.watchdog_is_expired() is not True:
                raise

    def _stop(self, error: HardwareError, cause: BaseException | None = None) -> NoReturn:
        """Stop driving (0 V, amplifier disabled, watchdog stopped: idle) and raise `error`."""
        try:
            self.idle()
        except BaseException as failure:
            raise error from failure
        raise error from cause

    def _refuse(self, message: str) -> NoReturn:
        self.zero_voltage()
        raise ValueError(message)

    def _checked_voltages(self, voltages) -> np.ndarray:
        n = len(self._volts)
        if type(voltages) is list and len(voltages) == n and (  # the common cases, without building an array
                type(voltages[0]) is float if n == 1 else all(type(v) is float for v in voltages)):
            return self._clipped(voltages, voltages)
        if type(voltages) is float and n == 1:
            return self._clipped([voltages], voltages)
        try:
            values = np.asarray(voltages)
        except (TypeError, ValueError):
            self._refuse(f"voltages must be numbers, got {voltages!r}")
        if values.dtype.kind not in "fiu":  # no text, booleans, complex numbers or objects
            self._refuse(f"voltages must be real numbers, got {voltages!r} of dtype {values.dtype}")
        if values.shape == () and n == 1:
            values = values.reshape(1)
        if values.shape != (n,):
            self._refuse(f"voltages must have shape ({n},), got {values.shape}")
        return self._clipped(values.astype(np.float64).tolist(), values)

    def _clipped(self, values: list[float], given) -> np.ndarray:
        """`values` (V, one per analog output) clipped to +-max_voltage into the output buffer;
        refused (0 V, ValueError naming `given`) unless all are finite."""
        limit, volts = self.max_voltage, self._volts
        for j, value in enumerate(values):
            if not math.isfinite(value):
                self._refuse(f"voltages must be finite, got {given}")
            volts[j] = -limit if value < -limit else limit if value > limit else value
        return volts

    def _checked_led(self, led) -> tuple[float, ...] | np.ndarray:
        """`led` itself if it is a tuple of floats in [0, 1] (the common case, without building an
        array), else an array of its values; refused (0 V, ValueError) unless one number in [0, 1]
        for each LED output."""
        if type(led) is tuple and len(led) == len(self._rgb):
            for x in led:  # a loop, not all(...): no generator or list built per sample
                if not (type(x) is float and 0.0 <= x <= 1.0):  # NaN fails the comparison
                    break
            else:
                return led
        try:
            rgb = np.array(led, dtype=np.float64)  # a copy of its own, contiguous whatever `led` is
        except (TypeError, ValueError):
            self._refuse(f"led must be {len(self.device.led_outputs)} numbers in [0, 1], got {led!r}")
        if rgb.shape != (len(self.device.led_outputs),) or not (np.isfinite(rgb).all()
                                                               and (rgb >= 0).all() and (rgb <= 1).all()):
            self._refuse(f"led must be {len(self.device.led_outputs)} numbers in [0, 1], got {led!r}")
        return rgb

    def _check_missed_samples(self, board, overflows: int | None = None) -> int:
        """Count the samples missed since the last action (returned) and stop if too many; `overflows`:
        the board's overflow count, if already asked."""
        if overflows is None:
            overflows = board.task_get_buffer_overflows(self._task)
        missed = 0 if self._overflows_seen is None else overflows - self._overflows_seen
        self._overflows_seen = overflows
        self.missed_samples += missed
        if self.max_missed_samples is not None and missed > self.max_missed_samples:
            self._stop(MissedSamplesError(
                f"{missed} samples at {self.frequency:g} Hz passed between two actions (at most "
                f"{self.max_missed_samples} allowed); {self.missed_samples} missed since open()"))
        return missed

    def _check_amplifier(self) -> None:
        flags = self._digitals.tolist()
        self.stall_warning = any(flags[i] for i in self._warning_at)
        if any(flags[i] for i in self._fault_at):
            self._stop(AmplifierFaultError("the amplifier reports a fault (e.g. overheating)"))
        if any(flags[i] for i in self._stall_at):
            self._stop(MotorStallError("the amplifier reports a motor stall and has disabled itself; reopen "
                                       "the board once the motor is free"))

    def _check_encoders(self, missed: int) -> None:
        """Stop if a count moved farther since the last sample (`missed` samples ago, plus one)
        than `max_encoder_speed` allows: more than the Qube can turn."""
        counts = self._encoders.tolist()
        last, self._last_counts = self._last_counts, counts
        if self.max_encoder_speed is None or last is None:
            return
        turn = self.max_encoder_speed * (missed + 1) / self.frequency
        for channel, scale, now, before in zip(self.device.encoder_inputs, self.device.encoder_scales, counts,
                                               last, strict=True):
            limit = turn / scale + 1
            if abs(now - before) > limit:
                self._last_counts = None
                self._stop(EncoderGlitchError(
                    f"encoder {channel} jumped {now - before} counts in {missed + 1} sample(s), more than "
                    f"{limit:.0f} (max_encoder_speed = {self.max_encoder_speed:g} rad/s): the position "
                    "reference is lost; close the board, put the Qube at its start position (pendulum "
                    "hanging, arm centred) and open it again"))

    def _check_arm(self, volts: float, returning: bool) -> None:
        """Stop if the arm is beyond `arm_limit`, unless `returning` it by `return_arm`'s rules with
        `volts` (board units) on the first analog output."""
        if self.arm_limit is None or self._arm_at is None:
            return
        angle = conventions.arm_angle(int(self._encoders[self._arm_at]))
        if abs(angle) <= self.arm_limit:
            self._return_from, self._held_samples = None, 0
            return
        where = (f"the arm is {math.degrees(abs(angle)):.0f} degrees from its zero (the centre), beyond "
                 f"arm_limit = {math.degrees(self.arm_limit):.0f} degrees")
        if not returning:
            self._stop(ArmLimitError(f"{where}; return_arm() may drive it back"))
        if self._return_from is None or volts == 0.0:  # coasting out at 0 V is not the motor's doing
            self._return_from = max(self._return_from or 0.0, abs(angle))
        held = abs(float(self._currents[0])) > RETURN_CURRENT if len(self._currents) else False
        self._held_samples = self._held_samples + 1 if held else 0
        if conventions.ARM_SIGN * volts * angle > 0.0 or abs(volts) > RETURN_VOLTAGE:
            self._stop(ArmLimitError(f"{where}: only at most {RETURN_VOLTAGE:g} V towards the centre may "
                                     f"bring it back, not {conventions.ARM_SIGN * volts:g} V"))
        if self._held_samples > RETURN_HELD_TIME * self.frequency:
            self._stop(ArmLimitError(f"{where}, and it is held: the motor current stayed above "
                                     f"{RETURN_CURRENT:g} A for {RETURN_HELD_TIME:g} s: free it"))
        if abs(angle) > self._return_from + RETURN_SLACK:
            self._stop(ArmLimitError(f"{where}, and moving away from the centre while being brought back"))


class QubeServo2(QuanserWrapper):
    """Quanser Qube-Servo 2: one motor, arm and pendulum encoders, tachometer, LED.

    QubeServo2(frequency=250, max_voltage=10, board="simulated" | "qube_servo2_usb",
    identifier="0", plant=None, realtime=None, ...): see `QuanserWrapper`.
    """

    def __init__(self, frequency: float = 250.0, max_voltage: float = 10.0, *, board: str = SIMULATED,
                 identifier: str = "0", **options: Any):
        super().__init__(QUBE_SERVO_2, board, identifier, frequency=frequency, max_voltage=max_voltage,
                         **options)


class QubeServo3(QuanserWrapper):
    """Quanser Qube-Servo 3, on the same channels (board="simulated" | "qube_servo3_usb")."""

    def __init__(self, frequency: float = 250.0, max_voltage: float = 10.0, *, board: str = SIMULATED,
                 identifier: str = "0", **options: Any):
        super().__init__(QUBE_SERVO_3, board, identifier, frequency=frequency, max_voltage=max_voltage,
                         **options)
