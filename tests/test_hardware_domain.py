"""Tasks on the hardware domain: the substitute board, reset controllers, LED, safety on exit."""

import math

import gymnasium
import numpy as np
import pytest
from hil_helpers import fake_quanser_sdk

import qube_suite  # noqa: F401  (registers the Gymnasium ids)
from qube_suite import baselines, suite
from qube_suite.angles import wrap_angle
from qube_suite.devices.qube.controllers.model import RigidBodyModel
from qube_suite.devices.qube.hardware import RESET_LED, ResetError
from qube_suite.hardware import conventions
from qube_suite.wrappers import HARDWARE_GYMNASIUM_IDS

SHORT = {"time_limit": 0.4}


def load(task, **kwargs):
    return suite.load("qube_hardware", task, task_kwargs={"random": 0},
                      environment_kwargs=kwargs.pop("environment_kwargs", SHORT), **kwargs)


@pytest.mark.parametrize("task", suite.TASKS_BY_DOMAIN["qube_hardware"])
def test_every_task_runs_an_episode_on_hardware(task):
    with load(task) as env:
        timestep = env.reset()
        steps = 0
        while not timestep.last():
            timestep = env.step(np.zeros(1))
            steps += 1
        assert steps == 100 or timestep.discount == 0.0
        board = env.physics.qube.board
        assert board.applied_voltage == 0.0 and not board.amplifier_enabled  # idle between episodes
        assert env.reset().first()


def test_balance_reset_ends_upright_and_the_episode_starts_from_there():
    with load("balance") as env:
        env.reset()
        theta, alpha, _, _ = env.physics.qube.board.true_state()
        assert abs(alpha) < math.radians(6) and abs(theta) < math.radians(20)
        assert env.physics.time() == 0.0


@pytest.mark.parametrize("task", ["swingup", "rotor"])
def test_hanging_starts_are_at_rest(task):
    with load(task) as env:
        observation = env.reset().observation["state"]
        theta, alpha, dtheta, dalpha = env.physics.qube.board.true_state()
        assert math.pi - abs(alpha) < math.radians(4) and abs(dalpha) < 0.5 and abs(theta) < math.radians(12)
        assert abs(wrap_angle(observation[1] - alpha)) < 0.01


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_dampen_starts_swinging_with_the_energy_of_the_drawn_start(seed):
    model = RigidBodyModel.from_parameters()
    hanging = -model.swing_up_energy
    with suite.load("qube_hardware", "dampen", task_kwargs={"random": seed}, environment_kwargs=SHORT) as env:
        env.reset()
        start = env.task.initial_state(np.random.RandomState(seed))  # the draw the reset aimed at
        theta, alpha, dtheta, dalpha = env.physics.qube.board.true_state()
        wanted = model.energy(start[1], start[2], start[3]) - hanging
        reached = model.energy(alpha, dtheta, dalpha) - hanging
        if math.pi - abs(start[1]) <= math.radians(30):
            assert reached < 0.1 * model.swing_up_energy  # near hanging: settled
        else:
            assert reached == pytest.approx(wanted, rel=0.25)


def test_observed_angles_are_encoder_angles():
    with load("swingup", environment_kwargs={"time_limit": 1.0}) as env:
        timestep = env.reset()
        for _ in range(50):
            timestep = env.step(np.array([2.0]))
            theta, alpha = timestep.observation["state"][:2]
            counts = theta / conventions.RADIANS_PER_COUNT
            assert counts == pytest.approx(round(counts), abs=1e-6)
            pendulum_counts = (alpha - math.pi) / conventions.RADIANS_PER_COUNT
            assert pendulum_counts == pytest.approx(round(pendulum_counts), abs=1e-6)


def test_led_is_yellow_during_resets_then_follows_the_reward():
    with load("balance") as env:
        env.reset()
        assert env.physics.qube.board.led == pytest.approx(RESET_LED)
        timestep = env.step(np.zeros(1))
        env.step(np.zeros(1))
        red, green, blue = env.physics.qube.board.led
        assert green == pytest.approx(timestep.reward, abs=0.05) and green > 0.9 and blue == 0.0


def test_an_exception_mid_episode_leaves_the_motor_off():
    env = load("swingup", environment_kwargs={"time_limit": 2.0})
    with pytest.raises(RuntimeError, match="boom"), env:
        env.reset()
        env.step(np.array([3.0]))
        assert env.physics.qube.board.applied_voltage != 0.0
        raise RuntimeError("boom")
    board = env.physics.qube.board
    assert board.applied_voltage == 0.0 and not board.amplifier_enabled and not env.physics.qube.is_open


def test_nothing_is_opened_before_the_first_reset():
    env = load("balance")
    assert env.physics.qube.board is None
    env.close()


def test_an_unreachable_start_is_a_reset_error_and_stops_the_motor():
    env = load("balance", domain_kwargs={"reset_voltage_limit": 0.05, "reset_timeout": 1.0})
    with pytest.raises(ResetError, match="swing up"):
        env.reset()
    assert env.physics.qube.board.applied_voltage == 0.0
    env.close()
    assert not env.physics.qube.board.amplifier_enabled


def test_real_board_path_with_the_substitute_injected(monkeypatch):
    log = fake_quanser_sdk(monkeypatch)
    with load("swingup", domain_kwargs={"board": "qube_servo2_usb"}) as env:
        env.reset()
        assert env.step(np.zeros(1)).mid()
        assert isinstance(env.physics.qube.board, log["class"])
    assert log["opened"] == [("qube_servo2_usb", "0")]


def test_gymnasium_hardware_ids():
    assert len(HARDWARE_GYMNASIUM_IDS) == 11 + 4 + 6  # the pendulum's, the disk's and the Aero 2's
    spec = gymnasium.spec("QubeSuite/BalanceHardware-v0")
    assert spec.nondeterministic
    env = gymnasium.make("QubeSuite/BalanceHardware-v0", time_limit=0.2)
    observation, info = env.reset(seed=0)
    assert observation.shape == (4,) and abs(observation[1]) < 0.1
    _, _, terminated, truncated, _ = env.step(np.zeros(1, np.float32))
    assert not terminated and not truncated
    env.close()
    assert not env.unwrapped.physics.qube.is_open


def test_invalid_domain_options_are_errors():
    with pytest.raises(ValueError, match="reset_voltage_limit"):
        load("balance", domain_kwargs={"reset_voltage_limit": 20.0})
    with pytest.raises(ValueError, match="board"):
        load("balance", domain_kwargs={"board": "qube_servo9"})


def test_randomization_effects_apply_on_hardware():
    noise = {"effects": {"observation_noise": {"std": [0.05, 0.05, 0.0, 0.0]}}}
    with load("balance", randomization=noise, environment_kwargs={"time_limit": 1.0}) as env:
        env.reset()
        errors = []
        for _ in range(40):
            observed = env.step(np.zeros(1)).observation["state"]
            errors.append(observed[:2] - env.physics.qube.board.true_state()[:2])
        assert np.std(errors, axis=0) == pytest.approx([0.05, 0.05], rel=0.35)
    delayed = {"effects": {"action_delay": {"steps": 2}}}
    with load("swingup", randomization=delayed) as env:
        env.reset()
        board = env.physics.qube.board
        written = []
        for volts in (1.0, 2.0, 0.5, 0.5):
            env.step(np.array([volts]))
            written.append(-board.written_voltage)  # board sign: see hardware.conventions
        assert written == pytest.approx([0.0, 0.0, 1.0, 2.0])


@pytest.mark.parametrize("config, message", [
    ({"parameters": {"pendulum_mass": {"distribution": "uniform", "low": 0.9, "high": 1.1}}}, "parameters"),
    ({"effects": {"control_jitter": True}}, "control_jitter"),
])
def test_randomizing_the_plant_on_hardware_is_a_clear_error(config, message):
    with pytest.raises(ValueError, match=message):
        load("balance", randomization=config)


def test_a_pendulum_left_at_rest_upright_is_brought_down_for_a_hanging_start():
    # Coulomb friction in the plant's pendulum bearing holds it exactly upright: the reset must tip it.
    with load("swingup", environment_kwargs={"time_limit": 4.0}) as env:
        controller = baselines.for_environment("swingup", env)
        timestep = env.reset()
        while not timestep.last():
            timestep = env.step(controller(timestep.observation))
        board = env.physics.qube.board
        assert abs(board.true_state()[1]) < math.radians(10)         # ended balanced ...
        board.set_true_state([0.0, 0.0, 0.0, 0.0])   # ... and now at rest upright, arm centred
        env.reset()
        theta, alpha, dtheta, dalpha = env.physics.qube.board.true_state()
        assert math.pi - abs(alpha) < math.radians(4) and abs(dalpha) < 0.5
