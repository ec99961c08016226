"""Episode rules, action validation, seeding and `suite.load` errors of the dm_env environments."""

import math

import dm_env
import numpy as np
import pytest
from dm_control.rl import control

from qube_suite import suite


def test_suite_lists_every_task_with_tags():
    tasks = suite.TASKS_BY_DOMAIN["qube"]
    assert sorted(tasks) == sorted([
        "swingup", "swingup_sparse", "balance", "balance_sparse", "dampen", "dampen_sparse",
        "swingup_follow", "swingup_follow_sparse", "balance_follow", "balance_follow_sparse", "rotor"])
    assert {"qube", "qube_hardware"} <= set(suite.TASKS_BY_DOMAIN)
    assert suite.TASKS_BY_DOMAIN["qube_hardware"] == tasks
    assert len([pair for pair in suite.ALL_TASKS if pair[0] in ("qube", "qube_hardware")]) == 22

    def pendulum(pairs):
        return {task for domain, task in pairs if domain == "qube"}

    assert pendulum(suite.SPARSE) == {t for t in tasks if t.endswith("sparse")}
    assert pendulum(suite.FOLLOW) == {t for t in tasks if "follow" in t}
    assert pendulum(suite.BENCHMARKING) == {
        "swingup", "balance", "dampen", "swingup_follow", "balance_follow", "rotor"}


def test_environment_exposes_physics_and_task_like_dm_control():
    env = suite.load("qube", "swingup")
    assert isinstance(env, control.Environment) and isinstance(env, dm_env.Environment)
    assert env.physics.pendulum_angle() is not None and env.task.voltage_limit == 3.0
    assert env.control_timestep() == pytest.approx(0.004)
    spec = env.action_spec()
    assert spec.shape == (1,) and spec.minimum == -3.0 and spec.maximum == 3.0


def test_time_limit_is_2048_steps_and_truncates_with_discount_one():
    env = suite.load("qube", "swingup", task_kwargs={"random": 0})
    timestep = env.reset()
    steps = 0
    while not timestep.last():
        timestep = env.step(np.zeros(1))  # hangs quietly, never leaves the safe set
        steps += 1
        assert timestep.discount == 1.0
    assert steps == 2048 and timestep.discount == 1.0
    assert env.physics.time() == pytest.approx(8.192)
    assert env.step(np.zeros(1)).first()


@pytest.mark.parametrize("frequency, steps", [(500, 4096), (100, 819), (1000, 8192)])
def test_control_frequency_keeps_the_episode_duration(frequency, steps):
    env = suite.load("qube", "rotor", environment_kwargs={"control_frequency": frequency})
    assert env.episode_steps == steps and env.control_timestep() == pytest.approx(1 / frequency)
    env.reset()
    env.step([0.0])
    assert env.physics.time() == pytest.approx(1 / frequency)


def test_time_limit_is_configurable():
    env = suite.load("qube", "swingup", environment_kwargs={"time_limit": 1.0})
    assert env.episode_steps == 250


def test_out_of_range_action_is_clipped():
    env = suite.load("qube", "swingup", task_kwargs={"voltage_limit": 5.0})
    env.reset()
    env.step(np.array([100.0]))
    assert env.physics.voltage() == 5.0
    env.step([-7.5])
    assert env.physics.voltage() == -5.0


BAD_ACTIONS = [np.array([np.nan]), np.array([np.inf]), [-np.inf], np.zeros(2), np.zeros((1, 1)), np.zeros(0),
               ["1.0"], "a", None, {"voltage": 1.0}, [[1.0], [2.0]], np.array([1 + 2j]), object()]


@pytest.mark.parametrize("action", BAD_ACTIONS, ids=lambda a: type(a).__name__ + repr(a)[:20])
def test_bad_action_raises_and_changes_nothing(action):
    env = suite.load("qube", "swingup", task_kwargs={"random": 0})
    env.reset()
    env.step([1.0])
    before = (env.physics.get_state().copy(), env.physics.voltage(), env.step_count)
    with pytest.raises(ValueError):
        env.step(action)
    assert np.array_equal(env.physics.get_state(), before[0])
    assert (env.physics.voltage(), env.step_count) == before[1:]
    assert env.step([0.5]).mid()  # still usable


def test_same_seed_same_trajectory_and_different_seed_different():
    def trajectory(seed):
        env = suite.load("qube", "swingup_follow", task_kwargs={"random": seed})
        actions = np.random.default_rng(42).uniform(-3, 3, (300, 1))
        timestep = env.reset()
        observations = [np.concatenate(list(timestep.observation.values()))]
        for action in actions:
            timestep = env.step(action)
            observations.append(np.concatenate(list(timestep.observation.values())))
            if timestep.last():
                timestep = env.reset()
        return np.array(observations)

    np.testing.assert_array_equal(trajectory(3), trajectory(3))
    assert not np.array_equal(trajectory(3), trajectory(4))


def test_trig_observation():
    env = suite.load("qube", "balance_follow", task_kwargs={"observation": "trig", "random": 0})
    observation = env.reset().observation
    theta, alpha = env.physics.arm_angle(), env.physics.pendulum_angle()
    np.testing.assert_allclose(observation["state"][:4],
                               [math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)])
    assert env.observation_spec()["state"].shape == (6,) and "target" in observation


@pytest.mark.parametrize("domain, task, message", [
    ("cube", "swingup", "valid domains: .*qube, qube_hardware"),
    ("qube", "swing_up", "valid tasks: .*swingup"),
])
def test_unknown_names_list_valid_ones(domain, task, message):
    with pytest.raises(ValueError, match=message):
        suite.load(domain, task)


@pytest.mark.parametrize("kwargs, message", [
    ({"task_kwargs": {"voltage_limit": 12.0}}, "voltage_limit"),
    ({"task_kwargs": {"voltage_limit": 0.0}}, "voltage_limit"),
    ({"task_kwargs": {"observation": "pixels"}}, "observation"),
    ({"environment_kwargs": {"control_frequency": 1e5}}, "control_frequency"),
    ({"environment_kwargs": {"time_limit": -1.0}}, "time_limit"),
    ({"environment_kwargs": {"n_sub_steps": 3}}, "valid: control_frequency, time_limit"),
    ({"randomization": "milder"}, "valid presets: none, mild, moderate, sim2real"),
])
def test_invalid_arguments_are_clear_errors(kwargs, message):
    with pytest.raises(ValueError, match=message):
        suite.load("qube", "swingup", **kwargs)
