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
* the board's encoder counts are kept across opens, as a real board keeps
  counting from where it was powered up (`zero_encoders=True` zeroes them at the
  first open instead, with the pendulum hanging at rest and the arm centred);
* randomization effects on the state or the voltage (`set_sensor_model`,
  `set_actuator_model`: noise, delays, dead-zone, ...) apply to what tasks see and
  send; the reset controllers work on the plain estimate. Physical parameters and
  control-period jitter belong to the plant and cannot be randomized here;
* starts are reached by reset controllers, with the LED yellow while they
  drive: "settle hanging" (dampen), "swing up and hold" (swing-up with LQR
  balance) for starts near upright, and for other starts (dampen's arbitrary
  swing) settle, then pump energy until the pendulum swings with the energy of
  the requested start. A domain never imports controllers: `suite.load` hands it
  `dampen` and `swingup` (`set_reset_controllers`), designed for the Qube's own
  parameters (`reset_controller_settings()`), before the board samples. A start
  the controllers cannot reach within `reset_timeout` raises `ResetError`;
* a reset that finds the arm beyond the board's arm limit (where an earlier run
  stopped) first brings it back towards the centre, slowly, through the
  wrapper's `return_arm` (`_return_arm`; docs/safety.md);
* anything that raises during a step or a reset (a safety stop, a board error,
  Ctrl-C, a failing controller) first stops the motor: the board idles (0 V,
  amplifier disabled) and the next reset drives again, or, after an encoder
  glitch, which loses the position reference, the board is closed and the next
  reset opens it afresh, zeroing the encoders where the Qube then rests.
"""

from __future__ import annotations

import gc
import math
import signal
import threading
import weakref
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
from dm_control.rl import control

from qube_suite.angles import wrap_angle
from qube_suite.arguments import keywords_of
from qube_suite.devices.qube import parameters as params
from qube_suite.domains.effects import Effects
from qube_suite.domains.interface import BoardClockAndLed, MeasuredState
from qube_suite.hardware import conventions
from qube_suite.hardware.errors import EncoderGlitchError, HardwareError, ResetError
from qube_suite.hardware.estimation import StateEstimator
from qube_suite.hardware.plant import BOARD_MOTORS
from qube_suite.hardware.quanser import DEVICES, SIMULATED, QuanserWrapper

RESET_CONTROLLERS = ("dampen", "swingup")
"""The controllers that reach the episodes' starts (names of `controllers`): handed to the domain
by `suite.load` before the board samples. Each is called with the state estimate [theta, alpha,
dtheta, dalpha] and returns volts, has `reset()` and `close()`, and its `model.energy(alpha, dtheta,
dalpha)` gives the energy (J) the reset pumps the swing to (`model.gravity_torque`: mp g l, N m)."""

RESET_LED = (1.0, 1.0, 0.0)
"""Yellow: a reset controller is driving."""

DEFAULT_RESET_VOLTAGE_LIMIT = 6.0
"""Largest voltage (V) the reset controllers use."""

DEFAULT_RESET_TIMEOUT = 30.0
"""Longest a reset may take (s of board time)."""

MAX_RESET_TIMEOUT = 120.0
"""Largest `reset_timeout` (s): a reset that cannot reach its start gives up (0 V, `ResetError`) within
two minutes of driving, however it was set; unattended, a Qube is not driven for longer by a reset."""

NEAR_GOAL = math.radians(30.0)
"""Starts within 30 degrees of upright are reached by swing-up and hold; within 30
degrees of hanging, by settling; others by pumping energy."""

WILD_SWING = 3.0
"""Pendulum speed (rad/s) above which an upright start first settles the pendulum hanging: the
swing-up catches a pendulum that starts near rest, not one swinging wildly."""

CALM_SWING_ENERGY = 0.25
"""An upright start also settles the pendulum hanging first when it swings with more than this
fraction of the swing-up energy (2 mp g l) above hanging at rest, however slowly it moves at the moment
(a swing seen at its turning point is slow): the swing-up pumps a calm pendulum, not a swinging one.
A quarter is a swing of about 60 degrees from hanging."""

FRESH_ESTIMATE_TIME = 0.1
"""Seconds that dampen drives before a reset without the encoder check decides whether the pendulum
swings too much for the swing-up: five time constants of the velocity filter, restarted when the board
woke, so that the decision is made on the Qube's present state; meanwhile dampen already brakes the
arm (at 0 V an arm still turning fast from the last episode could coast past the arm limit)."""

RETURN_SPEED = 1.0
"""Arm speed (rad/s) at which a reset brings back an arm found beyond the board's arm limit."""

RETURN_GAIN = 3.0
"""Volts per rad/s of arm speed short of `RETURN_SPEED` while an arm is brought back: a held arm
soon draws more than the wrapper's `RETURN_CURRENT`, which stops the return."""

RETURN_DRIVE = 2.5
"""Largest voltage (V) of the return, under the wrapper's `RETURN_VOLTAGE`."""

RETURN_MARGIN = math.radians(10.0)
"""Within this much of the arm limit (rad) the return pushes only inwards, as beyond it: a sample may
find the arm on the other side of the limit."""

RETURN_TARGET = math.radians(45.0)
"""The return ends with the arm this close to its zero (rad); the reset controllers take over."""

HOLD_TIME = 0.5
"""A reset is done when its condition has held this long (s)."""

ARM_CENTRE_TOLERANCE = math.radians(5.0)

SUBSTITUTE_ARM_SPREAD = math.radians(3.0)
"""Where a seeded episode finds the substitute's arm: within this of centre (rad), inside the
centring tolerance, as a person leaves a Qube after putting it back."""
"""With the encoder check on, every reset first centres the arm to within 5 degrees of its zero (the
reset controllers leave it within about 1 degree on the substitute; the cable's spring and the arm's
friction hold it there)."""

PENDULUM_REST_TOLERANCE = 1
"""Encoder counts: with the encoder check on, the pendulum hanging at rest must be at pi to within one
count (the bench's sway lets its Coulomb friction stop it within a count of hanging, where a count may
flicker). More means its zero is lost. A reading of k counts puts the pendulum in [k, k + 1) counts (the
encoder counts whole steps), so the readings -2 to 1 pass: a pendulum resting 1.2 counts below hanging
reads -2. The default of `pendulum_rest_tolerance`."""

MAX_PENDULUM_REST_TOLERANCE = 8
"""Largest `pendulum_rest_tolerance` (counts, 1.4 degrees): beyond it a lost zero would pass unseen and
the upright starts and balance tasks would lean by as much."""

REST_CHECK_TIME = 0.2
"""The encoder check reads the pendulum, the dampen controller still driving, until its counts have
stayed within a count of their median for this long (s), then judges that median: a single reading
may catch the last small swing of a pendulum the reset judged at rest, or a flicker of the bench's
sway."""


class _FullCollectionsHeld:
    """Python's full (oldest-generation) garbage collections held off while a board paced by the wall
    clock drives.

    A full collection stops the program for as long as its heap takes to scan (up to 0.1 s in
    a process that has loaded MuJoCo and torch): longer than a sample, enough to trip the
    missed-sample stop or the watchdog. While any such board drives, the oldest generation's
    threshold is raised out of reach (young generations, which are fast, still collect); when
    the last holder releases it, at the end of its episode, at its close, or when it is
    garbage-collected or the interpreter exits without either, the threshold comes back and a
    full collection runs while the motor is off. The fast substitute's time stands still while
    the program does: there a collection costs no sample, and none is held off.
    """

    def __init__(self):
        self.holders: dict[int, weakref.finalize] = {}
        self.threshold: int | None = None

    def hold(self, holder: object) -> None:
        if id(holder) in self.holders:
            return
        if not self.holders:
            young, middle, self.threshold = gc.get_threshold()
            gc.set_threshold(young, middle, 2**31 - 1)
        ending = self.holders[id(holder)] = weakref.finalize(holder, self._let_go, id(holder))
        ending.atexit = False  # an exiting interpreter needs no collections back

    def release(self, holder: object) -> None:
        ending = self.holders.get(id(holder))
        if ending is not None:
            ending()

    def _let_go(self, key: int) -> None:
        self.holders.pop(key, None)
        if not self.holders and self.threshold is not None:
            young, middle, _ = gc.get_threshold()
            gc.set_threshold(young, middle, self.threshold)
            self.threshold = None
            collect_keeping_signals()


def collect_keeping_signals() -> None:
    """A full garbage collection that loses no signal.

    A collection runs the finalizers of what it frees; a signal whose Python handler raises
    (Ctrl-C's KeyboardInterrupt, the SIGTERM unwinding of `hardware.quanser`) would raise inside
    one of them, where Python reports the exception and drops it: the program would go on as if
    the person had not pressed Ctrl-C. So, in the main thread, every Python handler is held by a
    recorder during the collection, and each signal that came is raised again after it.
    """
    if threading.current_thread() is not threading.main_thread():
        gc.collect()
        return
    came: list[int] = []
    held = {}
    for signum in signal.valid_signals():
        handler = signal.getsignal(signum)
        if callable(handler):
            held[signum] = signal.signal(signum, lambda number, frame: came.append(number))
    try:
        gc.collect()
    finally:
        for signum, handler in held.items():
            signal.signal(signum, handler)
        for signum in came:
            signal.raise_signal(signum)


FULL_COLLECTIONS = _FullCollectionsHeld()


class EncoderCheckError(HardwareError):
    """Between episodes, the pendulum hung at rest but its encoder did not read hanging: the encoder's
    zero is lost (missed counts, or the board was opened with the pendulum swinging)."""


class Physics(BoardClockAndLed, MeasuredState, control.Physics):
    """A Qube on a Quanser board, through the domain interface (`domains.interface.QubePhysics`).

    Args:
        control_frequency: sample rate of the board (Hz); one `step` is one sample.
        device: "qube_servo2" or "qube_servo3": which Qube (its channels, its motor data in the
            substitute's plant and in the model of the reset controllers). Default: the one
            `board` names, else "qube_servo2".
        board: "simulated" (the substitute) or the device's card type, "qube_servo2_usb" or
            "qube_servo3_usb" (a real Qube).
        plant: parameters of the substitute's plant (`qube_suite.hardware.plant`) by long name, changing
            the device's default plant (`plant.DEFAULT_PLANTS`: the real Qube's for a Qube-Servo 2, the
            estimated one for a Qube-Servo 3), or a named plant, "estimated" or "real_qube_servo2"
            (`plant.PLANTS`).
        realtime: pace the substitute by the wall clock (a real board always is).
        max_voltage: the wrapper's voltage clip (V).
        reset_voltage_limit: largest voltage of the reset controllers (V).
        reset_timeout: longest a reset may take (s).
        identifier: the board's number.
        check_encoders: at every reset, first settle the pendulum hanging, centre the arm to within
            `ARM_CENTRE_TOLERANCE` (5 degrees) and check that the pendulum, hanging at rest, reads
            pi to within `pendulum_rest_tolerance` counts; else raise `EncoderCheckError`
            (`ResetError` if the arm cannot be centred). Default True.
        pendulum_rest_tolerance: counts from hanging that the encoder check lets pass (default
            `PENDULUM_REST_TOLERANCE`, one; at most `MAX_PENDULUM_REST_TOLERANCE`): more for a bench
            whose sway stops the pendulum farther from hanging (four times the substitute's default
            sway leaves it 2 to 3 counts off).
        zero_encoders: zero the encoders at the board's first open, where the Qube rests (pendulum
            hanging, arm centred); default False: keep the board's counts, which a board counts
            from where the Qube was at power-up.
        parameters: physical parameters of this Qube by long name, or a calibration (file or
            object): what the reset controllers and `design_parameters()` use, on top of the
            device's motor data. Default: the nominal model with the device's motor.
        reset_controllers: `RESET_CONTROLLERS` by name, made for `reset_controller_settings()`
            (`suite.load` hands them in; `set_reset_controllers` later). Required to reset.
    """

    latency_steps = 1
    """A step reads the next sample, then writes its voltage: the voltage acts one sample after the
    observation it answers (`interface.QubePhysics.latency_steps`)."""

    paced_by_board = True
    """The board's clock paces every step: nothing slower than a sample (rendering, plotting) may
    run inside the loop; videos are filmed from the recorded trace after an episode."""

    physics_error = None
    """Always None: faults on hardware raise instead (see the safety table in docs/safety.md)."""

    reset_controller_names = RESET_CONTROLLERS
    """The controllers `set_reset_controllers` needs (see `RESET_CONTROLLERS`)."""

    def __init__(self, control_frequency: float = 250.0, board: str = SIMULATED,
                 plant: dict[str, float] | str | None = None, realtime: bool | None = None,
                 max_voltage: float = 10.0, reset_voltage_limit: float = DEFAULT_RESET_VOLTAGE_LIMIT,
                 reset_timeout: float = DEFAULT_RESET_TIMEOUT, identifier: str = "0",
                 device: str | None = None, check_encoders: bool = True, zero_encoders: bool = False,
                 pendulum_rest_tolerance: int = PENDULUM_REST_TOLERANCE,
                 parameters: Any = None, reset_controllers: Mapping[str, Any] | None = None):
        for name, flag in (("check_encoders", check_encoders), ("zero_encoders", zero_encoders)):
            if not isinstance(flag, bool):
                raise TypeError(f"{name} must be True or False, got {flag!r}")
        tolerance = pendulum_rest_tolerance
        if isinstance(tolerance, bool) or not isinstance(tolerance, (int, np.integer)):
            raise TypeError(f"pendulum_rest_tolerance must be a whole number of counts, got {tolerance!r}")
        if not 0 <= tolerance <= MAX_PENDULUM_REST_TOLERANCE:
            raise ValueError(f"pendulum_rest_tolerance must be in [0, {MAX_PENDULUM_REST_TOLERANCE}] counts, "
                             f"got {tolerance}")
        self._check_encoders = check_encoders
        self._rest_tolerance = int(pendulum_rest_tolerance)
        self._zero_at_open = zero_encoders
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
        if reset_timeout > MAX_RESET_TIMEOUT:
            raise ValueError(f"reset_timeout must be at most {MAX_RESET_TIMEOUT:g} s (MAX_RESET_TIMEOUT: a "
                             f"reset that cannot reach its start must give up), got {reset_timeout:g}")
        self.device = device
        self.qube = QuanserWrapper(DEVICES[device], board, identifier, frequency=control_frequency,
                                   max_voltage=max_voltage, plant=plant, realtime=realtime)
        self._motor = dict(BOARD_MOTORS[DEVICES[device].board_type])
        overrides = params.values_of(parameters)
        params.resolve(overrides)  # a misspelt name or a bad value fails here
        self._design = {**self._motor, **overrides}
        self._frequency = float(control_frequency)
        self._estimator = StateEstimator(control_frequency)
        self._reset_voltage_limit = float(reset_voltage_limit)
        self._reset_timeout = float(reset_timeout)
        self._controllers: dict[str, Any] = {}
        if reset_controllers is not None:
            self.set_reset_controllers(reset_controllers)
        self._closed = False
        self._voltage = 0.0
        self._applied = 0.0
        self._led: tuple[float, float, float] = RESET_LED
        self._led_shown: tuple[float, float, float] | None = None  # on the board; None: unknown
        self._estimate: tuple[float, float, float, float] = (0.0, math.pi, 0.0, 0.0)
        self._measured = self._estimate
        self._effects = Effects()
        self._samples = 0
        self._episode_start = 0
        self._twin = None
        self._substitute_seed: int | None = None
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

    def step(self, nstep: int = 1) -> None:
        """Wait for the next `nstep` samples, writing the commanded voltage at each."""
        volts = self._effects.actuate(self._voltage)
        try:
            for _ in range(nstep):
                self._sample(volts)
        except BaseException as error:
            self._stop_after(error)
            raise
        self._measured = self._effects.measure(self._estimate)

    def set_sensor_model(self, sensor_model) -> None:
        """Let tasks see `sensor_model(estimate)` instead of the board's estimate; None: the estimate.

        A `reset(estimate)` method, if present, is called when an episode starts.
        """
        self._effects.sensor = sensor_model

    def set_actuator_model(self, actuator_model) -> None:
        """Write `actuator_model(volts)` to the board instead of the commanded voltage; None: as
        commanded. A `reset(volts)` method, if present, is called with 0 V when an episode starts."""
        self._effects.actuator = actuator_model

    def reset(self) -> None:
        """Get the board ready for an episode: open it the first time, else wake it from idle.

        The reset controllers are built before the board samples, so nothing slower than a
        sample runs while it drives. An episode that was left running (abandoned, or ended by
        a wrapper's time limit) is idled first. Raises RuntimeError after `close()`.
        """
        if self._closed:
            raise RuntimeError("this hardware environment was closed and its board released; make a new one")
        missing = [name for name in RESET_CONTROLLERS if name not in self._controllers]
        if missing:
            raise RuntimeError(f"the hardware domain has no reset controllers {missing}: make it through "
                               "suite.load, or hand them in with set_reset_controllers()")
        if self.qube.is_open and not self.qube.is_idle:
            self.end_episode()
        if self.qube.realtime:
            FULL_COLLECTIONS.hold(self)
        try:
            if not self.qube.is_open:
                self.qube.open(zero_encoders=self._zero_at_open)
                self._zero_at_open = False  # zeroed once: from now on the board's counts hold
            else:
                self.qube.resume()
            self._restart_substitute()
            self._led_shown = None
            self._estimator.reset()  # the Qube moved on while the board idled: estimate it afresh
            self._sample(0.0, returning=True)
            self._return_arm()
            self._measured = self._estimate
        except BaseException as error:
            self._stop_after(error)
            raise
        self._voltage = 0.0

    def seed_substitute(self, seed: int) -> None:
        """At the next `reset`, on the substitute board only: reseed its noise and put its Qube hanging
        at rest with the arm within `SUBSTITUTE_ARM_SPREAD` of centre, both drawn from `seed`, so that
        a seeded episode starts the same way every time and seeds start differently. A real Qube is
        where it is: nothing changes."""
        self._substitute_seed = int(seed)

    def _restart_substitute(self) -> None:
        seed, self._substitute_seed = self._substitute_seed, None
        if seed is None or self.qube.board_name != SIMULATED:
            return
        arm = np.random.default_rng(seed).uniform(-SUBSTITUTE_ARM_SPREAD, SUBSTITUTE_ARM_SPREAD)
        self.qube.board.seed(seed)
        self.qube.board.set_true_state([arm, math.pi, 0.0, 0.0])

    def after_reset(self) -> None:
        """Nothing to do: `reset_to` leaves the board at the episode's start."""

    def reset_to(self, state: Sequence[float]) -> None:
        """Drive the Qube to the episode's start with the reset controllers (see the module docstring)."""
        target_alpha = wrap_angle(float(state[1]))
        model = self._controllers["dampen"].model
        self._led = RESET_LED
        try:
            upright = abs(target_alpha) <= NEAR_GOAL
            if self._check_encoders:
                self._drive("dampen", self._hanging_at_rest, "settle hanging")
                self._drive("dampen", self._centred_at_rest, "centre the arm")
                self._check_pendulum_zero()
            elif not upright:
                self._drive("dampen", self._hanging_at_rest, "settle hanging")
            else:
                self._drive_for("dampen", FRESH_ESTIMATE_TIME)
                if self._swinging(model):  # the swing-up pumps a calm pendulum, not a swinging one
                    self._drive("dampen", self._hanging_at_rest, "settle hanging")
            if upright:
                self._drive("swingup", self._held_upright, "swing up and hold upright")
            elif math.pi - abs(target_alpha) > NEAR_GOAL:
                energy = model.energy(target_alpha, float(state[2]), float(state[3]))
                self._drive("swingup", lambda s: model.energy(s[1], s[2], s[3]) >= energy,
                            "pump the swing", hold=0.0)
        except BaseException as error:
            self._stop_after(error)
            raise
        self._voltage = 0.0
        self._effects.restart_actuation()
        self._measured = self._effects.restart(self._estimate)
        self._episode_start = self._samples

    def end_episode(self) -> None:
        """Stop driving until the next reset: 0 V, amplifier disabled."""
        try:
            if self.qube.is_open and not self.qube.is_idle:
                self.qube.idle()
        finally:
            FULL_COLLECTIONS.release(self)

    def stop_motor(self) -> None:
        """Write 0 V at once, while an episode drives (an action was refused); the watchdog disables the
        amplifier if no valid action follows within its timeout."""
        if self.qube.is_open and not self.qube.is_idle:
            try:
                self.qube.zero_voltage()
            except BaseException as error:
                self._stop_after(error)
                raise

    @property
    def closed(self) -> bool:
        """Whether `close()` released the board for good."""
        return self._closed

    def drawable(self):
        """The simulated Qube put in the measured state with the LED's colour: a digital twin."""
        twin = self._digital_twin()
        twin.reset_to(self._estimate)
        twin.set_led(self._led)
        return twin.drawable()

    def render(self, *args: Any, **kwargs: Any) -> np.ndarray:
        """An image of the digital twin (`drawable()`), with dm_control's `Physics.render` arguments:
        what shimmy's and dm_control's tools draw. Never inside the control loop: it takes longer
        than a sample."""
        return self.drawable().render(*args, **kwargs)

    def show_reward(self, reward: float) -> None:
        """dm_control's reward colours (a task's `visualize_reward`) on the digital twin."""
        self._digital_twin().show_reward(reward)

    def _digital_twin(self):
        if self._twin is None:
            from qube_suite.devices.qube import simulation as qube

            self._twin = qube.make_physics(self._frequency, self._design)
        return self._twin

    def design_parameters(self) -> dict[str, float]:
        """Physical parameters (long names) that differ from the nominal Qube-Servo 2 for this Qube
        (the device's motor, then the `parameters` given): what controllers for it are designed with."""
        return dict(self._design)

    def reset_controller_settings(self) -> dict[str, Any]:
        """Keyword arguments to build each of `RESET_CONTROLLERS` with (`baselines.make(name, **...)`):
        the control frequency, the reset voltage limit, the board's latency and `design_parameters()`."""
        return {"control_frequency": self._frequency, "voltage_limit": self._reset_voltage_limit,
                "latency_steps": self.latency_steps, "parameters": self.design_parameters()}

    def set_reset_controllers(self, controllers: Mapping[str, Any]) -> None:
        """Hand in the controllers that reach the episodes' starts: `RESET_CONTROLLERS` by name, made for
        `reset_controller_settings()` (see `RESET_CONTROLLERS` for what each must offer). Building
        them takes longer than a sample: they must be ready before the board samples."""
        missing = [name for name in RESET_CONTROLLERS if name not in controllers]
        if missing:
            raise ValueError(f"reset controllers {missing} missing; needed: {', '.join(RESET_CONTROLLERS)}")
        for name in RESET_CONTROLLERS:
            controller = controllers[name]
            if not (callable(controller) and callable(getattr(controller, "reset", None))
                    and callable(getattr(getattr(controller, "model", None), "energy", None))):
                raise TypeError(f"reset controller {name!r} must be callable with reset() and "
                                f"model.energy(), got {controller!r}")
        self._controllers = {name: controllers[name] for name in RESET_CONTROLLERS}

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
                self._zero_at_open = True  # the position reference is lost
                qube.close()
            elif not qube.is_idle:
                try:
                    qube.idle()
                except BaseException:
                    qube.close()
                    raise
        finally:
            FULL_COLLECTIONS.release(self)

    def _sample(self, volts: float, returning: bool = False) -> None:
        qube, led = self.qube, self._led
        act = qube.return_arm if returning else qube.action
        self.currents, encoders, self.others = act(  # the last sample's: read before the next one
            [conventions.board_voltage(volts)], None if led == self._led_shown else led, copy=False)
        self.encoders = encoders
        self._led_shown = led  # written only when it changes: one board call less per sample
        limit = qube.max_voltage
        self._applied = -limit if volts < -limit else limit if volts > limit else volts
        self._estimate = self._estimator.estimate(encoders)
        self._samples += 1

    def _return_arm(self) -> None:
        """Bring an arm found beyond the board's arm limit, or turning outwards faster than
        `RETURN_SPEED` (an episode that ended with the arm leaving its safe set fast, which would coast
        past the limit), back to within `RETURN_TARGET` of its zero at `RETURN_SPEED`, with at most
        `RETURN_DRIVE`: beyond the limit the voltage only pushes inwards, and only once the arm no
        longer coasts outwards (0 V brakes it through the motor's back-EMF); within the limit it may
        brake harder. The wrapper's `return_arm` stops the motor if the arm is held or moves away."""
        limit = self.qube.arm_limit
        if limit is None:
            return
        before = self._arm_unwrapped()  # the estimator restarted with the board: the speed from two samples
        self._sample(0.0, returning=True)
        theta = self._arm_unwrapped()
        turning_out = (abs(theta) - abs(before)) * self._frequency > RETURN_SPEED
        if abs(theta) <= limit and not turning_out:
            return
        self._led = RESET_LED
        for _ in range(round(self._reset_timeout * self._frequency)):
            theta, dtheta = self._arm_unwrapped(), self._estimate[2]  # back the way it came
            if abs(theta) < RETURN_TARGET:
                return
            inward = -math.copysign(1.0, theta)
            near = abs(theta) > limit - RETURN_MARGIN  # the next sample may find it beyond the limit
            coasting_out = near and inward * dtheta < 0.0  # 0 V brakes it first (back-EMF)
            push = 0.0 if coasting_out else RETURN_GAIN * (RETURN_SPEED - inward * dtheta)
            brake = 0.0 if near else -RETURN_DRIVE  # near or beyond the limit: inwards only
            self._sample(inward * min(RETURN_DRIVE, max(brake, push)), returning=True)
        self._sample(0.0, returning=True)
        raise ResetError(f"reset failed: could not bring the arm back from beyond the arm limit within "
                         f"{self._reset_timeout:g} s (state {np.round(self._estimate, 3).tolist()})")

    def _arm_unwrapped(self) -> float:
        """theta (rad) of the last sample, not wrapped: the way back to the centre is the way it came."""
        return conventions.arm_angle(int(self.encoders[0]))

    def _swinging(self, model) -> bool:
        """True if the pendulum moves fast or swings with more than `CALM_SWING_ENERGY` of the swing-up
        energy above hanging at rest (by the reset controllers' `model`)."""
        theta, alpha, dtheta, dalpha = self._estimate
        above_rest = model.energy(alpha, dtheta, dalpha) + 2.0 * model.gravity_torque
        return abs(dalpha) > WILD_SWING or above_rest > CALM_SWING_ENERGY * 2.0 * model.gravity_torque

    def _drive_for(self, name: str, seconds: float) -> None:
        """Run controller `name` for `seconds` (at least one sample)."""
        controller = self._controllers[name]
        controller.reset()
        for _ in range(max(1, round(seconds * self._frequency))):
            self._sample(controller(np.array(self._estimate)))

    def _drive(self, name: str, done: Callable[[tuple], bool], purpose: str, hold: float = HOLD_TIME) -> None:
        """Run controller `name` until `done(state)` has held for `hold` s (at least one sample)."""
        controller = self._controllers[name]
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
        window = max(1, round(REST_CHECK_TIME * self._frequency))
        offsets: list[int] = []  # counts from hanging, signed
        controller = self._controllers["dampen"]  # still damping, as while it centred the arm
        for _ in range(round(self._reset_timeout * self._frequency)):
            self._sample(controller(np.array(self._estimate)))
            offsets = [*offsets[1 - window:], round(wrap_angle(self._estimate[1] - math.pi)
                                                      / conventions.RADIANS_PER_COUNT)]
            median = float(np.median(offsets))
            if len(offsets) == window and max(abs(count - median) for count in offsets) <= 1:
                break
        else:
            raise ResetError(f"reset failed: the pendulum did not come to rest for the encoder check within "
                             f"{self._reset_timeout:g} s (counts from hanging: {offsets[-5:]})")
        # an encoder reading of k counts puts the pendulum in [k, k + 1) counts: judge the count's centre
        if abs(median + 0.5) > self._rest_tolerance + 0.5 + 1e-6:
            raise EncoderCheckError(
                f"the pendulum hangs at rest but its encoder reads {abs(median):.0f} counts from hanging (at "
                f"most {self._rest_tolerance} allowed): its zero is lost. Close the environment, let the "
                "pendulum hang still, centre the arm and make a new one with domain_kwargs={'zero_encoders': "
                "True}; on a swaying bench domain_kwargs={'pendulum_rest_tolerance': n} allows n counts, "
                "and domain_kwargs={'check_encoders': False} turns this check off")

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


DOMAIN_KWARGS = keywords_of(Physics, skip=("control_frequency", "reset_controllers"))
"""Keys `suite.load`'s `domain_kwargs` may hold for this domain: `Physics`'s options."""


def make_physics(control_frequency: float = 250.0, **options: Any) -> Physics:
    """A Qube on a board for control at `control_frequency` (Hz); `options`: see `Physics`."""
    from collections.abc import Mapping

    from qube_suite.arguments import is_number
    from qube_suite.devices.qube.simulation import check_control_frequency

    check_control_frequency(control_frequency)
    for key in ("max_voltage", "reset_voltage_limit", "reset_timeout"):
        if key in options and not (is_number(options[key]) and 0.0 < options[key] < math.inf):
            raise ValueError(f"{key} must be a positive number, got {options[key]!r}")
    if options.get("plant") is not None and not isinstance(options["plant"], (Mapping, str)):
        raise ValueError(f"plant must be a mapping of plant parameter names to values or a named plant "
                         f"(qube_suite.hardware.plant.PLANTS), got {options['plant']!r}")
    return Physics(control_frequency, **options)
