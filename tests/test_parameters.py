"""Named physical parameters: one table, written into the compiled model in place."""

import math

import mujoco
import numpy as np
import pytest

from qube_suite.devices.qube import parameters
from qube_suite.devices.qube import simulation as qube

MODEL_FIELDS = ("body_mass", "body_inertia", "body_pos", "body_ipos", "dof_damping", "dof_armature",
                "dof_frictionloss", "jnt_stiffness", "actuator_gainprm", "actuator_biasprm",
                "geom_pos", "geom_size")


def test_xml_carries_the_nominal_table():
    as_written = mujoco.MjModel.from_xml_path(str(qube.SCENE_PATH))  # includes model.xml
    physics = qube.make_physics()
    physics.set_parameters({})
    for field in MODEL_FIELDS:
        np.testing.assert_allclose(getattr(physics.model.ptr, field), getattr(as_written, field),
                                   rtol=1e-8, atol=1e-12, err_msg=field)
    np.testing.assert_allclose(physics.model.opt.gravity, as_written.opt.gravity)
    assert as_written.opt.timestep == qube.MAX_TIMESTEP
    assert as_written.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4


def test_nominal_values_are_quanser_published_model():
    p = parameters.NOMINAL
    assert (p["motor_resistance"], p["motor_torque_constant"], p["motor_back_emf"]) == (8.4, 0.042, 0.042)
    assert (p["arm_mass"], p["arm_length"], p["pendulum_mass"], p["pendulum_length"]) == (
        0.095, 0.085, 0.024, 0.129)
    assert p["rotor_inertia"] == 4.0e-6 and p["motor_inductance"] == 1.16e-3 and p["gravity"] == 9.81
    assert parameters.ENCODER_COUNTS_PER_REVOLUTION == 2048
    assert parameters.arm_inertia(0.095, 0.085) == pytest.approx(0.095 * 0.085**2 / 12)


def test_pendulum_length_moves_centre_of_mass_inertia_and_drawing(physics):
    physics.set_parameters({"pendulum_length": 0.2})
    model = physics.model
    pendulum = physics.model.name2id("pendulum", "body")
    rod = physics.model.name2id("pendulum", "geom")
    assert model.body_ipos[pendulum][2] == pytest.approx(0.1)
    assert model.body_inertia[pendulum][0] == pytest.approx(0.024 * 0.2**2 / 12)
    assert model.geom_size[rod][1] == pytest.approx(0.1)
    assert physics.parameters["pendulum_length"] == 0.2


def test_arm_length_moves_the_pivot(physics):
    physics.set_parameters({"arm_length": 0.1})
    pendulum = physics.model.name2id("pendulum", "body")
    np.testing.assert_allclose(physics.model.body_pos[pendulum], [0.0, -0.1, 0.0])
    physics.reset_to([math.pi / 2, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(physics.data.xpos[pendulum][:2], [0.1, 0.0], atol=1e-12)


def test_set_parameters_keeps_the_state(physics):
    physics.reset_to([0.1, 2.0, 0.3, -0.4])
    physics.set_parameters({"pendulum_mass": 0.03})
    np.testing.assert_allclose(physics.qube_state(), [0.1, 2.0, 0.3, -0.4])


def test_unknown_parameter_lists_valid_names_and_changes_nothing(physics):
    before = physics.model.body_mass.copy()
    with pytest.raises(ValueError, match="pendulum_mass") as error:
        physics.set_parameters({"pendulum_mas": 0.03, "arm_mass": 0.2})
    assert "unknown parameter 'pendulum_mas'" in str(error.value)
    np.testing.assert_array_equal(physics.model.body_mass, before)


@pytest.mark.parametrize("name, value", [("pendulum_mass", -0.1), ("arm_length", 0.0),
                                         ("gravity", float("nan")), ("arm_damping", -1e-6),
                                         ("motor_resistance", float("inf"))])
def test_impossible_parameter_values_are_errors(physics, name, value):
    with pytest.raises(ValueError, match=name):
        physics.set_parameters({name: value})


def test_accuracy_options_are_off_in_the_nominal_model(physics):
    model = physics.model
    assert not model.dof_frictionloss.any() and not model.jnt_stiffness.any()
    physics.set_parameters({"arm_friction": 1e-3, "cable_stiffness": 2e-3})
    assert model.dof_frictionloss[0] == 1e-3 and model.jnt_stiffness[0] == 2e-3


def test_measurement_follows_direct_state_changes(physics):
    physics.data.qpos[:] = [0.3, -2.0]
    physics.forward()
    assert physics.arm_angle() == pytest.approx(0.3) and physics.pendulum_angle() == pytest.approx(-2.0)
    physics.data.qpos[0] = 2 * math.pi + 0.1  # angles are wrapped
    physics.forward()
    assert physics.arm_angle() == pytest.approx(0.1)


def test_sensor_and_actuator_models_change_what_is_measured_and_applied(physics):
    physics.reset_to([0.2, 1.0, 0.5, -0.5])
    physics.set_sensor_model(lambda exact: tuple(round(x, 1) + 0.01 for x in exact))
    assert physics.arm_angle() == pytest.approx(0.21) and physics.pendulum_velocity() == pytest.approx(-0.49)
    np.testing.assert_allclose(physics.true_state(), [0.2, 1.0, 0.5, -0.5])
    physics.set_actuator_model(lambda volts: 0.5 * volts)
    physics.set_voltage(2.0)
    assert physics.voltage() == 2.0 and physics.data.ctrl[0] == 1.0
    physics.set_sensor_model(None)
    physics.set_actuator_model(None)
    physics.set_voltage(2.0)
    assert physics.arm_angle() == pytest.approx(0.2) and physics.data.ctrl[0] == 2.0


def test_constraint_stage_runs_only_with_friction(physics):
    constraint = mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    assert physics.model.opt.disableflags & constraint
    physics.set_parameters({"pendulum_friction": 1e-4})
    assert not physics.model.opt.disableflags & constraint
    physics.reset_to([0.0, 0.5, 0.0, 0.0])  # friction really acts: the pendulum comes to rest
    physics.step(3000)
    assert abs(physics.pendulum_velocity()) < 1e-3


class CountingSensor:
    """A sensor model with memory: counts steps since it was last reset."""

    def __init__(self):
        self.steps_since_reset = 0

    def reset(self, exact):
        self.steps_since_reset = 0
        return exact

    def __call__(self, exact):
        self.steps_since_reset += 1
        return exact


def test_sensor_model_with_memory_restarts_when_the_state_is_set(physics):
    sensor = CountingSensor()
    physics.set_sensor_model(sensor)
    physics.step(3)
    physics.step()
    assert sensor.steps_since_reset == 2  # one call per step, whatever nstep
    physics.reset_to([0.0, 1.0, 0.0, 0.0])
    assert sensor.steps_since_reset == 0
    physics.step()
    physics.forward()
    assert sensor.steps_since_reset == 0


def test_actuator_model_restarts_with_the_physics(physics):
    calls = []

    class Recorder:
        def reset(self, volts):
            calls.append(("reset", volts))

        def __call__(self, volts):
            calls.append(("call", volts))
            return volts

    physics.set_actuator_model(Recorder())
    physics.set_voltage(1.5)
    physics.reset()
    assert calls == [("call", 1.5), ("reset", 0.0)]


def test_step_duration_model_changes_how_long_a_step_lasts(physics):
    durations = iter([0.0046, 0.0030])
    physics.set_step_duration_model(lambda nominal: next(durations))
    physics.reset_to([0.0, 0.5, 0.0, 0.0])
    physics.step()
    assert physics.time() == pytest.approx(0.0046)
    assert physics.timestep() == qube.MAX_TIMESTEP  # restored after the step
    physics.step()
    assert physics.time() == pytest.approx(0.0076)

    # The same as stepping a reference with timesteps dividing each duration (<= MAX_TIMESTEP).
    reference = qube.make_physics()
    reference.reset_to([0.0, 0.5, 0.0, 0.0])
    for duration, nstep in [(0.0046, 2), (0.0030, 1)]:
        reference.model.opt.timestep = duration / nstep
        reference.step(nstep)
    np.testing.assert_array_equal(physics.true_state(), reference.true_state())
