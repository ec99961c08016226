"""The Aero 2's simulated side: its table, model, physics against the table's own equations, tasks,
rewards, the LQR, bad input, and that nothing outside its folder names it. The hardware domain is
tested in its own files."""

from __future__ import annotations

import math
import pathlib
import re

import gymnasium
import mujoco
import numpy as np
import pytest
import scipy.linalg

from qube_suite import devices, suite
from qube_suite.devices.aero2 import controllers, parameters, simulation
from qube_suite.devices.aero2 import tasks as aero_tasks
from qube_suite.evaluation import evaluate

PACKAGE = pathlib.Path(suite.__file__).resolve().parent
FOLDER = PACKAGE / "devices" / "aero2"
TASKS = ("pitch", "pitch_sparse", "hover", "hover_sparse", "track", "track_sparse")
NOMINAL = parameters.resolve()


def _physics(configuration: str = "2dof", state=(0.0,) * 6) -> simulation.Physics:
    physics = simulation.make_physics(250.0, configuration=configuration)
    with physics.reset_context():
        physics.reset_to(state)
    return physics


def _hold(physics: simulation.Physics, volts, seconds: float) -> np.ndarray:
    """The states after each 4 ms step of holding `volts` for `seconds`."""
    physics.set_voltage(np.array(volts, dtype=float))
    states = []
    for _ in range(round(seconds * 250)):
        physics.step(1)
        states.append(physics.qube_state())
    return np.array(states)


def test_discovery_finds_the_aero_with_its_tasks_and_ids():
    device = devices.devices()["aero2"]
    assert device.domain_names == ("aero2", "aero2_hardware")
    assert set(suite.TASKS_BY_DOMAIN["aero2"]) == set(TASKS)
    assert ("aero2", "hover") in suite.BENCHMARKING and ("aero2", "track_sparse") in suite.SPARSE
    for env_id in ("QubeSuite/Aero2Hover-v0", "QubeSuite/Aero2PitchSparse-v0", "QubeSuite/Aero2Track-v0"):
        assert env_id in gymnasium.registry
    assert "yaw_target_hold_time" in suite.task_keywords("aero2", "track")
    assert "target_yaw" in suite.task_keywords("aero2", "hover")


def test_the_model_file_carries_the_parameter_table():
    """model.xml, compiled alone, holds the nominal table that the simulation writes into it."""
    alone = mujoco.MjModel.from_xml_path(str(FOLDER / "model.xml"))
    written = mujoco.MjModel.from_xml_path(str(FOLDER / "model.xml"))
    simulation.write_parameters(written, parameters.NOMINAL, "2dof")
    for field in ("body_mass", "body_pos", "body_ipos", "body_inertia", "dof_damping", "actuator_gainprm",
                  "actuator_biasprm", "opt_gravity"):
        left = alone.opt.gravity if field == "opt_gravity" else getattr(alone, field)
        right = written.opt.gravity if field == "opt_gravity" else getattr(written, field)
        np.testing.assert_allclose(left, right, rtol=1e-9, atol=1e-12, err_msg=field)


@pytest.mark.parametrize("configuration", ["2dof", "pitch_only"])
def test_the_body_has_the_tables_mass_centre_and_inertias(configuration):
    physics = _physics(configuration)
    model, data = physics.model.ptr, physics.data.ptr
    beam = model.body("beam").id
    assert model.body_subtreemass[beam] == pytest.approx(NOMINAL["body_mass"])
    pivot = data.xpos[beam]
    assert pivot[2] - data.subtree_com[beam][2] == pytest.approx(NOMINAL["center_of_mass_offset"], rel=1e-9)
    mass = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, mass)
    pitch = model.jnt_dofadr[model.joint("pitch").id]
    assert mass[pitch, pitch] == pytest.approx(NOMINAL["pitch_inertia"], rel=1e-9)
    if configuration == "2dof":
        yaw = model.jnt_dofadr[model.joint("yaw").id]
        assert mass[yaw, yaw] == pytest.approx(NOMINAL["yaw_inertia"], rel=1e-9)
    else:
        assert "yaw" not in [model.joint(i).name for i in range(model.njnt)]


def test_a_rotor_follows_the_tables_first_order_lag():
    """After a 10 V step the rotor reaches 1 - 1/e of K V in one time constant and K V at rest, with K and
    tau from the table (17.2 rad/s/V, 0.15 s)."""
    gain, tau = parameters.rotor_speed_gain(NOMINAL), parameters.rotor_time_constant(NOMINAL)
    states = _hold(_physics("pitch_only"), [10.0, 0.0], 2.0)
    at_tau = states[round(tau * 250) - 1, 4]
    assert at_tau == pytest.approx(10.0 * gain * (1.0 - math.exp(-1.0)), rel=0.01)
    assert states[-1, 4] == pytest.approx(10.0 * gain, rel=1e-3)
    assert states[-1, 5] == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("volts, sign", [([4.0, 0.0], 1.0), ([0.0, 4.0], -1.0)])
def test_the_pitch_settles_where_thrust_balances_gravity(volts, sign):
    """1-DOF: Dt kf w = Mb g Dm sin(theta) at rest, front thrust raising the front (pitch up), back
    thrust the back (pitch down)."""
    states = _hold(_physics("pitch_only"), volts, 40.0)
    speed = parameters.rotor_speed_gain(NOMINAL) * 4.0
    expected = math.asin(NOMINAL["thrust_arm"] * NOMINAL["thrust_constant"] * speed
                         / parameters.gravity_stiffness(NOMINAL))
    assert states[-1, 0] == pytest.approx(sign * expected, rel=2e-3)


def test_the_2dof_response_to_small_voltages_is_the_linear_models():
    """The MJCF and the linear model derived from the table by hand (`controllers.linear_model`: signs,
    couplings, reaction torques) agree for small voltages over 3 s."""
    a, b = controllers.linear_model(NOMINAL, "2dof")
    volts = np.array([0.6, -0.4])
    states = _hold(_physics("2dof"), volts, 3.0)
    block = np.zeros((8, 8))
    block[:6, :6], block[:6, 6:] = a, b
    for seconds in (0.5, 1.0, 3.0):
        predicted = (scipy.linalg.expm(block * seconds) @ np.concatenate([np.zeros(6), volts]))[:6]
        measured = states[round(seconds * 250) - 1]
        np.testing.assert_allclose(measured, predicted, rtol=0.02, atol=2e-4, err_msg=f"t = {seconds} s")
    assert states[-1, 0] > 0.01 and states[-1, 1] < -0.01  # front thrust lifts; both motors turn yaw back


def test_the_back_thruster_turns_the_yaw_and_its_motor_lifts_the_pitch():
    states = _hold(_physics("2dof"), [0.0, 5.0], 1.0)
    assert states[-1, 1] > 0.02 and states[-1, 3] > 0.0  # yaw counter-clockwise seen from above
    assert states[-1, 0] > 0.0                            # the back motor's reaction torque on the pitch


def test_the_beam_stops_at_its_mechanical_limit():
    states = _hold(_physics("pitch_only"), [24.0, -24.0], 3.0)
    assert math.radians(55.0) < states[:, 0].max() < math.radians(61.0)


def _env(task: str, configuration: str = "2dof", **task_kwargs):
    return suite.load("aero2", task, task_kwargs={"random": 0, **task_kwargs},
                      domain_kwargs={"configuration": configuration})


def test_dense_rewards_at_chosen_states():
    env = _env("track", pitch_target="fixed", pitch_target_angle=0.2, yaw_target="fixed",
               yaw_target_angle=-0.5)
    env.reset()
    env.physics.reset_to([0.2 + math.radians(6.0), -0.5 - math.radians(18.0), 0.0, 0.0, 50.0, 0.0])
    env.physics.set_voltage(np.array([9.0, -9.0]))
    assert env.task.get_reward(env.physics) == pytest.approx(1.0 - 0.2 - 0.2 - 0.1 * 0.25)
    env.physics.reset_to([0.2, -0.5 + math.radians(100.0), 0.0, 0.0, 0.0, 0.0])
    assert env.task.get_reward(env.physics) == 0.0  # never below 0
    pitch = _env("pitch", "pitch_only", target="fixed", target_angle=-0.3)
    pitch.reset()
    pitch.physics.reset_to([-0.3 - math.radians(15.0), 0.0, 0.0, 0.0, 0.0, 0.0])
    assert pitch.task.get_reward(pitch.physics) == pytest.approx(0.5)


@pytest.mark.parametrize("task, at_goal, off_goal", [
    ("pitch_sparse", [0.4 + math.radians(2.9), 0.0], [0.4 - math.radians(3.1), 0.0]),
    ("hover_sparse", [math.radians(2.9), 0.3 - math.radians(4.9)], [0.0, 0.3 + math.radians(5.1)]),
])
def test_sparse_rewards_are_the_goal_sets(task, at_goal, off_goal):
    configuration = "pitch_only" if task.startswith("pitch") else "2dof"
    kwargs = {"target": "fixed", "target_angle": 0.4} if task.startswith("pitch") else {"target_yaw": 0.3}
    env = _env(task, configuration, **kwargs)
    env.reset()
    for pose, reward in ((at_goal, 1.0), (off_goal, 0.0)):
        yaw = pose[1] if configuration == "2dof" else 0.0
        env.physics.reset_to([pose[0], yaw, 0.0, 0.0, 0.0, 0.0])
        assert env.task.get_reward(env.physics) == reward


def test_episodes_end_near_the_stops_and_a_turn_away():
    env = _env("hover")
    env.reset()
    env.physics.reset_to([math.radians(56.0), 0.0, 0.0, 0.0, 0.0, 0.0])
    assert not env.task.in_safe_set(env.physics)
    env.physics.reset_to([0.0, 2.0 * math.pi + 0.1, 0.0, 0.0, 0.0, 0.0])
    assert not env.task.in_safe_set(env.physics)
    env.physics.reset_to([math.radians(54.0), 6.0, 0.0, 0.0, 0.0, 0.0])
    assert env.task.in_safe_set(env.physics)


@pytest.mark.parametrize("task, configuration", [
    ("pitch", "pitch_only"), ("pitch", "2dof"), ("hover", "2dof"), ("track", "2dof"),
    ("pitch_sparse", "pitch_only"), ("hover_sparse", "2dof"), ("track_sparse", "2dof")])
def test_the_lqr_succeeds_on_every_task(task, configuration):
    result = evaluate("lqr", "aero2", task, episodes=2, seed=10,
                      domain_kwargs={"configuration": configuration})
    assert result.successes == [True, True], result.to_dict()


def test_an_idle_aero_does_not_succeed():
    """The goal sets are not met by doing nothing: success means control."""
    result = evaluate(lambda observation: np.zeros(2), "aero2", "hover", episodes=2, seed=10)
    assert result.successes == [False, False]


POLICY = FOLDER / "policies" / "ppo_hover.npz"


def test_the_learned_hover_policy_holds_the_yaw_target_at_the_frequency_it_learnt():
    """PPO (560 k steps at 50 Hz) gives two voltages and hovers where idling does not."""
    from qube_suite.policies import mlp

    policy = mlp.load(POLICY)
    assert policy.action_size == 2
    assert policy.meta["training"]["environment_kwargs"]["control_frequency"] == 50.0
    result = evaluate(policy, "aero2", "hover", episodes=2, seed=10,
                      environment_kwargs={"control_frequency": 50.0})
    assert result.successes == [True, True], result.to_dict()


def test_the_learned_pitch_policy_follows_its_steps_on_the_1dof_aero():
    """PPO (480 k steps at 50 Hz, yaw locked) follows the pitch schedule."""
    from qube_suite.policies import mlp

    policy = mlp.load(FOLDER / "policies" / "ppo_pitch.npz")
    assert policy.meta["training"]["domain_kwargs"] == {"configuration": "pitch_only"}
    result = evaluate(policy, "aero2", "pitch", episodes=2, seed=10,
                      domain_kwargs={"configuration": "pitch_only"},
                      environment_kwargs={"control_frequency": 50.0})
    assert result.successes == [True, True], result.to_dict()


def test_bad_input_is_refused_with_a_clear_error():
    env = _env("hover")
    env.reset()
    for action, message in ((np.array([1.0]), r"Action dimension mismatch: an action has shape \(2,\)"),
                            (np.zeros((2, 2)), "Action dimension mismatch"),
                            (np.array([np.nan, 0.0]), "finite"),
                            (np.array(["a", "b"]), "numbers")):
        with pytest.raises(ValueError, match=message):
            env.step(action)
    with pytest.raises(ValueError, match="unknown configuration 'three_dof'; valid configurations: 2dof, "
                                         "pitch_only"):
        suite.load("aero2", "hover", domain_kwargs={"configuration": "three_dof"})
    with pytest.raises(ValueError, match="needs the Aero in its 2-DOF configuration"):
        _env("hover", "pitch_only").reset()
    with pytest.raises(ValueError, match="yaw is locked"):
        _physics("pitch_only", (0.0, 0.3, 0.0, 0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="an Aero state is 6 finite numbers"):
        _physics("2dof", (0.0, 0.0))
    with pytest.raises(ValueError, match=r"voltage_limit must be in \(0, 24\] V"):
        _env("hover", voltage_limit=30.0)
    with pytest.raises(ValueError, match="beyond the 45 degrees"):
        _env("pitch", target_amplitude=math.radians(60.0))
    with pytest.raises(ValueError, match="valid names: thrust_arm"):
        parameters.resolve({"thrust_arms": 0.2})
    with pytest.raises(ValueError, match="two finite voltages"):
        _physics().set_voltage([1.0, 2.0, 3.0])


def test_gymnasium_and_its_vector_environment_take_two_voltages():
    from gymnasium.utils.env_checker import check_env

    env = gymnasium.make("QubeSuite/Aero2Track-v0")
    check_env(env.unwrapped, skip_render_check=True)
    assert env.action_space.shape == (2,) and env.observation_space.shape == (8,)
    env.close()
    envs = gymnasium.make_vec("QubeSuite/Aero2Hover-v0", num_envs=2)
    observations, _ = envs.reset(seed=0)
    assert observations.shape == (2, 8) and observations[0, 7] != observations[1, 7]  # own yaw targets
    observations, *_ = envs.step(np.array([[12.0, 0.0], [0.0, 12.0]], dtype=np.float32))
    assert observations[0, 4] > 1.0 and abs(observations[0, 5]) < 0.01 and observations[1, 5] > 1.0
    envs.close()


def test_the_voltage_effects_reach_both_motors_and_restart_with_each_episode():
    delayed = {"effects": {"action_delay": {"steps": 1}, "voltage_offset": {"voltage": 0.25}}}
    env = suite.load("aero2", "hover", task_kwargs={"random": 3}, randomization=delayed)
    for _ in range(2):
        env.reset()
        applied = []
        for volts in ([1.0, -1.0], [2.0, 0.5]):
            env.step(np.array(volts))
            applied.append(env.physics.applied_voltage())
        np.testing.assert_allclose(applied, [[0.25, 0.25], [1.25, -0.75]])
    env = suite.load("aero2", "hover", task_kwargs={"random": 3}, randomization="actuation")
    env.reset()
    assert set(env.randomization_sample.effects) == {"action_delay", "voltage_offset", "dead_zone"}


def test_the_command_line_runs_and_scores_the_aero(capsys):
    from qube_suite import cli

    assert cli.main(["eval", "--domain", "aero2", "--task", "hover", "--controller", "lqr", "--episodes", "1",
                     "--quiet"]) == 0
    assert "success 100 %" in capsys.readouterr().out
    assert cli.main(["run", "--domain", "aero2", "--task", "track", "--controller", "lqr", "--episodes", "1",
                     "--quiet"]) == 0
    assert "2048 steps" in capsys.readouterr().out


def test_a_recording_has_a_column_of_each_voltage_per_motor(tmp_path):
    from qube_suite import recording

    env = _env("hover")
    with recording.Recorder(tmp_path / "aero.jsonl", env):
        env.reset()
        env.step(np.array([3.0, -30.0]))
    episode = recording.load_recording(tmp_path / "aero.jsonl").episodes[0]
    assert episode["action_1"][1] == -30.0 and episode["voltage_1"][1] == -18.0
    assert episode["voltage_0"][1] == 3.0 and "voltage" not in episode.data
    assert episode["back_rotor_speed"][1] < 0.0


def protocol_members(protocol: type) -> set[str]:
    """The methods and attributes a `typing.Protocol` declares."""
    return {name for name in vars(protocol) if not name.startswith("_")} | set(protocol.__annotations__)


@pytest.mark.parametrize("configuration", ["2dof", "pitch_only"])
def test_the_simulation_has_every_member_of_the_aeros_domain_interface(configuration):
    physics = _physics(configuration)
    members = protocol_members(aero_tasks.Aero2Physics)
    assert {"rotor_speeds", "configuration", "reset_context", "stop_motor"} <= members
    assert [name for name in sorted(members) if not hasattr(physics, name)] == []
    assert physics.configuration == configuration and physics.state_names == simulation.STATE_NAMES
    assert physics.rotor_speeds().shape == (2,) and physics.voltage().shape == (2,)


def test_the_batch_safety_probe_reads_like_the_aero():
    probe = aero_tasks.ProbeAeros(aero_tasks.PROBE_STATES, np.zeros(2), 2)
    np.testing.assert_array_equal(probe.rotor_speeds(), aero_tasks.PROBE_STATES[:, 4:])
    assert probe.voltage().shape == (2, 2)


AERO_NAMES = re.compile(r"aero ?2|\bAero\b|thrust_arm|rotor_speeds", re.IGNORECASE)


def test_nothing_outside_the_aeros_folder_names_it():
    """A device is its folder: no other module of the package names the Aero."""
    naming = [str(path.relative_to(PACKAGE)) for path in sorted(PACKAGE.rglob("*"))
              if path.suffix in (".py", ".pyx", ".xml", ".yaml") and FOLDER not in path.parents
              and AERO_NAMES.search(path.read_text(encoding="utf-8"))]
    assert naming == []
    assert AERO_NAMES.search((FOLDER / "tasks.py").read_text())  # the pattern does find the Aero's names
