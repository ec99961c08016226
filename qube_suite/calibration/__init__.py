"""Calibrate a Qube: identify its model's parameters from its own recordings.

    from qube_suite import calibration, suite
    my_qube = calibration.calibrate("qube_hardware", {"board": "qube_servo2_usb"})   # about a minute
    my_qube.parameters["pendulum_mass"], my_qube.intervals["pendulum_mass"]
    my_qube.save("my_qube.yaml")
    env = suite.load("qube", "swingup", domain_kwargs={"parameters": "my_qube.yaml"})

`calibrate` runs the excitation experiment (`experiment`) on a domain and fits its
recording; `calibrate_recording` fits a recording made earlier. The modules, one
idea each: `experiment` (what the Qube does for a minute), `measurements` (the
recording checked and turned into signals), `identifiability` (what can be
identified and what is fixed), `fit` (the estimates), `intervals` (their
uncertainty), `prediction` (MuJoCo rollouts against the recording),
`calibration_file` (the result and its YAML file), `report` (HTML and PNG).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping
from typing import Any

import numpy as np

from qube_suite import parameters as params
from qube_suite.calibration import experiment, fit, intervals, measurements, prediction
from qube_suite.calibration.calibration_file import Calibration, load
from qube_suite.calibration.identifiability import FITTED, OFFSETS

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
    m = measurements.load(path, board_type)
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
                       prediction={"horizon": prediction.HORIZON, "nominal_rms": nominal.rms_at_horizon,
                                   "calibrated_rms": calibrated.rms_at_horizon})


__all__ = ["Calibration", "calibrate", "calibrate_recording", "load"]
