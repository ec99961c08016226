"""Calibrating the Aero 2 with the calibration engine: a thruster's motor and rotor, and the pitch.

The engine (`qube_suite.calibration.fit`) fits a motor's circuit, V = Rm i + km w, and a device's
momentum balances in their weak form. The experiment runs the Aero in its 1-DOF configuration
(yaw locked, as in Quanser's pitch-estimation lab) and drives the front thruster only, so the
engine's shaft is the front motor's (encoder 0) and its second joint the pitch (encoder 2):

    rotor:  d/dt (Js w) = kt i - kd w - Fr sgn(w),        Js = Jr + Jprop + mh rh^2 / 2
    pitch:  d/dt (Jp pitch') = Dt kf w - Mb g Dm sin(pitch) - Dp pitch' - Fp sgn(pitch')

The rotor's balance gives Js / kt and kd / kt, so kt is taken equal to km (one constant of the motor
in SI units), which the circuit identifies; the motor's rotor and hub inertias stay at the table's,
and the balance gives the propeller's. The pitch's balance gives its terms in proportion to Jp, which
stays at the CAD figure (as Quanser's lab holds it), with the arm Dt, the mass Mb and g.

    path = calibration.record_experiment("aero.npz", domain_kwargs={"board": "simulated"})
    aero = calibration.calibrate_recording(path)
    aero.parameters["thrust_constant"], aero.intervals["thrust_constant"]

`record_experiment` drives the Aero's hardware domain (the substitute board or a real Aero) with a
multisine on a steady lift, which keeps the rotor turning one way, for 6 s of every 10 s, and lets
the beam swing freely at 0 V in between; and saves the board's raw readings with the voltages
applied (`.npz`; the episode recorder writes one voltage per row).
"""

from __future__ import annotations

import datetime
import json
import math
import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from qube_suite import suite
from qube_suite.calibration import fit, intervals
from qube_suite.calibration.calibration_file import Calibration
from qube_suite.calibration.identifiability import Fitted
from qube_suite.calibration.measurements import MIN_SECONDS, Encoders, Measurements
from qube_suite.devices.aero2 import conventions
from qube_suite.devices.aero2 import parameters as aero_parameters

UNKNOWNS: tuple[Fitted, ...] = (
    Fitted("motor_resistance", aero_parameters.NOMINAL["motor_resistance"], "ohm", relative_tolerance=0.015),
    Fitted("motor_back_emf", aero_parameters.NOMINAL["motor_back_emf"], "V s/rad", relative_tolerance=0.01),
    Fitted("propeller_inertia", aero_parameters.NOMINAL["propeller_inertia"], "kg m^2",
           relative_tolerance=0.03),
    Fitted("propeller_drag", aero_parameters.NOMINAL["propeller_drag"], "N m s/rad", relative_tolerance=0.03),
    Fitted("rotor_friction", 4.0e-4, "N m", 5.0e-5),
    Fitted("thrust_constant", aero_parameters.NOMINAL["thrust_constant"], "N s/rad", relative_tolerance=0.02),
    Fitted("center_of_mass_offset", aero_parameters.NOMINAL["center_of_mass_offset"], "m",
           relative_tolerance=0.02),
    Fitted("pitch_damping", aero_parameters.NOMINAL["pitch_damping"], "N m s/rad", 1.0e-3),
    Fitted("pitch_friction", 5.0e-4, "N m", 2.0e-4),
)
"""The fit's unknowns, by the table's long names (and the substitute's `rotor_friction` and
`pitch_friction`, which the table does not have); the tolerances are the smallest 95 % half-widths:
what the model leaves out (the motor's inductance, the back rotor's friction) is not in the
residual's spread (the resistance came out up to 1.0 % off on substitute Aeros of seeds 1 to 6 and
the default one, the sampled current against the voltage of each interval)."""

HELD = ("rotor_inertia", "hub_mass", "hub_radius", "pitch_inertia", "thrust_arm", "body_mass", "gravity",
        "motor_inductance")
"""Parameters held at the table's values."""

ENCODERS = Encoders(shaft="encoder_front", pendulum="encoder_pitch", shaft_limit=None)
"""The front motor's shaft on encoder 0, the pitch on encoder 2 (raw columns of the experiment)."""

LIFT_VOLTAGE = 3.5
"""The front thruster's steady voltage (V) while driven: the beam hangs at about 12 degrees."""

EXCITATION = ((1.0, 0.11), (0.8, 0.37), (0.8, 0.9), (0.6, 2.3))
"""The multisine's components on top of the lift (V, Hz): the slow ones swing the beam, the fast ones
vary the rotor's acceleration."""

DRIVEN, PERIOD = 6.0, 10.0
"""The thruster is driven for the first `DRIVEN` s of every `PERIOD` s and at 0 V for the rest: the
beam then swings freely, its weight against its inertia (the swings of Quanser's pitch-estimation
lab), which separates the centre of mass's offset from the thrust and the damping from the
friction."""

SECONDS = 40.0
"""Default length of the experiment (s)."""


def model() -> fit.Model:
    """The engine's model of the Aero's front thruster and pitch (see the module docstring)."""
    held = aero_parameters.NOMINAL
    fixed_spin = held["rotor_inertia"] + 0.5 * held["hub_mass"] * held["hub_radius"] ** 2
    weight = held["body_mass"] * held["gravity"]

    def balances(p: dict[str, np.ndarray], s: fit.Signals, column: fit.Column) -> tuple[np.ndarray, ...]:
        speed, pitch, pitch_rate = column(s.dtheta), column(s.alpha), column(s.dalpha)
        kt = p["motor_back_emf"]
        rotor_momentum = (fixed_spin + p["propeller_inertia"]) * speed
        rotor_torque = -p["propeller_drag"] * speed - p["rotor_friction"] * np.sign(speed)
        rotor = fit.balance(rotor_momentum, rotor_torque, kt * column(s.current_after),
                            s.starts[s.arm_sliding], s.sample_time)
        pitch_momentum = held["pitch_inertia"] * pitch_rate
        pitch_torque = (held["thrust_arm"] * p["thrust_constant"] * speed
                        - weight * p["center_of_mass_offset"] * np.sin(pitch)
                        - p["pitch_damping"] * pitch_rate - p["pitch_friction"] * np.sign(pitch_rate))
        beam = fit.balance(pitch_momentum, pitch_torque, 0.0, s.starts[s.pendulum_sliding], s.sample_time)
        return rotor, beam

    positive = frozenset({"motor_resistance", "motor_back_emf", "propeller_inertia", "propeller_drag",
                          "thrust_constant", "center_of_mass_offset"})
    return fit.Model(unknowns=UNKNOWNS, positive=positive, balances=balances,
                     balance_starts=lambda s: (s.starts[s.arm_sliding], s.starts[s.pendulum_sliding]),
                     start_weights=(10.0, 1e5, 1e4), encoders=ENCODERS)


def excitation_voltage(time: float, phases: np.ndarray) -> float:
    """The front thruster's voltage at `time` (s), with the components' `phases` (rad)."""
    if time % PERIOD >= DRIVEN:
        return 0.0
    return LIFT_VOLTAGE + sum(amplitude * math.sin(2.0 * math.pi * frequency * time + phase)
                              for (amplitude, frequency), phase in zip(EXCITATION, phases, strict=True))


def record_experiment(path: str | os.PathLike, domain_kwargs: Mapping[str, Any] | None = None,
                      seconds: float = SECONDS, seed: int = 0) -> str:
    """Run the excitation on the Aero's hardware domain in its 1-DOF configuration (`domain_kwargs` to
    `suite.load`: board, the substitute's parameters, ...) for `seconds` and save it to `path` (.npz);
    return the path. An unfinished experiment leaves nothing. Raises ValueError for fewer than
    `MIN_SECONDS`."""
    if not seconds >= MIN_SECONDS:
        raise ValueError(f"seconds must be at least {MIN_SECONDS:g} for a calibration, got {seconds!r}")
    phases = np.random.default_rng(seed).uniform(0.0, 2.0 * math.pi, len(EXCITATION))
    kwargs = {**dict(domain_kwargs or {}), "configuration": "pitch_only"}
    environment = suite.load("aero2_hardware", "pitch", task_kwargs={"random": seed},
                             environment_kwargs={"time_limit": seconds}, domain_kwargs=kwargs)
    physics = environment.physics
    rows: dict[str, list[float]] = {}
    try:
        timestep = environment.reset()
        while True:
            readings = {"time": physics.time(), **physics.raw_readings(),
                        "applied_front": float(physics.applied_voltage()[0])}
            for name, value in readings.items():
                rows.setdefault(name, []).append(float(value))
            if timestep.last():
                break
            timestep = environment.step([excitation_voltage(physics.time(), phases), 0.0])
        if timestep.discount == 0.0:
            raise RuntimeError(f"the experiment left the Aero's safe range at t = {physics.time():.2f} s")
        wrapper = physics.qube
        metadata = {"experiment": __name__, "domain": "aero2_hardware", "seed": seed, "seconds": seconds,
                    "control_frequency": environment.control_frequency,
                    "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
                    "board_type": wrapper.device.board_type, "board": wrapper.board_name,
                    "identifier": wrapper.identifier}
    finally:
        environment.close()
    with open(path, "wb") as file:
        np.savez(file, metadata=json.dumps(metadata),
                 **{name: np.array(values) for name, values in rows.items()})
    return os.fspath(path)


def measurements(path: str | os.PathLike) -> Measurements:
    """The engine's measurements of the experiment saved at `path`: the front motor's angle as the
    shaft, the pitch as the second joint, the front voltage applied, the front motor's current.
    Raises ValueError for a file that is not such an experiment or too short."""
    try:
        with np.load(path) as saved:
            data = {name: saved[name] for name in saved.files}
    except (OSError, ValueError) as error:
        raise ValueError(f"{os.fspath(path)} is not an Aero 2 experiment ({error})") from None
    needed = ("metadata", "time", "applied_front", "current_front", ENCODERS.shaft, ENCODERS.pendulum)
    missing = [name for name in needed if name not in data]
    if missing:
        raise ValueError(f"{os.fspath(path)} is not an Aero 2 experiment: no {', '.join(missing)}")
    metadata = {**json.loads(str(data["metadata"])), "path": os.fspath(path)}
    time = data["time"]
    if time[-1] - time[0] < MIN_SECONDS:
        raise ValueError(f"{os.fspath(path)} is too short: {time[-1] - time[0]:.1f} s recorded, calibration "
                         f"needs at least {MIN_SECONDS:g} s")
    return Measurements(time=time, theta=data[ENCODERS.shaft] * conventions.TACHOMETER_TO_RAD_PER_S,
                        alpha=data[ENCODERS.pendulum] / conventions.PITCH_COUNTS_PER_RADIAN,
                        voltage=data["applied_front"], current=data["current_front"],
                        sample_time=1.0 / float(metadata["control_frequency"]), metadata=metadata)


def calibrate_recording(path: str | os.PathLike) -> Calibration:
    """Calibrate the Aero 2 from the experiment saved at `path` (`record_experiment`): the table's
    parameters with the estimates, their 95 % intervals, and the substitute's friction estimates
    (`identified`: `rotor_friction`, `pitch_friction`, N m). Raises ValueError naming the problem for
    a file that cannot calibrate."""
    m = measurements(path)
    result = fit.fit(m, model=model())
    found = intervals.statistical_intervals(result, UNKNOWNS)
    values = result.values
    estimated = [q.name for q in UNKNOWNS if q.name in aero_parameters.PARAMETERS]
    parameters = aero_parameters.resolve({**{name: values[name] for name in estimated},
                                          "motor_torque_constant": values["motor_back_emf"]})
    return Calibration(parameters=parameters, intervals=found, metadata=dict(m.metadata),
                       latency_steps=result.latency,
                       actuation={"latency_seconds": result.latency * m.sample_time}, held=HELD,
                       identified={name: values[name] for name in ("rotor_friction", "pitch_friction")})
