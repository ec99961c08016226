"""Calibrate a Qube: identify its model's parameters from its own recordings.

    from qube_suite import calibration, suite
    my_qube = calibration.calibrate("qube_hardware", {"board": "qube_servo2_usb"})   # about a minute
    my_qube.parameters["pendulum_mass"], my_qube.intervals["pendulum_mass"]
    my_qube.save("my_qube.yaml")
    env = suite.load("qube", "swingup", domain_kwargs={"parameters": "my_qube.yaml"})

`calibrate` runs the excitation experiment (`experiment`) on a domain and fits its
recording; `calibrate_recording` fits a recording made earlier; `calibrate_recordings` fits
recordings from any logger (CSV or .npz of `recordings`: encoders and voltage, no current
needed) with `fit.fit_voltage`. The modules, one
idea each: `experiment` (what the Qube does for a minute), `measurements` (the
recording checked and turned into signals), `identifiability` (what can be
identified and what is fixed), `fit` (the estimates), `intervals` (their
uncertainty), `prediction` (MuJoCo rollouts against the recording),
`calibration_file` (the result and its YAML file), `report` (HTML and PNG).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from qube_suite.calibration import experiment, fit, intervals, measurements, prediction, recordings
from qube_suite.calibration.calibration_file import Calibration, load
from qube_suite.calibration.identifiability import FITTED, OFFSETS
from qube_suite.devices.qube import parameters as params
from qube_suite.hardware.plant import BOARD_MOTORS

HELD_OUT_EVERY = 5
"""Every fifth block of `fit.BLOCK_SECONDS` is held out of the fit, for checking predictions."""


def calibrate(domain: str = "qube_hardware", domain_kwargs: Mapping[str, Any] | None = None,
              seconds: float = experiment.MAX_SECONDS, seed: int = 0,
              recording: str | os.PathLike | None = None) -> Calibration:
    """Run the excitation experiment on `domain` (with `domain_kwargs`, passed on untouched) for
    `seconds` (at most 60) and calibrate from it.

    `recording`: where to record the experiment (None: a new temporary file, named in the result's
    metadata). Raises ValueError before the Qube moves for a duration the fit cannot use (under
    `measurements.MIN_SECONDS`, or over 60 s), and after it if the recording cannot be calibrated from
    (see `measurements.load`).
    """
    if not measurements.MIN_SECONDS <= seconds <= experiment.MAX_SECONDS:
        raise ValueError(f"seconds must be in [{measurements.MIN_SECONDS:g}, {experiment.MAX_SECONDS:g}]: "
                         f"calibration needs at least {measurements.MIN_SECONDS:g} s of experiment, "
                         f"got {seconds!r}")
    if recording is None:
        recording = os.path.join(tempfile.mkdtemp(prefix="qube_calibration_"), "experiment.jsonl")
    experiment.run(recording, domain, domain_kwargs, seconds, seed)
    return calibrate_recording(recording)


def held_out(m: measurements.Measurements) -> np.ndarray:
    """Whether each sample lies in a held-out block."""
    return (m.time / fit.BLOCK_SECONDS).astype(int) % HELD_OUT_EVERY == HELD_OUT_EVERY // 2


def calibrate_recording(path: str | os.PathLike, board_type: str | None = None) -> Calibration:
    """Calibrate from the experiment recorded at `path`; `board_type`: the board type it must come
    from (None: any). Raises ValueError naming the problem for a recording that cannot calibrate."""
    return _calibrate_with_current(measurements.load(path, board_type))


def _calibrate_with_current(m: measurements.Measurements) -> Calibration:
    """Calibrate from one recording with motor currents (`fit.fit`), holding out every
    `HELD_OUT_EVERY`-th block to report predictions on."""
    test = held_out(m)
    result = fit.fit(m, np.flatnonzero(~test))
    found = intervals.intervals(result)
    values = result.values
    names = [q.name for q in FITTED]
    parameters = params.resolve({name: values[name] for name in names})
    offsets = {q.name: values[q.name] for q in OFFSETS}
    stiffness = values["cable_stiffness"]
    identified = found["cable_stiffness"][0] > 0.0
    offsets["arm_encoder_offset"] = -values["arm_torque_offset"] / stiffness if identified else None
    nominal = prediction.predict(m, {}, np.flatnonzero(test))
    calibrated = prediction.predict(m, parameters, np.flatnonzero(test), result.latency,
                                    (0.0, offsets["pendulum_encoder_offset"]))
    return Calibration(parameters=parameters, intervals={name: found[name] for name in names},
                       metadata=dict(m.metadata), offsets=offsets, latency_steps=result.latency,
                       actuation={"latency_seconds": result.latency * m.sample_time},
                       prediction={"horizon": prediction.HORIZON, "nominal_rms": nominal.rms_at_horizon,
                                   "calibrated_rms": calibrated.rms_at_horizon})


VOLTAGE_ONLY_PARAMETERS = ("motor_torque_constant", "rotor_inertia", "pendulum_length", "arm_damping",
                           "arm_friction", "cable_stiffness", "pendulum_damping", "pendulum_friction")
"""Model parameters a voltage-only fit identifies (motor_back_emf follows motor_torque_constant)."""


def calibrate_recordings(paths: Sequence[str | os.PathLike], device: str = "qube_servo2",
                         conventions: recordings.Conventions | None = None,
                         free: tuple[str, ...] | None = None, reversals: bool = False) -> Calibration:
    """Calibrate from one or several recordings of the same Qube in the CSV or `.npz` format of
    `recordings` (any logger, any constant sample period), all fitted at once.

    One recording with a `motor_current` column is fitted with its current (`fit.fit`, as the
    excitation experiment: resistance and back-EMF separately, the rotor's inertia fixed); several
    are fitted together from their encoders and voltages (`fit.fit_voltage`), current or not.
    `free`: the unknowns of the voltage-only fit (None: all); `reversals`: it also takes the windows
    where the arm reverses without sticking (`fit.signals`): on four or more of a real Qube's chirps
    it predicts held-out chirps better, on two it loses the cable, and it predicts recordings of
    another session worse (docs/calibration.md, "A real Qube"), so it is off by default. Raises
    ValueError (one line, naming the file) for a recording that cannot calibrate; nothing is
    written here.
    """
    if not paths:
        raise ValueError("no recordings given")
    read = [recordings.read(path, device, conventions) for path in paths]
    if len(read) == 1 and read[0].current is not None and free is None and not reversals:
        return _calibrate_with_current(read[0])
    periods = sorted({round(m.sample_time, 6) for m in read})
    if len(periods) > 1:  # the latency is fitted in samples of one period
        listed = ", ".join(f"{period:g} s" for period in periods)
        raise ValueError(f"recordings of different sample periods ({listed}) cannot be fitted together; "
                         "calibrate from those of one period")
    result = fit.fit_voltage(read, free=free, reversals=reversals)
    found = intervals.voltage_only_intervals(result)
    values = result.values
    motor = dict(BOARD_MOTORS[recordings.DEVICES[device]])
    parameters = params.resolve({**motor, **{name: values[name] for name in VOLTAGE_ONLY_PARAMETERS},
                                 "motor_back_emf": values["motor_torque_constant"]})
    stiffness = values["cable_stiffness"]
    rest = values["arm_torque_offset"] / stiffness if found["cable_stiffness"][0] > 0.0 else None
    gain = parameters["motor_torque_constant"] / parameters["motor_resistance"]
    return Calibration(
        parameters=parameters,
        intervals={name: found[name] for name in (*VOLTAGE_ONLY_PARAMETERS, "voltage_deadzone")},
        metadata={"board_type": recordings.DEVICES[device], "board": device,
                  "recording": ", ".join(os.path.abspath(os.fspath(p)) for p in paths),
                  "seconds": float(sum(m.time[-1] for m in read))},
        offsets={"arm_torque_offset": values["arm_torque_offset"],
                 "pendulum_encoder_offset": values["pendulum_encoder_offset"],
                 "arm_encoder_offset": None if rest is None else -rest,
                 "cable_slack": values["cable_slack"] if rest is not None else 0.0},
        latency_steps=result.latency,
        actuation={"latency_seconds": result.latency * read[0].sample_time,
                   "voltage_deadzone": values["voltage_deadzone"]},
        held=("motor_resistance", "pendulum_mass", "arm_mass", "arm_length", "gravity", "motor_inductance"),
        identified={"motor_gain": gain,
                    "arm_viscous_total": values["arm_damping"] + gain * parameters["motor_back_emf"],
                    "arm_axis_inertia": params.arm_inertia(parameters["arm_mass"], parameters["arm_length"])
                    + parameters["rotor_inertia"]})


__all__ = ["Calibration", "calibrate", "calibrate_recording", "calibrate_recordings", "load"]
