"""A pickled or deep-copied environment is the same environment: it continues bit-identically."""

import copy
import pickle

import gymnasium
import numpy as np
import pytest
from conftest import requires_offscreen_gl

import qube_suite  # noqa: F401  (registers the Gymnasium ids)
from qube_suite import suite
from qube_suite.randomization import PRESETS

COPIES = {"pickle": lambda env: pickle.loads(pickle.dumps(env)), "deepcopy": copy.deepcopy}

ACTIONS = np.random.default_rng(0).uniform(-3.0, 3.0, (700, 1))
"""Long enough to end the first episode (full voltage one way leaves the arm's range) and start another."""


def gymnasium_rollout(env) -> np.ndarray:
    values = []
    for action in ACTIONS.astype(np.float32):
        observation, reward, terminated, truncated, info = env.step(action)
        values.append(np.concatenate([observation, [reward, terminated, truncated, info["voltage"]]]))
        if terminated or truncated:
            observation, _ = env.reset()
            values.append(observation)
    return np.concatenate(values)


def dm_env_rollout(env) -> np.ndarray:
    values = []
    for action in ACTIONS:
        timestep = env.step(action)
        values.append(np.concatenate([timestep.observation["state"], [timestep.reward or 0.0,
                                                                      timestep.discount or 0.0]]))
    values.append(env.physics.true_state())
    return np.concatenate(values)


@pytest.mark.parametrize("how", sorted(COPIES))
@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_gymnasium_copy_continues_bit_identically(preset, how):
    env = gymnasium.make("QubeSuite/SwingupFollow-v0", randomization=preset)
    env.reset(seed=7)
    for _ in range(5):
        env.step(np.array([2.0], np.float32))
    twin = COPIES[how](env)
    if preset in ("moderate", "sim2real"):  # their sensor and actuator effects survive the copy
        assert twin.unwrapped.physics._effects.sensor is not None
        assert twin.unwrapped.physics._effects.actuator is not None
    np.testing.assert_array_equal(gymnasium_rollout(twin), gymnasium_rollout(env))
    # Reseeded, the copy still plays the same episode.
    first = env.reset(seed=3)[0], twin.reset(seed=3)[0]
    np.testing.assert_array_equal(*first)
    np.testing.assert_array_equal(gymnasium_rollout(twin), gymnasium_rollout(env))
    env.close()
    twin.close()


@pytest.mark.parametrize("how", sorted(COPIES))
@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_dm_env_copy_continues_bit_identically(preset, how):
    env = suite.load("qube", "balance", task_kwargs={"random": 2}, randomization=preset)
    env.reset()
    env.step(np.array([0.5]))
    twin = COPIES[how](env)
    np.testing.assert_array_equal(dm_env_rollout(twin), dm_env_rollout(env))
    assert twin.physics.parameters == env.physics.parameters


def test_a_quantised_copy_still_quantises():
    env = gymnasium.make("QubeSuite/Swingup-v0", randomization="sim2real")
    env.reset(seed=7)
    twin = pickle.loads(pickle.dumps(env))
    resolution = 2.0 * np.pi / 2048
    for _ in range(50):
        observation = twin.step(np.array([1.5], np.float32))[0]
        counts = observation[:2].astype(np.float64) / resolution
        np.testing.assert_allclose(counts, np.round(counts), atol=1e-3)


def test_a_pickle_holds_the_model_as_its_recipe():
    env = gymnasium.make("QubeSuite/Swingup-v0", randomization="sim2real")
    env.reset(seed=0)
    assert len(pickle.dumps(env)) < 40_000  # the compiled model alone is 5.5 MB (textures)
    nominal = gymnasium.make("QubeSuite/Swingup-v0")
    nominal.reset(seed=0)
    assert len(pickle.dumps(nominal)) < 40_000


def test_a_model_changed_directly_is_pickled_in_full_and_exactly():
    env = suite.load("qube", "swingup", task_kwargs={"random": 0})
    env.reset()
    env.physics.model.body_mass[env.physics.model.body("pendulum").id] *= 1.5  # not through set_parameters
    blob = pickle.dumps(env)
    assert len(blob) > 1_000_000
    twin = pickle.loads(blob)
    np.testing.assert_array_equal(twin.physics.model.body_mass, env.physics.model.body_mass)
    np.testing.assert_array_equal(dm_env_rollout(twin), dm_env_rollout(env))


def test_a_closed_environment_refuses_to_run_or_be_copied():
    env = gymnasium.make("QubeSuite/Balance-v0", render_mode="rgb_array", width=64, height=48)
    env.reset(seed=0)
    env.close()
    with pytest.raises(RuntimeError, match="closed"):
        env.step(np.zeros(1, np.float32))
    with pytest.raises(RuntimeError, match="closed"):
        env.reset(seed=0)
    with pytest.raises(RuntimeError, match="closed"):
        env.render()
    with pytest.raises(TypeError, match="closed"):
        pickle.dumps(env)
    with pytest.raises(TypeError, match="closed"):
        copy.deepcopy(env)
    env.close()  # twice is fine


def test_a_closed_dm_env_environment_refuses_to_run():
    env = suite.load("qube", "balance")
    env.reset()
    env.close()
    assert env.closed
    with pytest.raises(RuntimeError, match="closed"):
        env.step(np.zeros(1))
    with pytest.raises(RuntimeError, match="closed"):
        env.reset()
    with pytest.raises(RuntimeError, match="closed"):
        env.physics.render(48, 64)


@pytest.mark.slow
@requires_offscreen_gl
def test_a_rendering_environment_copies_and_renders_the_same_frame():
    env = gymnasium.make("QubeSuite/Balance-v0", render_mode="rgb_array", width=64, height=48)
    env.reset(seed=0)
    first = env.render()
    twin = pickle.loads(pickle.dumps(env))
    np.testing.assert_array_equal(twin.render(), first)
    env.close()
    twin.close()
