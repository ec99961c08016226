"""The substitute's plant of a real Qube: made from its calibration file, and its effects act on the board."""

import dataclasses
import math
import os
import shutil

import numpy as np
import pytest
import yaml
from hil_helpers import CLEAN_PLANT, Rig

from qube_suite import suite
from qube_suite.devices.qube import parameters
from qube_suite.hardware import _hil_sim, plant, quanser
from qube_suite.hardware.plant import (
    DEFAULT_PLANTS,
    ESTIMATED,
    REAL_EFFECT_PARAMETERS,
    named_plant,
    plant_parameters,
)

REAL = "real_qube_servo2"
STILL_CABLE = {"cable_rest_spread": 0.0, "cable_stiffness_spread": 0.0}
"""The real Qube's plant with the cable as calibrated, not drawn anew per session."""


def arm_acceleration_from_rest(plant_values, theta0):
    """The arm's acceleration (rad/s^2) from rest at `theta0`, pendulum hanging, amplifier off: from its
    move over the first 1 ms (x = a t^2 / 2)."""
    rig = Rig(plant=plant_values, frequency=1000.0, state=[theta0, math.pi, 0.0, 0.0])
    rig.board.write_digital(np.array([0], np.uint32), 1, np.array([0], np.int8))  # no motor, no back-EMF
    rig.read()
    return 2 * (rig.board.true_state()[0] - theta0) / 1e-3**2


def arm_axis_inertia(values):
    """Effective arm inertia with the pendulum hanging (kg m^2): det(M) / M22."""
    mp, lc, lr = values["pendulum_mass"], values["pendulum_length"] / 2, values["arm_length"]
    jp = parameters.pendulum_inertia(mp, values["pendulum_length"])
    axial = 0.5 * mp * parameters.PENDULUM_ROD_RADIUS**2
    m11 = parameters.arm_inertia(values["arm_mass"], lr) + values["rotor_inertia"] + mp * lr**2 + axial
    m12, m22 = mp * lr * lc, jp + mp * lc**2
    return (m11 * m22 - m12**2) / m22


def test_the_real_qube_plant_is_its_calibration_file():
    with open(parameters.REAL_QUBE_SERVO2, encoding="utf-8") as file:
        calibrated = yaml.safe_load(file)
    values = _hil_sim.HIL("qube_servo2_usb", plant=REAL).plant
    for name, value in calibrated["parameters"].items():
        assert values[name] == value, name
    assert values["latency"] == calibrated["actuation"]["latency_seconds"]
    assert values["voltage_deadzone"] == calibrated["actuation"]["voltage_deadzone"]
    assert values["cable_rest_angle"] == -calibrated["offsets"]["arm_encoder_offset"]
    assert values["cable_slack"] == calibrated["offsets"]["cable_slack"]
    estimated = plant_parameters("qube_servo2_usb", ESTIMATED)
    assert values["rotor_inertia"] > 5 * estimated["rotor_inertia"]        # not the estimated plant
    assert estimated["latency"] == estimated["voltage_deadzone"] == estimated["cable_slack"] == 0.0


def test_a_qube_servo2_substitute_integrates_the_real_qube_unless_told_otherwise():
    real = named_plant(REAL)
    assert DEFAULT_PLANTS == {"qube_servo2_usb": REAL, "qube_servo3_usb": ESTIMATED}
    assert _hil_sim.HIL("qube_servo2_usb").plant == real == plant_parameters()
    with suite.load("qube_hardware", "balance", environment_kwargs={"time_limit": 0.1}) as env:
        env.reset()
        assert env.physics.qube.board.plant == real
    estimated = _hil_sim.HIL("qube_servo2_usb", plant=ESTIMATED).plant
    assert estimated["rotor_inertia"] == parameters.NOMINAL["rotor_inertia"] < real["rotor_inertia"] / 5
    assert all(estimated[name] == 0.0 for name in REAL_EFFECT_PARAMETERS)
    # a mapping changes the default plant; a whole named plant with changes, another
    assert _hil_sim.HIL("qube_servo2_usb", plant={"latency": 0.0}).plant == {**real, "latency": 0.0}
    changed = _hil_sim.HIL("qube_servo2_usb", plant={**named_plant(ESTIMATED), "arm_friction": 2e-3}).plant
    assert changed == {**estimated, "arm_friction": 2e-3}


def test_a_qube_servo3_substitute_keeps_the_estimated_plant():
    """No recordings of a real Qube-Servo 3 exist: its substitute integrates the estimated plant."""
    default = _hil_sim.HIL("qube_servo3_usb").plant
    assert default == named_plant(ESTIMATED, "qube_servo3_usb")
    assert default["motor_resistance"] == 7.5 and default["latency"] == 0.0


def test_a_new_calibration_flows_into_the_plant(tmp_path, monkeypatch):
    copy = tmp_path / "recalibrated.yaml"
    shutil.copy(parameters.REAL_QUBE_SERVO2, copy)
    content = yaml.safe_load(copy.read_text())
    content["parameters"]["rotor_inertia"] = 2.0e-5
    content["actuation"]["latency_seconds"] = 0.008
    content["offsets"]["cable_slack"] = 0.3
    copy.write_text(yaml.safe_dump(content))
    recalibrated = dataclasses.replace(plant.PLANTS[REAL], calibration=str(copy))
    monkeypatch.setattr(plant, "PLANTS", {REAL: recalibrated})
    values = _hil_sim.HIL("qube_servo2_usb", plant=REAL).plant
    assert values["rotor_inertia"] == 2.0e-5 and values["latency"] == 0.008 and values["cable_slack"] == 0.3
    content["parameters"]["rotor_inertia"] = 3.0e-5                   # the same file changed in place
    copy.write_text(yaml.safe_dump(content))
    os.utime(copy, ns=(copy.stat().st_atime_ns, copy.stat().st_mtime_ns + 1_000_000))
    assert _hil_sim.HIL("qube_servo2_usb", plant=REAL).plant["rotor_inertia"] == 3.0e-5


def test_bad_plant_names_get_a_clear_error():
    listed = "unknown plant 'real_qube'; named plants: estimated, real_qube_servo2 "
    with pytest.raises(ValueError, match=listed):
        _hil_sim.HIL(plant="real_qube")
    with pytest.raises(ValueError, match="unknown plant"):
        quanser.QubeServo2(plant="real_qube")
    with pytest.raises(ValueError, match="qube_servo2_usb's, not a qube_servo3_usb's"):
        quanser.QubeServo3(plant=REAL)
    with pytest.raises(ValueError, match="named plant"):
        suite.load("qube_hardware", "balance", domain_kwargs={"plant": 3})


def test_the_hardware_domain_takes_the_named_plant():
    env = suite.load("qube_hardware", "balance", domain_kwargs={"plant": REAL})
    try:
        env.reset()
        assert env.physics.qube.board.plant == plant_parameters("qube_servo2_usb", REAL)
    finally:
        env.close()


def test_a_voltage_inside_the_dead_zone_does_not_move_the_arm():
    deadzone = 0.5
    held = Rig(plant={**CLEAN_PLANT, "voltage_deadzone": deadzone})
    states = held.run([0.9 * deadzone] * 100)
    np.testing.assert_allclose(states[-1], [0.0, math.pi, 0.0, 0.0], rtol=0, atol=1e-12)  # no friction
    assert abs(held.read()[0]) < 1e-12                                        # and no current
    beyond = Rig(plant={**CLEAN_PLANT, "voltage_deadzone": deadzone}).run([1.5] * 100)
    reduced = Rig(plant=CLEAN_PLANT).run([1.5 - deadzone] * 100)                # acts as 1 V
    np.testing.assert_allclose(beyond, reduced, rtol=0, atol=1e-12)
    assert abs(beyond[-1, 0]) > 0.1


def test_a_written_voltage_acts_after_the_latency_and_disabling_stops_at_once():
    voltages = np.r_[np.zeros(5), 1.5 * np.ones(60), -1.0 * np.ones(40)]
    late = Rig(plant={**CLEAN_PLANT, "latency": 0.006}, frequency=1000.0).run(voltages)
    prompt = Rig(plant=CLEAN_PLANT, frequency=1000.0).run(voltages)
    np.testing.assert_allclose(late[6:], prompt[:-6], rtol=0, atol=1e-12)   # 6 samples of 1 ms later
    assert np.abs(late[:12] - prompt[0]).max() < 1e-12 < np.abs(prompt[6:12, 0]).max()
    rig = Rig(plant={"latency": 0.05})
    rig.set_voltage(2.0)
    rig.read()
    assert rig.board.applied_voltage == 0.0                                  # not yet applied
    rig.board.write_digital(np.array([0], np.uint32), 1, np.array([0], np.int8))
    for _ in range(20):
        rig.read()
        assert rig.board.applied_voltage == 0.0 and rig.read()[0] == 0.0      # disabled: nothing, ever


def test_the_cable_pulls_the_arm_to_its_calibrated_band():
    real = named_plant(REAL)
    rest, slack, stiffness = real["cable_rest_angle"], real["cable_slack"], real["cable_stiffness"]
    cable = {**CLEAN_PLANT, **{k: real[k] for k in ("cable_rest_angle", "cable_slack", "cable_stiffness",
                                                    "rotor_inertia")}}
    inertia = arm_axis_inertia(plant_parameters("qube_servo2_usb", cable))
    for stretch in (0.3, -0.3):
        theta0 = rest + math.copysign(slack, stretch) + stretch
        expected = -stiffness * stretch / inertia
        assert arm_acceleration_from_rest(cable, theta0) == pytest.approx(expected, rel=1e-2)
    assert abs(arm_acceleration_from_rest(cable, rest + 0.9 * slack)) < 1e-6   # slack: no pull
    assert rest < 0.0 < rest + slack                                            # the start (0) is inside
    settled = Rig(plant={**real, **STILL_CABLE}, state=[1.2, math.pi, 0.0, 0.0])
    settled.board.write_digital(np.array([0], np.uint32), 1, np.array([0], np.int8))
    final = settled.run(np.zeros(1500))[-1, 0]
    holds = real["arm_breakaway"] / stiffness                                  # friction holds beyond it
    assert rest - slack - holds <= final <= rest + slack + holds and final < 1.0


def test_a_stuck_arm_holds_up_to_its_breakaway_torque_and_slides_above_coulomb():
    p = plant_parameters()
    friction = 5e-4
    volts = lambda torque: torque * p["motor_resistance"] / p["motor_torque_constant"]  # noqa: E731
    plant_values = {"cable_stiffness": 0.0, "bench_vibration": 0.0, "arm_friction": friction,
                    "arm_breakaway": 2 * friction}
    stuck = Rig(plant=plant_values).run([volts(1.5 * friction)] * 250)
    assert np.all(stuck[:, [0, 2]] == 0.0)                                    # between Coulomb and breakaway
    broke = Rig(plant=plant_values).run([volts(2.5 * friction)] * 250)
    assert broke[-1, 0] > 0.05
    sliding = Rig(plant=plant_values, state=[0.0, math.pi, 1.0, 0.0]).run([volts(1.5 * friction)] * 250)
    assert sliding[-1, 0] > 0.5 and sliding[-1, 2] > 0.5                      # once moving, Coulomb's
    coulomb_only = Rig(plant={**plant_values, "arm_breakaway": 0.0}).run([volts(1.5 * friction)] * 250)
    assert coulomb_only[-1, 0] > 0.05


def test_each_session_lays_the_cable_anew_from_the_seed():
    real = named_plant(REAL)
    cables = {seed: _hil_sim.HIL("qube_servo2_usb", plant=REAL, seed=seed).cable for seed in range(8)}
    assert len(set(cables.values())) == 8                                    # every session its own cable
    assert _hil_sim.HIL("qube_servo2_usb", plant=REAL, seed=3).cable == cables[3]
    rests = np.array([rest for rest, _ in cables.values()])
    assert np.all(np.abs(rests - real["cable_rest_angle"]) < 4 * real["cable_rest_spread"])
    board = _hil_sim.HIL("qube_servo2_usb", plant=REAL, seed=0)
    board.seed(5)
    assert board.cable == cables[5]
    still = _hil_sim.HIL("qube_servo2_usb", plant={**real, **STILL_CABLE}, seed=5)
    assert still.cable == (real["cable_rest_angle"], real["cable_stiffness"])
