"""Conventions third-party clients rely on: vector modes, keywords, the action contract, dm_control's
environment options, TorchRL."""

import gymnasium
import numpy as np
import pytest
from dm_control.rl import control

import qube_suite  # noqa: F401  (registers the Gymnasium ids)
from qube_suite import suite
from qube_suite.wrappers import GYMNASIUM_IDS

MODES = ("sync", "async", "vector_entry_point")


def vector_rollout(mode: str, env_id: str, **kwargs) -> np.ndarray:
    envs = gymnasium.make_vec(env_id, num_envs=3, vectorization_mode=mode, **kwargs)
    observations, _ = envs.reset(seed=4)
    values = [observations]
    actions = np.random.default_rng(1).uniform(-3.0, 3.0, (700, 3, 1)).astype(np.float32)
    for action in actions:  # long enough for worlds to end episodes and autoreset
        observations, rewards, terminated, truncated, _ = envs.step(action)
        values += [observations, rewards[:, None], terminated[:, None], truncated[:, None]]
    envs.close()
    return np.concatenate(values, axis=1)


@pytest.mark.slow
@pytest.mark.parametrize("randomization", [None, "sim2real"])
def test_make_vec_modes_give_identical_observations(randomization):
    rollouts = {mode: vector_rollout(mode, "QubeSuite/SwingupFollow-v0", randomization=randomization)
                for mode in MODES}
    assert rollouts["sync"][:, 2::4].any()  # some world terminated: autoreset was exercised
    np.testing.assert_array_equal(rollouts["async"], rollouts["sync"])
    np.testing.assert_array_equal(rollouts["vector_entry_point"], rollouts["sync"])


@pytest.mark.parametrize("make", [
    lambda: gymnasium.make("QubeSuite/Swingup-v0", frameskip=1),
    lambda: gymnasium.make_vec("QubeSuite/Swingup-v0", num_envs=2, frameskip=1),
    lambda: suite.load("qube", "swingup", task_kwargs={"frameskip": 1}),
    lambda: suite.load("qube", "swingup", environment_kwargs={"frameskip": 1}),
    lambda: suite.load("qube", "swingup", domain_kwargs={"frameskip": 1}),
], ids=["make", "make_vec", "task_kwargs", "environment_kwargs", "domain_kwargs"])
def test_an_unknown_keyword_is_a_type_error_that_lists_the_valid_ones(make):
    with pytest.raises(TypeError, match="unexpected keyword argument 'frameskip'; valid: .*") as error:
        make()
    assert isinstance(error.value, ValueError)  # and still a ValueError, as every other bad argument


@pytest.mark.slow
def test_torchrl_gym_env_and_its_spec_check():
    pytest.importorskip("torchrl")
    from torchrl.envs import GymEnv
    from torchrl.envs.utils import check_env_specs

    env = GymEnv("QubeSuite/Swingup-v0")  # passes frameskip, retries without on TypeError
    check_env_specs(env, seed=0)
    rollout = env.rollout(20)
    assert rollout["next", "observation"].shape == (20, 4)
    env.close()


# -- the action contract (docs/conventions.md) -------------------------------------------------


def test_gymnasium_refuses_every_wrong_action_shape_as_its_mujoco_environments_do():
    env = gymnasium.make("QubeSuite/Balance-v0")
    env.reset(seed=0)
    sample = env.action_space.sample()
    for action in (sample[1:], np.append(sample, 0.0), 0.1, np.float32(0.1), np.expand_dims(sample, 0),
                   np.expand_dims(sample, 1), [[0.1]]):
        with pytest.raises(ValueError, match="Action dimension mismatch"):
            env.step(action)
    assert env.unwrapped.environment.step_count == 0  # nothing moved
    env.step([0.1])  # a list of one number has the right shape
    env.close()


def test_dm_env_takes_a_plain_number_as_well_as_shape_1():
    env, twin = (suite.load("qube", "balance", task_kwargs={"random": 0}) for _ in range(2))
    env.reset()
    twin.reset()
    np.testing.assert_array_equal(env.step(0.5).observation["state"],
                                  twin.step(np.array([0.5])).observation["state"])
    for action in (np.zeros(2), np.zeros((1, 1)), []):
        with pytest.raises(ValueError, match="Action dimension mismatch"):
            env.step(action)


def test_vector_actions_must_have_the_batch_shape():
    envs = gymnasium.make_vec("QubeSuite/Balance-v0", num_envs=2)
    envs.reset(seed=0)
    for actions in (np.zeros(2), np.zeros((2, 1, 1)), np.zeros((3, 1))):
        with pytest.raises(ValueError, match="Action dimension mismatch"):
            envs.step(actions)
    envs.step(np.zeros((2, 1)))
    envs.close()


def test_action_spec_bounds_have_the_action_shape():
    spec = suite.load("qube", "swingup", task_kwargs={"voltage_limit": 5.0}).action_spec()
    assert spec.shape == spec.minimum.shape == spec.maximum.shape == (1,)
    np.testing.assert_array_equal(spec.minimum, [-5.0])
    np.testing.assert_array_equal(spec.maximum, [5.0])


# -- dm_control's environment options ---------------------------------------------------------


@pytest.mark.parametrize("task", ["balance", "swingup_follow"])
def test_flat_observation_as_dm_control_gives_it(task):
    flat = suite.load("qube", task, task_kwargs={"random": 1}, environment_kwargs={"flat_observation": True})
    nested = suite.load("qube", task, task_kwargs={"random": 1})
    spec = flat.observation_spec()
    assert list(spec) == [control.FLAT_OBSERVATION_KEY]
    expected = control.flatten_observation(nested.reset().observation)
    observation = flat.reset().observation
    assert list(observation) == [control.FLAT_OBSERVATION_KEY]
    np.testing.assert_array_equal(observation["observations"], expected["observations"])
    spec["observations"].validate(observation["observations"])
    step = flat.step(np.array([1.0])).observation["observations"]
    np.testing.assert_array_equal(step, control.flatten_observation(nested.step(np.array([1.0])).observation)
                                  ["observations"])
    with pytest.raises(ValueError, match="flat_observation"):
        suite.load("qube", task, environment_kwargs={"flat_observation": "yes"})


def test_every_pendulum_id_is_registered_for_make_vec():
    for env_id in GYMNASIUM_IDS:
        native = gymnasium.spec(env_id).vector_entry_point is not None
        assert native == (gymnasium.spec(env_id).kwargs["domain"] == "qube"), env_id  # the one batch
