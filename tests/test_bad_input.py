"""Bad input at every entry point: a clear ValueError that lists valid values, and nothing changed."""

import math

import gymnasium
import numpy as np
import pytest

import qube_suite  # noqa: F401  (registers the Gymnasium ids)
from qube_suite import baselines, cli, evaluate, suite
from qube_suite.hardware import QubeServo2

BAD_ACTIONS = [np.array([np.nan]), np.array([np.inf]), [-np.inf], np.zeros(2), np.zeros((1, 1)), np.zeros(0),
               ["1.0"], "1.0", None, True, np.array([True]), {"voltage": 1.0}, [[1.0], [2.0]],
               np.array([1 + 2j]), np.array([1.0], dtype=object), object()]
ACTION_IDS = [type(a).__name__ + repr(a)[:20] for a in BAD_ACTIONS]


def snapshot(environment):
    """Everything a step could change: physics state, time, voltages, step count, every RNG."""
    physics, task = environment.physics, environment.task
    return {"state": physics.qube_state(), "time": physics.time(), "voltage": physics.voltage(),
            "steps": environment.step_count, "task_random": task.random.get_state()[1].copy(),
            "target": getattr(task, "target", None)}


def assert_same(before, after):
    for key, value in before.items():
        np.testing.assert_array_equal(after[key], value, err_msg=key)


def rollout(environment, actions):
    return np.array([np.concatenate(list(environment.step(a).observation.values())) for a in actions])


@pytest.mark.parametrize("action", BAD_ACTIONS, ids=ACTION_IDS)
def test_refused_dm_env_action_changes_nothing_even_with_randomization(action):
    def load():
        env = suite.load("qube", "swingup_follow", task_kwargs={"random": 5}, randomization="moderate")
        env.reset()
        env.step([1.0])
        return env

    env, twin = load(), load()
    before = snapshot(env)
    sim_state = env.physics.get_state().copy()
    with pytest.raises(ValueError, match="action"):
        env.step(action)
    assert_same(before, snapshot(env))
    np.testing.assert_array_equal(env.physics.get_state(), sim_state)
    actions = np.random.default_rng(0).uniform(-3, 3, (30, 1))
    np.testing.assert_array_equal(rollout(env, actions), rollout(twin, actions))  # noise RNGs untouched


@pytest.mark.parametrize("action", BAD_ACTIONS, ids=ACTION_IDS)
def test_refused_gymnasium_action_changes_nothing(action):
    env = gymnasium.make("QubeSuite/BalanceFollow-v0", randomization="sim2real")
    env.reset(seed=3)
    env.step(np.array([0.5], np.float32))
    before = snapshot(env.unwrapped.environment)
    with pytest.raises(ValueError):
        env.step(action)
    assert_same(before, snapshot(env.unwrapped.environment))
    _, _, terminated, truncated, info = env.step(np.array([0.5], np.float32))  # still usable
    assert info["time"] == pytest.approx(0.008) and not (terminated or truncated)


@pytest.mark.parametrize("actions", [np.array([[np.nan], [0.0]]), np.zeros((2, 2)), [["1"], ["2"]], None,
                                     np.array([[True], [False]])], ids=repr)
def test_refused_vector_action_changes_nothing_in_any_world(actions):
    def make():
        env = gymnasium.make_vec("QubeSuite/SwingupFollow-v0", num_envs=2)
        env.reset(seed=3)
        env.step(np.ones((2, 1), np.float32))
        return env

    env, twin = make(), make()
    randoms = [random.get_state()[1].copy() for random in env.unwrapped.task.randoms]
    with pytest.raises(ValueError):
        env.step(actions)
    for random, before in zip(env.unwrapped.task.randoms, randoms, strict=True):
        np.testing.assert_array_equal(random.get_state()[1], before)
    for _ in range(30):
        action = np.full((2, 1), 2.0, np.float32)
        np.testing.assert_array_equal(env.step(action)[0], twin.step(action)[0])


@pytest.mark.parametrize("action", [np.array([np.nan]), np.zeros(2), "1.0", None])
def test_refused_action_on_hardware_never_reaches_the_board_and_zeroes_the_motor(action):
    with suite.load("qube_hardware", "swingup", task_kwargs={"random": 0},
                    environment_kwargs={"time_limit": 0.2}) as env:
        env.reset()
        env.step(np.array([1.0]))
        board = env.physics.qube.board
        before = (board.time, board.written_voltage, env.step_count, board.true_state())
        with pytest.raises(ValueError):
            env.step(action)
        after = (board.time, board.written_voltage, env.step_count, board.true_state())
        assert after[0] == before[0] and after[2] == before[2]          # no sample read, no step taken
        assert after[1] == 0.0                                          # but the last voltage is off
        np.testing.assert_array_equal(after[3], before[3])
        assert env.step(np.array([1.0])).mid()


@pytest.mark.parametrize("bad", ["1.5", True, [1 + 2j], np.array([1.0], dtype=object), b"1", 10**400])
def test_board_refuses_non_numbers_without_reading_a_sample(bad):
    with QubeServo2() as qube:
        qube.action(2.0)
        time_before = qube.board.time
        with pytest.raises(ValueError, match="voltages"):
            qube.action(bad)
        assert qube.board.time == time_before and qube.board.written_voltage == 0.0  # stopped, not stepped
        qube.action(1.0)
        assert qube.board.written_voltage == 1.0


@pytest.mark.parametrize("kwargs, message", [
    ({"domain_name": "cube"}, "valid domains: .*qube, qube_hardware"),
    ({"task_name": "swing_up"}, "valid tasks: .*swingup_follow"),
    ({"task_kwargs": {"voltagelimit": 3.0}}, "'voltagelimit'; valid: voltage_limit, observation, random"),
    ({"task_kwargs": {"sparse": True}}, "'sparse'; valid: voltage_limit"),
    ({"task_kwargs": {"voltage_limit": True}}, "voltage_limit"),
    ({"task_kwargs": {"voltage_limit": math.nan}}, "voltage_limit"),
    ({"task_kwargs": {"voltage_limit": 10.5}}, r"voltage_limit must be in \(0, 10\]"),
    ({"environment_kwargs": {"time_limit": True}}, "time_limit"),
    ({"environment_kwargs": {"control_frequency": 9.0}}, r"\[10, 2000\] Hz"),
    ({"environment_kwargs": {"control_frequency": math.inf}}, "control_frequency"),
    ({"environment_kwargs": {"control_frequency": "250"}}, "control_frequency"),
    ({"domain_kwargs": {"paramters": {}}},
     "domain 'qube' got an unexpected keyword argument 'paramters'; valid: parameters"),
    ({"domain_kwargs": {"parameters": {"pendulum_mas": 0.03}}}, "valid.*pendulum_mass"),
    ({"domain_kwargs": {"parameters": {"pendulum_mass": -1.0}}}, "pendulum_mass"),
    ({"randomization": "milder"}, "valid presets: none, mild, moderate, sim2real"),
    ({"randomization": {"parameters": {"pendulum_mas": {}}}}, "valid parameters: .*pendulum_mass"),
    ({"randomization": {"effects": {"noise": True}}}, "valid effects: .*observation_noise"),
    ({"randomization": {"parameters": {"pendulum_mass": {"distribution": "uniform", "low": 2, "high": 1}}}},
     "low"),
    ({"randomization": 3}, "preset name"),
])
def test_suite_load_names_the_mistake_and_the_valid_values(kwargs, message):
    arguments = {"domain_name": "qube", "task_name": "swingup", **kwargs}
    with pytest.raises(ValueError, match=message):
        suite.load(**arguments)


@pytest.mark.parametrize("domain_kwargs, task_kwargs, message", [
    ({"bord": "simulated"}, {}, "'bord'; valid: board, plant, realtime, max_voltage"),
    ({"board": "qube_servo9"}, {}, "qube_servo2_usb"),
    ({"plant": {"arm_frction": 0.0}}, {}, "arm_friction"),
    ({"max_voltage": 5.0, "reset_voltage_limit": 4.0}, {"voltage_limit": 6.0}, "exceeds the board"),
    ({"max_voltage": math.nan}, {}, "max_voltage"),
    ({"reset_timeout": 0.0}, {}, "reset_timeout"),
])
def test_hardware_domain_options_name_the_mistake(domain_kwargs, task_kwargs, message):
    with pytest.raises(ValueError, match=message):
        suite.load("qube_hardware", "balance", task_kwargs=task_kwargs, domain_kwargs=domain_kwargs)


@pytest.mark.parametrize("kwargs, message", [
    ({"voltagelimit": 3.0}, "'voltagelimit'; valid: render_mode, randomization, .*voltage_limit"),
    ({"domain": "cube"}, "valid domains"),
    ({"voltage_limit": True}, "voltage_limit"),
    ({"control_frequency": 5000}, "control_frequency"),
    ({"randomization": "strong"}, "valid presets"),
    ({"domain_kwargs": {"parameter": {}}}, "valid: parameters"),
    ({"render_mode": "pixels"}, "render_mode"),
])
def test_gymnasium_make_names_the_mistake(kwargs, message):
    with pytest.raises(ValueError, match=message):
        gymnasium.make("QubeSuite/Swingup-v0", **kwargs)


@pytest.mark.parametrize("kwargs, message", [
    ({"voltagelimit": 3.0}, "'voltagelimit'; valid: autoreset_mode, .*voltage_limit"),
    ({"num_envs": True}, "num_envs"),
    ({"num_envs": 0}, "num_envs"),
    ({"threads": -1}, "threads"),
    ({"autoreset_mode": "sometimes"}, "valid: NextStep, SameStep, Disabled"),
    ({"control_frequency": 1.0}, "control_frequency"),
    ({"random": "seed"}, "random"),
])
def test_gymnasium_make_vec_names_the_mistake(kwargs, message):
    with pytest.raises(ValueError, match=message):
        gymnasium.make_vec("QubeSuite/Swingup-v0", **{"num_envs": 2, **kwargs})


@pytest.mark.parametrize("name, kwargs, message", [
    ("lqr", {}, "valid controllers: balance, swingup"),
    ("balance", {"voltagelimit": 3.0}, "'voltagelimit'; valid: control_frequency, voltage_limit, parameters"),
    ("mpc", {"horizon_steps": 3}, "valid: .*horizon"),
    ("balance", {"control_frequency": 0.0}, "control_frequency"),
    ("swingup", {"voltage_limit": -3.0}, "voltage_limit"),
    ("swingup", {"voltage_limit": math.inf}, "voltage_limit"),
])
def test_baselines_make_names_the_mistake(name, kwargs, message):
    with pytest.raises(ValueError, match=message):
        baselines.make(name, **kwargs)


def test_evaluate_names_an_unknown_controller():
    with pytest.raises(ValueError, match="valid controllers"):
        evaluate("lqr", task="balance", episodes=1)


@pytest.mark.parametrize("argv, message", [
    (["run", "--domain", "cube", "--task", "swingup", "--controller", "swingup"], "valid domains"),
    (["run", "--task", "swing", "--controller", "swingup"], "valid tasks"),
    (["run", "--task", "swingup", "--controller", "lqr"], "valid controllers"),
    (["run", "--task", "swingup", "--controller", "swingup", "--randomization", "milder"], "valid presets"),
    (["run", "--domain", "qube_hardware", "--board", "qube9", "--task", "balance", "--controller", "balance"],
     "qube_servo2_usb"),
    (["eval", "--task", "swing", "--controller", "swingup", "--episodes", "1"], "valid tasks"),
    (["eval", "--task", "swingup", "--controller", "lqr", "--episodes", "1"], "valid controllers"),
    (["eval", "--task", "swingup", "--controller", "swingup", "--episodes", "0"], "episodes"),
])
def test_command_line_mistakes_are_one_line_with_the_valid_names(argv, message, capsys):
    assert cli.main(argv) == 2
    error = capsys.readouterr().err
    assert error.startswith("qube-suite: error: ") and error.count("\n") == 1
    assert pytest.importorskip("re").search(message, error)
