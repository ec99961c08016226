"""The substitute board's plant for the Aero 2: its own equations, independent of the MJCF.

The board (`qube_suite.hardware._hil_sim.HIL`, a device's own plant through
`qube_suite.hardware.board_plant`) keeps the clock, the watchdog and the encoder offsets; this
plant moves a rigid Aero 2 between its samples and is read in board units.

The body (beam, shrouds, yoke) turns about the yaw axis (vertical) and the pitch axis (the beam's
cross axis); body axes x along the beam to the front rotor, z up when level, pitch positive front
up. With the kinetic energy T = Jp pitch'^2 / 2 + Jy(pitch) yaw'^2 / 2,
Jy(pitch) = Jy - (Jp - Jx) sin^2(pitch) (the beam's pitch inertia leaves the vertical as it tilts;
Jx its small inertia about its own axis), Lagrange's equations give

    Jp pitch'' = Dt F_front - Mb g Dm sin(pitch) - Dp pitch' - Fp sgn(pitch')
                 + R_back - (Jp - Jx) sin(pitch) cos(pitch) yaw'^2 + G_pitch
    Jy(pitch) yaw'' = Dt F_back cos(pitch) - R_front cos(pitch) - Dy yaw' - Fy sgn(yaw')
                 + 2 (Jp - Jx) sin(pitch) cos(pitch) pitch' yaw' + G_yaw

(2-DOF: the front thruster lifts, the back one pushes sideways, its motor along the pitch axis);
in the 1-DOF "pitch_only" configuration yaw is locked and both thrusters lift, the back one at
-Dt. F = kf w is a rotor's thrust: the linear form of Quanser's Aero 2 labs and digital twin
([L4] of `parameters.py`), which fits their measured thrust over the working speeds and keeps the
control authority at w = 0 that a signed square kf' w |w| would lose (the Aero's level hover needs
no thrust: its centre of mass hangs below the pivot). R = J w' + kd w is the reaction of a rotor
on the body about its shaft (what its motor turns against, the air's drag on its propeller
excepted), G = -(Omega x h) the gyroscopic torque of the spinning rotors' momentum h = Js w along
their shafts, with the body's rate Omega = (yaw' sin(pitch), -pitch', yaw' cos(pitch)) in body
axes. Each thruster is a DC motor with its inductance, L i' = V - Rm i - km w (open circuit, i = 0,
while its amplifier is disabled), and a rotor Js w' = kt i - kd w - Fr sgn(w).

Coulomb friction (pitch, yaw, rotors) sticks: a joint at rest stays so while the other torques on
it are within the friction. The beam's mechanical stops at +-`conventions.PITCH_LIMIT` stop it
(a collision keeping `STOP_RESTITUTION` of its speed, reversed). Integration: the currents exactly
over each substep (their 0.14 ms time constant is far below it), the rest by semi-implicit Euler at
`MAX_STEP`. Encoders read counts at the conventions' resolutions (the board floors them),
tachometers counts/s; the inertial unit (gyroscope, accelerometer) is not offered.

Hidden truth. `make_plant()` draws the plant's parameters from the nominal table with seeded
relative spreads (`SPREADS`, log-normal): a calibration on the substitute has something to find, as
on a real Aero, whose parameters are never exactly the table's. `make_plant(parameters=...)` gives a
plant with exactly those parameters instead.
"""

from __future__ import annotations

import math
import types
from collections.abc import Mapping

import numpy as np

from qube_suite.devices.aero2 import conventions
from qube_suite.devices.aero2 import parameters as aero_parameters
from qube_suite.hardware.board_plant import PlantChannels

CARD_TYPE = "quanser_aero2_usb"
"""The Aero 2's QUARC card type."""

CHANNELS = PlantChannels(
    card_type=CARD_TYPE, analog_outputs=(0, 1), digital_outputs=(0, 1), analog_inputs=(0, 1),
    encoder_inputs=(0, 1, 2, 3), other_inputs=(14000, 14001, 14002, 14003),
    voltage_limit=conventions.VOLTAGE_LIMIT)
"""What the substitute offers of the Aero 2's card (the map is in `hardware.py`): both motors'
voltages, enables, currents and encoders, the pitch and yaw encoders, four tachometers."""

PLANT_DEFAULTS: types.MappingProxyType[str, float] = types.MappingProxyType({
    "pitch_friction": 5.0e-4,
    "yaw_friction": 1.0e-3,
    "rotor_friction": 4.0e-4,
    "beam_roll_inertia": 2.0e-3,
})
"""Plant parameters the nominal table does not have (estimates: no Aero 2 source gives them).
`pitch_friction` (N m): the level beam sticks within +-1.1 degrees (against Mb g Dm = 0.025 N m/rad),
a free swing decays over several cycles as in Quanser's pitch-estimation lab. `yaw_friction` (N m):
0.6 V on the back thruster before the yaw breaks away. `rotor_friction` (N m): a no-load current of
10 mA (kt = 0.042), a dead zone of 0.08 V. `beam_roll_inertia` (kg m^2): the beam about its own axis."""

SPREADS: types.MappingProxyType[str, float] = types.MappingProxyType({
    "thrust_constant": 0.10, "propeller_drag": 0.15, "propeller_inertia": 0.10,
    "motor_resistance": 0.05, "motor_back_emf": 0.04,
    "yaw_inertia": 0.05, "center_of_mass_offset": 0.15,
    "pitch_damping": 0.30, "yaw_damping": 0.30,
    "pitch_friction": 0.30, "yaw_friction": 0.30, "rotor_friction": 0.30,
})
"""Relative spread (log-normal sigma) of each hidden parameter around its nominal value: manufacturing
tolerances for the motors (5 %), CAD against the built body (5 %), and the poorly known
aerodynamic and friction terms (10 to 30 %). The pitch inertia is the CAD figure's: the Aero's motion
fixes the pitch terms only in proportion to it, and Quanser's own pitch-estimation lab holds it at the
CAD value, as the calibration does."""

HIDDEN_SEED = 20260
"""The seed of the default substitute Aero: the same plant in every run, unknown to the controllers."""

MAX_STEP = 1.0e-3
"""Longest integration substep (s)."""

STOP_RESTITUTION = 0.2
"""Share of the beam's speed it keeps, reversed, when it hits a pitch stop."""

_MOTOR_COUNTS_PER_RADIAN = 1.0 / conventions.TACHOMETER_TO_RAD_PER_S
ENCODER_COUNTS_PER_RADIAN = np.array([_MOTOR_COUNTS_PER_RADIAN, _MOTOR_COUNTS_PER_RADIAN,
                                      conventions.PITCH_COUNTS_PER_RADIAN, conventions.YAW_COUNTS_PER_RADIAN])
"""Counts per radian of encoders 0-3 (front motor, back motor, pitch, yaw) and of their tachometers."""


def plant_values(parameters: Mapping[str, float] | None = None,
                 seed: int | None = HIDDEN_SEED) -> dict[str, float]:
    """Every parameter of a substitute Aero: the table and `PLANT_DEFAULTS`, drawn around their values
    with `SPREADS` by `seed` (None: not drawn), then updated by `parameters` (by long name; these are
    not drawn). kt stays equal to km (one constant of the motor in SI units). Raises ValueError for an
    unknown name or an impossible value."""
    given = dict(parameters or {})
    unknown = set(given) - set(aero_parameters.PARAMETERS) - set(PLANT_DEFAULTS)
    if unknown:
        raise ValueError(f"unknown plant parameter {sorted(unknown)[0]!r}; valid names: "
                         f"{', '.join([*aero_parameters.PARAMETERS, *PLANT_DEFAULTS])}")
    values = {**aero_parameters.NOMINAL, **PLANT_DEFAULTS}
    if seed is not None:
        rng = np.random.default_rng(seed)
        for name, spread in SPREADS.items():
            values[name] *= float(np.exp(spread * rng.standard_normal()))
        values["motor_torque_constant"] = values["motor_back_emf"]
    values.update(given)
    for name in PLANT_DEFAULTS:
        value = float(values[name])
        if not (math.isfinite(value) and value >= 0.0):
            raise ValueError(f"plant parameter {name!r} must be finite and >= 0, got {values[name]!r}")
    table = aero_parameters.resolve({name: values[name] for name in aero_parameters.PARAMETERS})
    return {**table, **{name: float(values[name]) for name in PLANT_DEFAULTS}}


def _stick_or_slip(speed: float, torque: float, friction: float, inertia: float, h: float) -> float:
    """The speed after `h` s of `torque` (N m, friction excepted) and Coulomb `friction` (N m): a joint at
    rest stays at rest while |torque| <= friction; a moving one that would reverse within the step stops."""
    if speed == 0.0 and abs(torque) <= friction:
        return 0.0
    direction = speed if speed != 0.0 else torque
    new = speed + h * (torque - math.copysign(friction, direction)) / inertia
    if speed != 0.0 and new * speed < 0.0 and abs(torque) <= friction:
        return 0.0
    return new


class Aero2Plant:
    """A rigid Aero 2 with two DC thrusters, in the board's terms (`board_plant.BoardPlant`).

    Args:
        parameters: every parameter by long name (`plant_values`).
        configuration: "2dof" (default) or "pitch_only" (yaw locked).
    """

    channels = CHANNELS

    def __init__(self, parameters: Mapping[str, float], configuration: str = "2dof"):
        if configuration not in conventions.CONFIGURATIONS:
            raise ValueError(f"unknown configuration {configuration!r}; valid configurations: "
                             f"{', '.join(conventions.CONFIGURATIONS)}")
        self.configuration = configuration
        self.parameters = dict(parameters)
        p = self.parameters
        self._spin = aero_parameters.rotor_assembly_inertia(p)
        self._weight = p["body_mass"] * p["gravity"] * p["center_of_mass_offset"]
        self._tilt = p["pitch_inertia"] - p["beam_roll_inertia"]
        # pitch, yaw, their rates, rotor speeds, motor currents, rotor angles
        self._x = [0.0] * 10

    def advance(self, seconds: float, volts: np.ndarray, enabled: np.ndarray) -> None:
        """Move on by `seconds` (s) under `volts` (V) on the (front, back) motors `enabled`."""
        steps = max(1, math.ceil(seconds / MAX_STEP - 1e-9))
        h = seconds / steps
        v0, v1 = float(volts[0]), float(volts[1])
        on0, on1 = bool(enabled[0]), bool(enabled[1])
        for _ in range(steps):
            self._substep(h, v0, v1, on0, on1)

    def _substep(self, h: float, v0: float, v1: float, on0: bool, on1: bool) -> None:
        p, x = self.parameters, self._x
        pitch, yaw, dpitch, dyaw, w0, w1, i0, i1, a0, a1 = x
        rm, km, kt, kd, lm = (p["motor_resistance"], p["motor_back_emf"], p["motor_torque_constant"],
                              p["propeller_drag"], p["motor_inductance"])
        decay = math.exp(-h * rm / lm) if lm > 0.0 else 0.0
        i0 = (v0 - km * w0) / rm * (1.0 - decay) + i0 * decay if on0 else 0.0
        i1 = (v1 - km * w1) / rm * (1.0 - decay) + i1 * decay if on1 else 0.0
        spin, fr = self._spin, p["rotor_friction"]
        new0 = _stick_or_slip(w0, kt * i0 - kd * w0, fr, spin, h)
        new1 = _stick_or_slip(w1, kt * i1 - kd * w1, fr, spin, h)
        react0 = spin * (new0 - w0) / h + kd * w0       # what each rotor turns against, on the body
        react1 = spin * (new1 - w1) / h + kd * w1
        w0, w1 = new0, new1
        arm, kf = p["thrust_arm"], p["thrust_constant"]
        s, c = math.sin(pitch), math.cos(pitch)
        if self.configuration == "2dof":
            # gyroscopic torque -(Omega x h), h = spin (0, w1, w0), Omega = (dyaw s, -dpitch, dyaw c)
            ox, oy, oz = dyaw * s, -dpitch, dyaw * c
            gx = -(oy * spin * w0 - oz * spin * w1)
            gy = -(oz * 0.0 - ox * spin * w0)
            gz = -(ox * spin * w1 - oy * 0.0)
            pitch_torque = (arm * kf * w0 - self._weight * s - p["pitch_damping"] * dpitch + react1
                            - self._tilt * s * c * dyaw * dyaw - gy)
            yaw_inertia = p["yaw_inertia"] - self._tilt * s * s
            yaw_torque = (arm * kf * w1 * c - react0 * c - p["yaw_damping"] * dyaw
                          + 2.0 * self._tilt * s * c * dpitch * dyaw + gx * s + gz * c)
            dyaw = _stick_or_slip(dyaw, yaw_torque, p["yaw_friction"], yaw_inertia, h)
            yaw += h * dyaw
        else:
            pitch_torque = arm * kf * (w0 - w1) - self._weight * s - p["pitch_damping"] * dpitch
        dpitch = _stick_or_slip(dpitch, pitch_torque, p["pitch_friction"], p["pitch_inertia"], h)
        pitch += h * dpitch
        limit = conventions.PITCH_LIMIT
        if abs(pitch) >= limit:
            pitch = math.copysign(limit, pitch)
            if dpitch * pitch > 0.0:
                dpitch = -STOP_RESTITUTION * dpitch
        self._x = [pitch, yaw, dpitch, dyaw, w0, w1, i0, i1, a0 + h * w0, a1 + h * w1]

    def encoder_positions(self) -> np.ndarray:
        """Encoders 0-3 (front motor, back motor, pitch, yaw) in counts."""
        x = self._x
        return np.array([x[8], x[9], x[0], x[1]]) * ENCODER_COUNTS_PER_RADIAN

    def analog_inputs(self) -> np.ndarray:
        """Front and back motor currents (A)."""
        return np.array(self._x[6:8])

    def other_inputs(self) -> np.ndarray:
        """Tachometers 14000-14003 (front motor, back motor, pitch, yaw) in counts/s."""
        x = self._x
        return np.array([x[4], x[5], x[2], x[3]]) * ENCODER_COUNTS_PER_RADIAN

    def true_state(self) -> np.ndarray:
        """[pitch, yaw, pitch rate, yaw rate, front rotor speed, back rotor speed] (rad, rad/s)."""
        x = self._x
        return np.array([x[0], x[1], x[2], x[3], x[4], x[5]])

    def set_true_state(self, state: np.ndarray) -> None:
        """Put the Aero in `state` (as `true_state`), the motor currents at 0. Raises ValueError for
        anything but six finite numbers, a pitch beyond the stops, or a moving yaw when it is locked."""
        state = np.asarray(state, dtype=np.float64)
        if state.shape != (6,) or not np.isfinite(state).all():
            raise ValueError(f"an Aero state is 6 finite numbers {conventions.STATE_NAMES}, got {state!r}")
        if abs(state[0]) > conventions.PITCH_LIMIT:
            raise ValueError(f"pitch {state[0]} rad is beyond the stops "
                             f"(+-{conventions.PITCH_LIMIT:.3f} rad)")
        if self.configuration == "pitch_only" and (state[1] != self._x[1] or state[3] != 0.0):
            raise ValueError("the pitch-only Aero's yaw is locked")
        self._x = [*(float(v) for v in state), 0.0, 0.0, self._x[8], self._x[9]]


def make_plant(parameters: Mapping[str, float] | None = None, configuration: str = "2dof",
               seed: int | None = None) -> Aero2Plant:
    """A substitute Aero 2 in `configuration`: with `parameters` (by long name, the rest nominal) if
    given, else hidden ones drawn by `seed` (None: `HIDDEN_SEED`, the default substitute Aero); with
    both, drawn by `seed` then updated by `parameters`. See `plant_values`."""
    if parameters is None and seed is None:
        seed = HIDDEN_SEED
    return Aero2Plant(plant_values(parameters, seed), configuration)
