"""The named randomization presets, as plain data (copy one to start your own config).

- `none`: the nominal model exactly; nothing is drawn.
- `mild`: manufacturing tolerances of the published parameters; no effects.
- `moderate`: wider parameter ranges, some friction and cable spring, and sensor and
  actuator effects, for policies meant to be robust in general.
- `sim2real`: covers what the hardware substitute's estimated plant (`plant="estimated"`)
  adds to the nominal model (a real Qube's rotor inertia and damping lie outside it: `wide`
  and `real_qube` hold them): Coulomb friction on both joints and the encoder cable's spring
  (ranges from 0 to twice that plant's estimates of 1e-3 N m, 5e-5 N m and 1e-3 N m/rad),
  2048-count encoders, velocities from Quanser's 50 rad/s filter,
  and up to one control step of actuation lag (board latency; the motor
  inductance's electrical time constant, Lm / Rm = 0.14 ms, is far shorter). The
  amplifier's limits are left out: within the tasks' voltage limits (3 V by
  default, at most 10 V) they act rarely if ever (+-15 V range, 1.8 A current
  limit against 3 V / 8.4 ohm = 0.36 A at stall).
- `wide`: parameter ranges that cover a Qube nobody has described, and the Qube-Servo 2
  that recordings described (`real_qube`'s calibrated values): pendulum mass +-30 %,
  pendulum length +-10 %, motor resistance +-25 %, torque and back-EMF constants 0.8 to
  1.15 times, rotor inertia 0.7 to 12 times (log-uniform), arm damping 0.3 to 40 times and
  pendulum damping 0.3 to 10 times, Coulomb friction 0 to 4e-3 N m on the arm and 0 to 2e-4
  N m on the pendulum (four times the estimated plant's), cable stiffness 0 to 5e-3
  N m/rad; arm mass and length as in `sim2real`; effects: `sim2real`'s encoders and
  velocity filter, `real_qube`'s command delay (0 to 12 ms), voltage offset and dead zone.
  For policies trained once for many plants (with observation history:
  `qube_suite.training`). Until 2026-11-28 its rotor inertia stopped at 1.3 times, its
  dampings at 3, its delay at one control step, without offset or dead zone: a Qube like
  the real one was outside it.
- `real_qube`: ranges around what recordings of a real Qube-Servo 2 identified
  (`qube_suite.devices.qube.parameters.REAL_QUBE_SERVO2`, TU Darmstadt's unit), each containing its
  calibrated value and its interval: rotor inertia 4 to 12 times the published motor's
  (8.1x: the hub and encoder disc turn with it), arm damping 3 to 40 times (9.6x),
  pendulum damping 1 to 10 times (4.3x), torque and back-EMF constants 0.8 to 1.1 times
  (0.89x), pendulum length 0.9 to 1.05 times (0.95x), Coulomb friction on the arm to
  1e-3 N m (3.8e-4) and on the pendulum to 5e-5 N m (2.1e-5), cable stiffness to
  5e-3 N m/rad (2.7e-3); effects: a command delay of 0 to 12 ms (6 ms, rounded to whole
  control steps), a dead zone of 0 to 0.15 V (0.013 V; 0.066 V without the cable's slack),
  and a voltage offset of +-0.2 V for a cable pulling at the encoder's zero (the
  recordings' sessions differ: 0 to 6e-4 N m, the torque of 0 to 0.13 V), with
  `sim2real`'s encoders and velocity filter. Not drawn: the cable's slack band (the
  preset's spring is linear) and the pendulum encoder's offset (0.0014 rad, below one
  encoder count). `sim2real` stays as it was: the shipped follow policies and the
  published sim-to-real figures were made with it.
- `sim2real_frictionless`: `sim2real` without its Coulomb friction: for the JAX backend
  (`qube_suite.mjx`), where friction is a constraint that makes each step about ten
  times dearer; policies trained under it met the swing-up recipe's targets on the
  substitute, whose plant has friction (docs/gpu-training.md).
- `actuation`: effects on the voltage alone, for any device whose domains take them (a device
  with parameters of its own has none of the pendulum's to randomize): up to one control step of
  actuation lag, a voltage offset of +-0.1 V and a dead zone of 0 to 0.2 V, on each motor.

Friction and spring torques compare with the motor's kt / Rm = 0.005 N m per volt:
1e-3 N m is the torque of 0.2 V.
"""

from __future__ import annotations

from typing import Any

_TOLERANCE = {"distribution": "uniform", "low": 0.95, "high": 1.05}


def _scale(low: float, high: float) -> dict[str, Any]:
    return {"distribution": "uniform", "low": low, "high": high}


def _log_scale(low: float, high: float) -> dict[str, Any]:
    return {"distribution": "loguniform", "low": low, "high": high}


def _absolute(low: float, high: float) -> dict[str, Any]:
    return {"distribution": "uniform", "low": low, "high": high, "relative": False}


PRESETS: dict[str, dict[str, Any]] = {
    "none": {},
    "mild": {
        "parameters": {
            "pendulum_mass": _TOLERANCE, "pendulum_length": _TOLERANCE,
            "arm_mass": _TOLERANCE, "arm_length": _TOLERANCE,
            "motor_resistance": _TOLERANCE, "motor_torque_constant": _TOLERANCE,
            "motor_back_emf": _TOLERANCE, "rotor_inertia": _scale(0.9, 1.1),
            "arm_damping": _log_scale(0.5, 2.0), "pendulum_damping": _log_scale(0.5, 2.0),
        },
    },
    "moderate": {
        "parameters": {
            "pendulum_mass": _scale(0.9, 1.1), "pendulum_length": _scale(0.9, 1.1),
            "arm_mass": _scale(0.9, 1.1), "arm_length": _scale(0.9, 1.1),
            "motor_resistance": _scale(0.85, 1.15), "motor_torque_constant": _scale(0.85, 1.15),
            "motor_back_emf": _scale(0.85, 1.15), "rotor_inertia": _scale(0.8, 1.2),
            "arm_damping": _log_scale(0.2, 5.0), "pendulum_damping": _log_scale(0.2, 5.0),
            "arm_friction": _absolute(0.0, 5e-4), "pendulum_friction": _absolute(0.0, 2e-5),
            "cable_stiffness": _absolute(0.0, 5e-4),
        },
        "effects": {
            "quantization": {"counts_per_revolution": 2048},
            "observation_noise": {"std": [0.002, 0.002, 0.05, 0.05]},
            "action_delay": {"steps": {"distribution": "uniform", "low": 0, "high": 1}},
            "voltage_offset": {"voltage": {"distribution": "uniform", "low": -0.05, "high": 0.05}},
            "control_jitter": {"fraction": 0.05},
        },
    },
    "sim2real": {
        "parameters": {
            "pendulum_mass": _TOLERANCE, "pendulum_length": _TOLERANCE,
            "arm_mass": _TOLERANCE, "arm_length": _TOLERANCE,
            "motor_resistance": _scale(0.85, 1.15), "motor_torque_constant": _scale(0.9, 1.1),
            "motor_back_emf": _scale(0.9, 1.1), "rotor_inertia": _scale(0.8, 1.2),
            "arm_damping": _log_scale(0.3, 3.0), "pendulum_damping": _log_scale(0.3, 3.0),
            "arm_friction": _absolute(0.0, 2e-3), "pendulum_friction": _absolute(0.0, 1e-4),
            "cable_stiffness": _absolute(0.0, 2e-3),
        },
        "effects": {
            "quantization": {"counts_per_revolution": 2048},
            "velocity_filter": {"cutoff": 50.0},
            "action_delay": {"steps": {"distribution": "uniform", "low": 0, "high": 1}},
        },
    },
    "wide": {
        "parameters": {
            "pendulum_mass": _scale(0.7, 1.3), "pendulum_length": _scale(0.9, 1.1),
            "arm_mass": _TOLERANCE, "arm_length": _TOLERANCE,
            "motor_resistance": _scale(0.75, 1.25), "motor_torque_constant": _scale(0.8, 1.15),
            "motor_back_emf": _scale(0.8, 1.15), "rotor_inertia": _log_scale(0.7, 12.0),
            "arm_damping": _log_scale(0.3, 40.0), "pendulum_damping": _log_scale(0.3, 10.0),
            "arm_friction": _absolute(0.0, 4e-3), "pendulum_friction": _absolute(0.0, 2e-4),
            "cable_stiffness": _absolute(0.0, 5e-3),
        },
        "effects": {
            "quantization": {"counts_per_revolution": 2048},
            "velocity_filter": {"cutoff": 50.0},
            "action_delay": {"seconds": {"distribution": "uniform", "low": 0.0, "high": 0.012}},
            "voltage_offset": {"voltage": {"distribution": "uniform", "low": -0.2, "high": 0.2}},
            "dead_zone": {"voltage": {"distribution": "uniform", "low": 0.0, "high": 0.15}},
        },
    },
    "real_qube": {
        "parameters": {
            "pendulum_mass": _TOLERANCE, "pendulum_length": _scale(0.9, 1.05),
            "arm_mass": _TOLERANCE, "arm_length": _TOLERANCE,
            "motor_resistance": _scale(0.85, 1.15), "motor_torque_constant": _scale(0.8, 1.1),
            "motor_back_emf": _scale(0.8, 1.1), "rotor_inertia": _log_scale(4.0, 12.0),
            "arm_damping": _log_scale(3.0, 40.0), "pendulum_damping": _log_scale(1.0, 10.0),
            "arm_friction": _absolute(0.0, 1e-3), "pendulum_friction": _absolute(0.0, 5e-5),
            "cable_stiffness": _absolute(0.0, 5e-3),
        },
        "effects": {
            "quantization": {"counts_per_revolution": 2048},
            "velocity_filter": {"cutoff": 50.0},
            "action_delay": {"seconds": {"distribution": "uniform", "low": 0.0, "high": 0.012}},
            "voltage_offset": {"voltage": {"distribution": "uniform", "low": -0.2, "high": 0.2}},
            "dead_zone": {"voltage": {"distribution": "uniform", "low": 0.0, "high": 0.15}},
        },
    },
}
PRESETS["sim2real_frictionless"] = {
    "parameters": {name: distribution for name, distribution in PRESETS["sim2real"]["parameters"].items()
                   if name not in ("arm_friction", "pendulum_friction")},
    "effects": PRESETS["sim2real"]["effects"],
}
PRESETS["actuation"] = {
    "effects": {
        "action_delay": {"steps": {"distribution": "uniform", "low": 0, "high": 1}},
        "voltage_offset": {"voltage": {"distribution": "uniform", "low": -0.1, "high": 0.1}},
        "dead_zone": {"voltage": {"distribution": "uniform", "low": 0.0, "high": 0.2}},
    },
}
"""Preset name -> config data (see `qube_suite.randomization.config`)."""
