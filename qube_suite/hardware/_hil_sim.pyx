# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""A substitute for the HIL board of a Quanser Qube-Servo 2 (or 3) with a simulated Qube inside.

`HIL` has the method names and semantics of Quanser's Python HIL API
(`quanser.hardware.HIL`) for what a Qube offers, so the code that drives it is the
code that drives a real Qube: `open`/`close`, immediate I/O (`read_encoder`,
`read_analog`, `read_digital`, `read_other`, `write_analog`, `write_digital`,
`write_other`, `set_encoder_counts`), reader tasks (`task_create_reader`,
`task_create_encoder_reader`, `task_start`, `task_read`, `task_read_encoder`,
`task_stop`, `task_delete`, `task_set_buffer_overflow_mode`,
`task_get_buffer_overflows`) and the watchdog (`watchdog_set_analog_expiration_state`,
`watchdog_set_digital_expiration_state`, `watchdog_start`, `watchdog_reload`,
`watchdog_is_expired`, `watchdog_clear`, `watchdog_stop`). Errors raise `HILError`.

Channels (Qube-Servo 2 and 3; signs and offsets in `conventions.py`):
analog output 0 = motor voltage (V); digital output 0 = amplifier enable;
encoder inputs 0 = arm, 1 = pendulum (2048 counts/rev, 0 at power-up, where the
plant starts hanging at rest); analog input 0 = motor current (A); other input
14000 = tachometer (arm speed, counts/s), and on a Qube-Servo 3 other input 14001 =
pendulum tachometer (counts/s); other outputs 11000-11002 = LED red,
green, blue (0..1); digital inputs 0 = amplifier fault, 1 = stall detected,
2 = stall error.

The plant (parameters by long name in `plant.py`) is the closed-form Furuta
pendulum of `tests/reference_dynamics.py`, with state [theta, alpha, dtheta,
dalpha, i] in the package's signs, plus: the motor's electrical ODE
L di/dt = V - R i - km dtheta (torque kt i); the amplifier's voltage saturation
and current limit (at the limit it holds the current); the cable spring
-kc theta on the arm; Coulomb friction on both joints; the bench's sway as a
random torque on the pendulum (`bench_vibration` RMS, a Gauss-Markov process with
correlation time `vibration_time`, from the board's random stream seeded by
`seed`: the same seed, the same sway); stall detection (a stall
lasting `stall_time` disables the amplifier until its enable line is toggled).
A disabled amplifier leaves the motor open-circuit: no current, no torque.

What a real Qube adds (`plant.REAL_EFFECT_PARAMETERS`, all off in the estimated plant; the
real Qube's plant `real_qube_servo2`, a Qube-Servo 2's default (`plant.DEFAULT_PLANTS`), has
them): the amplifier's `latency` (a written voltage acts that
long after its write, to the substep; the amplifier's enable acts at once, so a
disabled amplifier stops the motor without delay) and `voltage_deadzone`; the
cable's rest angle and a slack band around it, -kc deadband(theta - rest, slack);
the arm's breakaway torque, the friction limit of an arm that is stuck; and a
cable that lies differently in each session: its rest and stiffness drawn from the
board's random stream when the board opens and at each `seed`.

A device that is not a Qube brings its own plant (`board_plant.BoardPlant`, e.g. a
device with two rotors): the board then offers that plant's channels under its card type and
keeps the clock, the task buffers, the watchdog, the encoder offsets and the
amplifier fault; the plant is advanced in Python from event to event (a sample due,
the watchdog's deadline), one call each, under the outputs as they stand between
them. The Furuta plant below is the default and never leaves C.

Integration, in C with the GIL released: classical RK4 at a fixed substep of at
most 0.1 ms (at least 10 kHz; 40 substeps per sample at 250 Hz). RK4 because the
smooth dynamics are non-stiff except for the electrical mode (time constant
L/R = 0.14 ms): at h = 0.1 ms its h*lambda = 0.72 lies well inside RK4's
stability interval (2.78), and fourth order keeps the mechanical error far below
an encoder count (the tests compare with a DOP853 solution to 1e-6 rad). The
discontinuous parts act between substeps, never inside an RK4 stage: Coulomb
friction as an implicit (backward-Euler) impulse that solves the 2x2
stick/slip complementarity problem exactly, so a joint sticks exactly with no
creep; the current limit as a clamp; stall and watchdog timers at substep
resolution.

Time: with `realtime=False` (default) simulated time advances only when a
running task's samples are read (`task_read` integrates up to the next sample
and returns at once). With `realtime=True` the plant follows the wall clock:
every call first integrates up to "now", writes act from that instant, and
`task_read` sleeps until the next sample is due. Samples that fall due while
nobody reads fill the task buffer; what happens when it is full is the task's
buffer-overflow mode, and `task_get_buffer_overflows` counts them (missed samples).

The watchdog runs on simulated time. When it expires, the analog outputs go to
their expiration states (0 V unless set otherwise), the digital outputs too
(low: amplifier disabled), and further writes raise `HILError` until
`watchdog_clear` (which leaves the outputs at their expiration states).

Not part of Quanser's API: `ClearSamples`, a safety wrapper's sample in one call in fast
mode (the task read, the watchdog reload and, when no safety check could stop at that
sample, the voltage and LED writes), which `quanser.QuanserWrapper` uses on this board.

For tests and for studying the sim-to-real gap: `true_state()`,
`set_true_state()`, `applied_voltage`, `amplifier_enabled`, `time`, `led` and
`plant`; in real-time mode they too catch up with the wall clock first.

Faults, injected on purpose to test what drives the board (the safety table in
docs/safety.md says what the package does about each):

* `set_amplifier_fault(True)`: the amplifier reports a fault (digital input 0)
  and drives nothing, as in a thermal shutdown, until `set_amplifier_fault(False)`;
* `glitch_encoder(channel, counts)`: the encoder's count jumps by `counts` and
  counts on from there, as after electrical noise on its lines;
* `block_arm(True)`: something holds the arm; with more than `stall_voltage`
  applied for `stall_time` the amplifier reports a stall error and disables itself;
* `stall(seconds)`: the control loop stalls: `seconds` of board time pass without
  a task read (missed samples; the watchdog expires if it is longer than the
  timeout). In real-time mode it sleeps; in fast mode board time advances;
* `fail_read(exception, after=0)`: the task read after `after` more reads raises
  `exception` instead of returning, e.g. KeyboardInterrupt (Ctrl-C while the loop
  waits for a sample) or an `HILError` (a driver error);
* module functions `unplug(card_identifier)` and `plug(card_identifier)`: a board
  that is unplugged fails to open with `HILError` (BOARD_NOT_FOUND) until it is
  plugged in again; boards already open are not affected.
"""

import math
import threading
import time

import numpy as np

from libc.math cimport INFINITY, ceil, copysign, cos, exp, fabs, floor, fmax, isfinite, log, sin, sqrt
from libc.stdlib cimport free, llabs, malloc

from qube_suite.angles import wrap_angle
from qube_suite.hardware import conventions
from qube_suite.hardware.board_plant import LED_OUTPUTS, BoardPlant, substitute_plant
from qube_suite.hardware.plant import plant_parameters
from qube_suite.devices.qube.parameters import PENDULUM_ROD_RADIUS, arm_inertia, pendulum_inertia

MIN_INTEGRATION_RATE = 10000.0
"""Lowest plant integration rate (Hz): the RK4 substep is at most 0.1 ms."""

BOARD_TYPES = ("qube_servo2_usb", "qube_servo3_usb")

ANALOG_CURRENT = 0
DIGITAL_ENABLE = 0
OTHER_TACHOMETER = 14000
OTHER_PENDULUM_TACHOMETER = 14001
OTHER_INPUTS = (OTHER_TACHOMETER, OTHER_PENDULUM_TACHOMETER)
PENDULUM_TACHOMETER_CARDS = ("qube_servo3_usb",)
"""Cards with a pendulum tachometer (other input 14001)."""
DIVERGENCE_SPEED = 1.0e4
"""A plant turning faster than this (rad/s), or not finite, has diverged."""
cdef double _DIVERGENCE_SPEED = DIVERGENCE_SPEED
OTHER_LED = LED_OUTPUTS
MAX_CHANNELS = 4
"""Most analog outputs, digital outputs, analog inputs and encoders a board offers."""
MAX_OTHER_INPUTS = 10
"""Most other inputs a board offers."""
QUBE_CHANNELS = {"analog_outputs": (0,), "digital_outputs": (DIGITAL_ENABLE,), "analog_inputs": (ANALOG_CURRENT,),
                 "encoder_inputs": (0, 1), "digital_inputs": (0, 1, 2), "other_inputs": OTHER_INPUTS}
"""A Qube's channels, those of the Furuta plant."""
CHANNEL_KINDS = {"analog_outputs": "analog output", "digital_outputs": "digital output",
                 "analog_inputs": "analog input", "encoder_inputs": "encoder", "digital_inputs": "digital input",
                 "other_inputs": "other input"}

# Error codes of the substitute (its own numbers, not Quanser's).
BOARD_NOT_OPEN = -1
INVALID_CARD = -2
INVALID_CHANNEL = -3
INVALID_BUFFER = -4
INVALID_TASK = -5
INVALID_ARGUMENT = -6
CLOCK_IN_USE = -7
BUFFER_OVERFLOW = -8
WATCHDOG_EXPIRED = -9
TOO_MANY_SAMPLES = -10
BOARD_NOT_FOUND = -11
PLANT_DIVERGED = -12

_UNPLUGGED = set()
"""Identifiers of the substitute boards that `unplug` disconnected."""


def unplug(card_identifier="0"):
    """Disconnect substitute board `card_identifier`: opening it fails until `plug`."""
    _UNPLUGGED.add(str(card_identifier))


def plug(card_identifier="0"):
    """Connect substitute board `card_identifier` again after `unplug`."""
    _UNPLUGGED.discard(str(card_identifier))

cdef enum:                      # digital inputs
    _FAULT = 0
    _STALL_DETECTED = 1
    _STALL_ERROR = 2

cdef double ARM_SIGN = conventions.ARM_SIGN
cdef double PENDULUM_SIGN = conventions.PENDULUM_SIGN
cdef double COUNTS_PER_RADIAN = 1.0 / conventions.RADIANS_PER_COUNT
cdef double PI = math.pi


class HILError(Exception):
    """An error of the board, like `quanser.hardware.HILError`: `error_code` and a message."""

    def __init__(self, error_code, message=""):
        super().__init__(error_code, message)
        self.error_code = error_code
        self.message = message

    def get_error_message(self):
        """The error's description."""
        return self.message

    def __str__(self):
        return f"{self.message} (substitute HIL error {self.error_code})"


class Clock:
    """Task clocks; a Qube has one hardware clock."""

    HARDWARE_CLOCK_0 = 0


class BufferOverflowMode:
    """What a reader task does with a new sample when its buffer is full."""

    ERROR_ON_OVERFLOW = 0       # the next task read raises HILError
    OVERWRITE_ON_OVERFLOW = 1   # the oldest sample is dropped
    DISCARD_ON_OVERFLOW = 2     # the new sample is dropped


class DigitalState:
    """Watchdog expiration states of digital outputs."""

    LOW = 0
    HIGH = 1
    TRISTATE = 2                # the amplifier enable line floats low: disabled
    NO_CHANGE = 3


# -- the plant, in C ------------------------------------------------------------------

cdef struct Params:
    double Rm, kt, km, Lm
    double J0           # Jr + Jm + mp Lr^2: arm-axis inertia with the pendulum's mass at the pivot
    double Kn           # mp lc^2 + J_n: the pendulum's extra arm-axis inertia per sin^2(alpha)
    double Ja           # the rod's inertia about its own axis
    double K            # mp lc^2 + J_n - J_a
    double mLl          # mp Lr lc
    double M22          # J_h + mp lc^2: pendulum inertia about its pivot
    double mgl          # mp g lc
    double Dr, Dp, Fr, Fp, kc
    double Fs           # the arm's breakaway torque (N m): friction limit of a stuck arm (0: Fr)
    double rest, slack  # the cable: rest angle and the half-width of its slack band (rad)
    double rest_spread, kc_spread   # the cable's per-session spread: rest (rad), stiffness (relative), std
    double latency      # between a voltage written and the amplifier applying it (s)
    double deadzone     # the amplifier's voltage dead zone (V)
    double vibration, vibration_time   # the bench's sway on the pendulum: RMS torque (N m), correlation (s)
    double v_limit, i_limit, stall_v, stall_w, stall_t

DEF DELAY_CAPACITY = 512


cdef struct Plant:
    double x[5]         # theta, alpha (unwrapped), dtheta, dalpha, motor current; package signs
    double t            # simulated time (s)
    double sway         # the bench's torque on the pendulum now (N m)
    double sway_step, sway_decay, sway_scale    # the sway's decay and innovation scale over a substep of
                                                # sway_step s (0: not computed for these parameters)
    unsigned long long random_state     # splitmix64 state of the board's random stream
    double kc, rest     # this session's cable: stiffness (N m/rad) and rest angle (rad)
    double command      # the voltage written last that is queued to act (V, board sign)
    double delayed      # the written voltage the amplifier acts on now, `latency` after its write (V)
    double queue_due[DELAY_CAPACITY]    # writes waiting out the latency: when each acts (s) ...
    double queue_volts[DELAY_CAPACITY]  # ... and its voltage (V, board sign)
    int queue_head, queue_count
    double stall_timer
    bint stall_detected, stall_error, fault, arm_blocked, diverged

cdef struct Outputs:
    double analog[4]    # analog outputs as written, by place (V, board sign); the Furuta plant's is 0
    bint enable[4]      # digital outputs (amplifier enables), by place
    double led[3]

cdef struct Watchdog:
    bint running, expired
    double timeout, deadline
    double analog_state[4]
    int digital_state[4]

cdef struct Sample:
    double analog[4]    # analog inputs by place (the Furuta plant's: motor current, A, board sign)
    int encoder[4]      # by place
    signed char digital[3]
    double other[10]    # other inputs by place (the Furuta plant's: tachometers, counts/s)

cdef struct Sampler:
    bint running
    long substeps_per_sample, countdown, remaining     # remaining < 0: infinite
    Sample* ring
    long capacity, head, count, overflows
    int overflow_mode
    bint overflow_pending


cdef inline double _clamp(double value, double limit) noexcept nogil:
    if value > limit:
        return limit
    if value < -limit:
        return -limit
    return value


cdef inline double _uniform(unsigned long long* state) noexcept nogil:
    """A number in (0, 1) from the splitmix64 stream `state` (Steele, Lea and Flood, OOPSLA 2014)."""
    cdef unsigned long long z
    state[0] += 0x9E3779B97F4A7C15ULL
    z = state[0]
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL
    z = z ^ (z >> 31)
    return ((z >> 11) + 0.5) * (1.0 / 9007199254740992.0)


cdef inline double _normal(unsigned long long* state) noexcept nogil:
    """A standard normal number (Box-Muller) from the stream `state`."""
    cdef double u1 = _uniform(state), u2 = _uniform(state)
    return sqrt(-2.0 * log(u1)) * cos(2.0 * PI * u2)


cdef inline void _derivative(const Params* p, const Plant* sp, const double* x, double v, bint on,
                             double sway, double* dx) noexcept nogil:
    """d/dt of [theta, alpha, dtheta, dalpha, i] with package voltage `v` at the motor, the
    amplifier `on`, the bench's torque `sway` on the pendulum and the session's cable of `sp`."""
    cdef double i, di, s, c, m11, m12, k, f1, f2, det, stretch
    if not on:
        i = 0.0
        di = 0.0
    elif p.Lm > 0.0:
        i = x[4]
        di = (v - p.Rm * i - p.km * x[2]) / p.Lm
        if (i >= p.i_limit and di > 0.0) or (i <= -p.i_limit and di < 0.0):
            di = 0.0                                    # the amplifier holds the current at its limit
    else:
        i = _clamp((v - p.km * x[2]) / p.Rm, p.i_limit)
        di = 0.0
    s = sin(x[1])
    c = cos(x[1])
    m11 = p.J0 + p.Kn * s * s + p.Ja * c * c
    m12 = -p.mLl * c
    k = p.K
    stretch = x[0] - sp.rest                        # beyond the slack band the cable pulls back
    if stretch > p.slack:
        stretch -= p.slack
    elif stretch < -p.slack:
        stretch += p.slack
    else:
        stretch = 0.0
    f1 = p.kt * i - p.Dr * x[2] - sp.kc * stretch - 2.0 * k * s * c * x[2] * x[3] - p.mLl * s * x[3] * x[3]
    f2 = -p.Dp * x[3] + k * s * c * x[2] * x[2] + p.mgl * s + sway
    det = m11 * p.M22 - m12 * m12
    dx[0] = x[2]
    dx[1] = x[3]
    dx[2] = (p.M22 * f1 - m12 * f2) / det
    dx[3] = (m11 * f2 - m12 * f1) / det
    dx[4] = di


cdef inline bint _friction_mode(double v1, double v2, double a11, double a12, double a22, double f1,
                                double f2, int m1, int m2, double* tau) noexcept nogil:
    """Friction impulses for one stick/slip mode (m = 0 stick, +-1 slip); False if inconsistent."""
    cdef double t1 = m1 * f1, t2 = m2 * f2, w1, w2, det
    cdef double tol1 = 1e-12 * (fabs(v1) + 1e-9), tol2 = 1e-12 * (fabs(v2) + 1e-9)
    if m1 == 0 and m2 == 0:
        det = a11 * a22 - a12 * a12
        t1 = (a22 * v1 - a12 * v2) / det
        t2 = (a11 * v2 - a12 * v1) / det
    elif m1 == 0:
        t1 = (v1 - a12 * t2) / a11
    elif m2 == 0:
        t2 = (v2 - a12 * t1) / a22
    if fabs(t1) > f1 * (1.0 + 1e-12) or fabs(t2) > f2 * (1.0 + 1e-12):
        return False
    w1 = v1 - a11 * t1 - a12 * t2
    w2 = v2 - a12 * t1 - a22 * t2
    if (m1 != 0 and f1 > 0.0 and m1 * w1 < -tol1) or (m2 != 0 and f2 > 0.0 and m2 * w2 < -tol2):
        return False
    tau[0] = t1
    tau[1] = t2
    return True


cdef inline int _sign(double value) noexcept nogil:
    return (value > 0.0) - (value < 0.0)


cdef void _coulomb_friction(const Params* p, double* x, const double* x_start, double h) noexcept nogil:
    """Apply Coulomb friction over a substep as an implicit impulse (exact stick/slip).

    Finds friction torques tau, |tau_j| <= F_j, with the new velocity
    w = v - h M^-1 tau and tau_j = F_j sign(w_j) wherever w_j != 0 (a linear
    complementarity problem with a unique solution, M being positive definite),
    by trying the nine stick/slip modes, the likely one first. Stuck joints keep
    their start-of-substep position.
    """
    cdef double f1 = p.Fr, f2 = p.Fp, s, c, m11, m12, det, a11, a12, a22
    cdef double tau[2]
    cdef int m1, m2, first1, first2
    cdef bint found = False
    if p.Fs > f1 and x_start[2] == 0.0:                 # a stuck arm holds up to its breakaway torque
        f1 = p.Fs
    if f1 == 0.0 and f2 == 0.0:
        return
    s = sin(x[1])
    c = cos(x[1])
    m11 = p.J0 + p.Kn * s * s + p.Ja * c * c
    m12 = -p.mLl * c
    det = m11 * p.M22 - m12 * m12
    a11 = h * p.M22 / det                               # A = h M^-1
    a12 = -h * m12 / det
    a22 = h * m11 / det
    first1 = _sign(x[2]) if f1 > 0.0 else 0
    first2 = _sign(x[3]) if f2 > 0.0 else 0
    # A joint without friction is "slipping" with zero torque: its mode is fixed to 1 with F = 0.
    if f1 == 0.0:
        first1 = 1
    if f2 == 0.0:
        first2 = 1
    found = _friction_mode(x[2], x[3], a11, a12, a22, f1, f2, first1, first2, tau)
    m1 = -1
    while not found and m1 <= 1:
        m2 = -1
        while not found and m2 <= 1:
            if (f1 > 0.0 or m1 == 1) and (f2 > 0.0 or m2 == 1):
                found = _friction_mode(x[2], x[3], a11, a12, a22, f1, f2, m1, m2, tau)
            m2 += 1
        m1 += 1
    if not found:                                       # unreachable for positive-definite M
        return
    x[0] -= 0.5 * h * (a11 * tau[0] + a12 * tau[1])
    x[1] -= 0.5 * h * (a12 * tau[0] + a22 * tau[1])
    x[2] -= a11 * tau[0] + a12 * tau[1]
    x[3] -= a12 * tau[0] + a22 * tau[1]
    if f1 > 0.0 and fabs(tau[0]) < f1 * (1.0 - 1e-12):   # stuck (within the breakaway torque if it was)
        x[2] = 0.0
        x[0] = x_start[0]
    if f2 > 0.0 and fabs(tau[1]) < f2 * (1.0 - 1e-12):
        x[3] = 0.0
        x[1] = x_start[1]


cdef void _substep(const Params* p, Plant* s, double applied, bint on, double h) noexcept nogil:
    """Advance the plant by h with the amplifier applying `applied` volts (board sign) if `on`."""
    cdef double k1[5]
    cdef double k2[5]
    cdef double k3[5]
    cdef double k4[5]
    cdef double y[5]
    cdef double start[5]
    cdef double v = ARM_SIGN * applied
    cdef int j
    if p.deadzone > 0.0:            # the amplifier passes nothing of the first `deadzone` volts
        v = copysign(fmax(fabs(v) - p.deadzone, 0.0), v)
    for j in range(5):
        start[j] = s.x[j]
    if p.vibration > 0.0:           # exact discretisation of the Gauss-Markov sway over h
        if h != s.sway_step:
            s.sway_step, s.sway_decay = h, exp(-h / p.vibration_time)
            s.sway_scale = p.vibration * sqrt(1.0 - s.sway_decay * s.sway_decay)
        s.sway = s.sway_decay * s.sway + s.sway_scale * _normal(&s.random_state)
    else:
        s.sway = 0.0
    _derivative(p, s, s.x, v, on, s.sway, k1)
    for j in range(5):
        y[j] = s.x[j] + 0.5 * h * k1[j]
    _derivative(p, s, y, v, on, s.sway, k2)
    for j in range(5):
        y[j] = s.x[j] + 0.5 * h * k2[j]
    _derivative(p, s, y, v, on, s.sway, k3)
    for j in range(5):
        y[j] = s.x[j] + h * k3[j]
    _derivative(p, s, y, v, on, s.sway, k4)
    for j in range(5):
        s.x[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
    _coulomb_friction(p, s.x, start, h)
    if s.arm_blocked:                                   # held: the arm does not move
        s.x[0] = start[0]
        s.x[2] = 0.0
    if not on:
        s.x[4] = 0.0
    elif p.Lm > 0.0:
        s.x[4] = _clamp(s.x[4], p.i_limit)
    else:
        s.x[4] = _clamp((v - p.km * s.x[2]) / p.Rm, p.i_limit)
    s.stall_detected = on and fabs(applied) > p.stall_v and fabs(s.x[2]) < p.stall_w
    if s.stall_detected:
        s.stall_timer += h
        if s.stall_timer >= p.stall_t:
            s.stall_error = True
    else:
        s.stall_timer = 0.0
    s.t += h


# -- the board ------------------------------------------------------------------------

cdef class Task:
    """A reader task's handle; channels are fixed when it is created (kept by their places on the board)."""

    cdef int analog[4]
    cdef int encoder[4]
    cdef int digital[3]
    cdef int other[10]
    cdef int n_analog, n_encoder, n_digital, n_other
    cdef long samples_in_buffer
    cdef int overflow_mode
    cdef bint deleted
    cdef object board


cdef class HIL:
    """A Qube-Servo board with a simulated Qube: Quanser's HIL API, plus inspection for tests.

    HIL(card_type=None, card_identifier="0", *, plant=None, realtime=False, seed=0): like
    Quanser's HIL, opens the board when `card_type` is given, with the card's default plant
    (`plant.DEFAULT_PLANTS`). `plant` overrides that plant's parameters by long name
    (`qube_suite.hardware.plant`), or is a device's own
    plant (a `board_plant.BoardPlant`): the board is then that device's card, with its
    channels; a board opened as a card that a device's substitute declares, without a
    plant, makes that device's plant. `plant` may also name a plant of `plant.PLANTS`
    ("estimated", "real_qube_servo2"). `realtime=True` paces tasks by the wall clock;
    `seed` (a non-negative integer) seeds the random stream of the bench's sway (and of the
    session's cable, for a plant that spreads it).
    """

    INFINITE = -1

    cdef Params p
    cdef Plant s
    cdef Outputs out
    cdef Watchdog wd
    cdef Sampler smp
    cdef int encoder_offset[4]
    cdef double h_idle, h
    cdef double wall_origin
    cdef bint realtime_, is_open
    cdef object lock, plant_overrides, plant_values, card_type, running_task
    cdef object read_failure, options_
    cdef long reads_before_failure
    cdef object device_plant    # a device's own plant (BoardPlant), or None: the Furuta plant
    cdef dict chans_            # channel kind -> the board's channels of that kind, in place order
    cdef int n_analog_outputs, n_digital_outputs

    def __cinit__(self):
        self.smp.ring = NULL

    def __init__(self, card_type=None, card_identifier="0", *, plant=None, realtime=False, seed=0):
        if isinstance(plant, BoardPlant):
            self._use_device_plant(plant)
            plant = None
        else:
            plant_parameters("qube_servo2_usb", plant)     # unknown names fail here, before opening
            self._use_channels(QUBE_CHANNELS)
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**64:
            raise ValueError(f"seed must be an integer in [0, 2**64), got {seed!r}")
        self.s.random_state = int(seed)
        self.s.sway = 0.0
        self.plant_overrides = plant if isinstance(plant, str) else dict(plant or {})
        self.realtime_ = bool(realtime)
        self.lock = threading.Lock()
        self.h_idle = 1.0 / MIN_INTEGRATION_RATE
        self.h = self.h_idle
        self.s.x[0] = 0.0
        self.s.x[1] = PI                                 # power-up: hanging at rest
        self.s.x[2] = self.s.x[3] = self.s.x[4] = 0.0
        self.s.t = 0.0
        self.out.led[0] = self.out.led[1] = self.out.led[2] = 0.0
        for j in range(MAX_CHANNELS):
            self.encoder_offset[j] = 0
            self.out.analog[j] = self.wd.analog_state[j] = 0.0
            self.out.enable[j] = False
            self.wd.digital_state[j] = 0
        if card_type is not None:
            self.open(card_type, card_identifier)

    def __dealloc__(self):
        free(self.smp.ring)

    # -- opening and closing -------------------------------------------------------------

    def open(self, card_type, card_identifier):
        """Open the board `card_type` ("qube_servo2_usb", "qube_servo3_usb", or a device's own card, see
        the class docstring) number `card_identifier`."""
        with self.lock:
            if self.is_open:
                raise HILError(INVALID_ARGUMENT, "the board is already open")
            if self.device_plant is None and card_type not in BOARD_TYPES:
                found = substitute_plant(card_type)
                if found is None:
                    raise HILError(INVALID_CARD, f"unknown card type {card_type!r}; the substitute offers "
                                                  f"{', '.join(BOARD_TYPES)} and the cards of the devices "
                                                  "that bring their own plant")
                self._use_device_plant(found)
            if self.device_plant is not None and card_type != self.device_plant.channels.card_type:
                raise HILError(INVALID_CARD, f"this substitute board carries a "
                                              f"{self.device_plant.channels.card_type}'s plant, not a "
                                              f"{card_type!r}'s")
            if str(card_identifier) in _UNPLUGGED:
                raise HILError(BOARD_NOT_FOUND, f"no {card_type} board {card_identifier} is connected "
                                                "(the substitute board was unplugged)")
            if self.device_plant is None:
                values = plant_parameters(card_type, self.plant_overrides)
                self._set_parameters(values)
                self._draw_session()
                self.plant_values = values
            self.card_type = card_type
            self.wall_origin = time.perf_counter() - self.s.t
            self.is_open = True

    def set_card_specific_options(self, options, max_length):
        """Card options ("name=value;..."), as Quanser's Qube-Servo 3 code sets them; kept in
        `card_options` (the substitute's plant does not model them)."""
        if not isinstance(options, str) or len(options) >= int(max_length):
            raise HILError(INVALID_ARGUMENT, f"options must be a string shorter than {max_length}")
        with self.lock:
            self._require_open()
            self.options_ = options

    @property
    def card_options(self):
        """The card options last set ("" if none)."""
        return self.options_ or ""

    def is_valid(self):
        """True while the board is open."""
        return bool(self.is_open)

    def close(self):
        """Stop tasks and the watchdog, zero the outputs (0 V, amplifier disabled) and close."""
        with self.lock:
            if not self.is_open:
                return
            self._sync()
            self.smp.running = False
            self.running_task = None
            self.wd.running = False
            for j in range(MAX_CHANNELS):
                self.out.analog[j] = 0.0
                self.out.enable[j] = False
            self.h = self.h_idle
            self.is_open = False

    # -- immediate I/O -------------------------------------------------------------------

    def read_encoder(self, channels, num_channels, int[::1] buffer):
        """Read encoder counts now into `buffer`."""
        cdef list places = self._places(channels, num_channels, _length_i(buffer), "encoder_inputs")
        cdef Sample sample = self._read_now()
        for j, c in enumerate(places):
            buffer[j] = sample.encoder[c]

    def read_analog(self, channels, num_channels, double[::1] buffer):
        """Read the analog inputs (a Qube's: the motor current, A) now into `buffer`."""
        cdef list places = self._places(channels, num_channels, _length_d(buffer), "analog_inputs")
        cdef Sample sample = self._read_now()
        for j, c in enumerate(places):
            buffer[j] = sample.analog[c]

    def read_digital(self, channels, num_channels, signed char[::1] buffer):
        """Read the fault and stall flags now into `buffer` (1 = asserted)."""
        cdef list chans = self._places(channels, num_channels, _length_b(buffer), "digital_inputs")
        cdef Sample sample = self._read_now()
        for j, c in enumerate(chans):
            buffer[j] = sample.digital[c]

    def read_other(self, channels, num_channels, double[::1] buffer):
        """Read the other inputs (a Qube's: tachometers, counts/s) now into `buffer`."""
        cdef list places = self._places(channels, num_channels, _length_d(buffer), "other_inputs")
        cdef Sample sample = self._read_now()
        for j, c in enumerate(places):
            buffer[j] = sample.other[c]

    def write_analog(self, channels, num_channels, const double[::1] buffer):
        """Set the motor voltages (V); the amplifier applies them within its limit while enabled."""
        cdef list places = self._places(channels, num_channels, _length_cd(buffer), "analog_outputs")
        cdef Py_ssize_t j, n = len(places)
        for j in range(n):
            if not isfinite(buffer[j]):
                raise HILError(INVALID_ARGUMENT, f"analog output value {buffer[j]} is not finite")
        with self.lock:
            self._require_writable()
            for j in range(n):
                self.out.analog[<int>places[j]] = buffer[j]

    def write_digital(self, channels, num_channels, const signed char[::1] buffer):
        """Set the amplifier enable lines; a low level also clears a stall error."""
        cdef list places = self._places(channels, num_channels, _length_cb(buffer), "digital_outputs")
        with self.lock:
            self._require_writable()
            for j, c in enumerate(places):
                self.out.enable[<int>c] = buffer[j] != 0
                if not self.out.enable[<int>c]:
                    self.s.stall_error = False
                    self.s.stall_timer = 0.0

    def write_other(self, channels, num_channels, const double[::1] buffer):
        """Set LED colour components (other outputs 11000-11002), each saturated to [0, 1]."""
        cdef list chans = _channels(channels, num_channels, _length_cd(buffer), "other output", OTHER_LED, "this board")
        with self.lock:
            self._require_writable()
            for j, c in enumerate(chans):
                self.out.led[c - OTHER_LED[0]] = min(max(float(buffer[j]), 0.0), 1.0)

    def set_encoder_counts(self, channels, num_channels, const int[::1] buffer):
        """Make the encoders read `buffer` at their present positions."""
        cdef list places = self._places(channels, num_channels, _length_ci(buffer), "encoder_inputs")
        cdef double positions[4]
        with self.lock:
            self._require_writable()
            self._all_encoder_positions(positions)
            for j, c in enumerate(places):
                self.encoder_offset[<int>c] = buffer[j] - <int>floor(positions[<int>c])

    # -- tasks ---------------------------------------------------------------------------

    def task_create_reader(self, samples_in_buffer, analog_channels, num_analog_channels, encoder_channels,
                           num_encoder_channels, digital_channels, num_digital_channels, other_channels,
                           num_other_channels):
        """A task reading analog, encoder, digital and other inputs at each sample."""
        cdef Task task = Task()
        analog = self._places(analog_channels, num_analog_channels, -1, "analog_inputs")
        encoder = self._places(encoder_channels, num_encoder_channels, -1, "encoder_inputs")
        digital = self._places(digital_channels, num_digital_channels, -1, "digital_inputs")
        other = self._places(other_channels, num_other_channels, -1, "other_inputs")
        for name, chans in (("analog", analog), ("encoder", encoder), ("digital", digital), ("other", other)):
            if len(set(chans)) != len(chans):
                raise HILError(INVALID_CHANNEL, f"repeated {name} channels in {chans}")
        task.n_analog, task.n_encoder, task.n_digital, task.n_other = (
            len(analog), len(encoder), len(digital), len(other))
        for j, c in enumerate(analog):
            task.analog[j] = c
        for j, c in enumerate(encoder):
            task.encoder[j] = c
        for j, c in enumerate(digital):
            task.digital[j] = c
        for j, c in enumerate(other):
            task.other[j] = c
        return self._new_task(task, samples_in_buffer)

    def task_create_encoder_reader(self, samples_in_buffer, channels, num_channels):
        """A task reading encoders at each sample."""
        return self.task_create_reader(samples_in_buffer, None, 0, channels, num_channels, None, 0, None, 0)

    def task_set_buffer_overflow_mode(self, Task task not None, mode):
        """Choose what a full task buffer does with a new sample (a `BufferOverflowMode`)."""
        if mode not in (BufferOverflowMode.ERROR_ON_OVERFLOW, BufferOverflowMode.OVERWRITE_ON_OVERFLOW,
                        BufferOverflowMode.DISCARD_ON_OVERFLOW):
            raise HILError(INVALID_ARGUMENT, f"unsupported buffer overflow mode {mode!r}")
        with self.lock:
            self._require_task(task)
            task.overflow_mode = mode
            if task is self.running_task:
                self.smp.overflow_mode = mode

    def task_start(self, Task task not None, clock, frequency, num_samples):
        """Start sampling at `frequency` (Hz) for `num_samples` samples (HIL.INFINITE: until stopped).

        The first sample is taken at once; the plant then integrates at
        ceil(10 kHz / frequency) substeps per sample.
        """
        frequency = float(frequency)
        if clock != Clock.HARDWARE_CLOCK_0:
            raise HILError(INVALID_ARGUMENT, f"unsupported clock {clock!r}; a Qube has HARDWARE_CLOCK_0")
        if not (math.isfinite(frequency) and frequency > 0.0):
            raise HILError(INVALID_ARGUMENT, f"frequency must be positive, got {frequency}")
        if num_samples != HIL.INFINITE and num_samples <= 0:
            raise HILError(INVALID_ARGUMENT, f"num_samples must be positive or HIL.INFINITE, got {num_samples}")
        with self.lock:
            self._require_task(task)
            if self.smp.running:
                raise HILError(CLOCK_IN_USE, "another task is running on the hardware clock")
            self._sync()
            free(self.smp.ring)
            self.smp.ring = <Sample*>malloc(task.samples_in_buffer * sizeof(Sample))
            if self.smp.ring == NULL:
                raise MemoryError()
            self.smp.capacity = task.samples_in_buffer
            self.smp.head = self.smp.count = self.smp.overflows = 0
            self.smp.overflow_mode = task.overflow_mode
            self.smp.overflow_pending = False
            self.smp.substeps_per_sample = max(1, math.ceil(MIN_INTEGRATION_RATE / frequency - 1e-9))
            self.h = 1.0 / (frequency * self.smp.substeps_per_sample)
            self.smp.countdown = self.smp.substeps_per_sample
            self.smp.remaining = num_samples
            self.smp.running = True
            self.running_task = task
            self._take_present_sample()

    def task_read(self, Task task not None, num_samples, double[::1] analog_buffer, int[::1] encoder_buffer,
                  signed char[::1] digital_buffer, double[::1] other_buffer):
        """Read `num_samples` samples (the oldest first), waiting for them; returns how many were read.

        Returns 0 once a finite task has delivered all its samples.
        """
        cdef long n = num_samples
        _check_buffer(_length_d(analog_buffer), n * task.n_analog, "analog")
        _check_buffer(_length_i(encoder_buffer), n * task.n_encoder, "encoder")
        _check_buffer(_length_b(digital_buffer), n * task.n_digital, "digital")
        _check_buffer(_length_d(other_buffer), n * task.n_other, "other")
        with self.lock:
            return self._read_task(task, n, analog_buffer, encoder_buffer, digital_buffer, other_buffer)

    def task_read_encoder(self, Task task not None, num_samples, int[::1] buffer):
        """`task_read` of an encoder reader task."""
        cdef long n = num_samples
        _check_buffer(-1, n * task.n_analog, "analog")          # no buffers for the task's other inputs
        _check_buffer(_length_i(buffer), n * task.n_encoder, "encoder")
        _check_buffer(-1, n * task.n_digital, "digital")
        _check_buffer(-1, n * task.n_other, "other")
        with self.lock:
            return self._read_task(task, n, None, buffer, None, None)

    def task_get_buffer_overflows(self, Task task not None):
        """Samples lost (overwritten or discarded) because the task buffer was full."""
        with self.lock:
            self._require_task(task)
            return int(self.smp.overflows) if task is self.running_task else 0

    def task_stop(self, Task task not None):
        """Stop a task's sampling; it may be started again."""
        with self.lock:
            self._require_task(task)
            if task is self.running_task:
                self._sync()
                self.smp.running = False
                self.running_task = None
                self.h = self.h_idle

    def task_delete(self, Task task not None):
        """Stop (if running) and delete a task; its handle becomes invalid."""
        if task.deleted or task.board is not self:
            raise HILError(INVALID_TASK, "not a task of this board")
        with self.lock:
            if task is self.running_task:
                self._sync()
                self.smp.running = False
                self.running_task = None
                self.h = self.h_idle
            task.deleted = True

    # -- watchdog ------------------------------------------------------------------------

    def watchdog_set_analog_expiration_state(self, channels, num_channels, const double[::1] voltages):
        """Voltages that the analog outputs take when the watchdog expires (default 0 V)."""
        cdef list places = self._places(channels, num_channels, _length_cd(voltages), "analog_outputs")
        with self.lock:
            self._require_open()
            for j, c in enumerate(places):
                self.wd.analog_state[<int>c] = voltages[j]

    def watchdog_set_digital_expiration_state(self, channels, num_channels, states):
        """`DigitalState`s that the digital outputs take when the watchdog expires (default LOW)."""
        cdef list places = self._places(channels, num_channels, -1 if states is None else len(states),
                                        "digital_outputs")
        values = [int(states[j]) for j in range(len(places))]
        for value in values:
            if value not in (DigitalState.LOW, DigitalState.HIGH, DigitalState.TRISTATE, DigitalState.NO_CHANGE):
                raise HILError(INVALID_ARGUMENT, f"{value} is not a DigitalState")
        with self.lock:
            self._require_open()
            for c, value in zip(places, values):
                self.wd.digital_state[<int>c] = value

    def watchdog_start(self, timeout):
        """Start the watchdog: it expires `timeout` (s) of board time after the last reload."""
        timeout = float(timeout)
        if not (math.isfinite(timeout) and timeout > 0.0):
            raise HILError(INVALID_ARGUMENT, f"watchdog timeout must be positive, got {timeout}")
        with self.lock:
            self._require_open()
            self._sync()
            self.wd.timeout = timeout
            self.wd.deadline = self.s.t + timeout
            self.wd.running = True

    def watchdog_reload(self):
        """Restart the watchdog's countdown; False (and no reload) if it has already expired."""
        with self.lock:
            self._require_open()
            self._sync()
            if self.wd.expired:
                return False
            self.wd.deadline = self.s.t + self.wd.timeout
            return True

    def watchdog_is_expired(self):
        """True if the watchdog has expired and not been cleared."""
        with self.lock:
            self._require_open()
            self._sync()
            return bool(self.wd.expired)

    def watchdog_clear(self):
        """Allow writes again after an expiry; the outputs stay at their expiration states."""
        with self.lock:
            self._require_open()
            self._sync()
            self.wd.expired = False
            self.wd.running = False

    def watchdog_stop(self):
        """Stop the watchdog (an expiry stays until `watchdog_clear`)."""
        with self.lock:
            self._require_open()
            self._sync()
            self.wd.running = False

    # -- inspection (not part of Quanser's API) ------------------------------------------

    def true_state(self):
        """[theta, alpha, dtheta, dalpha] of the plant (rad, rad/s), angles wrapped to (-pi, pi]; a device's
        own plant gives its own (`BoardPlant.true_state`)."""
        with self.lock:
            self._sync()
            self._require_finite()
            if self.device_plant is not None:
                return self.device_plant.true_state()
            return np.array([wrap_angle(self.s.x[0]), wrap_angle(self.s.x[1]), self.s.x[2], self.s.x[3]])

    def set_true_state(self, state):
        """Put the plant at [theta, alpha, dtheta, dalpha] (rad, rad/s), or a device's own plant in its own
        state; the encoders count the move."""
        if self.device_plant is not None:
            with self.lock:
                self._sync()
                self.device_plant.set_true_state(np.asarray(state, dtype=np.float64))
            return
        values = [float(v) for v in state]
        if len(values) != 4 or not all(math.isfinite(v) for v in values):
            raise ValueError(f"state must be 4 finite numbers, got {state!r}")
        with self.lock:
            self._sync()
            for j in range(4):
                self.s.x[j] = values[j]
            self.s.x[4] = 0.0

    def seed(self, seed):
        """Reseed the board's random stream (the bench's sway) and calm the sway: with the same plant
        state, the same seed gives the same run. A plant whose cable spreads from session to session
        (`cable_rest_spread`, `cable_stiffness_spread`) draws this session's cable from it."""
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**64:
            raise ValueError(f"seed must be an integer in [0, 2**64), got {seed!r}")
        with self.lock:
            self._sync()
            self.s.random_state = int(seed)
            self.s.sway = 0.0
            if self.is_open and self.device_plant is None:
                self._draw_session()

    # -- fault injection (not part of Quanser's API; see the module docstring) ------------

    def set_amplifier_fault(self, fault):
        """Raise (True) or clear (False) an amplifier fault, as a thermal shutdown would."""
        with self.lock:
            self._sync()
            self.s.fault = bool(fault)

    def glitch_encoder(self, channel, counts):
        """Make encoder `channel` (a Qube's: 0 arm, 1 pendulum) jump by `counts` and count on from there."""
        valid = self.chans_["encoder_inputs"]
        if channel not in valid:
            raise ValueError(f"encoder channel must be one of {valid}, got {channel!r}")
        with self.lock:
            self._sync()
            self.encoder_offset[<int>valid.index(channel)] += int(counts)

    def block_arm(self, blocked):
        """Hold the arm still (True), e.g. against an obstacle, or let it go (False); the Furuta plant's."""
        if self.device_plant is not None:
            raise ValueError("block_arm holds a Qube's arm; this board carries a device's own plant")
        with self.lock:
            self._sync()
            self.s.arm_blocked = bool(blocked)

    def stall(self, seconds):
        """Let `seconds` of board time pass without a task read, as a stalled control loop does."""
        seconds = float(seconds)
        if not (math.isfinite(seconds) and seconds >= 0.0):
            raise ValueError(f"seconds must be a non-negative number, got {seconds}")
        if self.realtime_:
            time.sleep(seconds)
            return
        with self.lock:
            self._require_open()
            self._integrate(round(seconds / self.h))

    def fail_read(self, exception, after=0):
        """Make the task read after `after` more reads raise `exception` (an exception instance)."""
        if not isinstance(exception, BaseException) or after < 0:
            raise ValueError(f"need an exception instance and after >= 0, got {exception!r}, {after!r}")
        with self.lock:
            self.read_failure = exception
            self.reads_before_failure = int(after)

    @property
    def applied_voltage(self):
        """Voltage (V, board sign) the amplifier applies to the motor now: 0 while it is disabled. With a
        device's own plant, an array: one per analog output."""
        cdef double[::1] volts
        cdef unsigned char[::1] enabled
        with self.lock:
            self._sync()
            if self.device_plant is None:
                return self._applied()
            volts, enabled = np.zeros(self.n_analog_outputs), np.zeros(self.n_analog_outputs, dtype=np.uint8)
            self._device_outputs(volts, enabled)
            return np.asarray(volts).copy()

    @property
    def written_voltage(self):
        """Voltage (V, board sign) last written to the motor's analog output, as the board holds it: what
        the amplifier applies `latency` later (`applied_voltage`), while enabled. With a device's own
        plant, an array: one per analog output."""
        with self.lock:
            self._sync()
            if self.device_plant is None:
                return self.out.analog[0]
            return np.array([self.out.analog[j] for j in range(self.n_analog_outputs)])

    @property
    def amplifier_enabled(self):
        """True if the amplifier drives the motor (enabled, no fault, no stall error); with a device's own
        plant, if it drives any of them."""
        cdef double[::1] volts
        cdef unsigned char[::1] enabled
        with self.lock:
            self._sync()
            if self.device_plant is None:
                return bool(self._amplifier_on())
            volts, enabled = np.zeros(self.n_analog_outputs), np.zeros(self.n_analog_outputs, dtype=np.uint8)
            self._device_outputs(volts, enabled)
            return bool(np.asarray(enabled).any())

    @property
    def time(self):
        """The board's time (s): simulated time, which follows the wall clock in real-time mode."""
        with self.lock:
            self._sync()
            return self.s.t

    @property
    def led(self):
        """The LED's (red, green, blue), each in [0, 1]."""
        return (self.out.led[0], self.out.led[1], self.out.led[2])

    @property
    def plant(self):
        """The plant's parameters by long name (a copy); set when the board opens. A device's own plant:
        the plant itself."""
        if self.device_plant is not None:
            return self.device_plant
        return dict(self.plant_values or {})

    @property
    def cable(self):
        """This session's cable: (rest angle, rad; stiffness, N m/rad), drawn when the board opened or was
        last seeded (the plant's own unless it spreads them)."""
        return (self.s.rest, self.s.kc)

    @property
    def realtime(self):
        """True if the board follows the wall clock."""
        return bool(self.realtime_)

    # -- internals -----------------------------------------------------------------------

    cdef int _set_parameters(self, dict values) except -1:
        mp, lc, Lr = values["pendulum_mass"], values["pendulum_length"] / 2.0, values["arm_length"]
        jp = pendulum_inertia(mp, values["pendulum_length"])
        self.p.Rm, self.p.kt, self.p.km = (values["motor_resistance"], values["motor_torque_constant"],
                                           values["motor_back_emf"])
        self.p.Lm = values["motor_inductance"]
        self.p.J0 = arm_inertia(values["arm_mass"], Lr) + values["rotor_inertia"] + mp * Lr * Lr
        self.p.Ja = 0.5 * mp * PENDULUM_ROD_RADIUS ** 2
        self.p.Kn = mp * lc * lc + jp
        self.p.K = mp * lc * lc + jp - self.p.Ja
        self.p.mLl = mp * Lr * lc
        self.p.M22 = jp + mp * lc * lc
        self.p.mgl = mp * values["gravity"] * lc
        self.p.Dr, self.p.Dp = values["arm_damping"], values["pendulum_damping"]
        self.p.Fr, self.p.Fp = values["arm_friction"], values["pendulum_friction"]
        self.p.kc = values["cable_stiffness"]
        self.p.rest, self.p.slack = values["cable_rest_angle"], values["cable_slack"]
        self.p.rest_spread, self.p.kc_spread = values["cable_rest_spread"], values["cable_stiffness_spread"]
        self.p.Fs = values["arm_breakaway"]
        self.p.latency, self.p.deadzone = values["latency"], values["voltage_deadzone"]
        self.p.vibration, self.p.vibration_time = values["bench_vibration"], values["vibration_time"]
        self.s.sway_step = 0.0
        self.p.v_limit, self.p.i_limit = values["amplifier_voltage_limit"], values["current_limit"]
        self.p.stall_v, self.p.stall_w, self.p.stall_t = (values["stall_voltage"], values["stall_speed"],
                                                          values["stall_time"])
        return 0

    cdef inline bint _amplifier_on(self) noexcept nogil:
        return self.out.enable[0] and not self.s.fault and not self.s.stall_error

    cdef inline double _applied(self) noexcept nogil:
        if not self._amplifier_on():
            return 0.0
        return _clamp(self.s.delayed if self.p.latency > 0.0 else self.out.analog[0], self.p.v_limit)

    cdef void _delay_command(self) noexcept nogil:
        """Queue a newly written voltage to act `latency` later, and act on those now due. A queue
        that is full (writes faster than DELAY_CAPACITY per latency) lets its oldest act early."""
        cdef Plant* s = &self.s
        cdef int slot
        if self.out.analog[0] != s.command:
            if s.queue_count == DELAY_CAPACITY:
                s.delayed = s.queue_volts[s.queue_head]
                s.queue_head = (s.queue_head + 1) % DELAY_CAPACITY
                s.queue_count -= 1
            slot = (s.queue_head + s.queue_count) % DELAY_CAPACITY
            s.queue_due[slot] = s.t + self.p.latency
            s.queue_volts[slot] = self.out.analog[0]
            s.queue_count += 1
            s.command = self.out.analog[0]
        while s.queue_count > 0 and s.queue_due[s.queue_head] <= s.t + 1e-12:
            s.delayed = s.queue_volts[s.queue_head]
            s.queue_head = (s.queue_head + 1) % DELAY_CAPACITY
            s.queue_count -= 1

    cdef int _draw_session(self) except -1:
        """This session's cable: its rest angle and stiffness drawn about the plant's from the board's
        random stream (`cable_rest_spread`, `cable_stiffness_spread`; none drawn when both are 0)."""
        self.s.rest, self.s.kc = self.p.rest, self.p.kc
        if self.p.rest_spread > 0.0:
            self.s.rest += self.p.rest_spread * _normal(&self.s.random_state)
        if self.p.kc_spread > 0.0:
            self.s.kc *= exp(self.p.kc_spread * _normal(&self.s.random_state))
        return 0

    cdef void _encoder_positions(self, double* positions) noexcept nogil:
        positions[0] = ARM_SIGN * self.s.x[0] * COUNTS_PER_RADIAN
        positions[1] = PENDULUM_SIGN * (self.s.x[1] - PI) * COUNTS_PER_RADIAN

    cdef int _all_encoder_positions(self, double* positions) except -1:
        """Every encoder's position (counts, before the board's offsets), the plant's own or the Furuta's."""
        if self.device_plant is None:
            self._encoder_positions(positions)
            return 0
        for j, value in enumerate(self.device_plant.encoder_positions()):
            positions[j] = value
        return 0

    cdef void _sample(self, Sample* sample) noexcept nogil:
        cdef double positions[2]
        if self.s.diverged:                                 # nothing to cast to counts: the read raises
            sample.analog[0] = sample.other[0] = sample.other[1] = 0.0
            sample.encoder[0] = sample.encoder[1] = 0
            return
        self._encoder_positions(positions)
        sample.analog[0] = ARM_SIGN * self.s.x[4]
        sample.encoder[0] = self.encoder_offset[0] + <int>floor(positions[0])
        sample.encoder[1] = self.encoder_offset[1] + <int>floor(positions[1])
        sample.digital[_FAULT] = self.s.fault
        sample.digital[_STALL_DETECTED] = self.s.stall_detected
        sample.digital[_STALL_ERROR] = self.s.stall_error
        sample.other[0] = ARM_SIGN * self.s.x[2] * COUNTS_PER_RADIAN
        sample.other[1] = PENDULUM_SIGN * self.s.x[3] * COUNTS_PER_RADIAN

    # -- a device's own plant ---------------------------------------------------------------

    cdef int _use_channels(self, dict chans) except -1:
        self.chans_ = chans
        self.n_analog_outputs = len(chans["analog_outputs"])
        self.n_digital_outputs = len(chans["digital_outputs"])
        return 0

    cdef int _use_device_plant(self, plant) except -1:
        c = plant.channels
        for kind, limit in (("analog_outputs", MAX_CHANNELS), ("digital_outputs", MAX_CHANNELS),
                            ("analog_inputs", MAX_CHANNELS), ("encoder_inputs", MAX_CHANNELS),
                            ("other_inputs", MAX_OTHER_INPUTS)):
            if len(getattr(c, kind)) > limit:
                raise ValueError(f"the substitute board offers at most {limit} {kind}, the plant declares "
                                 f"{getattr(c, kind)}")
        self.device_plant = plant
        self._use_channels({"analog_outputs": tuple(c.analog_outputs),
                            "digital_outputs": tuple(c.digital_outputs),
                            "analog_inputs": tuple(c.analog_inputs), "encoder_inputs": tuple(c.encoder_inputs),
                            "digital_inputs": (), "other_inputs": tuple(c.other_inputs)})
        return 0

    cdef list _places(self, channels, num_channels, Py_ssize_t buffer_length, str kind):
        """The places on this board of `channels` of `kind` (a key of its channel table), checked as
        `_channels` checks them."""
        valid = self.chans_[kind]
        chans = _channels(channels, num_channels, buffer_length, CHANNEL_KINDS[kind], valid,
                          "a Qube" if self.device_plant is None else self.device_plant.channels.card_type)
        if kind == "other_inputs" and self.device_plant is None:
            self._check_other_inputs(chans)
        return [valid.index(c) for c in chans]

    cdef int _device_outputs(self, double[::1] volts, unsigned char[::1] enabled) except -1:
        """The voltages the amplifiers apply now (V, within their range; 0 where disabled) and which
        are enabled."""
        cdef double limit = self.device_plant.channels.voltage_limit
        cdef int j
        for j in range(self.n_analog_outputs):
            enabled[j] = (self.out.enable[j if self.n_digital_outputs > 1 else 0]
                          and not self.s.fault)
            volts[j] = _clamp(self.out.analog[j], limit) if enabled[j] else 0.0
        return 0

    cdef int _device_sample(self, Sample* sample) except -1:
        """The present sample of the device's plant; a plant whose encoders leave the finite range has
        diverged (the read raises)."""
        cdef int j
        plant = self.device_plant
        positions = plant.encoder_positions()
        if not (np.all(np.isfinite(positions)) and np.all(np.abs(positions) < 1e9)):
            self.s.diverged = True
            return 0
        for j, value in enumerate(positions):
            sample.encoder[j] = self.encoder_offset[j] + <int>floor(value)
        for j, value in enumerate(plant.analog_inputs()):
            sample.analog[j] = value
        for j, value in enumerate(plant.other_inputs()):
            sample.other[j] = value
        return 0

    cdef int _expire_watchdog_if_due(self) noexcept nogil:
        cdef int j
        if self.wd.running and not self.wd.expired and self.s.t >= self.wd.deadline - 1e-12:
            self.wd.expired = True
            for j in range(self.n_analog_outputs):
                self.out.analog[j] = self.wd.analog_state[j]
            for j in range(self.n_digital_outputs):
                if self.wd.digital_state[j] != 3:          # NO_CHANGE
                    self.out.enable[j] = self.wd.digital_state[j] == 1
        return 0

    cdef int _advance_device(self, long substeps) except -1:
        """`_advance` for a device's own plant: the plant moves from event to event (a sample due, the
        watchdog's deadline) in one call each, under the outputs as they are between them."""
        cdef long n, due
        cdef double[::1] volts = np.zeros(self.n_analog_outputs)
        cdef unsigned char[::1] enabled = np.zeros(self.n_analog_outputs, dtype=np.uint8)
        while substeps > 0:
            n = substeps
            if self.smp.running and self.smp.remaining != 0 and self.smp.countdown < n:
                n = self.smp.countdown
            if self.wd.running and not self.wd.expired:
                due = max(1, <long>ceil((self.wd.deadline - 1e-12 - self.s.t) / self.h - 1e-9))
                n = min(n, due)
            if not self.s.diverged:
                self._device_outputs(volts, enabled)
                self.device_plant.advance(n * self.h, np.asarray(volts).copy(), np.asarray(enabled, dtype=bool))
            self.s.t += n * self.h
            substeps -= n
            self._expire_watchdog_if_due()
            if self.smp.running and self.smp.remaining != 0:
                self.smp.countdown -= n
                if self.smp.countdown == 0:
                    self.smp.countdown = self.smp.substeps_per_sample
                    self._take_present_sample()
        return 0

    cdef int _take_present_sample(self) except -1:
        """`_take_sample`, of whichever plant the board carries."""
        cdef long slot
        if self.device_plant is None:
            self._take_sample()
            return 0
        slot = self._claim_slot()
        if slot >= 0:
            self._device_sample(&self.smp.ring[slot])
        return 0

    cdef int _integrate(self, long substeps) except -1:
        """Advance the board by `substeps` substeps, the Furuta plant in C without the GIL."""
        if self.device_plant is None:
            with nogil:
                self._advance(substeps)
        else:
            self._advance_device(substeps)
        return 0

    cdef long _read_task(self, Task task, long n, double[::1] analog_buffer, int[::1] encoder_buffer,
                         signed char[::1] digital_buffer, double[::1] other_buffer) except -1:
        """`task_read`'s work, the lock held and the buffers checked: the samples read (0: the task
        has delivered all its samples)."""
        cdef long j, c, k
        cdef Sample* sample
        self._require_task(task)
        if task is not self.running_task:
            raise HILError(INVALID_TASK, "the task is not running")
        if self.read_failure is not None:
            if self.reads_before_failure == 0:
                failure, self.read_failure = self.read_failure, None
                raise failure
            self.reads_before_failure -= 1
        if n <= 0 or n > self.smp.capacity:
            raise HILError(TOO_MANY_SAMPLES, f"can read 1 to {self.smp.capacity} samples, not {n}")
        if not self._wait_for_samples(n):
            return 0
        self._require_finite()
        if self.smp.overflow_pending:
            self.smp.overflow_pending = False
            raise HILError(BUFFER_OVERFLOW, "the task buffer overflowed: samples were not read in time")
        for k in range(n):
            sample = &self.smp.ring[self.smp.head]
            for j in range(task.n_analog):
                analog_buffer[k * task.n_analog + j] = sample.analog[task.analog[j]]
            for j in range(task.n_encoder):
                c = task.encoder[j]
                encoder_buffer[k * task.n_encoder + j] = sample.encoder[c]
            for j in range(task.n_digital):
                c = task.digital[j]
                digital_buffer[k * task.n_digital + j] = sample.digital[c]
            for j in range(task.n_other):
                other_buffer[k * task.n_other + j] = sample.other[task.other[j]]
            self.smp.head = (self.smp.head + 1) % self.smp.capacity
            self.smp.count -= 1
        return n

    cdef Sample _read_now(self) except *:
        """The present sample of an open board (the immediate reads)."""
        cdef Sample sample
        with self.lock:
            self._require_open()
            self._sync()
            self._require_finite()
            if self.device_plant is None:
                self._sample(&sample)
            else:
                self._device_sample(&sample)
                self._require_finite()
        return sample

    cdef void _take_sample(self) noexcept nogil:
        """Put the present sample into the task buffer, by the overflow mode if it is full."""
        cdef long slot = self._claim_slot()
        if slot >= 0:
            self._sample(&self.smp.ring[slot])

    cdef long _claim_slot(self) noexcept nogil:
        """The task buffer's slot for a new sample, by the overflow mode if it is full; -1: none."""
        cdef long slot
        if self.smp.remaining > 0:
            self.smp.remaining -= 1
        if self.smp.count == self.smp.capacity:
            self.smp.overflows += 1
            if self.smp.overflow_mode == 2:                 # DISCARD_ON_OVERFLOW
                return -1
            if self.smp.overflow_mode == 0:                 # ERROR_ON_OVERFLOW: keep the buffer, fail the read
                self.smp.overflow_pending = True
                return -1
            self.smp.head = (self.smp.head + 1) % self.smp.capacity
            self.smp.count -= 1
        slot = (self.smp.head + self.smp.count) % self.smp.capacity
        self.smp.count += 1
        return slot

    cdef void _advance(self, long substeps) noexcept nogil:
        """Integrate `substeps` substeps, expiring the watchdog and taking samples when due."""
        cdef long k
        for k in range(substeps):
            if self.s.diverged:
                self.s.t += self.h
            else:
                if self.p.latency > 0.0:
                    self._delay_command()
                _substep(&self.p, &self.s, self._applied(), self._amplifier_on(), self.h)
                if not (fabs(self.s.x[2]) <= _DIVERGENCE_SPEED and fabs(self.s.x[3]) <= _DIVERGENCE_SPEED
                        and fabs(self.s.x[0]) <= 1e6 and fabs(self.s.x[1]) <= 1e6 and fabs(self.s.x[4]) <= 1e6):
                    self.s.diverged = True
            self._expire_watchdog_if_due()
            if self.smp.running and self.smp.remaining != 0:
                self.smp.countdown -= 1
                if self.smp.countdown == 0:
                    self.smp.countdown = self.smp.substeps_per_sample
                    self._take_sample()

    cdef int _sync(self) except -1:
        """In real-time mode, integrate up to the wall clock's present."""
        cdef long substeps
        if not self.realtime_ or not self.is_open:
            return 0
        substeps = <long>floor((time.perf_counter() - self.wall_origin - self.s.t) / self.h + 1e-9)
        if substeps > 0:
            self._integrate(substeps)
        return 0

    cdef bint _wait_for_samples(self, long n) except -1:
        """Make `n` samples available (integrating or sleeping); False if the task has finished."""
        while self.smp.count < n:
            if not self.smp.running:
                raise HILError(INVALID_TASK, "the task was stopped while being read")
            if self.smp.remaining == 0:
                return self.smp.count >= n
            if not self.realtime_:
                self._integrate(self.smp.countdown)
                continue
            due = self.wall_origin + self.s.t + self.smp.countdown * self.h
            delay = due - time.perf_counter()
            if delay > 0.0:
                self.lock.release()
                try:
                    time.sleep(delay)
                finally:
                    self.lock.acquire()
            self._sync()
        return True

    cdef object _new_task(self, Task task, samples_in_buffer):
        if int(samples_in_buffer) <= 0:
            raise HILError(INVALID_ARGUMENT, f"samples_in_buffer must be positive, got {samples_in_buffer}")
        with self.lock:
            self._require_open()
            task.samples_in_buffer = int(samples_in_buffer)
            task.overflow_mode = BufferOverflowMode.ERROR_ON_OVERFLOW
            task.board = self
        return task

    cdef int _require_finite(self) except -1:
        if self.s.diverged:
            raise HILError(PLANT_DIVERGED, "the substitute's plant diverged (its state left the finite range or "
                                           f"turned faster than {DIVERGENCE_SPEED:g} rad/s): check its parameters")
        return 0

    cdef int _check_other_inputs(self, list chans) except -1:
        if OTHER_PENDULUM_TACHOMETER in chans and self.card_type not in PENDULUM_TACHOMETER_CARDS:
            raise HILError(INVALID_CHANNEL, f"other input {OTHER_PENDULUM_TACHOMETER} (pendulum tachometer) "
                                            f"exists on {', '.join(PENDULUM_TACHOMETER_CARDS)} only")
        return 0

    cdef int _require_open(self) except -1:
        if not self.is_open:
            raise HILError(BOARD_NOT_OPEN, "the board is not open")
        return 0

    cdef int _require_writable(self) except -1:
        self._require_open()
        self._sync()
        if self.wd.expired:
            raise HILError(WATCHDOG_EXPIRED, "the watchdog has expired; outputs are locked until watchdog_clear")
        return 0

    cdef int _require_task(self, Task task) except -1:
        self._require_open()
        if task.deleted or task.board is not self:
            raise HILError(INVALID_TASK, "not a task of this board")
        return 0


cdef class ClearSamples:
    """A safety wrapper's samples on this board in fast mode, one call each, for the samples in
    which none of its checks could stop the motor (the wrapper: `quanser.QuanserWrapper`).

    ClearSamples(board, task, currents, encoders, digitals, others, volts, arm_at, arm_scale,
    radians_per_count) binds the wrapper's buffers: the task's readings, and `volts`, the
    voltage for analog output 0 (V, board sign, finite). `sample(led, overflows_seen,
    last_counts, max_missed_samples, max_encoder_speed, frequency, arm_limit)` does what
    `task_read(task, 1, ...)`, `watchdog_reload()` and `task_get_buffer_overflows(task)` do, in
    that order; then, if the sample is clear, what `write_analog` of analog output 0 and, unless
    `led` is None, `write_other` of the LED (other outputs 11000-11002, `led` three values in
    [0, 1], a tuple or an array) do, and returns None. A sample is clear if the watchdog
    reloaded, the overflow count is `overflows_seen` (no sample missed; None: unknown) and
    `max_missed_samples` is None or not negative, no digital input is set (amplifier fault,
    stall warning, stall error), no encoder count moved from `last_counts` (a list, one per
    encoder; None: unknown) by more than `max_encoder_speed` (rad/s; None: any) allows in one
    sample at `frequency` (Hz) plus one count, the arm encoder's count (`arm_at`, -1: none)
    times `arm_scale` (rad per count) is within `arm_limit` (rad; None: anywhere) of zero, and
    the board takes writes. Otherwise nothing is written and it returns (watchdog reloaded,
    buffer overflows) for the wrapper's own checks. Errors of the read raise as from
    `task_read`. `sample_given(voltages, led, max_voltage, ...)` first does the wrapper's action
    checks for a plain action (a list of one finite float, the LED None or a tuple of three floats
    in [0, 1]) and its clip to +-`max_voltage`, then `sample`; any other action it leaves, before
    reading, to the wrapper (returns False).
    """

    cdef HIL board
    cdef Task task
    cdef double[::1] currents
    cdef int[::1] encoders
    cdef signed char[::1] digitals
    cdef double[::1] others
    cdef double[::1] volts
    cdef double arm_scale, radians_per_count
    cdef int arm_at

    def __init__(self, HIL board not None, Task task not None, double[::1] currents, int[::1] encoders,
                 signed char[::1] digitals, double[::1] others, double[::1] volts, int arm_at,
                 double arm_scale, double radians_per_count):
        _check_buffer(_length_d(currents), task.n_analog, "analog")
        _check_buffer(_length_i(encoders), task.n_encoder, "encoder")
        _check_buffer(_length_b(digitals), task.n_digital, "digital")
        _check_buffer(_length_d(others), task.n_other, "other")
        _check_buffer(_length_d(volts), 1, "analog output")
        if not -1 <= arm_at < task.n_encoder:
            raise ValueError(f"arm_at must be -1 or an encoder's place in the task, got {arm_at}")
        self.board, self.task = board, task
        self.currents, self.encoders, self.digitals, self.others = currents, encoders, digitals, others
        self.volts = volts
        self.arm_at, self.arm_scale, self.radians_per_count = arm_at, arm_scale, radians_per_count

    def sample(self, led, overflows_seen, list last_counts, max_missed_samples, max_encoder_speed,
               double frequency, arm_limit):
        """One sample: None if it was clear and written, else (watchdog reloaded, buffer overflows)."""
        return self._sample(led, overflows_seen, last_counts, max_missed_samples, max_encoder_speed,
                            frequency, arm_limit)

    def sample_given(self, voltages, led, double max_voltage, overflows_seen, list last_counts,
                     max_missed_samples, max_encoder_speed, double frequency, arm_limit):
        """`sample` for the action as given to the wrapper, unchecked: False, before anything is read,
        unless `voltages` is a list of one finite float and `led` None or a tuple of three floats in
        [0, 1] (what the wrapper's checks let pass as they are); else `volts` gets the voltage clipped
        to +-`max_voltage` (V), as the wrapper clips it, and `sample(led, ...)` follows."""
        cdef double value
        if type(voltages) is not list or len(voltages) != 1 or type(voltages[0]) is not float:
            return False
        value = voltages[0]
        if not isfinite(value):
            return False
        if led is not None:
            if type(led) is not tuple or len(led) != 3:
                return False
            for x in led:
                if type(x) is not float or not (0.0 <= <double>x <= 1.0):  # NaN fails the comparison
                    return False
        self.volts[0] = -max_voltage if value < -max_voltage else max_voltage if value > max_voltage else value
        return self._sample(led, overflows_seen, last_counts, max_missed_samples, max_encoder_speed,
                            frequency, arm_limit)

    cdef object _sample(self, led, overflows_seen, list last_counts, max_missed_samples, max_encoder_speed,
                        double frequency, arm_limit):
        cdef HIL b = self.board
        cdef double jump_limit = INFINITY, arm_reach = INFINITY
        if max_encoder_speed is not None:                       # the wrapper's limit, no sample missed
            jump_limit = <double>max_encoder_speed * 1 / frequency / self.radians_per_count + 1
        if arm_limit is not None:
            arm_reach = arm_limit
        cdef const double[::1] rgb
        cdef bint reloaded, clear
        cdef long long overflows, now, before
        cdef long j
        cdef double value
        cdef double colour[3]
        if type(led) is tuple:
            if len(led) != 3:
                raise ValueError(f"led must hold 3 values, got {led!r}")
            colour[0], colour[1], colour[2] = led
        elif led is not None:
            rgb = led
            _check_buffer(_length_cd(rgb), 3, "other output")
            colour[0], colour[1], colour[2] = rgb[0], rgb[1], rgb[2]
        with b.lock:
            b._read_task(self.task, 1, self.currents, self.encoders, self.digitals, self.others)
            b._require_open()                                   # watchdog_reload
            b._sync()
            reloaded = not b.wd.expired
            if reloaded:
                b.wd.deadline = b.s.t + b.wd.timeout
            b._require_task(self.task)                          # task_get_buffer_overflows
            overflows = b.smp.overflows if self.task is b.running_task else 0
            clear = (reloaded and overflows_seen is not None and overflows == overflows_seen
                     and (max_missed_samples is None or max_missed_samples >= 0)
                     and last_counts is not None and len(last_counts) == self.task.n_encoder)
            j = 0
            while clear and j < self.task.n_digital:
                clear = self.digitals[j] == 0
                j += 1
            j = 0
            while clear and j < self.task.n_encoder:
                now, before = self.encoders[j], last_counts[j]
                clear = not (<double>llabs(now - before) > jump_limit)
                j += 1
            if clear and self.arm_at >= 0:
                clear = fabs(self.arm_scale * <double>self.encoders[self.arm_at]) <= arm_reach
            if clear:                                           # write_analog, write_other
                b._sync()
                clear = not b.wd.expired and isfinite(self.volts[0])
            if not clear:
                return reloaded, overflows
            b.out.analog[0] = self.volts[0]
            if led is not None:
                for j in range(3):
                    value = 0.0 if 0.0 > colour[j] else colour[j]   # Python's min(max(value, 0.0), 1.0)
                    b.out.led[j] = 1.0 if 1.0 < value else value
        return None


cdef list _channels(channels, num_channels, Py_ssize_t buffer_length, str kind, tuple valid, str where):
    """Channel numbers as a list, checking the count, the channels and the buffer's length (-1: none)."""
    cdef long n = num_channels
    if n < 0:
        raise HILError(INVALID_ARGUMENT, f"num_channels must be >= 0, got {n}")
    if n == 0:
        return []
    if channels is None or len(channels) < n:
        raise HILError(INVALID_BUFFER, f"{kind} channel array holds fewer than {n} channels")
    if buffer_length >= 0 and buffer_length < n:
        raise HILError(INVALID_BUFFER, f"{kind} buffer holds fewer than {n} values")
    chans = [int(channels[j]) for j in range(n)]
    for c in chans:
        if c not in valid:
            raise HILError(INVALID_CHANNEL, f"{kind} channel {c} does not exist on {where}; valid: {valid}")
    return chans


cdef int _check_buffer(Py_ssize_t length, long needed, str kind) except -1:
    if needed > 0 and length < needed:
        raise HILError(INVALID_BUFFER, f"{kind} buffer must hold at least {needed} values")
    return 0


cdef inline Py_ssize_t _length_d(double[::1] buffer):
    return -1 if buffer is None else buffer.shape[0]


cdef inline Py_ssize_t _length_cd(const double[::1] buffer):
    return -1 if buffer is None else buffer.shape[0]


cdef inline Py_ssize_t _length_i(int[::1] buffer):
    return -1 if buffer is None else buffer.shape[0]


cdef inline Py_ssize_t _length_ci(const int[::1] buffer):
    return -1 if buffer is None else buffer.shape[0]


cdef inline Py_ssize_t _length_b(signed char[::1] buffer):
    return -1 if buffer is None else buffer.shape[0]


cdef inline Py_ssize_t _length_cb(const signed char[::1] buffer):
    return -1 if buffer is None else buffer.shape[0]
