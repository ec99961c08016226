"""The inertia-disk module as the second device: its table, model, substitute plant, domains, tasks,
controllers, and that nothing outside its folder names it."""

from __future__ import annotations

import math
import pathlib
import re

import gymnasium
import mujoco
import numpy as np
import pytest

from qube_suite import devices, recording, suite
from qube_suite.calibration import experiment
from qube_suite.devices.qube_disk import calibration, controllers, parameters, simulation, substitute
from qube_suite.evaluation import evaluate
from qube_suite.hardware import _hil_sim
from qube_suite.hardware.plant import REAL_EFFECT_PARAMETERS
from qube_suite.hardware.quanser import QuanserWrapper
from qube_suite.policies import mlp

PACKAGE = pathlib.Path(suite.__file__).resolve().parent
FOLDER = PACKAGE / "devices" / "qube_disk"
TASKS = ("position", "position_sparse", "speed", "speed_sparse")


def test_discovery_finds_the_disk_with_its_domains_tasks_and_ids():
    device = devices.devices()["qube_disk"]
    assert device.domain_names == ("qube_disk", "qube_disk_hardware")
    assert set(suite.TASKS_BY_DOMAIN["qube_disk_hardware"]) == set(TASKS)
    assert ("qube_disk", "position") in suite.BENCHMARKING
    assert ("qube_disk", "speed_sparse") in suite.SPARSE
    for env_id in ("QubeSuite/DiskPosition-v0", "QubeSuite/DiskSpeedSparse-v0",
                   "QubeSuite/DiskSpeedHardware-v0"):
        assert env_id in gymnasium.registry
    assert "target_speed" in suite.task_keywords("qube_disk", "speed")
    assert "target" in suite.task_keywords("qube_disk", "position")
    assert "observation" not in suite.task_keywords("qube_disk", "position")


def test_the_model_file_carries_the_parameter_table():
    """model.xml, compiled alone, holds the nominal table that the simulation writes into it."""
    alone = mujoco.MjModel.from_xml_path(str(FOLDER / "model.xml"))
    written = mujoco.MjModel.from_xml_path(str(FOLDER / "model.xml"))
    simulation.write_parameters(written, parameters.NOMINAL)
    for field in ("body_mass", "body_inertia", "dof_armature", "dof_damping", "actuator_gainprm",
                  "actuator_biasprm"):
        np.testing.assert_allclose(getattr(alone, field), getattr(written, field), rtol=1e-6, err_msg=field)
    disk = alone.body("disk").id
    assert alone.body_inertia[disk][2] == pytest.approx(0.5 * 0.053 * 0.0248**2)


def test_the_motor_rows_are_the_qubes_own():
    from qube_suite.devices.qube import parameters as shared

    for name in parameters.MOTOR_NAMES:
        assert parameters.PARAMETERS[name] is shared.PARAMETERS[name]
    with pytest.raises(ValueError, match="valid names: motor_resistance"):
        parameters.resolve({"disc_mass": 0.05})
    with pytest.raises(ValueError, match="disk_radius"):
        parameters.resolve({"disk_radius": 0.0})


@pytest.mark.parametrize("board_type", ["qube_servo2_usb", "qube_servo3_usb"])
def test_the_substitute_plant_is_the_first_order_disk(board_type):
    """Without Coulomb friction the substitute's disk answers a voltage step as K / (tau s + 1) with the
    disk's K and tau (the board's motor), and reads a count of the pendulum encoder never."""
    overrides = {**substitute.plant_overrides(board_type), "arm_friction": 0.0}
    assert all(overrides[name] == 0.0 for name in REAL_EFFECT_PARAMETERS)  # not the real Qube-Servo 2's
    board = _hil_sim.HIL(board_type, plant=overrides)
    board.write_digital(np.array([0], dtype=np.uint32), 1, np.ones(1, dtype=np.int8))
    task = board.task_create_reader(1, np.zeros(0, np.uint32), 0, np.array([0, 1], np.uint32), 2,
                                    np.zeros(0, np.uint32), 0, np.zeros(0, np.uint32), 0)
    board.task_start(task, 0, 1000.0, -1)
    board.write_analog(np.array([0], dtype=np.uint32), 1, np.array([-2.0]))  # +2 V in theta's sign
    counts = np.zeros(2, dtype=np.int32)
    for _ in range(100):
        board.task_read(task, 1, np.zeros(0), counts, np.zeros(0, np.int8), np.zeros(0))
    theta, _, speed = board.true_state()[:3]
    board.close()
    disk = {name: overrides[name] for name in parameters.MOTOR_NAMES}
    disk["rotor_inertia"] -= parameters.NOMINAL["hub_inertia"]
    gain, tau = controllers.speed_model(disk)
    assert speed == pytest.approx(2.0 * gain * (1.0 - math.exp(-0.1 / tau)), rel=0.01)
    assert -counts[0] * 2 * math.pi / 2048 == pytest.approx(theta, abs=2 * math.pi / 2048)


@pytest.mark.parametrize("domain", ["qube_disk", "qube_disk_hardware"])
@pytest.mark.parametrize("task", TASKS)
def test_every_task_runs_on_both_domains(domain, task):
    env = suite.load(domain, task, task_kwargs={"random": 3}, environment_kwargs={"time_limit": 0.4})
    try:
        step = env.reset()
        size = 3 if task.startswith("position") else 2
        assert mlp.flat_values(step.observation, size).shape == (size,)
        rewards = []
        while not step.last():
            step = env.step(np.array([0.5]))
            rewards.append(step.reward)
        assert len(rewards) == 100 and all(0.0 <= r <= 1.0 for r in rewards)
        speed = env.physics.disk_velocity()
        assert 5.0 < speed < 15.0  # 0.5 V spins the disk up towards 0.5 K = 11.6 rad/s (less friction)
    finally:
        env.close()


@pytest.mark.parametrize("domain", ["qube_disk", "qube_disk_hardware"])
def test_voltage_effects_reach_the_disks_motor_and_restart_with_each_episode(domain):
    delayed = {"effects": {"action_delay": {"steps": 1}, "voltage_offset": {"voltage": 0.25}}}
    env = suite.load(domain, "speed", task_kwargs={"random": 3}, randomization=delayed)
    try:
        for _ in range(2):  # the second episode starts at 0 V again, not from the first's last command
            env.reset()
            applied = []
            for volts in (1.0, 2.0, 3.0):
                env.step(np.array([volts]))
                applied.append(env.physics.applied_voltage())
            assert applied == pytest.approx([0.25, 1.25, 2.25])
    finally:
        env.close()
    with pytest.raises(ValueError, match="cannot apply observation_noise"):
        suite.load(domain, "speed", randomization={"effects": {"observation_noise": {"std": [0.1] * 4}}})


def test_sparse_rewards_are_the_goal_sets():
    env = suite.load("qube_disk", "position_sparse", task_kwargs={"target": "fixed", "target_angle": 0.5})
    env.reset()
    env.physics.reset_to([0.5 + math.radians(2.9), 0.0])
    assert env.task.get_reward(env.physics) == 1.0
    env.physics.reset_to([0.5 + math.radians(3.1), 0.0])
    assert env.task.get_reward(env.physics) == 0.0


def test_the_dense_position_reward_counts_the_voltage():
    env = suite.load("qube_disk", "position", task_kwargs={"target": "fixed", "target_angle": 0.0})
    env.reset()
    env.physics.reset_to([0.0, 0.0])
    env.physics.set_voltage(0.0)
    assert env.task.get_reward(env.physics) == 1.0
    env.physics.set_voltage(3.0)
    assert env.task.get_reward(env.physics) == pytest.approx(0.9)


def test_gymnasium_checks_pass_on_the_disk_ids():
    from gymnasium.utils.env_checker import check_env

    for env_id in ("QubeSuite/DiskPosition-v0", "QubeSuite/DiskSpeed-v0"):
        env = gymnasium.make(env_id, disable_env_checker=True)
        check_env(env.unwrapped, skip_render_check=True)
        env.close()


@pytest.mark.parametrize("device", ["qube_servo2", "qube_servo3"])
def test_the_board_is_left_safe_by_every_exit(device):
    """End of episode: idle. An exception in a step: idle. Close: 0 V, amplifier off, board closed."""
    env = suite.load("qube_disk_hardware", "speed", domain_kwargs={"device": device},
                     environment_kwargs={"time_limit": 0.1})
    wrapper: QuanserWrapper = env.physics.qube
    step = env.reset()
    board = wrapper.board
    assert wrapper.device.encoder_inputs == (0,) and wrapper.device.arm_encoder is None
    while not step.last():
        step = env.step(np.array([2.0]))
    assert wrapper.is_idle and not board.amplifier_enabled and board.applied_voltage == 0.0
    env.reset()
    env.step(np.array([2.0]))
    assert board.amplifier_enabled
    board.fail_read(KeyboardInterrupt())
    with pytest.raises(KeyboardInterrupt):
        env.step(np.array([2.0]))
    assert wrapper.is_idle and not board.amplifier_enabled and board.applied_voltage == 0.0
    env.close()
    assert not wrapper.is_open and not board.amplifier_enabled and board.applied_voltage == 0.0


def test_a_reset_waits_for_the_disk_to_rest_and_counts_from_there():
    env = suite.load("qube_disk_hardware", "speed", environment_kwargs={"time_limit": 0.4})
    step = env.reset()
    while not step.last():
        step = env.step(np.array([3.0]))
    assert env.physics.qube.board.true_state()[2] > 30.0  # the disk still spins when the episode ends
    env.reset()
    assert abs(env.physics.qube.board.true_state()[2]) < 0.5
    assert env.physics.disk_angle() == 0.0 and env.physics.disk_velocity() == 0.0
    env.close()


@pytest.mark.parametrize(("controller", "task"), [("pid", "position"), ("lqr", "position"), ("pi", "speed")])
def test_classical_controllers_succeed_in_simulation(controller, task):
    result = evaluate(controller, domain="qube_disk", task=task, episodes=2)
    assert result.success_rate == 1.0, result.to_dict()


def test_the_pi_controller_holds_the_speed_on_the_substitute():
    result = evaluate("pi", domain="qube_disk_hardware", task="speed", episodes=1,
                      task_kwargs={"target_speed": -25.0})
    assert result.success_rate == 1.0, result.to_dict()


DISK_NAMES = re.compile(r"qube_disk|inertia[- ]dis[ck]|\bDisk[A-Z]|\"Disk\"|"
                        r"disk_(angle|velocity|state|mass|radius)", re.IGNORECASE)


def test_nothing_outside_the_disks_folder_names_it():
    """A device is its folder: no other module of the package names the disk."""
    naming = [str(path.relative_to(PACKAGE)) for path in sorted(PACKAGE.rglob("*"))
              if path.suffix in (".py", ".pyx", ".xml", ".yaml") and FOLDER not in path.parents
              and DISK_NAMES.search(path.read_text(encoding="utf-8"))]
    assert naming == []
    assert DISK_NAMES.search((FOLDER / "tasks.py").read_text())  # the pattern does find the disk's names


def test_make_vec_steps_single_disks_without_a_batch_simulation():
    envs = gymnasium.make_vec("QubeSuite/DiskSpeed-v0", num_envs=2)
    observations, _ = envs.reset(seed=0)
    assert observations.shape == (2, 2) and observations[0, 1] != observations[1, 1]  # own targets
    observations, *_ = envs.step(np.full((2, 1), 1.0))
    assert (observations[:, 0] > 0.0).all()
    envs.close()


POLICY = FOLDER / "policies" / "ppo_position.npz"


def test_the_command_line_runs_and_scores_the_disk(capsys):
    from qube_suite import cli

    assert cli.main(["eval", "--domain", "qube_disk_hardware", "--device", "qube_servo3", "--task", "speed",
                     "--controller", "pi", "--episodes", "1", "--quiet"]) == 0
    assert "success 100 %" in capsys.readouterr().out
    assert cli.main(["run", "--domain", "qube_disk", "--task", "position", "--policy", str(POLICY),
                     "--episodes", "1", "--quiet"]) == 0
    assert "2048 steps, time limit" in capsys.readouterr().out


@pytest.mark.parametrize("domain", ["qube_disk", "qube_disk_hardware"])
def test_the_learned_position_policy_follows_the_targets(domain):
    """PPO (250 k steps in simulation) keeps the disk near its targets on both domains."""
    result = evaluate(mlp.load(POLICY), domain=domain, task="position", episodes=2)
    assert result.mean_return > 1700.0, result.to_dict()


@pytest.mark.parametrize("domain", ["qube_disk", "qube_disk_hardware"])
def test_a_recording_of_the_disk_reads_back_with_its_own_state_columns(domain, tmp_path):
    env = suite.load(domain, "speed", task_kwargs={"random": 0}, environment_kwargs={"time_limit": 0.2})
    path = tmp_path / "disk.jsonl"
    speeds = []
    with recording.Recorder(path, env):
        timestep = env.reset()
        speeds.append(env.physics.qube_state()[1])
        while not timestep.last():
            timestep = env.step([2.0])
            speeds.append(env.physics.qube_state()[1])
    env.close()
    episode = recording.load_recording(path).episodes[0]
    assert "alpha" not in episode.data
    np.testing.assert_array_equal(episode["disk_velocity"], speeds)
    assert episode["disk_angle"][-1] > 0.0
    if domain.endswith("_hardware"):
        assert episode["raw_encoder_disk"][-1] != 0 and np.all(np.isfinite(episode["raw_current"]))


@pytest.mark.hardware
def test_calibration_recovers_a_changed_disk_inertia_on_the_substitute(tmp_path):
    # The same calibration engine as the pendulum's, with the disk's unknowns, balance and encoder.
    nominal = parameters.NOMINAL["disk_mass"]
    found = {}
    for mass in (nominal, 1.4 * nominal):
        path = calibration.record_experiment(tmp_path / f"disk_{mass:.4f}.jsonl", seconds=25.0,
                                             domain_kwargs={"parameters": {"disk_mass": mass}})
        disk = calibration.calibrate_recording(path)
        low, high = disk.intervals["disk_mass"]
        assert low <= mass <= high
        assert disk.parameters["disk_mass"] == pytest.approx(mass, rel=0.04)
        inertia = parameters.disk_inertia(mass, parameters.NOMINAL["disk_radius"])
        assert disk.identified["disk_inertia"] == pytest.approx(inertia, rel=0.04)
        assert disk.parameters["motor_resistance"] == pytest.approx(8.4, rel=0.01)
        assert disk.parameters["motor_back_emf"] == pytest.approx(0.042, rel=0.01)
        assert disk.parameters["disk_friction"] == pytest.approx(1e-3, rel=0.05)  # the substitute's shaft
        found[mass] = disk.parameters["disk_mass"]
    assert found[1.4 * nominal] / found[nominal] == pytest.approx(1.4, rel=0.015)


def test_a_pendulum_recording_is_no_disk_recording(tmp_path):
    path = experiment.run(tmp_path / "pendulum.jsonl", "qube_hardware", seconds=20.0)
    with pytest.raises(ValueError, match="no encoder column raw_encoder_disk"):
        calibration.calibrate_recording(path)


@pytest.mark.parametrize("bad", [np.array([np.nan]), np.array([1.0, 2.0]), "one volt"])
def test_a_bad_action_on_the_simulated_disk_is_a_value_error_and_moves_nothing(bad):
    env = suite.load("qube_disk", "position", task_kwargs={"random": 0})
    env.reset()
    before = env.physics.qube_state().copy()
    with pytest.raises(ValueError):
        env.step(bad)
    np.testing.assert_array_equal(env.physics.qube_state(), before)
