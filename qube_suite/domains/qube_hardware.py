"""The hardware Qube: the domain interface over a Quanser board.

`suite.load("qube_hardware", task)` runs a task on a Qube-Servo 2 driven through
`qube_suite.hardware.QubeServo2`: by default the compiled substitute board and
plant (`board="simulated"`, fast: it advances simulated time only); with
`domain_kwargs={"board": "qube_servo2_usb"}` a real Qube through Quanser's SDK,
paced by its hardware clock. Every task in `qube_suite.tasks` runs unchanged.

What differs from the simulated domain, as on a real Qube:

* the board is opened at the first reset (never by a constructor) and closed by
  `close()` / the environment's `close()`; between episodes it idles (0 V,
  amplifier off);
* angles are the quantised encoder angles; velocities come from Quanser's
  50 s/(s + 50) filter (`hardware.estimation`), so they lag by about 20 ms;
* a step reads the board's next sample and then writes the voltage, as the
  Quanser toolkits do: a voltage takes effect one sample after the observation
  it answers (`latency_steps` = 1, which `baselines.for_environment` passes to
  the controllers, as do the reset controllers; the simulated domain's is 0);
* randomization effects on the state or the voltage (`set_sensor_model`,
  `set_actuator_model`: noise, delays, dead-zone, ...) apply to what tasks see and
  send; the reset controllers work on the plain estimate. Physical parameters and
  control-period jitter belong to the plant and cannot be randomized here;
* starts are reached by reset controllers (`qube_suite.baselines`), with the LED
  yellow while they drive: "settle hanging" (dampen), "swing up and hold"
  (swing-up with LQR balance) for starts near upright, and for other starts
  (dampen's arbitrary swing) settle, then pump energy until the pendulum swings
  with the energy of the requested start. A start the controllers cannot reach
  within `reset_timeout` raises `ResetError`;
* anything that raises during a step or a reset (a safety stop, a board error,
  Ctrl-C, a failing controller) first stops the motor: the board idles (0 V,
  amplifier disabled) and the next reset drives again, or, after an encoder
  glitch, which loses the position reference, the board is closed and the next
  reset opens it afresh (zeroing the encoders where the Qube is then).
"""

from __future__ import annotations

import gc
import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from dm_control.rl import control

from qube_suite import baselines
from qube_suite.angles import wrap_angle
from qube_suite.arguments import keywords_of
from qube_suite.baselines.model import RigidBodyModel
from qube_suite.domains.interface import MeasuredState
from qube_suite.hardware import conventions
from qube_suite.hardware.errors import EncoderGlitchError, HardwareError
from qube_suite.hardware.estimation import StateEstimator
from qube_suite.hardware.plant import BOARD_MOTORS
from qube_suite.hardware.quanser import DEVICES, SIMULATED, QuanserWrapper

RESET_CONTROLLERS = ("dampen", "swingup")
"""The controllers that reach the episodes' starts; built before the board samples."""

RESET_LED = (1.0, 1.0, 0.0)
"""Yellow: a reset controller is driving."""

DEFAULT_RESET_VOLTAGE_LIMIT = 6.0
"""Largest voltage (V) the reset controllers use."""

DEFAULT_RESET_TIMEOUT = 30.0
"""Longest a reset may take (s of board time)."""

NEAR_GOAL = math.radians(30.0)
"""Starts within 30 degrees of upright are reached by swing-up and hold; within 30
degrees of hanging, by settling; others by pumping energy."""

WILD_SWING = 3.0
"""Pendulum speed (rad/s) above which an upright start first settles the pendulum hanging: the
swing-up catches a pendulum that starts near rest, not one swinging wildly."""

HOLD_TIME = 0.5
"""A reset is done when its condition has held this long (s)."""

ARM_CENTRE_TOLERANCE = math.radians(5.0)
"""With the encoder check on, a hanging reset also centres the arm to within 5 degrees of the zero
set at open() (the reset controllers leave it within about 1 degree on the substitute)."""

PENDULUM_REST_TOLERANCE = 2
"""Encoder counts: with the encoder check on, the pendulum hanging at rest must read pi to within two
counts: its Coulomb friction stops it within a count of hanging, and the zero was itself set at such
a rest, within a count of hanging. More means its zero is lost."""


class _FullCollectionsHeld:
    """Python's full (oldest-generation) garbage collections held off while a board drives.

    A full collection stops the program for as long as its heap takes to scan (up to 0.1 s in
    a process that has loaded MuJoCo and torch): longer than a sample, enough to trip the
    missed-sample stop or the watchdog. While any board drives, the oldest generation's
    threshold is raised out of reach (young generations, which are fast, still collect); when
    the last one idles, the threshold comes back and a full collection runs while the motor is
    off.
    """

    def __init__(self):
        self.holders: set[int] = set()
        self.threshold: int | None = None

    def hold(self, holder: object) -> None:
        if not self.holders:
            young, middle, self.threshold = gc.get_threshold()
            gc.set_threshold(young, middle, 2**31 - 1)
        self.holders.add(id(holder))

    def release(self, holder: object) -> None:
        if id(holder) not in self.holders:
            return
        self.holders.discard(id(holder))
        if not self.holders:
            young, middle, _ = gc.get_threshold()
            gc.set_threshold(young, middle, self.threshold)
            gc.collect()


FULL_COLLECTIONS = _FullCollectionsHeld()


class ResetError(HardwareError):
    """A reset controller did not reach the episode's start in time."""


class EncoderCheckError(HardwareError):
    """Between episodes, the pendulum hung at rest but its encoder did not read hanging: the encoder's
    zero is lost (missed counts, or the board was opened with the pendulum swinging)."""


class Physics(MeasuredState, control.Physics):
    """A Qube on a Quanser board, through the domain interface (`domains.interface.QubePhysics`).

    Args:
        control_frequency: sample rate of the board (Hz); one `step` is one sample.
        device: "qube_servo2" or "qube_servo3": which Qube (its channels, its motor data in the
            substitute's plant and in the model of the reset controllers). Default: the one
            `board` names, else "qube_servo2".
        board: "simulated" (the substitute) or the device's card type, "qube_servo2_usb" or
            "qube_servo3_usb" (a real Qube).
        plant: parameters of the substitute's plant (`qube_suite.hardware.plant`).
        realtime: pace the substitute by the wall clock (a real board always is).
        max_voltage: the wrapper's voltage clip (V).
        reset_voltage_limit: largest voltage of the reset controllers (V).
        reset_timeout: longest a reset may take (s).
        identifier: the board's number.
        check_encoders: at each reset that settles the pendulum hanging, centre the arm to within
            `ARM_CENTRE_TOLERANCE` (5 degrees) and check that the pendulum, hanging at rest, reads
            pi to within `PENDULUM_REST_TOLERANCE` (one count); else raise `EncoderCheckError`
            (`ResetError` if the arm cannot be centred). Default True.
    """

    latency_steps = 1
    """A step reads the next sample, then writes its voltage: the voltage acts one sample after the
    observation it answers (`interface.QubePhysics.latency_steps`)."""

    paced_by_board = True
    """The board's clock paces every step: nothing slower than a sample (rendering, plotting) may
    run inside the loop; videos are filmed from the recorded trace after an episode."""

    physics_error = None
    """Always None: faults on hardware raise instead (see the safety table in docs/safety.md)."""

    def __init__(self, control_frequency: float = 250.0, board: str = SIMULATED,
                 plant: dict[str, float] | None = None, realtime: bool | None = None,
                 max_voltage: float = 10.0, reset_voltage_limit: float = DEFAULT_RESET_VOLTAGE_LIMIT,
                 reset_timeout: float = DEFAULT_RESET_TIMEOUT, identifier: str = "0",
                 device: str | None = None, check_encoders: bool = True):
        if not isinstance(check_encoders, bool):
            raise TypeError(f"check_encoders must be True or False, got {check_encoders!r}")
        self._check_encoders = check_encoders
        if device is None:
            device = next((name for name, d in DEVICES.items() if d.board_type == board), "qube_servo2")
        if device not in DEVICES:
            raise ValueError(f"unknown device {device!r}; valid: {', '.join(DEVICES)}")
        for name, value in (("max_voltage", max_voltage), ("reset_voltage_limit", reset_voltage_limit),
                            ("reset_timeout", reset_timeout)):
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
                raise TypeError(f"{name} must be a number, got {value!r}")
        if not (0.0 < reset_voltage_limit <= max_voltage):
            raise ValueError(f"reset_voltage_limit must be in (0, max_voltage={max_voltage}] V, "
                             f"got {reset_voltage_limit}")
        if not (math.isfinite(reset_timeout) and reset_timeout > 0.0):
            raise ValueError(f"reset_timeout must be a positive number of seconds, got {reset_timeout}")
        self.device = device
        self.qube = QuanserWrapper(DEVICES[device], board, identifier, frequency=control_frequency,
                                   max_voltage=max_voltage, plant=plant, realtime=realtime)
        self._motor = dict(BOARD_MOTORS[DEVICES[device].board_type])
        self._frequency = float(control_frequency)
        self._estimator = StateEstimator(control_frequency)
        self._reset_voltage_limit = float(reset_voltage_limit)
        self._reset_timeout = float(reset_timeout)
        self._controllers: dict[str, baselines.Controller] = {}
        self._model = RigidBodyModel.from_parameters(self._motor)
        self._closed = False
        self._voltage = 0.0
        self._applied = 0.0
        self._led: tuple[float, float, float] = RESET_LED
        self._estimate: tuple[float, float, float, float] = (0.0, math.pi, 0.0, 0.0)
        self._measured = self._estimate
        self._sensor_model = None
        self._sensor_reset = None
        self._actuator_model = None
        self._samples = 0
        self._episode_start = 0
        self._twin = None
        self.currents = np.zeros(1)
        self.encoders = np.zeros(2, dtype=np.int32)
        self.others = np.zeros(len(DEVICES[device].other_inputs))

    # -- the domain interface ---------------------------------------------------------------

    @property
    def max_voltage(self) -> float:
        """The board wrapper's voltage clip (V): no task may ask for more."""
        return self.qube.max_voltage

    def set_voltage(self, volts: float) -> None:
        """Command `volts` (V); written to the board at the next `step`."""
        self._voltage = volts

    def applied_voltage(self) -> float:
        """Motor voltage (V) written to the board at the last sample, after actuator effects and the
        wrapper's clip to `max_voltage`."""
        return self._applied

    def raw_readings(self) -> dict[str, float]:
        """The board's readings of the last sample in board units and signs: motor current (A),
        encoder counts, tachometer (counts/s; on a Qube-Servo 3 also the pendulum's), and the
        missed samples since the board opened."""
        readings = {"current": float(self.currents[0]), "encoder_arm": int(self.encoders[0]),
                    "encoder_pendulum": int(self.encoders[1]), "tachometer": float(self.others[0]),
                    "missed_samples": self.qube.missed_samples}
        if len(self.others) > 1:
            readings["pendulum_tachometer"] = float(self.others[1])
        return readings

    def motor_current(self) -> float:
        """Motor current (A) measured by the board at the last sample."""
        return conventions.motor_current(float(self.currents[0]))

    def set_led(self, rgb: Sequence[float]) -> None:
        """Show (r, g, b) on the Qube's LED from the next sample on."""
        self._led = (float(rgb[0]), float(rgb[1]), float(rgb[2]))

    def led(self) -> tuple[float, float, float]:
        """The LED colour being shown."""
        return self._led

    def time(self) -> float:
        """Board time since the episode started (s)."""
        return (self._samples - self._episode_start) / self._frequency

    def timestep(self) -> float:
        """One sample (s)."""
        return 1.0 / self._frequency

    def step(self, nstep: int = 1) -> None:
        """Wait for the next `nstep` samples, writing the commanded voltage at each."""
        volts = self._voltage if self._actuator_model is None else self._actuator_model(self._voltage)
        try:
            for _ in range(nstep):
                self._sample(volts)
        except BaseException as error:
            self._stop_after(error)
            raise
        self._measured = self._estimate if self._sensor_model is None else self._sensor_model(self._estimate)

    def set_sensor_model(self, sensor_model) -> None:
        """Let tasks see `sensor_model(estimate)` instead of the board's estimate; None: the estimate.

        A `reset(estimate)` method, if present, is called when an episode starts.
        """
        self._sensor_model = sensor_model
        self._sensor_reset = getattr(sensor_model, "reset", sensor_model)

    def set_actuator_model(self, actuator_model) -> None:
        """Write `actuator_model(volts)` to the board instead of the commanded voltage; None: as
        commanded. A `reset(volts)` method, if present, is called with 0 V when an episode starts."""
        self._actuator_model = actuator_model

    def reset(self) -> None:
        """Get the board ready for an episode: open it the first time, else wake it from idle.

        The reset controllers are built before the board samples, so nothing slower than a
        sample runs while it drives. An episode that was left running (abandoned, or ended by
        a wrapper's time limit) is idled first. Raises RuntimeError after `close()`.
        """
        if self._closed:
            raise RuntimeError("this hardware environment was closed and its board released; make a new one")
        self._prepare_controllers()
        if self.qube.is_open and not self.qube.is_idle:
            self.end_episode()
        FULL_COLLECTIONS.hold(self)
        try:
            if not self.qube.is_open:
                self.qube.open()
                self._estimator.reset()
                self._sample(0.0)
                self._measured = self._estimate
            else:
                self.qube.resume()
        except BaseException as error:
            self._stop_after(error)
            raise
        self._voltage = 0.0

    def after_reset(self) -> None:
        """Nothing to do: `reset_to` leaves the board at the episode's start."""

    def reset_to(self, state: Sequence[float]) -> None:
        """Drive the Qube to the episode's start with the reset controllers (see the module docstring)."""
        target_alpha = wrap_angle(float(state[1]))
        self._led = RESET_LED
        try:
            if abs(target_alpha) <= NEAR_GOAL:
                if abs(self._estimate[3]) > WILD_SWING:  # e.g. still falling from the last run: calm it first
                    self._drive("dampen", self._hanging_at_rest, "settle hanging")
                self._drive("swingup", self._held_upright, "swing up and hold upright")
            else:
                self._drive("dampen", self._hanging_at_rest, "settle hanging")
                if self._check_encoders:
                    self._drive("dampen", self._centred_at_rest, "centre the arm")
                    self._check_pendulum_zero()
                if math.pi - abs(target_alpha) > NEAR_GOAL:
                    energy = self._model.energy(target_alpha, float(state[2]), float(state[3]))
                    self._drive("swingup", lambda s: self._model.energy(s[1], s[2], s[3]) >= energy,
                                "pump the swing", hold=0.0)
        except BaseException as error:
            self._stop_after(error)
            raise
        self._voltage = 0.0
        if hasattr(self._actuator_model, "reset"):
            self._actuator_model.reset(0.0)
        self._measured = self._estimate if self._sensor_reset is None else self._sensor_reset(self._estimate)
        self._episode_start = self._samples

    def end_episode(self) -> None:
        """Stop driving until the next reset: 0 V, amplifier disabled."""
        try:
            if self.qube.is_open and not self.qube.is_idle:
                self.qube.idle()
        finally:
            FULL_COLLECTIONS.release(self)

    def drawable(self):
        """The simulated Qube put in the measured state with the LED's colour: a digital twin."""
        twin = self._digital_twin()
        twin.reset_to(self._estimate)
        twin.set_led(self._led)
        return twin.drawable()

    def _digital_twin(self):
        if self._twin is None:
            from qube_suite.domains import qube

            self._twin = qube.make_physics(self._frequency, self._motor)
        return self._twin

    def design_parameters(self) -> dict[str, float]:
        """Physical parameters (long names) that differ from the nominal Qube-Servo 2 for this
        device (a Qube-Servo 3's motor): what controllers for it are designed with."""
        return dict(self._motor)

    @property
    def model(self):
        """The digital twin's `MjModel` (the simulated Qube drawn by `drawable()`), for dm_control
        tools that read a physics' model (element names, cameras)."""
        return self._digital_twin().model

    def free(self) -> None:
        """Stop the motor and close the board: what shimmy's and dm_control's `close()` call."""
        self.close()

    def close(self) -> None:
        """Stop the motor and close the board, for good: a later `reset` raises."""
        self._closed = True
        try:
            self.qube.close()
        finally:
            FULL_COLLECTIONS.release(self)
        if self._twin is not None:
            self._twin.close()
            self._twin = None
        for controller in self._controllers.values():
            controller.close()
        self._controllers.clear()

    # -- helpers ----------------------------------------------------------------------------

    def _stop_after(self, error: BaseException) -> None:
        """Leave the motor stopped after `error`: the board idles (0 V, amplifier disabled), or is
        closed after an encoder glitch (the next reset reopens it and zeroes the encoders)."""
        qube = self.qube
        try:
            if not qube.is_open:
                return
            if isinstance(error, EncoderGlitchError):
                qube.close()
            elif not qube.is_idle:
                try:
                    qube.idle()
                except BaseException:
                    qube.close()
                    raise
        finally:
            FULL_COLLECTIONS.release(self)

    def _sample(self, volts: float) -> None:
        self.currents, self.encoders, self.others = self.qube.action(
            [conventions.board_voltage(volts)], led=self._led)
        limit = self.qube.max_voltage
        self._applied = -limit if volts < -limit else limit if volts > limit else volts
        theta, alpha, dtheta, dalpha = self._estimator(self.encoders).tolist()
        self._estimate = (theta, alpha, dtheta, dalpha)
        self._samples += 1

    def _prepare_controllers(self) -> None:
        """Build the reset controllers (designing them takes longer than a sample) while the board
        is closed or idle."""
        for name in RESET_CONTROLLERS:
            if name not in self._controllers:
                self._controllers[name] = baselines.make(name, control_frequency=self._frequency,
                                                         voltage_limit=self._reset_voltage_limit,
                                                         latency_steps=self.latency_steps,
                                                         parameters=self._motor)

    def _controller(self, name: str) -> baselines.Controller:
        return self._controllers[name]

    def _drive(self, name: str, done: Callable[[tuple], bool], purpose: str, hold: float = HOLD_TIME) -> None:
        """Run controller `name` until `done(state)` has held for `hold` s (at least one sample)."""
        controller = self._controller(name)
        controller.reset()
        needed = max(1, round(hold * self._frequency))
        held = 0
        for _ in range(round(self._reset_timeout * self._frequency)):
            held = held + 1 if done(self._estimate) else 0
            if held >= needed:
                return
            self._sample(controller(np.array(self._estimate)))
        self._sample(0.0)
        raise ResetError(f"reset failed: could not {purpose} within {self._reset_timeout:g} s "
                         f"(state {np.round(self._estimate, 3).tolist()})")

    @staticmethod
    def _held_upright(state: tuple) -> bool:
        theta, alpha, dtheta, dalpha = state
        return abs(alpha) < math.radians(5) and abs(theta) < math.radians(15) and abs(dalpha) < 1.0

    def _check_pendulum_zero(self) -> None:
        counts = (math.pi - abs(self._estimate[1])) / conventions.RADIANS_PER_COUNT
        if counts > PENDULUM_REST_TOLERANCE + 1e-6:
            self._sample(0.0)
            raise EncoderCheckError(
                f"the pendulum hangs at rest but its encoder reads {counts:.0f} counts from hanging (at most "
                f"{PENDULUM_REST_TOLERANCE} allowed): its zero is lost. Close the environment, let the "
                "pendulum hang still, centre the arm and make a new one (opening zeroes the encoders); "
                "domain_kwargs={'check_encoders': False} turns this check off")

    @staticmethod
    def _centred_at_rest(state: tuple) -> bool:
        theta, alpha, dtheta, dalpha = state
        return (abs(theta) < ARM_CENTRE_TOLERANCE and math.pi - abs(alpha) < math.radians(3)
                and abs(dalpha) < 0.3 and abs(dtheta) < 0.3)

    @staticmethod
    def _hanging_at_rest(state: tuple) -> bool:
        theta, alpha, dtheta, dalpha = state
        return (math.pi - abs(alpha) < math.radians(3) and abs(theta) < math.radians(10)
                and abs(dalpha) < 0.3 and abs(dtheta) < 0.3)


DOMAIN_KWARGS = keywords_of(Physics, skip=("control_frequency",))
"""Keys `suite.load`'s `domain_kwargs` may hold for this domain: `Physics`'s options."""


def make_physics(control_frequency: float = 250.0, **options: Any) -> Physics:
    """A Qube on a board for control at `control_frequency` (Hz); `options`: see `Physics`."""
    from collections.abc import Mapping

    from qube_suite.arguments import is_number
    from qube_suite.domains.qube import check_control_frequency

    check_control_frequency(control_frequency)
    for key in ("max_voltage", "reset_voltage_limit", "reset_timeout"):
        if key in options and not (is_number(options[key]) and 0.0 < options[key] < math.inf):
            raise ValueError(f"{key} must be a positive number, got {options[key]!r}")
    if options.get("plant") is not None and not isinstance(options["plant"], Mapping):
        raise ValueError(f"plant must be a mapping of plant parameter names to values, "
                         f"got {options['plant']!r}")
    return Physics(control_frequency, **options)
