"""Calibration: the experiment, recovery of hidden plants of the substitute, the file, bad input."""

import json
import math
import os

import numpy as np
import pytest

from qube_suite import baselines, calibration, suite
from qube_suite.calibration import experiment, measurements
from qube_suite.calibration.identifiability import FITTED
from qube_suite.cli import main
from qube_suite.devices.qube import parameters
from qube_suite.devices.qube.controllers.lqr import lqr_gain
from qube_suite.hardware.plant import ESTIMATED, named_plant, plant_parameters

HIDDEN_PLANTS = [
    {"pendulum_mass": 0.024 * 1.25, "pendulum_length": 0.129 * 0.92, "motor_resistance": 8.4 * 1.2,
     "motor_torque_constant": 0.042 * 0.88, "rotor_inertia": 4e-6 * 1.2, "arm_friction": 3.5e-3,
     "pendulum_friction": 1.5e-4, "cable_stiffness": 3e-3},
    {"pendulum_mass": 0.024 * 0.75, "pendulum_length": 0.129 * 1.08, "motor_resistance": 8.4 * 0.8,
     "motor_torque_constant": 0.042 * 1.12, "rotor_inertia": 4e-6 * 0.8, "arm_friction": 2e-4,
     "pendulum_friction": 1e-5, "cable_stiffness": 5e-4},
]
"""Plants the fitter is not told, near the edges of the benchmark's ranges, about the estimated plant.

Drawn about the real Qube's plant (the default) instead, the one-minute calibration does not recover
them (2026-11-28): on the first it found a torque constant of 0.033 N m/A where the plant had 0.037,
and on the second the reset could not settle the pendulum (its friction, 1e-5 N m, below the bench's
sway) within 30 s."""

FRICTION_LIKE = ("arm_friction", "pendulum_friction", "cable_stiffness", "arm_damping", "pendulum_damping")


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """The experiment recorded on the default substitute, and its calibration."""
    path = str(tmp_path_factory.mktemp("calibration") / "experiment.jsonl")
    return path, calibration.calibrate("qube_hardware", seconds=60, recording=path)


@pytest.fixture(scope="module")
def recorded_on_the_estimated_plant(tmp_path_factory):
    """The experiment recorded on the substitute's estimated plant, and its calibration."""
    path = str(tmp_path_factory.mktemp("calibration") / "experiment.jsonl")
    return path, calibration.calibrate("qube_hardware", {"plant": ESTIMATED}, seconds=60, recording=path)


@pytest.mark.slow
@pytest.mark.parametrize("plant", HIDDEN_PLANTS)
def test_recovers_hidden_plants(plant, tmp_path):
    plant = {**named_plant(ESTIMATED), **plant}
    result = calibration.calibrate("qube_hardware", {"plant": plant}, recording=tmp_path / "experiment.jsonl")
    true = plant_parameters(overrides=plant)
    for name in ("motor_resistance", "motor_back_emf", "motor_torque_constant", "pendulum_mass",
                 "pendulum_length"):
        assert result.parameters[name] == pytest.approx(true[name], rel=0.05), name
    for name in FRICTION_LIKE:
        tolerance = max(0.1 * true[name], 1.5e-4 if name in FRICTION_LIKE[:3] else 1.5e-5)
        assert abs(result.parameters[name] - true[name]) <= tolerance, name
    inertia = parameters.arm_inertia(true["arm_mass"], true["arm_length"]) + true["rotor_inertia"]
    assert result.combinations["arm_acceleration_per_ampere"] == pytest.approx(
        true["motor_torque_constant"] / inertia, rel=0.02)
    covered = [low <= true[q.name] <= high for q in FITTED for low, high in [result.intervals[q.name]]]
    assert np.mean(covered) >= 0.8
    assert result.prediction["calibrated_rms"] < 0.02  # the bench's random sway is no model's
    assert result.prediction["nominal_rms"] > 10 * result.prediction["calibrated_rms"]


@pytest.mark.slow
def test_experiment_stays_safe_and_records_currents(recorded):
    path, _ = recorded
    m = measurements.load(path)
    assert m.time[-1] == pytest.approx(60.0, abs=0.01)
    assert np.max(np.abs(m.theta)) < math.radians(65.0)
    assert np.max(np.abs(m.voltage)) <= experiment.EXCITATION_VOLTAGE
    assert np.max(np.abs(m.current)) > 0.2
    swing = np.max(np.abs(np.pi - np.abs(np.angle(np.exp(1j * m.alpha)))))
    assert math.radians(60.0) < swing < math.radians(150.0)  # large swings, never over the top
    assert m.metadata["board_type"] == "qube_servo2_usb" and m.metadata["identifier"] == "0"


@pytest.mark.slow
def test_curvature_only_intervals_are_narrower_than_the_calibrated_ones(recorded_on_the_estimated_plant):
    # On the estimated plant: on the real Qube's (the default) not every curvature-only interval was
    # narrower (2026-11-28), a calibration of a plant whose effects its model does not all contain.
    from qube_suite.calibration import fit, intervals

    path, result = recorded_on_the_estimated_plant
    m = measurements.load(path)
    curvature = intervals.curvature_half_widths(fit.fit(m, np.flatnonzero(~calibration.held_out(m))))
    widths = {q.name: (high - low) / 2 for q in FITTED for low, high in [result.intervals[q.name]]}
    narrower = [curvature[i] * fit.SCALES[i] < widths[q.name] for i, q in enumerate(FITTED)]
    assert all(narrower)


def test_file_round_trip_feeds_simulation_controllers_and_randomization(recorded, tmp_path):
    _, result = recorded
    path = result.save(tmp_path / "my_qube.yaml")
    loaded = calibration.load(path)
    assert loaded.parameters == result.parameters
    assert loaded.intervals == result.intervals
    assert loaded.metadata["board_type"] == "qube_servo2_usb"
    for source in (path, loaded, dict(loaded.parameters)):
        env = suite.load("qube", "swingup", domain_kwargs={"parameters": source})
        assert env.physics.parameters["pendulum_mass"] == result.parameters["pendulum_mass"]
        assert env.physics.model.dof_frictionloss[0] == result.parameters["arm_friction"]
    controller = baselines.make("balance", parameters=path)
    assert controller.model.torque_per_volt == pytest.approx(
        result.parameters["motor_torque_constant"] / result.parameters["motor_resistance"])
    randomization_file = os.path.join(tmp_path, "my_qube.randomization.yaml")
    for randomization in (result.randomization(), randomization_file):
        env = suite.load("qube", "balance", task_kwargs={"random": 3}, randomization=randomization)
        env.reset()
        drawn = env.physics.parameters
        for name, (low, high) in result.intervals.items():
            assert low <= drawn[name] <= high, name


def test_lqr_design_leaves_coulomb_friction_to_the_observer():
    nominal = lqr_gain(250.0)
    with_friction = lqr_gain(250.0, {"arm_friction": 2e-3, "pendulum_friction": 1e-4})
    np.testing.assert_allclose(with_friction, nominal, rtol=1e-9)


def test_parameters_from_a_file_that_is_not_a_calibration(tmp_path):
    path = tmp_path / "other.yaml"
    path.write_text("something: 1\n")
    with pytest.raises(ValueError, match="not a calibration file"):
        suite.load("qube", "swingup", domain_kwargs={"parameters": str(path)})
    with pytest.raises(TypeError, match="parameters must be"):
        parameters.values_of(3.0)


def _rewrite(source, target, change_row=None, change_header=None):
    """Copy recording `source` to `target`, changing rows or the file's header."""
    with open(source) as file:
        lines = file.read().splitlines()
    header = json.loads(lines[0])
    if change_header:
        change_header(header)
    lines[0] = json.dumps(header)
    columns = json.loads(lines[1])["episode"]["columns"]
    for number, line in enumerate(lines[2:], start=2):
        value = json.loads(line)
        if isinstance(value, list) and change_row:
            change_row(dict(zip(columns, range(len(columns)), strict=True)), value)
            lines[number] = json.dumps(value)
    with open(target, "w") as file:
        file.write("\n".join(lines) + "\n")
    return target


def _cut(source, target):
    with open(source) as file:
        text = file.read()
    with open(target, "w") as file:
        file.write(text[:len(text) // 2])
    return target


def _other_board(header):
    header["board_type"] = "simulation"


def _saturate(columns, row):
    if row[columns["step"]] % 10 == 0:
        row[columns["raw_current"]] = 1.8


def _arm_at_limit(columns, row):
    if row[columns["step"]] == 5000:
        row[columns["raw_encoder_arm"]] = 520  # 91 degrees


@pytest.mark.parametrize("make, problem", [
    (lambda source, target: _cut(source, target), "truncated"),
    (lambda source, target: _rewrite(source, target, change_header=_other_board), "board type"),
    (lambda source, target: _rewrite(source, target, change_row=_saturate), "saturated"),
    (lambda source, target: _rewrite(source, target, change_row=_arm_at_limit), "limit"),
])
def test_bad_recordings_are_refused_and_nothing_is_written(recorded, tmp_path, make, problem, capsys):
    bad = make(recorded[0], str(tmp_path / "bad.jsonl"))
    out = tmp_path / "my_qube.yaml"
    assert main(["calibrate", "--recording", bad, "--out", str(out)]) == 2
    assert problem in capsys.readouterr().err
    assert not out.exists() and not (tmp_path / "my_qube.randomization.yaml").exists()


@pytest.mark.slow
def test_short_recordings_and_recordings_without_currents_are_refused(tmp_path):
    short = experiment.run(tmp_path / "short.jsonl", "qube_hardware", seconds=10.0)
    with pytest.raises(ValueError, match="too short"):
        calibration.calibrate_recording(short)
    simulated = experiment.run(tmp_path / "simulated.jsonl", "qube", seconds=25.0)
    with pytest.raises(ValueError, match="board type 'simulation'"):
        calibration.calibrate_recording(simulated)
    with pytest.raises(ValueError, match="seconds must be in"):
        experiment.run(tmp_path / "long.jsonl", seconds=61.0)


def test_an_experiment_that_does_not_finish_leaves_no_recording(tmp_path):
    from qube_suite.devices.qube.hardware import ResetError

    with pytest.raises(ResetError):  # the settling before the experiment needs 0.5 s at rest
        experiment.run(tmp_path / "experiment.jsonl", "qube_hardware", {"reset_timeout": 0.1})
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_recording_without_current_column_is_refused(recorded, tmp_path):
    source = recorded[0]
    with open(source) as file:
        lines = file.read().splitlines()
    episode = json.loads(lines[1])
    columns = episode["episode"]["columns"]
    index = columns.index("raw_current")
    episode["episode"]["columns"] = columns[:index] + columns[index + 1:]
    rows = [json.dumps(episode)]
    for line in lines[2:]:
        value = json.loads(line)
        if isinstance(value, list):
            del value[index]
        rows.append(json.dumps(value))
    target = tmp_path / "no_current.jsonl"
    target.write_text("\n".join([lines[0], *rows]) + "\n")
    with pytest.raises(ValueError, match="no motor currents"):
        calibration.calibrate_recording(target)


@pytest.mark.slow
def test_cli_calibrates_a_recording_and_writes_file_and_report(recorded, tmp_path, capsys):
    pytest.importorskip("matplotlib")
    out = tmp_path / "my_qube.yaml"
    arguments = ["calibrate", "--recording", recorded[0], "--board", "qube_servo2_usb", "--out", str(out)]
    assert main(arguments) == 0
    assert calibration.load(out).parameters == recorded[1].parameters
    for suffix in (".html", ".png", ".randomization.yaml"):
        assert (tmp_path / f"my_qube{suffix}").stat().st_size > 0
    assert "pendulum_mass" in capsys.readouterr().out
    assert main(["calibrate", "--recording", recorded[0], "--board", "qube_servo3_usb",
                 "--out", str(tmp_path / "other.yaml")]) == 2
    assert not (tmp_path / "other.yaml").exists()
