"""run_episode and EpisodeTrace: one row per reading, the same episode as a hand-written loop."""

import math

import numpy as np
import pytest

from qube_suite import baselines, episodes, suite
from qube_suite.environment import reward_colour


def short_env(task="balance", seconds=0.4, seed=0):
    return suite.load("qube", task, task_kwargs={"random": seed}, environment_kwargs={"time_limit": seconds})


def test_trace_has_a_row_per_reading_and_the_loops_return():
    controller = baselines.make("balance")
    reference = short_env()
    timestep, rewards, states = reference.reset(), [], [reference.physics.qube_state()]
    while not timestep.last():
        timestep = reference.step(controller(timestep.observation))
        rewards.append(timestep.reward)
        states.append(reference.physics.qube_state())

    trace = episodes.run_episode(short_env(), controller, label="lqr")
    assert trace.steps == 100 and trace.label == "lqr" and not trace.terminated
    assert trace.time.shape == (101,) and trace.state.shape == (101, 4) and trace.led.shape == (101, 3)
    assert trace.time[0] == 0.0 and trace.time[-1] == trace.duration == pytest.approx(0.4)
    assert math.isnan(trace.reward[0]) and trace.voltage[0] == 0.0
    np.testing.assert_allclose(trace.reward[1:], rewards)
    np.testing.assert_allclose(trace.state, states)
    assert trace.episode_return == pytest.approx(sum(rewards))
    for reward, led in zip(trace.reward[1:], trace.led[1:], strict=True):
        assert tuple(led) == reward_colour(reward)
    assert trace.target is None


def test_hooks_see_every_step_and_policies_are_reset():
    calls = []

    class Policy:
        resets = 0

        def reset(self):
            self.resets += 1

        def __call__(self, observation):
            return 3.0  # drives the arm out of balance: terminates

    policy = Policy()
    trace = episodes.run_episode(short_env(seconds=2.0), policy,
                                 hooks=[lambda step, env: calls.append((step, env.step_count))])
    assert policy.resets == 1 and trace.terminated and trace.steps < 500
    assert calls == [(k, k) for k in range(trace.steps + 1)]
    assert np.all(trace.voltage[1:] == 3.0)


def test_follow_tasks_trace_the_target():
    trace = episodes.run_episode(short_env("balance_follow", seconds=2.0), baselines.make("balance"))
    assert trace.target.shape == trace.time.shape
    assert np.all(np.abs(trace.target) <= math.radians(80)) and len(set(trace.target)) > 1
