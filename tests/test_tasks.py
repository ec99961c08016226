"""Rewards at chosen states, safe sets and start states of every task."""

import math

import dm_env
import numpy as np
import pytest

from qube_suite import suite

PI = math.pi
DEG = math.pi / 180


def load(task, **task_kwargs):
    env = suite.load("qube", task, task_kwargs={"random": 0, **task_kwargs})
    env.reset()
    return env


def reward_at(env, state):
    env.physics.reset_to(state)
    return env.task.get_reward(env.physics)


def shaped(pendulum_error, arm_error):
    """The task table's dense reward, written out independently of the package."""
    return max(0.0, 1.0 - (0.8 * abs(pendulum_error) + 0.2 * abs(arm_error)) / PI)


@pytest.mark.parametrize("task", ["swingup", "balance"])
@pytest.mark.parametrize("state, expected", [
    ([0.0, 0.0, 0.0, 0.0], 1.0),                      # upright, centred
    ([0.0, PI, 0.0, 0.0], 0.2),                       # hanging
    ([0.0, -PI / 2, 3.0, -4.0], 0.6),                 # horizontal; speeds do not matter
    ([0.5, 1.0, 0.0, 0.0], 1 - (0.8 + 0.1) / PI),
    ([-1.2, -0.3, 0.0, 0.0], 1 - (0.24 + 0.24) / PI),
])
def test_upright_reward(task, state, expected):
    assert reward_at(load(task), state) == pytest.approx(expected, abs=1e-12)
    assert reward_at(load(task), state) == pytest.approx(shaped(state[1], state[0]), abs=1e-12)


@pytest.mark.parametrize("state, expected", [
    ([0.0, PI, 0.0, 0.0], 1.0),                       # hanging at rest is the goal
    ([0.0, -PI + 0.1, 0.0, 0.0], 1 - 0.08 / PI),      # 0.1 rad from hanging, the other side
    ([0.0, 0.0, 0.0, 0.0], 0.2),                      # upright is the worst pendulum angle
    ([0.7, PI - 0.5, 0.0, 0.0], 1 - (0.4 + 0.14) / PI),
])
def test_dampen_reward(state, expected):
    assert reward_at(load("dampen"), state) == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize("task, goal_alpha", [("swingup_sparse", 0.0), ("balance_sparse", 0.0),
                                              ("dampen_sparse", PI)])
def test_sparse_goal_set_is_reachable_and_bounded(task, goal_alpha):
    env = load(task)
    inside = [[0.0, goal_alpha, 0.0, 0.0], [19.9 * DEG, goal_alpha + 9.9 * DEG, 2.0, 3.0],
              [-19.9 * DEG, goal_alpha - 9.9 * DEG, 0.0, 0.0]]
    outside = [[20.1 * DEG, goal_alpha, 0.0, 0.0], [0.0, goal_alpha + 10.1 * DEG, 0.0, 0.0],
               [0.0, goal_alpha + PI / 2, 0.0, 0.0]]
    assert [reward_at(env, s) for s in inside] == [1.0, 1.0, 1.0]
    assert [reward_at(env, s) for s in outside] == [0.0, 0.0, 0.0]


@pytest.mark.parametrize("task", ["swingup_follow", "balance_follow"])
def test_follow_reward_measures_the_arm_from_its_target(task):
    env = load(task)
    target = env.task.target
    assert abs(target) <= 80 * DEG
    assert reward_at(env, [target, 0.0, 0.0, 0.0]) == pytest.approx(1.0)
    assert reward_at(env, [target + 0.5, 0.2, 0.0, 0.0]) == pytest.approx(shaped(0.2, 0.5))
    assert reward_at(env, [0.0, 0.0, 0.0, 0.0]) == pytest.approx(shaped(0.0, target))


@pytest.mark.parametrize("task", ["swingup_follow_sparse", "balance_follow_sparse"])
def test_sparse_follow_goal_moves_with_the_target(task):
    env = load(task)
    target = env.task.target
    assert reward_at(env, [target + 15 * DEG, 0.0, 0.0, 0.0]) == 1.0
    assert reward_at(env, [target + 25 * DEG, 0.0, 0.0, 0.0]) == 0.0


def test_follow_target_is_observed_redrawn_about_twice_a_second_and_reproducible():
    env = suite.load("qube", "swingup_follow", task_kwargs={"random": 5})
    timestep = env.reset()
    targets = [float(timestep.observation["target"][0])]
    while not timestep.last():
        timestep = env.step(np.zeros(1))
        targets.append(float(timestep.observation["target"][0]))
    changes = np.count_nonzero(np.diff(targets))
    assert 8 <= changes <= 30  # Poisson, mean 16 in 8.192 s
    assert max(np.abs(targets)) <= 80 * DEG and np.std(targets) > 0.3

    again = suite.load("qube", "swingup_follow", task_kwargs={"random": 5})
    timestep = again.reset()
    replay = [float(timestep.observation["target"][0])]
    while not timestep.last():
        timestep = again.step(np.zeros(1))
        replay.append(float(timestep.observation["target"][0]))
    assert replay == targets
    assert again.reset().observation["target"][0] != targets[0]  # fresh draw at every reset


def turn_pendulum(env, alphas):
    """Move the pendulum through `alphas` (unwrapped, rad) and collect the rotor's rewards."""
    rewards = []
    for alpha in alphas:
        env.physics.reset_to([0.0, alpha, 0.0, 0.0])
        env.task.after_step(env.physics)
        rewards.append(env.task.get_reward(env.physics))
    return rewards


def test_rotor_rewards_each_full_revolution_once():
    env = load("rotor")
    start = env.physics.pendulum_angle()
    forward = start + np.linspace(0.05, 2.5 * 2 * PI, 200)
    rewards = turn_pendulum(env, forward)
    assert sum(rewards) == 2.0 and env.task.revolutions == 2
    first = rewards.index(1.0)
    assert forward[first] - start >= 2 * PI and forward[first - 1] - start < 2 * PI
    # Swinging back over counted turns earns nothing; a new net turn in either direction does.
    backward = forward[-1] - np.linspace(0.05, 5.6 * 2 * PI, 400)  # net -3.1 turns
    rewards = turn_pendulum(env, backward)
    assert sum(rewards) == 1.0 and env.task.revolutions == 3


def test_rotor_gives_nothing_for_swinging():
    env = load("rotor")
    swing = PI + 2.5 * np.sin(np.linspace(0, 20 * PI, 400))  # large swings, never over the top
    assert sum(turn_pendulum(env, swing)) == 0.0


@pytest.mark.parametrize("task", suite.TASKS_BY_DOMAIN["qube"])
def test_arm_beyond_90_degrees_terminates(task):
    env = load(task)
    alpha = 0.0 if "balance" in task else PI
    env.physics.reset_to([89 * DEG, alpha, 0.0, 0.0])
    assert env.task.get_termination(env.physics) is None
    env.physics.reset_to([-91 * DEG, alpha, 0.0, 0.0])
    assert env.task.get_termination(env.physics) == 0.0


@pytest.mark.parametrize("task", ["balance", "balance_sparse", "balance_follow", "balance_follow_sparse"])
def test_balance_pendulum_beyond_20_degrees_terminates(task):
    env = load(task)
    env.physics.reset_to([0.0, 19.5 * DEG, 0.0, 0.0])
    assert env.task.get_termination(env.physics) is None
    env.physics.reset_to([0.0, -20.5 * DEG, 0.0, 0.0])
    assert env.task.get_termination(env.physics) == 0.0


def test_termination_ends_the_episode_with_discount_zero():
    env = load("swingup")
    env.physics.reset_to([89.9 * DEG, PI, 5.0, 0.0])
    timestep = env.step([3.0])
    assert timestep.step_type == dm_env.StepType.LAST and timestep.discount == 0.0
    assert env.step([0.0]).step_type == dm_env.StepType.FIRST


def start_states(task, n=200):
    env = suite.load("qube", task, task_kwargs={"random": 1})
    return np.array([env.reset().observation["state"] for _ in range(n)])


def test_swingup_and_rotor_start_hanging_nearly_at_rest():
    for task, noise in [("swingup", 0.05), ("rotor", 0.01)]:
        states = start_states(task)
        down = np.abs(np.abs(states[:, 1]) - PI)
        assert down.max() <= noise + 1e-12 and np.abs(states[:, [0, 2, 3]]).max() <= noise + 1e-12
        assert states[:, 0].std() > noise / 4  # really random


def test_balance_starts_near_upright_with_gaussian_noise():
    states = start_states("balance", 1000)
    assert np.abs(states[:, 1]).max() <= 0.09 + 1e-12
    assert states[:, 1].std() == pytest.approx(0.03, rel=0.15)
    assert states[:, 3].std() == pytest.approx(0.05, rel=0.15)


def test_dampen_starts_anywhere_with_a_small_speed():
    states = start_states("dampen", 1000)
    assert np.abs(states[:, 3]).max() <= 1.0 and np.abs(states[:, 0]).max() <= 0.1
    counts, _ = np.histogram(states[:, 1], bins=4, range=(-PI, PI))
    assert counts.min() > 150  # alpha covers the whole circle


@pytest.mark.parametrize("task", suite.TASKS_BY_DOMAIN["qube"])
def test_led_follows_the_reward(task):
    env = load(task)
    timestep = env.step([0.0])
    red, green, blue = env.physics.led()
    assert green == pytest.approx(min(max(timestep.reward, 0.0), 1.0), abs=1e-6)
    assert red == pytest.approx(1 - green, abs=1e-6)
    assert blue == 0.0
