"""The Gymnasium API: spaces, seeding, episode end flags, info and conversion."""

import math

import gymnasium
import numpy as np
import pytest

import qube_suite
from qube_suite import suite


def test_spaces_are_volts_and_flat_float32_state():
    env = gymnasium.make("QubeSuite/Swingup-v0")
    assert env.action_space == gymnasium.spaces.Box(-3.0, 3.0, (1,), np.float32)
    assert env.observation_space.shape == (4,) and env.observation_space.dtype == np.float32
    observation, info = env.reset(seed=0)
    assert observation.dtype == np.float32 and observation in env.observation_space
    assert abs(abs(observation[1]) - math.pi) < 0.06  # hanging
    assert info == {"time": 0.0, "voltage": 0.0}

    follow = gymnasium.make("QubeSuite/BalanceFollow-v0", observation="trig", voltage_limit=5.0)
    assert follow.observation_space.shape == (7,) and follow.action_space.high[0] == 5.0
    observation, info = follow.reset(seed=0)
    assert observation[-1] == pytest.approx(info["target"])


def test_reset_seed_reproduces_the_episode_and_matches_dm_env():
    def run(seed):
        env = gymnasium.make("QubeSuite/Dampen-v0")
        observations = [env.reset(seed=seed)[0]]
        for _ in range(50):
            observations.append(env.step(np.array([1.0], np.float32))[0])
        return np.array(observations)

    np.testing.assert_array_equal(run(9), run(9))
    assert not np.array_equal(run(9), run(10))
    dm = suite.load("qube", "dampen", task_kwargs={"random": 9})
    np.testing.assert_allclose(run(9)[0], dm.reset().observation["state"].astype(np.float32))


def test_terminated_and_truncated():
    env = gymnasium.make("QubeSuite/Swingup-v0", time_limit=0.2)
    env.reset(seed=0)
    for step in range(50):
        _, _, terminated, truncated, _ = env.step(np.zeros(1, np.float32))
        assert not terminated and truncated == (step == 49)
    with pytest.raises(RuntimeError, match="reset"):
        env.unwrapped.step(np.zeros(1, np.float32))

    env = gymnasium.make("QubeSuite/Swingup-v0")
    env.reset(seed=0)
    terminated = False
    for _ in range(300):
        _, reward, terminated, truncated, _ = env.step(np.array([3.0], np.float32))
        if terminated:
            break
    assert terminated and not truncated
    assert abs(env.unwrapped.physics.arm_angle()) > math.pi / 2


def test_info_reports_time_and_the_applied_voltage():
    env = gymnasium.make("QubeSuite/Balance-v0")
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([9.0], np.float32))
    assert info["voltage"] == 3.0 and info["time"] == pytest.approx(0.004)


def test_bad_action_is_a_value_error():
    env = gymnasium.make("QubeSuite/Balance-v0")
    observation, _ = env.reset(seed=0)
    with pytest.raises(ValueError):
        env.step(np.array([np.nan], np.float32))
    assert env.unwrapped.environment.step_count == 0


def test_to_gymnasium_wraps_any_suite_environment():
    environment = suite.load("qube", "rotor", environment_kwargs={"control_frequency": 500})
    env = qube_suite.to_gymnasium(environment)
    assert env.metadata["render_fps"] == 500 and env.unwrapped.environment is environment
    observation, _ = env.reset(seed=1)
    assert observation.shape == (4,)


def test_human_rendering_without_a_display_is_a_clear_error(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(ValueError, match="display"):
        gymnasium.make("QubeSuite/Swingup-v0", render_mode="human")
    env = gymnasium.make("QubeSuite/Swingup-v0", render_mode="rgb_array")
    assert "human" not in env.metadata["render_modes"]


def test_order_enforced_by_the_environment_itself():
    # gymnasium.make adds no OrderEnforcing/PassiveEnvChecker (CHECKS_BUILT_IN): the env refuses on its own
    env = gymnasium.make("QubeSuite/Balance-v0")
    assert type(env).__name__ == "QubeEnv"
    with pytest.raises(RuntimeError, match="call reset"):
        env.step(np.zeros(1, np.float32))
    env.reset(seed=0)
    env.step(np.zeros(1, np.float32))
    checked = gymnasium.make("QubeSuite/Balance-v0", disable_env_checker=False)
    assert type(checked).__name__ == "PassiveEnvChecker"
