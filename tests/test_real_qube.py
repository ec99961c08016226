"""Recordings from any logger: the reader's refusals, the voltage-only fit on a known plant, and
the calibration on recordings of a real Qube-Servo 2 (`../shared/real_qube/`, skipped if absent)."""

import glob
import os

import numpy as np
import pytest

from qube_suite import calibration
from qube_suite.calibration import fit, prediction, recordings
from qube_suite.calibration.measurements import Measurements
from qube_suite.cli import main
from qube_suite.devices.qube import simulation as qube

REAL_QUBE = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "real_qube")
HEADER = "time,voltage,arm_angle,pendulum_angle"


def write(path, rows, header=HEADER):
    path.write_text(header + "\n" + "\n".join(",".join(f"{x:.9g}" for x in row) for row in rows) + "\n")
    return str(path)


def good_rows(seconds=3.0, period=0.004):
    t = np.arange(0.0, seconds, period)
    return np.column_stack([t, np.sin(2 * np.pi * t), 0.1 * np.sin(2 * np.pi * t), np.pi + 0 * t])


def spoil(kind):
    rows = good_rows()
    if kind == "nan":
        rows[10, 2] = np.nan
    elif kind == "backwards":
        rows[20, 0] = rows[18, 0]
    elif kind == "gap":
        rows[200:, 0] += 0.5
    elif kind == "short":
        rows = rows[:100]
    elif kind == "arm":
        rows[:, 2] *= 30.0
    elif kind == "saturated":
        rows[:, 1] = np.sign(rows[:, 1]) * 4.0
    return rows


@pytest.mark.parametrize("kind, words", [
    ("nan", "not finite"), ("backwards", "does not increase"), ("gap", "not constant"),
    ("short", "too short"), ("arm", "degrees, beyond"), ("saturated", "saturated")])
def test_bad_recordings_get_one_line_naming_the_problem_and_nothing_is_written(kind, words, tmp_path, capsys):
    path = write(tmp_path / f"{kind}.csv", spoil(kind))
    with pytest.raises(ValueError, match=words) as error:
        recordings.read(path)
    assert "\n" not in str(error.value) and path in str(error.value)
    out = tmp_path / "my_qube.yaml"
    assert main(["calibrate", "--recording", path, "--out", str(out)]) != 0
    assert words in capsys.readouterr().err
    assert not out.exists()


def test_a_missing_column_is_named(tmp_path):
    path = write(tmp_path / "a.csv", good_rows()[:, :3], header="time,voltage,arm_angle")
    with pytest.raises(ValueError, match="no column 'pendulum_angle'"):
        recordings.read(path)


def test_recordings_of_different_periods_are_not_fitted_together(tmp_path):
    paths = [write(tmp_path / "a.csv", good_rows()), write(tmp_path / "b.csv", good_rows(period=0.002))]
    with pytest.raises(ValueError, match="different sample periods"):
        calibration.calibrate_recordings(paths)


def test_conventions_and_npz_give_the_same_measurements(tmp_path):
    rows = good_rows()
    rows[:, 0] += 0.0004 * np.sin(np.arange(len(rows)))  # timestamps with jitter
    reference = recordings.read(write(tmp_path / "a.csv", rows))
    other = rows.copy()
    other[:, 2] = -np.degrees(rows[:, 2])
    other[:, 3] = np.degrees(rows[:, 3] - np.pi)
    npz = tmp_path / "b.npz"
    np.savez(npz, time=other[:, 0], voltage=other[:, 1], arm_angle=other[:, 2], pendulum_angle=other[:, 3])
    converted = recordings.read(npz, conventions=recordings.Conventions(
        degrees=True, pendulum_zero_hanging=True, arm_sign=-1))
    assert reference.sample_time == pytest.approx(0.004, rel=1e-3)
    from scipy.io import savemat

    savemat(tmp_path / "c.mat", {"time": rows[:, 0], "voltage": rows[:, 1], "arm_angle": rows[:, 2],
                                 "pendulum_angle": rows[:, 3]})
    np.testing.assert_allclose(recordings.read(tmp_path / "c.mat").theta, reference.theta, atol=1e-12)
    np.testing.assert_allclose(converted.theta, reference.theta, atol=1e-12)
    np.testing.assert_allclose(np.cos(converted.alpha), np.cos(reference.alpha), atol=1e-12)


def simulated_chirp(truth, latency, deadzone, seconds=8.0, rate=250.0, cable=None):
    """Angles of the simulated Qube with parameters `truth` under a chirp whose voltage acts `latency`
    samples late through a dead zone of `deadzone` V; `cable`: its effects (rest angle, slack) if any,
    and a slow sine added to the chirp that swings the arm beyond the slack."""
    t = np.arange(0.0, seconds, 1.0 / rate)
    voltage = 1.5 * np.sin(2 * np.pi * (6.0 - 0.35 * t) * t)
    if cable:
        voltage += 0.1 * np.sin(2 * np.pi * 0.4 * t)
    acting = fit.delayed_voltage(voltage, latency)
    acting = np.sign(acting) * np.maximum(np.abs(acting) - deadzone, 0.0)
    physics = qube.make_physics(rate, truth)
    if cable:
        physics.set_calibrated_effects(cable, 1.0 / rate)
    physics.reset_to([0.0, np.pi, 0.0, 0.0])
    angles = []
    for volts in acting:
        angles.append(physics.true_state()[:2])
        physics.set_voltage(float(volts))
        physics.step(qube.substeps_per_control_period(rate))
    angles = np.array(angles)
    return np.column_stack([t, voltage, angles[:, 0], angles[:, 1]])


def test_the_voltage_only_fit_recovers_a_known_simulated_qube(tmp_path):
    truth = {"motor_torque_constant": 0.038, "motor_back_emf": 0.038, "rotor_inertia": 3e-5,
             "pendulum_damping": 4e-6, "arm_damping": 5e-5, "pendulum_length": 0.125,
             "cable_stiffness": 1.5e-3}
    cable = {"cable_rest_angle": -0.2, "cable_slack": 0.4}
    rows = simulated_chirp(truth, latency=1.5, deadzone=0.05, cable=cable)
    assert np.ptp(rows[:, 2]) > 2 * (cable["cable_slack"] + 0.2)  # the arm pulls on the cable both ways
    found = calibration.calibrate_recordings([write(tmp_path / "chirp.csv", rows)])
    assert found.latency_steps == pytest.approx(1.5, abs=0.25)
    for name in ("motor_torque_constant", "rotor_inertia", "pendulum_length", "cable_stiffness"):
        assert found.parameters[name] == pytest.approx(truth[name], rel=0.05), name
    assert found.actuation["voltage_deadzone"] == pytest.approx(0.05, abs=0.03)
    assert found.offsets["cable_slack"] == pytest.approx(cable["cable_slack"], abs=0.1)
    assert -found.offsets["arm_encoder_offset"] == pytest.approx(cable["cable_rest_angle"], abs=0.05)


def test_the_voltage_only_fit_can_take_the_arms_reversals_but_never_a_stick():
    h = 0.004
    t = np.arange(0.0, 4.0, h)
    theta = -0.3 * t + 0.015 * np.sin(2 * np.pi * 10.0 * t)  # creeping while reversing 20 times a second
    still = (t > 3.0) & (t < 3.1)
    theta[still] = theta[np.argmax(still)]                    # then stuck for 0.1 s
    theta[t >= 3.1] += theta[np.argmax(still)] - theta[np.argmax(t >= 3.1)]
    m = Measurements(time=t, theta=theta, alpha=np.pi + 0 * t, voltage=0 * t, current=0 * t, sample_time=h,
                     metadata={})
    sliding, taken = fit.voltage_signals(m), fit.voltage_signals(m, reversals=True)
    starts_time = taken.starts * h
    far = (starts_time + fit.INTERVAL * h < 2.9) | (starts_time > 3.2)
    overlapping = (starts_time + fit.INTERVAL * h > 3.0) & (starts_time < 3.1)
    assert not sliding.arm_sliding.any()  # by default: sliding throughout
    assert taken.arm_sliding[far].all()
    assert not taken.arm_sliding[overlapping].any()


@pytest.mark.skipif(not os.path.isdir(REAL_QUBE),
                    reason=f"recordings of a real Qube not found at {REAL_QUBE}")
def test_calibrating_on_real_chirps_predicts_another_far_better_than_nominal(tmp_path):
    chirps = sorted(glob.glob(os.path.join(REAL_QUBE, "qs2_chirp_*.csv")))
    out = tmp_path / "real.yaml"
    assert main(["calibrate", "--recording", chirps[0], chirps[5], "--out", str(out)]) == 0
    found = calibration.load(out)
    m = recordings.read(chirps[7])
    samples = np.arange(len(m))
    nominal = prediction.predict(m, {}, samples).rms_at_horizon
    calibrated = prediction.predict(
        m, found.parameters, samples, found.actuation["latency_seconds"] / m.sample_time,
        (0.0, found.offsets["pendulum_encoder_offset"]),
        voltage_deadzone=found.actuation["voltage_deadzone"],
        cable_rest_angle=-found.offsets["arm_encoder_offset"]).rms_at_horizon
    assert calibrated < 0.5 * nominal


@pytest.mark.skipif(not os.path.isdir(REAL_QUBE),
                    reason=f"recordings of a real Qube not found at {REAL_QUBE}")
def test_the_arms_reversals_let_four_real_chirps_predict_another_better():
    chirps = sorted(glob.glob(os.path.join(REAL_QUBE, "qs2_chirp_*.csv")))
    training = [chirps[i] for i in (0, 1, 5, 6)]  # neg_0, neg_1, pos_0, pos_1
    m = recordings.read(chirps[7])                 # pos_2

    def error(found):
        latency = found.actuation["latency_seconds"] / m.sample_time
        return prediction.predict(
            m, found.parameters, np.arange(len(m)), latency, (0.0, found.offsets["pendulum_encoder_offset"]),
            voltage_deadzone=found.actuation["voltage_deadzone"],
            cable_rest_angle=-found.offsets["arm_encoder_offset"], cable_slack=found.offsets["cable_slack"],
        ).rms_at_horizon

    sliding = calibration.calibrate_recordings(training)
    reversing = calibration.calibrate_recordings(training, reversals=True)
    assert -reversing.offsets["arm_encoder_offset"] == pytest.approx(-0.43, abs=0.1)  # where the arm creeps
    assert error(reversing) < 0.85 * error(sliding)


def test_the_suites_recordings_export_to_the_format(tmp_path):
    from qube_suite import suite
    from qube_suite.recording import Recorder

    source = tmp_path / "run.jsonl"
    environment = suite.load("qube", "swingup", task_kwargs={"random": 0},
                             environment_kwargs={"time_limit": 3.0})
    with Recorder(source, environment):
        timestep = environment.reset(seed=0)
        while not timestep.last():
            timestep = environment.step([0.5 * np.sin(environment.physics.time() * 20.0)])
    out = tmp_path / "run.csv"
    assert main(["recording", "export", str(source), "--out", str(out)]) == 0
    m = recordings.read(out)
    assert m.sample_time == pytest.approx(1 / 250.0) and len(m) > 700


def test_a_calibration_file_gives_the_simulation_its_latency_dead_zone_and_offsets(tmp_path):
    from qube_suite.calibration.calibration_file import Calibration
    from qube_suite.devices.qube import parameters

    found = Calibration(parameters=parameters.resolve({"cable_stiffness": 2e-3}), intervals={}, metadata={},
                        offsets={"arm_encoder_offset": -0.3, "pendulum_encoder_offset": 0.01},
                        actuation={"latency_seconds": 0.006, "voltage_deadzone": 0.2})
    path = found.save(tmp_path / "mine.yaml")
    physics = qube.make_physics(250.0, path)
    physics.reset_to([0.0, np.pi, 0.0, 0.0])
    assert physics.pendulum_angle() == pytest.approx(np.pi - 0.01)
    applied = []
    for volts in (1.0, 1.0, 1.0, 0.1, 0.1, 0.1):
        physics.set_voltage(volts)
        applied.append(physics.applied_voltage())
        physics.step(1)
    # 1.5 periods late: nothing, half of the first command, then all of it; 0.1 V lies in the dead zone
    np.testing.assert_allclose(applied, [0.0, 0.5 * 1.0 - 0.2, 0.8, 0.8, 0.55 - 0.2, 0.0], atol=1e-12)
    physics.reset_to([0.0, np.pi, 0.0, 0.0])
    for _ in range(2000):
        physics.set_voltage(0.0)
        physics.step(1)
    assert physics.true_state()[0] > 0.1  # the cable pulls the arm towards its rest angle, 0.3 rad


def test_a_slack_cable_pulls_the_arm_only_beyond_its_band(tmp_path):
    from qube_suite.calibration.calibration_file import Calibration
    from qube_suite.devices.qube import parameters

    found = Calibration(parameters=parameters.resolve({"cable_stiffness": 2e-3}), intervals={}, metadata={},
                        offsets={"arm_encoder_offset": -0.3, "cable_slack": 0.2})
    physics = qube.make_physics(250.0, found.save(tmp_path / "slack.yaml"))

    def settle(theta):
        physics.reset_to([theta, np.pi, 0.0, 0.0])
        for _ in range(1000):
            physics.set_voltage(0.0)
            physics.step(1)
        return physics.true_state()[0]

    assert settle(0.45) == pytest.approx(0.45, abs=1e-9)  # within 0.3 +- 0.2: slack, nothing pulls
    assert settle(0.15) == pytest.approx(0.15, abs=1e-9)
    assert settle(-0.4) > 0.0  # pulled towards the band
    assert settle(1.0) < 0.7
    assert physics.copy().model.tendon_stiffness[0] == 2e-3


def test_the_shipped_real_qube_is_a_calibration_the_suite_simulates():
    from qube_suite import suite
    from qube_suite.devices.qube import parameters

    shipped = calibration.load(parameters.REAL_QUBE_SERVO2)
    assert shipped.parameters["rotor_inertia"] > 5 * parameters.NOMINAL["rotor_inertia"]
    environment = suite.load("qube", "swingup", domain_kwargs={"parameters": parameters.REAL_QUBE_SERVO2})
    physics = environment.physics
    assert physics.parameters["pendulum_length"] == shipped.parameters["pendulum_length"]
    physics.set_voltage(1.0)
    assert physics.applied_voltage() == 0.0  # 1.5 periods late
    environment.close()


def test_effects_of_a_calibration_without_actuation_are_its_offsets():
    from qube_suite.calibration.calibration_file import Calibration
    from qube_suite.devices.qube import parameters

    old = Calibration(parameters=parameters.resolve(), intervals={}, metadata={}, latency_steps=1,
                      offsets={"arm_encoder_offset": 0.05, "pendulum_encoder_offset": -0.002})
    assert parameters.effects_of(old) == {"cable_rest_angle": -0.05, "pendulum_encoder_offset": -0.002}
    assert parameters.effects_of({"pendulum_mass": 0.03}) == {}


def test_one_recording_with_current_is_fitted_with_it(tmp_path):
    truth = {"motor_resistance": 9.2, "pendulum_mass": 0.026, "cable_stiffness": 1.5e-3}
    rate = 250.0
    t = np.arange(0.0, 8.0, 1.0 / rate)
    voltage = 1.5 * np.sin(2 * np.pi * (6.0 - 0.35 * t) * t)
    physics = qube.make_physics(rate, truth)
    physics.reset_to([0.0, np.pi, 0.0, 0.0])
    rows = []
    for k, volts in enumerate(voltage):
        theta, alpha = physics.true_state()[:2]
        rows.append((t[k], volts, theta, alpha, physics.motor_current()))  # of the interval before
        physics.set_voltage(float(volts))
        physics.step(qube.substeps_per_control_period(rate))
    path = write(tmp_path / "with_current.csv", rows, header=HEADER + ",motor_current")
    found = calibration.calibrate_recordings([path])
    assert found.parameters["motor_resistance"] == pytest.approx(9.2, rel=0.03)
    assert found.parameters["pendulum_mass"] == pytest.approx(0.026, rel=0.05)


def test_the_real_qube_preset_contains_the_calibrated_real_qube():
    from qube_suite import randomization
    from qube_suite.devices.qube import parameters

    shipped = calibration.load(parameters.REAL_QUBE_SERVO2)
    preset = randomization.load("real_qube")

    def inside(distribution, value, nominal=1.0):
        scale = nominal if distribution.relative else 1.0
        return distribution.low * scale <= value <= distribution.high * scale

    for name, value in shipped.parameters.items():
        nominal = parameters.NOMINAL[name]
        if name in preset.parameters:
            assert inside(preset.parameters[name], value, nominal), name
        else:
            assert value == nominal, name  # what the preset leaves alone is the calibration's too
    effects = preset.effects
    period = 1.0 / 250.0
    delay = effects["action_delay"]["seconds"]
    assert delay.low <= shipped.actuation["latency_seconds"] <= delay.high - period  # 1.5 steps: 1, 2 drawn
    assert inside(effects["dead_zone"]["voltage"], shipped.actuation["voltage_deadzone"])
    cable = parameters.effects_of(shipped)
    rest, slack = cable["cable_rest_angle"], cable.get("cable_slack", 0.0)
    pull_at_zero = shipped.parameters["cable_stiffness"] * (np.clip(0.0, rest - slack, rest + slack) - 0.0)
    gain = shipped.parameters["motor_torque_constant"] / shipped.parameters["motor_resistance"]
    assert inside(effects["voltage_offset"]["voltage"], pull_at_zero / gain)
    count = 2 * np.pi / parameters.ENCODER_COUNTS_PER_REVOLUTION
    assert abs(shipped.offsets["pendulum_encoder_offset"]) < count
    rotor = shipped.parameters["rotor_inertia"]
    # `sim2real`, which the shipped follow policies were trained with, does not; `wide` does
    nominal = parameters.NOMINAL["rotor_inertia"]
    assert not inside(randomization.load("sim2real").parameters["rotor_inertia"], rotor, nominal)
    assert inside(randomization.load("wide").parameters["rotor_inertia"], rotor, nominal)


def recorded(rows, tmp_path, name):
    return recordings.read(write(tmp_path / name, rows))


def test_a_start_error_grows_upright_and_stays_small_hanging(tmp_path):
    count = 2 * np.pi / 2048
    hanging = recorded(simulated_chirp({}, latency=0.0, deadzone=0.0, seconds=3.0), tmp_path, "hanging.csv")
    physics = qube.make_physics(250.0, {})
    physics.reset_to([0.0, 1e-4, 0.0, 0.0])
    angles = []
    for _ in range(750):  # released almost upright, 0 V: it stays near upright for the first starts
        angles.append(physics.true_state()[:2])
        physics.set_voltage(0.0)
        physics.step(qube.substeps_per_control_period(250.0))
    angles = np.array(angles)
    t = np.arange(750) / 250.0
    rows = np.column_stack([t, np.zeros(750), angles[:, 0], angles[:, 1]])
    upright = recorded(rows, tmp_path, "upright.csv")
    assert abs(angles[50, 1]) < 0.01  # the first start (0.1 s of estimation + 25 samples in)
    moved = {}
    for name, m in (("hanging", hanging), ("upright", upright)):
        base, other = (prediction.predict(m, {}, np.arange(len(m)), start_perturbation=np.array([0, a, 0, 0]))
                       for a in (0.0, count))
        moved[name] = abs(other.predicted[0, -1, 1] - base.predicted[0, -1, 1])
    assert moved["hanging"] < 2 * count
    assert moved["upright"] > 10 * count


def test_a_start_fitted_through_the_horizon_leaves_only_the_models_error(tmp_path):
    truth = {"rotor_inertia": 3e-5, "arm_damping": 5e-5}
    m = recorded(simulated_chirp(truth, latency=0.0, deadzone=0.0, seconds=3.0), tmp_path, "chirp.csv")
    samples = np.arange(len(m))
    exact = prediction.predict(m, truth, samples, fit_through_horizon=True).rms_at_horizon
    wrong_past = prediction.predict(m, {}, samples).rms_at_horizon
    wrong_best = prediction.predict(m, {}, samples, fit_through_horizon=True).rms_at_horizon
    assert exact < 1e-3
    assert 1e-3 < wrong_best < 0.5 * wrong_past
