"""The MJCF model against an independent closed-form model of the Qube."""

import math

import mujoco
import numpy as np
import pytest
import scipy.linalg
from reference_dynamics import FurutaPendulum

from qube_suite.devices.qube import parameters
from qube_suite.devices.qube import simulation as qube
from qube_suite.devices.qube.controllers.linearization import linearize

CONTROL_PERIOD = 0.004
ENCODER_RESOLUTION = 2 * math.pi / parameters.ENCODER_COUNTS_PER_REVOLUTION

# Tolerances: a third of one encoder count (3.1e-3 rad) in angle, and 1/77 of the
# resolution of a one-sample encoder velocity at 250 Hz (0.77 rad/s). RK4 at 4 ms stays
# within 3.5e-4 rad and 4.7e-3 rad/s of a 64x finer run on chaotic 2 s trajectories
# (benchmarks/timestep_convergence.py); a modelling error such as the workbook's missing
# inertia terms shows up as 1e-2 rad or more (test_tolerance_detects_a_modelling_error).
ANGLE_TOLERANCE = 1e-3
VELOCITY_TOLERANCE = 1e-2


def reference_for(values):
    p = parameters.resolve(values)
    axial = 0.5 * p["pendulum_mass"] * parameters.PENDULUM_ROD_RADIUS**2
    return FurutaPendulum(p, axial_inertia=axial)


def simulate(physics, state0, voltages):
    nstep = qube.substeps_per_control_period(1 / CONTROL_PERIOD)
    physics.reset_to(state0)
    states = [np.asarray(state0, float)]
    for v in voltages:
        physics.set_voltage(v)
        physics.step(nstep)
        data = physics.data.ptr
        states.append(np.concatenate([data.qpos, data.qvel]))  # unwrapped, like the reference
    return np.array(states)


def assert_trajectories_agree(simulated, reference):
    angle_error = np.abs(simulated[:, :2] - reference[:, :2]).max()
    velocity_error = np.abs(simulated[:, 2:] - reference[:, 2:]).max()
    assert angle_error < ANGLE_TOLERANCE, f"angle error {angle_error:.2e} rad"
    assert velocity_error < VELOCITY_TOLERANCE, f"velocity error {velocity_error:.2e} rad/s"
    assert angle_error < ENCODER_RESOLUTION / 3


@pytest.mark.parametrize("state0", [
    [0.0, 0.3, 0.0, 0.0],            # falls from near upright, swings through hanging
    [0.2, math.pi - 1.0, 0.0, 2.0],  # large swing from below horizontal
])
def test_free_swing_matches_closed_form_model(physics, state0):
    voltages = np.zeros(500)  # 2 s
    simulated = simulate(physics, state0, voltages)
    reference = reference_for({}).simulate(state0, voltages, CONTROL_PERIOD)
    assert_trajectories_agree(simulated, reference)
    assert np.ptp(simulated[:, 1]) > 1.0  # the pendulum really swung


def test_voltage_driven_motion_matches_closed_form_model(physics):
    rng = np.random.default_rng(7)
    voltages = np.clip(np.cumsum(rng.normal(0.0, 0.8, 500)), -3.0, 3.0)
    state0 = [0.0, math.pi - 0.2, 0.0, 0.0]
    simulated = simulate(physics, state0, voltages)
    reference = reference_for({}).simulate(state0, voltages, CONTROL_PERIOD)
    assert_trajectories_agree(simulated, reference)
    assert np.ptp(simulated[:, 0]) > 0.5  # the arm really moved


def test_tolerance_detects_a_modelling_error():
    """Quanser's workbook equations (no rod inertia about the vertical, no rotor) differ measurably."""
    voltages = 3.0 * np.sign(np.sin(np.arange(250) * 0.1))
    state0 = [0.0, math.pi - 0.5, 0.0, 0.0]
    p = parameters.resolve({})
    full = FurutaPendulum(p, axial_inertia=0.0).simulate(state0, voltages, CONTROL_PERIOD)
    workbook = FurutaPendulum(p, axial_inertia=0.0, workbook=True).simulate(state0, voltages, CONTROL_PERIOD)
    assert np.abs(full[:, :2] - workbook[:, :2]).max() > 10 * ANGLE_TOLERANCE


def test_other_parameters_match_closed_form_model():
    values = {"pendulum_mass": 0.031, "pendulum_length": 0.15, "arm_length": 0.1, "arm_mass": 0.08,
              "arm_damping": 2e-4, "pendulum_damping": 5e-5, "motor_resistance": 7.5, "gravity": 9.7}
    physics = qube.make_physics(parameters=values)
    voltages = 2.0 * np.sign(np.sin(np.arange(500) * 0.05))
    state0 = [0.0, math.pi - 0.5, 0.0, 0.0]
    simulated = simulate(physics, state0, voltages)
    reference = reference_for(values).simulate(state0, voltages, CONTROL_PERIOD)
    assert_trajectories_agree(simulated, reference)


def test_motor_torque_is_the_dc_motor_law(physics):
    physics.reset_to([0.0, math.pi, 5.0, 0.0])
    physics.set_voltage(2.5)
    mujoco.mj_forward(physics.model.ptr, physics.data.ptr)
    torque = physics.data.ptr.actuator_force[0]
    assert torque == pytest.approx(0.042 * (2.5 - 0.042 * 5.0) / 8.4, rel=1e-12)
    assert physics.motor_current() == pytest.approx((2.5 - 0.042 * 5.0) / 8.4, rel=1e-12)


def test_linearisation_at_upright_matches_closed_form_model(physics):
    a_continuous, b_continuous = reference_for({}).linearized_upright()
    # Exact zero-order-hold discretisation of the closed-form linear model.
    block = np.zeros((5, 5))
    block[:4, :4], block[:4, 4:] = a_continuous, b_continuous
    discrete = scipy.linalg.expm(block * CONTROL_PERIOD)
    a_expected, b_expected = discrete[:4, :4], discrete[:4, 4:]

    a, b = linearize(physics, np.zeros(4), 0.0, nstep=1)
    np.testing.assert_allclose(a, a_expected, rtol=1e-5, atol=1e-8)
    np.testing.assert_allclose(b, b_expected, rtol=1e-5, atol=1e-10)

    # One unstable mode, the inverted pendulum's, with the closed form's growth rate.
    growth = np.log(np.abs(np.linalg.eigvals(a))).max() / CONTROL_PERIOD
    assert growth == pytest.approx(np.linalg.eigvals(a_continuous).real.max(), rel=1e-5)
    assert 10.0 < growth < 20.0


def test_chosen_timestep_converged():
    """RK4 at the chosen timestep against a run 16 times finer, over 2 s of swinging."""
    state0 = [0.0, 0.3, 0.0, 0.0]
    voltages = 3.0 * np.sign(np.sin(np.arange(500) * 0.03))
    coarse = simulate(qube.make_physics(), state0, voltages)
    fine_physics = qube.make_physics()
    fine_physics.model.opt.timestep = qube.MAX_TIMESTEP / 16
    nstep = 16 * qube.substeps_per_control_period(250)
    fine_physics.reset_to(state0)
    fine = [np.asarray(state0, float)]
    for v in voltages:
        fine_physics.set_voltage(v)
        fine_physics.step(nstep)
        fine.append(np.concatenate([fine_physics.data.qpos, fine_physics.data.qvel]))
    assert np.abs(coarse[:, :2] - np.array(fine)[:, :2]).max() < ANGLE_TOLERANCE


def test_model_uses_rk4_with_timestep_dividing_the_control_period():
    assert qube.make_physics().model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    for frequency, substeps in [(250, 1), (500, 1), (1000, 1), (50, 5), (100, 3)]:
        physics = qube.make_physics(frequency)
        assert qube.substeps_per_control_period(frequency) == substeps
        assert physics.timestep() * substeps == pytest.approx(1 / frequency, rel=1e-12)
        assert physics.timestep() <= qube.MAX_TIMESTEP + 1e-15


@pytest.mark.parametrize("frequency", [0, 5, 5000, float("nan"), "250", True])
def test_unsupported_control_frequency_is_an_error(frequency):
    with pytest.raises(ValueError, match="control_frequency"):
        qube.make_physics(frequency)
