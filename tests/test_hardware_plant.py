"""The substitute board's plant: the closed-form model's physics plus what a real Qube adds.

These tests check the board's integrator against the values `plant.py` documents for the estimated
plant (`plant="estimated"`), each named here; the default Qube-Servo 2 plant, the real Qube's, has its
effects tested in test_real_qube_substitute.py."""

import math

import numpy as np
import pytest
from hil_helpers import CLEAN_PLANT, ESTIMATED_PLANT, Rig
from reference_dynamics import FurutaPendulum

from qube_suite.angles import wrap_angle
from qube_suite.devices.qube import parameters
from qube_suite.hardware import _hil_sim
from qube_suite.hardware.plant import ESTIMATED, plant_parameters

PERIOD = 0.004

# The plant's RK4 at 0.1 ms stays within 1e-10 rad of the DOP853 reference on these chaotic
# 2 s trajectories; 1e-7 rad leaves a factor 1000 for compilers and libm while staying 30000
# times below one encoder count, so a modelling error (a missing inertia term moves the
# trajectory by 1e-2 rad, the motor's inductance alone by 1e-3 rad) fails it.
ANGLE_TOLERANCE = 1e-7
VELOCITY_TOLERANCE = 1e-6


def reference(values=None):
    p = parameters.resolve(values)
    return FurutaPendulum(p, axial_inertia=0.5 * p["pendulum_mass"] * parameters.PENDULUM_ROD_RADIUS**2)


def deviation(simulated, expected):
    angles = np.abs(np.vectorize(wrap_angle)(simulated[:, :2] - expected[:, :2])).max()
    return angles, np.abs(simulated[:, 2:] - expected[:, 2:]).max()


@pytest.mark.parametrize("state0, voltages", [
    ([0.0, 0.3, 0.0, 0.0], np.zeros(500)),                                   # falls from near upright
    ([0.2, math.pi - 1.0, 0.0, 2.0], np.zeros(500)),                          # large swing
    ([0.0, math.pi - 0.2, 0.0, 0.0],
     np.clip(np.cumsum(np.random.default_rng(7).normal(0.0, 0.8, 500)), -3.0, 3.0)),  # voltage walk
])
def test_plant_without_extras_is_the_closed_form_model(state0, voltages):
    simulated = Rig(plant=CLEAN_PLANT, state=state0).run(voltages)
    angle_error, velocity_error = deviation(simulated, reference().simulate(state0, voltages, PERIOD))
    assert angle_error < ANGLE_TOLERANCE, angle_error
    assert velocity_error < VELOCITY_TOLERANCE, velocity_error
    assert np.abs(simulated[:, 2:]).max() > 1.0                 # it really moved


def test_changed_parameters_reach_the_plant():
    changed = {"pendulum_mass": 0.03, "arm_length": 0.1, "motor_resistance": 9.0, "arm_damping": 1e-4}
    voltages = 2.0 * np.sign(np.sin(np.arange(250) * 0.1))
    state0 = [0.0, math.pi - 0.3, 0.0, 0.0]
    simulated = Rig(plant={**CLEAN_PLANT, **changed}, state=state0).run(voltages)
    assert max(deviation(simulated, reference(changed).simulate(state0, voltages, PERIOD))) < 1e-6
    assert max(deviation(simulated, reference().simulate(state0, voltages, PERIOD))) > 1e-2


def test_inductance_delays_the_current_by_its_time_constant():
    p = plant_parameters(overrides=ESTIMATED)
    rig = Rig(plant={**ESTIMATED_PLANT, "arm_friction": 0.0}, frequency=10000.0)  # a 0.1 ms substep a sample
    rig.set_voltage(2.0)
    currents = [-rig.read()[0] for _ in range(3)]               # package sign
    tau = p["motor_inductance"] / p["motor_resistance"]
    expected = [2.0 / p["motor_resistance"] * (1 - math.exp(-k * 1e-4 / tau)) for k in (1, 2, 3)]
    np.testing.assert_allclose(currents, expected, rtol=1e-2)   # back-EMF is still negligible here


def test_current_limit_holds_the_current():
    rig = Rig(plant={**ESTIMATED_PLANT, "current_limit": 0.1})
    rig.set_voltage(3.0)                                        # 3 V / 8.4 ohm = 0.36 A unlimited
    current = -rig.read()[0]
    assert current == pytest.approx(0.1, abs=1e-9)
    unlimited = Rig(plant=ESTIMATED)
    unlimited.set_voltage(3.0)
    assert -unlimited.read()[0] > 0.2


def test_amplifier_saturates_at_its_voltage_limit():
    rig = Rig(plant={**ESTIMATED_PLANT, "amplifier_voltage_limit": 4.0})
    rig.set_voltage(9.0)
    assert abs(rig.board.applied_voltage) == 4.0


def test_arm_friction_holds_the_arm_below_breakaway():
    p = plant_parameters(overrides=ESTIMATED)
    breakaway = p["arm_friction"] * p["motor_resistance"] / p["motor_torque_constant"]  # 0.2 V
    below = Rig(plant={**ESTIMATED_PLANT, "cable_stiffness": 0.0}).run([0.8 * breakaway] * 250)
    assert np.all(below[:, [0, 2]] == 0.0)                      # exactly still: no creep
    above = Rig(plant={**ESTIMATED_PLANT, "cable_stiffness": 0.0}).run([1.3 * breakaway] * 250)
    assert above[-1, 0] > 0.05 and above[-1, 2] > 0.0


def test_pendulum_friction_decays_swings_linearly_and_stops_near_hanging():
    friction = 2e-4
    plant = {**ESTIMATED_PLANT, "pendulum_friction": friction,
             "arm_friction": 1.0,                                  # the arm held still by its friction
             "bench_vibration": 0.0}                               # on a still bench: it sticks exactly
    states = Rig(plant=plant, state=[0.0, math.pi - 0.4, 0.0, 0.0]).run(np.zeros(2500))
    offset = np.vectorize(wrap_angle)(states[:, 1] - math.pi)
    size = np.abs(offset)
    peaks = [size[k] for k in range(1, len(size) - 1)
             if size[k] >= size[k - 1] and size[k] > size[k + 1] and size[k] > 0.05]
    p = plant_parameters(overrides=ESTIMATED)
    mgl = p["pendulum_mass"] * p["gravity"] * p["pendulum_length"] / 2
    decrements = -np.diff(peaks)                                # per half swing
    np.testing.assert_allclose(decrements, 2 * friction / mgl, rtol=0.1)
    assert np.all(states[-50:, 3] == 0.0)                       # stuck, exactly
    assert abs(offset[-1]) <= friction / mgl * 1.001            # inside the friction band
    frictionless = Rig(plant={**plant, "pendulum_friction": 0.0}, state=[0.0, math.pi - 0.4, 0.0, 0.0])
    swing = np.vectorize(wrap_angle)(frictionless.run(np.zeros(2500))[-250:, 1] - math.pi)
    assert np.ptp(swing) > 0.7                                  # still swinging


def test_cable_spring_pulls_the_arm_towards_the_centre():
    stiffness, theta0 = 5e-3, 0.5
    plant = {**CLEAN_PLANT, "cable_stiffness": stiffness}
    rig = Rig(plant=plant, frequency=1000.0, state=[theta0, math.pi, 0.0, 0.0])
    rig.board.write_digital(np.array([0], np.uint32), 1, np.array([0], np.int8))  # no motor, no back-EMF
    rig.read()
    p = plant_parameters(overrides=ESTIMATED)
    mp, lc, lr = p["pendulum_mass"], p["pendulum_length"] / 2, p["arm_length"]
    jp = parameters.pendulum_inertia(mp, p["pendulum_length"])
    axial = 0.5 * mp * parameters.PENDULUM_ROD_RADIUS**2
    m11 = parameters.arm_inertia(p["arm_mass"], lr) + p["rotor_inertia"] + mp * lr**2 + axial
    m12, m22 = mp * lr * lc, jp + mp * lc**2
    expected = -stiffness * theta0 * m22 / (m11 * m22 - m12**2)
    measured = 2 * (rig.board.true_state()[0] - theta0) / 1e-3**2
    assert measured == pytest.approx(expected, rel=1e-2)


def test_spring_and_friction_leave_the_arm_inside_the_friction_band():
    p = plant_parameters(overrides=ESTIMATED)
    states = Rig(plant=ESTIMATED, state=[1.5, math.pi, 0.0, 0.0]).run(np.zeros(1500))
    band = p["arm_friction"] / p["cable_stiffness"]
    assert abs(states[-1, 0]) <= band * 1.001 and states[-1, 0] < 1.5
    assert np.all(states[-20:, 2] == 0.0)


def test_disabled_amplifier_gives_no_torque():
    rig = Rig(plant={"bench_vibration": 0.0})
    rig.board.write_digital(np.array([0], np.uint32), 1, np.array([0], np.int8))
    states = rig.run([5.0] * 250)
    assert not rig.board.amplifier_enabled and rig.board.applied_voltage == 0.0
    np.testing.assert_array_equal(states[-1], [0.0, math.pi, 0.0, 0.0])
    assert rig.read()[0] == 0.0                                  # no current


def test_long_stall_disables_the_amplifier_until_it_is_re_enabled():
    rig = Rig(plant={**ESTIMATED_PLANT, "arm_friction": 1.0, "stall_time": 0.5})  # the arm cannot move
    rig.set_voltage(6.0)
    flags = [rig.read()[2] for _ in range(130)]                 # 0.52 s
    assert flags[0].tolist() == [0, 1, 0]                       # stall detected, no error yet
    assert flags[-1].tolist() == [0, 0, 1]                      # stall error, amplifier off
    assert not rig.board.amplifier_enabled and rig.board.applied_voltage == 0.0
    rig.set_voltage(4.0)                                        # below the stall voltage
    enable = np.array([0], np.uint32)
    rig.board.write_digital(enable, 1, np.array([0], np.int8))
    rig.board.write_digital(enable, 1, np.array([1], np.int8))
    assert rig.board.amplifier_enabled and rig.read()[2].tolist() == [0, 0, 0]


def test_amplifier_fault_stops_the_motor():
    rig = Rig()
    rig.set_voltage(2.0)
    rig.board.set_amplifier_fault(True)
    assert rig.read()[2][0] == 1 and rig.board.applied_voltage == 0.0
    rig.board.set_amplifier_fault(False)
    assert rig.read()[2][0] == 0 and rig.board.amplifier_enabled


def test_qube_servo_3_has_its_own_motor():
    board = _hil_sim.HIL("qube_servo3_usb", "0")
    assert board.plant["motor_resistance"] == 7.5 and board.plant["rotor_inertia"] == 1.4e-6
    assert _hil_sim.HIL("qube_servo2_usb", "0").plant["motor_resistance"] == 8.4


def test_plant_names_are_checked():
    with pytest.raises(ValueError, match="arm_friction"):
        _hil_sim.HIL(plant={"arm_frction": 1e-3})
    with pytest.raises(ValueError, match="> 0"):
        plant_parameters("qube_servo2_usb", {"current_limit": 0.0})
    assert plant_parameters("qube_servo2_usb", {"motor_inductance": 0.0})["motor_inductance"] == 0.0
