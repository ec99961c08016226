"""Calibrating the disk-loaded Qube with the calibration engine: its motor and its disk's inertia.

The engine (`qube_suite.calibration.fit`) fits the motor's circuit, V = Rm i + km theta', and a
device's momentum balances in their weak form. The disk has one, its shaft's:

    d/dt (J theta') = kt i - Dd theta' - Fd sign(theta') + shaft_torque_offset,
    J = Jm + Jh + md rd^2 / 2

Its current against its motion gives J / kt only (doubling kt and J gives the same motion), so the
torque constant is taken equal to the back-EMF constant, which the circuit identifies (in SI units
they are one constant of the motor, kt = km); the rotor's and the hub's inertia and the disk's
radius stay at their values (the rotor's: the board's Qube's), and the balance gives the disk's
mass, reported with its inertia md rd^2 / 2 (`identified`).

    path = calibration.record_experiment("disk.jsonl", domain_kwargs={"board": "simulated"})
    disk = calibration.calibrate_recording(path)
    disk.parameters["disk_mass"], disk.intervals["disk_mass"], disk.identified["disk_inertia"]

`record_experiment` drives a hardware domain of the disk (the substitute board or a real one) with a
multisine voltage that turns the disk both ways, and records it with the board's raw readings
(encoder counts, motor current). No held-out MuJoCo prediction is made (the engine's `prediction`
rolls out the pendulum's simulation).
"""

from __future__ import annotations

import datetime
import math
import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from qube_suite import suite
from qube_suite.calibration import fit, intervals, measurements
from qube_suite.calibration.calibration_file import Calibration
from qube_suite.calibration.experiment import board_metadata
from qube_suite.calibration.identifiability import Fitted
from qube_suite.devices.qube_disk import parameters as disk_parameters
from qube_suite.hardware.plant import ESTIMATED, plant_parameters
from qube_suite.recording import Recorder

DISK_MASS_BIAS = 0.04
"""Smallest relative 95 % half-width of the disk's mass: the fit's own bias. It came out 1.4 to 3.2 %
low on the plants of `benchmarks/disk_calibration.py --seed 100` (the torque scale's weak-form bias
the pendulum's estimates carry too, `qube_suite.calibration.intervals.TORQUE_SCALE_BIAS`, here on
the disk's part of the shaft's inertia alone)."""

UNKNOWNS: tuple[Fitted, ...] = (
    Fitted("motor_resistance", disk_parameters.NOMINAL["motor_resistance"], "ohm", relative_tolerance=0.005),
    Fitted("motor_back_emf", disk_parameters.NOMINAL["motor_back_emf"], "V s/rad", relative_tolerance=0.005),
    Fitted("disk_mass", disk_parameters.NOMINAL["disk_mass"], "kg", relative_tolerance=DISK_MASS_BIAS),
    Fitted("disk_damping", 1.0e-5, "N m s/rad", 2.0e-6),
    Fitted("disk_friction", 1.0e-3, "N m", 1.0e-4),
    Fitted("shaft_torque_offset", 1.0e-4, "N m", 1.0e-5),
)
"""The fit's unknowns: the disk table's long names, then a constant torque on the shaft."""

HELD = ("rotor_inertia", "hub_inertia", "disk_radius", "motor_inductance")
"""Parameters held at their values (the rotor's and the inductance: the board's Qube's)."""

ENCODERS = measurements.Encoders(shaft="raw_encoder_disk", pendulum=None, shaft_limit=None)
"""The disk on encoder 0 (the board's raw column `encoder_disk`), no pendulum, turning freely."""

EXCITATION = ((2.0, 0.15), (1.0, 0.45), (0.7, 1.3), (0.4, 3.1))
"""The multisine's components (V, Hz): the slowest turns the disk both ways (its friction then acts
both ways), the faster ones vary its acceleration within each turn."""
EXCITATION_VOLTAGE = 4.0
"""Largest voltage of the experiment (V): about 0.5 A and 90 rad/s on a nominal disk."""
MIN_SECONDS = measurements.MIN_SECONDS


def model(board_type: str) -> fit.Model:
    """The engine's model of the disk on `board_type` (its rotor's inertia is the board's Qube's)."""
    rotor_inertia = plant_parameters(board_type, ESTIMATED)["rotor_inertia"]
    held = {**disk_parameters.NOMINAL, "rotor_inertia": rotor_inertia}
    fixed_inertia = held["rotor_inertia"] + held["hub_inertia"]
    radius = held["disk_radius"]

    def shaft_balance(p: dict[str, np.ndarray], s: fit.Signals, column: fit.Column) -> tuple[np.ndarray]:
        speed = column(s.dtheta)
        momentum = (fixed_inertia + disk_parameters.disk_inertia(p["disk_mass"], radius)) * speed
        torque = -p["disk_damping"] * speed - p["disk_friction"] * np.sign(speed) + p["shaft_torque_offset"]
        motor = p["motor_back_emf"] * column(s.current_after)  # kt = km
        return (fit.balance(momentum, torque, motor, s.starts[s.arm_sliding], s.sample_time),)

    positive = frozenset({"motor_resistance", "motor_back_emf", "disk_mass"})
    return fit.Model(unknowns=UNKNOWNS, positive=positive, balances=shaft_balance,
                     balance_starts=lambda s: (s.starts[s.arm_sliding],), start_weights=(10.0, 1e4),
                     encoders=ENCODERS)


def excitation_voltage(time: float, phases: np.ndarray) -> float:
    """The experiment's voltage at `time` (s), with the components' `phases` (rad)."""
    volts = sum(amplitude * math.sin(2.0 * math.pi * frequency * time + phase)
                for (amplitude, frequency), phase in zip(EXCITATION, phases, strict=True))
    return min(max(volts, -EXCITATION_VOLTAGE), EXCITATION_VOLTAGE)


def record_experiment(path: str | os.PathLike, domain_kwargs: Mapping[str, Any] | None = None,
                      seconds: float = 30.0, seed: int = 0) -> str:
    """Run the excitation on the disk's hardware domain (`domain_kwargs` to `suite.load`: board,
    device, the substitute's parameters) for `seconds` and record it to `path`; return the path.
    An unfinished experiment leaves no recording. Raises ValueError for fewer than `MIN_SECONDS`."""
    if not seconds >= MIN_SECONDS:
        raise ValueError(f"seconds must be at least {MIN_SECONDS:g} for a calibration, got {seconds!r}")
    phases = np.random.default_rng(seed).uniform(0.0, 2.0 * math.pi, len(EXCITATION))
    environment = suite.load("qube_disk_hardware", "speed",
                             task_kwargs={"random": seed, "voltage_limit": EXCITATION_VOLTAGE},
                             environment_kwargs={"time_limit": seconds}, domain_kwargs=domain_kwargs)
    metadata = {"experiment": __name__, "domain": "qube_disk_hardware", "seed": seed, "seconds": seconds,
                "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
                **board_metadata(environment.physics)}
    try:
        with Recorder(path, environment, metadata=metadata):
            timestep = environment.reset(seed=seed)
            while not timestep.last():
                timestep = environment.step([excitation_voltage(environment.physics.time(), phases)])
    except BaseException:
        os.remove(path)
        raise
    finally:
        environment.close()
    return os.fspath(path)


def calibrate_recording(path: str | os.PathLike, board_type: str | None = None) -> Calibration:
    """Calibrate the disk-loaded Qube from the experiment recorded at `path` (`board_type`: the board
    type it must come from, None: any). Raises ValueError naming the problem for a recording that
    cannot calibrate (`qube_suite.calibration.measurements.load`)."""
    m = measurements.load(path, board_type, ENCODERS)
    result = fit.fit(m, model=model(m.board_type))
    found = intervals.statistical_intervals(result, UNKNOWNS)
    values = result.values
    estimated = [q.name for q in UNKNOWNS if q.name in disk_parameters.PARAMETERS]
    motor = plant_parameters(m.board_type, ESTIMATED)
    parameters = disk_parameters.resolve({**{name: motor[name] for name in disk_parameters.MOTOR_NAMES},
                                          **{name: values[name] for name in estimated},
                                          "motor_torque_constant": values["motor_back_emf"]})
    return Calibration(
        parameters=parameters, intervals={name: found[name] for name in estimated},
        metadata=dict(m.metadata), offsets={"shaft_torque_offset": values["shaft_torque_offset"]},
        latency_steps=result.latency, actuation={"latency_seconds": result.latency * m.sample_time},
        held=HELD, identified={"disk_inertia": disk_parameters.disk_inertia(parameters["disk_mass"],
                                                                            parameters["disk_radius"]),
                               "shaft_inertia": disk_parameters.shaft_inertia(parameters)})
