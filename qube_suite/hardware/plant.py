"""The "true" parameters of the substitute board's plant.

The substitute board (`_hil_sim.HIL`) integrates a Qube that differs from the
nominal model the way a real one does. Its parameters are the nominal table of
`qube_suite.devices.qube.parameters` (same long names), with the accuracy options that are
zero in the nominal model switched on, plus the amplifier's limits, which the
nominal model does not have. `plant_parameters(board_type, overrides)` gives the
full set; `HIL(plant=...)` and `QubeServo2(plant=...)` take overrides by these
names (on top of the board's default plant) or the name of a plant of `PLANTS`.

Which plant a board integrates without `plant=` is `DEFAULT_PLANTS`, by board type:

- a Qube-Servo 2 (`qube_servo2_usb`): `"real_qube_servo2"`, the plant like a real Qube
  (below), calibrated from recordings of TU Darmstadt's Qube-Servo 2;
- a Qube-Servo 3 (`qube_servo3_usb`): `"estimated"`, the tables of this module alone.
  No recordings of a real Qube-Servo 3 exist to calibrate one from, so its plant keeps
  our estimates.

The estimated plant (`plant="estimated"`, the Qube-Servo 2's default until 2026-11-28)
is the nominal table with the defaults below. It is about six times easier to predict
than a real Qube (docs/calibration.md); figures measured on it are labelled so.

The estimated plant's values that differ from the nominal model. Values marked *estimate* are ours,
chosen to be physically plausible: no published identification of a
Qube-Servo 2 gives them.

- `arm_friction` = 1.0e-3 N m (*estimate*): kt times a no-load current of 24 mA,
  typical of small coreless brushed motors. The motor then breaks away at 0.2 V,
  a dead zone of the order of the 0.65 V amplifier deadband compensation that
  Quanser ship with the Qube-Servo 3 (Qube-Servo 3 user manual, table 2.2).
- `pendulum_friction` = 5.0e-5 N m (*estimate*): a free swing from 30 degrees
  loses 0.013 rad per cycle, stops after about 25 s, and rests within one
  encoder count of hanging.
- `cable_stiffness` = 1.0e-3 N m/rad (*estimate*): the encoder cable pulls the
  arm towards the centre with 1.6e-3 N m at 90 degrees (the torque of 0.3 V).
  Le, Dang, Pham and Vo, "System identifications of a 2DOF pendulum controlled by
  QUBE-servo and its unwanted oscillation factors", Archive of Mechanical
  Engineering 67(4), 2020, found the encoder cable's effect not negligible.
- `motor_inductance` = 1.16e-3 H: nominal (Qube-Servo 2 user manual); the nominal
  MJCF leaves it out, the plant integrates L di/dt = V - R i - km dtheta.
- `amplifier_voltage_limit` = 15 V: the amplifier's range, "maximum range is
  +-15V" (QUARC documentation of the Qube-Servo analog output; Qube-Servo 3 user
  manual: output voltage range, maximum).
- `current_limit` = 1.8 A: the amplifier's peak stall current (Qube-Servo 3 user
  manual, table 2.2; assumed the same on the Qube-Servo 2).
- `stall_voltage` = 5 V: a stall is detected when the motor is stalled or
  excessively slowed with more than 5 V applied (QUARC documentation of the
  Qube-Servo's digital input 1).
- `stall_speed` = 5 rad/s (*estimate*): "stalled or excessively slowed" taken as
  below 4 % of the no-load speed at 5 V (119 rad/s); 0 disables stall detection.
- `stall_time` = 3 s: a stall warning asserted for about 3 s becomes a stall
  error and the amplifier disables itself (QUARC documentation, digital input 2).
- `bench_vibration` = 4.0e-5 N m (*estimate*) with `vibration_time` = 0.02 s: the
  bench the Qube stands on is never still (people walking, fans, a computer). Its
  horizontal sway acts on the pendulum as a torque mp lc a; 4e-5 N m RMS is the
  torque of a 0.026 m/s^2 (2.6 milli-g) RMS sway, modelled as a Gauss-Markov
  (Ornstein-Uhlenbeck) process with a 20 ms correlation time (sway below about
  8 Hz), drawn from the board's seeded random stream. It is below the pendulum's
  Coulomb friction most of the time, so a pendulum hanging at rest moves less than
  an encoder count, but it exceeds it often enough that a pendulum left upright
  at 0 V falls within a few seconds (0.95 to 5.3 s for seeds 0 to 7), as a real one
  does, instead of resting on its friction inside a count of upright. Its action
  on the arm is far below the arm's friction and is left out. 0 turns it off.

The plant like a real Qube, the Qube-Servo 2's default: `plant="real_qube_servo2"` (`PLANTS`;
`HIL(plant=...)`, `QubeServo2(plant=...)`, `domain_kwargs={"plant": ...}` of `qube_hardware`) is
TU Darmstadt's Qube-Servo 2 as calibrated from its recordings (`devices/qube/real_qube_servo2.yaml`,
read when the board opens, so a recalibration flows into it): its parameters (rotor inertia 8x
nominal, the motor's gain, both joints' damping and Coulomb friction, the cable's stiffness) and the
effects it identified, by the plant parameters of `REAL_EFFECT_PARAMETERS`: `latency`,
`voltage_deadzone`, `cable_rest_angle` and `cable_slack`. On top, what that calibration's
model does not contain (each off, 0, in the estimated plant):

- `cable_rest_spread` = 0.18 rad: the cable's rest is drawn anew in each session (board
  opened or reseeded), normal with this standard deviation about the calibrated rest. The
  encoders count from wherever the arm stands at power-up, and the cable lies differently
  each time: fitted per session on the real recordings, its rest was -0.46 rad in the chirps,
  -0.27 +- 0.05 in the 250 Hz swing-ups and about -0.1 at 500 Hz (docs/calibration.md), a
  standard deviation of 0.18 rad over three sessions.
- `cable_stiffness_spread` = 0.4: the cable's stiffness drawn per session, log-normal with
  this spread: fitted per chirp, the linear cable's stiffness varied by +-5e-4 about
  1.3e-3 N m/rad (+-40 %) between consecutive chirps (docs/calibration.md).
- `arm_breakaway` = 6e-4 N m (*estimate*): a stuck arm holds up to 1.6x its sliding
  (Coulomb) friction before it moves; the calibration fits only windows where the arm slides,
  so it cannot see this. Static friction above Coulomb is usual for brushed DC motors and
  their brushes (e.g. Armstrong-Helouvry, Dupont and Canudas de Wit, "A survey of models,
  analysis tools and compensation methods for the control of machines with friction",
  Automatica 30(7), 1994); the ratio is ours.

The estimated plant's motor inductance and bench sway stay on as well.

For `qube_servo3_usb` the motor rows are those of the Qube-Servo 3 user manual
(table 2.2): Rm = 7.5 ohm, kt = km = 0.0422, Jm = 1.4e-6 kg m^2, Lm = 1.15 mH.
A zero `motor_inductance` makes the current follow the voltage instantly, as in
the nominal model.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import types
from collections.abc import Mapping

from qube_suite.devices.qube import parameters


@dataclasses.dataclass(frozen=True)
class PlantParameter:
    """A plant parameter that the nominal table does not have."""

    name: str
    default: float
    unit: str
    description: str


_AMPLIFIER = (
    PlantParameter("amplifier_voltage_limit", 15.0, "V", "largest voltage the amplifier applies"),
    PlantParameter("current_limit", 1.8, "A", "largest current the amplifier lets through"),
    PlantParameter("stall_voltage", 5.0, "V", "stall detection: applied voltage above which a slow motor "
                   "counts as stalled"),
    PlantParameter("stall_speed", 5.0, "rad/s", "stall detection: arm speed below which the motor counts as "
                   "stalled (0 disables stall detection)"),
    PlantParameter("stall_time", 3.0, "s", "how long a stall lasts before the amplifier disables itself"),
)

AMPLIFIER_PARAMETERS: types.MappingProxyType[str, PlantParameter] = types.MappingProxyType(
    {p.name: p for p in _AMPLIFIER})
"""The amplifier's parameters by long name."""

_BENCH = (
    PlantParameter("bench_vibration", 4.0e-5, "N m", "RMS torque of the bench's sway on the pendulum "
                   "(0 turns it off)"),
    PlantParameter("vibration_time", 0.02, "s", "correlation time of the bench's sway"),
)

BENCH_PARAMETERS: types.MappingProxyType[str, PlantParameter] = types.MappingProxyType(
    {p.name: p for p in _BENCH})
"""The bench's parameters by long name: what the Qube stands on."""

_REAL_EFFECTS = (
    PlantParameter("latency", 0.0, "s", "time between a voltage written and the amplifier applying it"),
    PlantParameter("voltage_deadzone", 0.0, "V", "the amplifier passes nothing of the first this many volts "
                   "(a command u acts as sign(u) max(|u| - deadzone, 0))"),
    PlantParameter("cable_rest_angle", 0.0, "rad", "arm angle at which the cable pulls nothing (the encoder "
                   "counts from where the arm stands at power-up)"),
    PlantParameter("cable_slack", 0.0, "rad", "half-width of the band around the cable's rest within which "
                   "it is slack; beyond, it pulls with cable_stiffness per radian"),
    PlantParameter("cable_rest_spread", 0.0, "rad", "standard deviation of the cable's rest from one "
                   "session (board opened or reseeded) to the next"),
    PlantParameter("cable_stiffness_spread", 0.0, "", "standard deviation of the log of the cable's "
                   "stiffness from one session to the next"),
    PlantParameter("arm_breakaway", 0.0, "N m", "friction torque a stuck arm holds before it slides "
                   "(0 or below arm_friction: arm_friction)"),
)

REAL_EFFECT_PARAMETERS: types.MappingProxyType[str, PlantParameter] = types.MappingProxyType(
    {p.name: p for p in _REAL_EFFECTS})
"""Effects a real Qube shows that the estimated plant leaves out (all 0: off), by long name."""

_MAY_BE_NEGATIVE = frozenset({"cable_rest_angle"})

HARDWARE_DEFAULTS: types.MappingProxyType[str, float] = types.MappingProxyType({
    "arm_friction": 1.0e-3,
    "pendulum_friction": 5.0e-5,
    "cable_stiffness": 1.0e-3,
})
"""Accuracy options of the nominal table that a real Qube has (see the module docstring)."""

BOARD_MOTORS: types.MappingProxyType[str, Mapping[str, float]] = types.MappingProxyType({
    "qube_servo2_usb": types.MappingProxyType({}),
    "qube_servo3_usb": types.MappingProxyType({
        "motor_resistance": 7.5, "motor_torque_constant": 0.0422, "motor_back_emf": 0.0422,
        "rotor_inertia": 1.4e-6, "motor_inductance": 1.15e-3}),
})
"""Motor data that differ from the nominal (Qube-Servo 2) table, by board type."""

_ZERO_ALLOWED = frozenset({"arm_damping", "pendulum_damping", "arm_friction", "pendulum_friction",
                           "cable_stiffness", "motor_inductance", "stall_speed", "bench_vibration",
                           *REAL_EFFECT_PARAMETERS})


def plant_parameters(board_type: str = "qube_servo2_usb",
                     overrides: Mapping[str, float] | str | None = None) -> dict[str, float]:
    """Every plant parameter of a `board_type` Qube: of the plant of `PLANTS` that `overrides` names,
    or of the board's default plant (`DEFAULT_PLANTS`) updated by `overrides`, a mapping by long name.

    Raises ValueError for an unknown board type, an unknown plant or parameter name (listing the
    valid ones), a named plant of another board type, or a value that is not finite, negative
    (except a cable's rest angle), or zero where zero is impossible.
    """
    if board_type not in BOARD_MOTORS:
        raise ValueError(f"unknown board type {board_type!r}; valid: {', '.join(BOARD_MOTORS)}")
    if isinstance(overrides, str):
        overrides = _named_overrides(overrides, board_type)
    else:
        overrides = {**_named_overrides(DEFAULT_PLANTS[board_type], board_type), **(overrides or {})}
    values = dict(parameters.NOMINAL)
    values.update(HARDWARE_DEFAULTS)
    values.update(BOARD_MOTORS[board_type])
    values.update({p.name: p.default for p in _AMPLIFIER + _BENCH + _REAL_EFFECTS})
    for name, value in overrides.items():
        if name not in values:
            raise ValueError(f"unknown plant parameter {name!r}; valid names: {', '.join(values)}")
        value = float(value)
        if not math.isfinite(value):
            raise ValueError(f"plant parameter {name!r} must be finite, got {value}")
        if name not in _MAY_BE_NEGATIVE and (value < 0.0 or (value == 0.0 and name not in _ZERO_ALLOWED)):
            bound = ">= 0" if name in _ZERO_ALLOWED else "> 0"
            raise ValueError(f"plant parameter {name!r} must be {bound}, got {value}")
        values[name] = value
    return values


@dataclasses.dataclass(frozen=True)
class NamedPlant:
    """A plant by name: the estimated plant's tables, updated by a calibration of a real Qube and by
    what that calibration's model leaves out.

    Attributes:
        board_type: the board the calibrated Qube sat on (None: any board).
        calibration: path of the calibration file (`qube_suite.calibration`), or None: the estimated
            plant's own values. Its parameters and its identified effects (latency, dead zone, the
            cable's rest and slack) are read when the plant is made, so a new calibration flows into it.
        unmodelled: plant parameters the calibration does not identify, by long name (see the module).
    """

    board_type: str | None
    calibration: str | None
    unmodelled: Mapping[str, float]

    def overrides(self) -> dict[str, float]:
        """The plant's parameters by long name, as overrides of the estimated plant."""
        values: dict[str, float] = {}
        if self.calibration is not None:
            values.update(_calibrated(self.calibration, os.stat(self.calibration).st_mtime_ns))
        values.update(self.unmodelled)
        return values


@functools.lru_cache(maxsize=8)
def _calibrated(path: str, modified: int) -> types.MappingProxyType[str, float]:
    """The parameters and reproduced effects (`_CALIBRATED_EFFECTS`) of the calibration file at `path`, by
    plant parameter name. `modified` (the file's modification time, ns) keys the cache: a board opens with
    the file as it is, read once per change instead of at every opening (28 ms of YAML each)."""
    effects = parameters.effects_of(path)
    values = parameters.values_of(path)
    values.update({plant_name: effects[name] for name, plant_name in _CALIBRATED_EFFECTS.items()
                   if name in effects})
    return types.MappingProxyType(values)


_CALIBRATED_EFFECTS = {"latency_seconds": "latency", "voltage_deadzone": "voltage_deadzone",
                       "cable_rest_angle": "cable_rest_angle", "cable_slack": "cable_slack"}
"""A calibration's effects (`parameters.CALIBRATED_EFFECTS`) by the plant parameter that reproduces them;
the pendulum encoder's offset (a millirad) is left out: the board's encoders count from power-up."""

ESTIMATED = "estimated"
"""The name of the estimated plant: this module's tables alone (see the module docstring)."""

PLANTS: types.MappingProxyType[str, NamedPlant] = types.MappingProxyType({
    ESTIMATED: NamedPlant(None, None, types.MappingProxyType({})),
    "real_qube_servo2": NamedPlant("qube_servo2_usb", parameters.REAL_QUBE_SERVO2, types.MappingProxyType({
        "cable_rest_spread": 0.18,
        "cable_stiffness_spread": 0.4,
        "arm_breakaway": 6.0e-4,
    })),
})
"""Named plants: `plant="estimated"`, `plant="real_qube_servo2"` (see the module docstring)."""

DEFAULT_PLANTS: types.MappingProxyType[str, str] = types.MappingProxyType({
    "qube_servo2_usb": "real_qube_servo2",
    "qube_servo3_usb": ESTIMATED,     # no recordings of a real Qube-Servo 3 to calibrate a plant from
})
"""The plant of `PLANTS` that a board of each type integrates without `plant=`."""


def named_plant(name: str, board_type: str = "qube_servo2_usb") -> dict[str, float]:
    """Every parameter of the plant `name` of `PLANTS` on a `board_type` board: a whole plant, which
    `plant=` takes with changes (`{**named_plant("estimated"), "arm_friction": 2e-3}`). ValueError for
    an unknown name (listing the valid ones) or a plant of another board type."""
    return plant_parameters(board_type, name)


def _named_overrides(name: str, board_type: str) -> dict[str, float]:
    """The overrides of the estimated plant that make the plant `name` of `PLANTS` on a `board_type` board."""
    if name not in PLANTS:
        raise ValueError(f"unknown plant {name!r}; named plants: {', '.join(PLANTS)} (or a mapping of plant "
                         "parameters by long name)")
    plant = PLANTS[name]
    if plant.board_type not in (None, board_type):
        raise ValueError(f"the plant {name!r} is a {plant.board_type}'s, not a {board_type}'s")
    return plant.overrides()
