"""The native vector environment: the same episodes as single environments, batched, with autoreset."""

import gymnasium
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import qube_suite  # noqa: F401  (registers the Gymnasium ids)
from qube_suite import suite
from qube_suite.wrappers import GYMNASIUM_IDS, QubeVectorEnv

SEEDS = [3, 17, 101]


def spin_or_random(observations, rng, limit):
    """Actions for a batch: pump the pendulum round (earns rotor rewards) in half the worlds,
    random volts beyond the limit (clipped) in the others."""
    theta, alpha, dtheta, dalpha = (observations[:, i].astype(np.float64) for i in range(4))
    pump = np.clip(limit * np.sign(dalpha * np.cos(alpha)) - 8 * theta - 0.3 * dtheta, -limit, limit)
    random = rng.uniform(-1.3 * limit, 1.3 * limit, len(observations))
    return np.where(np.arange(len(observations)) % 2 == 0, pump, random)[:, None].astype(np.float32)


def run_side_by_side(env_id, steps, **kwargs):
    """Step a vector env and independent single envs with the same seeds and actions; compare each step.

    The single envs follow Gymnasium's NEXT_STEP autoreset by hand: the step after an
    episode's end is a reset (no new seed), with reward 0 and both flags False.
    """
    vector = gymnasium.make_vec(env_id, num_envs=len(SEEDS), **kwargs)
    singles = [gymnasium.make(env_id, **kwargs) for _ in SEEDS]
    observations, info = vector.reset(seed=SEEDS)
    expected = np.array([env.reset(seed=seed)[0] for env, seed in zip(singles, SEEDS, strict=True)])
    np.testing.assert_array_equal(observations, expected)
    rng = np.random.default_rng(0)
    limit = float(vector.single_action_space.high[0])
    ended = [False] * len(SEEDS)
    totals = np.zeros(len(SEEDS))
    episodes = 0
    for _ in range(steps):
        actions = spin_or_random(observations, rng, limit)
        observations, rewards, terminated, truncated, info = vector.step(actions)
        for i, env in enumerate(singles):
            single = (env.reset()[0], 0.0, False, False) if ended[i] else env.step(actions[i])[:4]
            np.testing.assert_array_equal(observations[i], single[0])
            assert (rewards[i], terminated[i], truncated[i]) == single[1:]
            ended[i] = single[2] or single[3]
            episodes += ended[i]
        totals += rewards
        assert observations in vector.observation_space
    vector.close()
    return totals, episodes


NATIVE_IDS = sorted(env_id for env_id in GYMNASIUM_IDS
                    if gymnasium.spec(env_id).vector_entry_point is not None)
"""The ids of devices with a batch simulation (the pendulum's)."""


@pytest.mark.parametrize("env_id", NATIVE_IDS)
def test_trajectories_equal_independent_single_envs_across_resets(env_id):
    totals, episodes = run_side_by_side(env_id, 160, time_limit=0.2)
    assert episodes >= 3 * len(SEEDS)  # every world went through several resets


@pytest.mark.parametrize("kwargs", [{"observation": "trig"},
                                    {"control_frequency": 100.0, "voltage_limit": 5.0}])
def test_options_keep_the_trajectories_equal(kwargs):
    run_side_by_side("QubeSuite/BalanceFollow-v0", 120, time_limit=0.3, **kwargs)


def test_rotor_counts_revolutions_per_world_like_single_envs():
    totals, _ = run_side_by_side("QubeSuite/Rotor-v0", 800, voltage_limit=10.0)
    assert totals[0] > 5 and totals[2] > 5  # the pumped worlds spin; the counter follows each world


def test_make_vec_returns_the_native_vector_env_for_every_id():
    assert {gymnasium.spec(env_id).kwargs["domain"] for env_id in NATIVE_IDS} == {"qube"}
    assert len(NATIVE_IDS) == len(suite.TASKS_BY_DOMAIN["qube"])
    env = gymnasium.make_vec("QubeSuite/Swingup-v0", num_envs=4)
    assert isinstance(env.unwrapped, QubeVectorEnv)
    assert env.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
    env.close()
    env.close()  # closing twice is harmless


def test_spaces_are_batched_single_spaces():
    env = gymnasium.make_vec("QubeSuite/SwingupFollow-v0", num_envs=5,
                             vectorization_mode="vector_entry_point", observation="trig", voltage_limit=4.0)
    single = gymnasium.make("QubeSuite/SwingupFollow-v0", observation="trig", voltage_limit=4.0)
    assert env.single_action_space == single.action_space
    assert env.single_observation_space == single.observation_space
    assert env.action_space == gymnasium.vector.utils.batch_space(single.action_space, 5)
    assert env.observation_space.shape == (5, 7) and env.action_space.shape == (5, 1)
    observations, info = env.reset(seed=0)
    assert observations.dtype == np.float32 and observations in env.observation_space
    observations, rewards, terminated, truncated, info = env.step(env.action_space.sample())
    assert rewards.shape == terminated.shape == truncated.shape == (5,)
    assert rewards.dtype == np.float64 and terminated.dtype == truncated.dtype == np.bool_
    assert set(info) == {"time", "_time", "voltage", "_voltage", "target", "_target"}
    np.testing.assert_allclose(info["time"], 0.004)
    np.testing.assert_array_equal(observations[:, -1], info["target"].astype(np.float32))
    env.close()


def test_int_seed_and_random_keyword_expand_like_sync_vector_env():
    native = gymnasium.make_vec("QubeSuite/Dampen-v0", num_envs=3, vectorization_mode="vector_entry_point")
    sync = gymnasium.make_vec("QubeSuite/Dampen-v0", num_envs=3, vectorization_mode="sync")
    np.testing.assert_array_equal(native.reset(seed=42)[0], sync.reset(seed=42)[0])
    seeded = gymnasium.make_vec("QubeSuite/Dampen-v0", num_envs=3, random=42)
    np.testing.assert_array_equal(seeded.reset()[0], native.reset(seed=42)[0])


def test_next_step_autoreset_returns_the_reset_observation_with_zero_reward():
    env = gymnasium.make_vec("QubeSuite/Swingup-v0", num_envs=2, time_limit=0.02)  # 5 steps
    env.reset(seed=[0, 1])
    for _ in range(4):
        _, _, terminated, truncated, _ = env.step(np.zeros((2, 1), np.float32))
        assert not truncated.any() and not terminated.any()
    _, rewards, terminated, truncated, _ = env.step(np.zeros((2, 1), np.float32))
    assert truncated.all() and not terminated.any() and (rewards > 0).all()
    observations, rewards, terminated, truncated, info = env.step(np.full((2, 1), 3.0, np.float32))
    single = gymnasium.make("QubeSuite/Swingup-v0")
    single.reset(seed=0)
    # The reset draws the next start from the world's random state, continuing after the first episode's.
    np.testing.assert_array_equal(observations[0], single.reset()[0])
    assert (rewards == 0.0).all() and not terminated.any() and not truncated.any()
    np.testing.assert_array_equal(info["time"], 0.0)
    np.testing.assert_array_equal(info["voltage"], 0.0)  # the action was ignored


def test_same_step_autoreset_matches_sync_vector_env():
    kwargs = {"num_envs": 3, "time_limit": 0.1, "voltage_limit": 5.0}
    native = gymnasium.make_vec("QubeSuite/BalanceFollow-v0", vectorization_mode="vector_entry_point",
                                autoreset_mode="SameStep", **kwargs)
    sync = gymnasium.make_vec("QubeSuite/BalanceFollow-v0", vectorization_mode="sync",
                              vector_kwargs={"autoreset_mode": AutoresetMode.SAME_STEP}, **kwargs)
    assert native.metadata["autoreset_mode"] is AutoresetMode.SAME_STEP
    native.reset(seed=5)
    sync.reset(seed=5)
    rng = np.random.default_rng(1)
    finals = 0
    for _ in range(120):
        actions = rng.uniform(-5, 5, (3, 1)).astype(np.float32)
        got, expected = native.step(actions), sync.step(actions)
        for a, b in zip(got[:4], expected[:4], strict=True):
            np.testing.assert_array_equal(a, b)
        assert set(got[4]) == set(expected[4])
        if "final_obs" in expected[4]:
            finals += expected[4]["_final_obs"].sum()
            np.testing.assert_array_equal(got[4]["_final_obs"], expected[4]["_final_obs"])
            for world in np.flatnonzero(expected[4]["_final_obs"]):
                np.testing.assert_array_equal(got[4]["final_obs"][world], expected[4]["final_obs"][world])
                for key in ("time", "voltage", "target"):
                    assert got[4]["final_info"][key][world] == expected[4]["final_info"][key][world]
        for key in ("time", "voltage", "target"):
            np.testing.assert_array_equal(got[4][key], expected[4][key])
    assert finals >= 6


def test_disabled_autoreset_needs_a_masked_reset():
    env = gymnasium.make_vec("QubeSuite/Swingup-v0", num_envs=3, autoreset_mode=AutoresetMode.DISABLED,
                             time_limit=0.008)
    env.reset(seed=0)
    env.step(np.zeros((3, 1), np.float32))
    _, _, _, truncated, _ = env.step(np.zeros((3, 1), np.float32))
    assert truncated.all()
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros((3, 1), np.float32))
    before = env.unwrapped.batch.qube_state()
    observations, info = env.reset(options={"reset_mask": np.array([True, False, False])})
    np.testing.assert_array_equal(info["_time"], [True, False, False])
    np.testing.assert_array_equal(observations[1:], before[1:].astype(np.float32))
    with pytest.raises(RuntimeError):
        env.step(np.zeros((3, 1), np.float32))  # worlds 1 and 2 still ended
    env.reset(options={"reset_mask": np.array([False, True, True])})
    env.step(np.zeros((3, 1), np.float32))


BAD_ACTIONS = [np.array([[np.nan], [0.0]]), np.array([[0.0], [np.inf]]), np.zeros((3, 1)), np.zeros((2, 2)),
               np.zeros(1), [["1.0"], ["2.0"]], None, "a", [[1.0], [2.0, 3.0]], np.array([[1j], [0]])]


@pytest.mark.parametrize("actions", BAD_ACTIONS, ids=lambda a: type(a).__name__ + repr(a)[:24])
def test_bad_actions_raise_before_any_world_moves(actions):
    env = gymnasium.make_vec("QubeSuite/Balance-v0", num_envs=2)
    env.reset(seed=0)
    env.step(np.ones((2, 1), np.float32))
    batch = env.unwrapped.batch
    before = (batch.qube_state(), batch.time().copy(), batch.voltage().copy())
    with pytest.raises(ValueError):
        env.step(actions)
    np.testing.assert_array_equal(batch.qube_state(), before[0])
    np.testing.assert_array_equal(batch.time(), before[1])
    np.testing.assert_array_equal(batch.voltage(), before[2])
    observations, _, _, _, info = env.step(np.ones((2, 1), np.float32))
    np.testing.assert_allclose(info["time"], 0.008)  # the bad step did not count


def test_world_parameters_set_at_reset_match_single_envs_with_those_parameters():
    masses = [0.02, 0.024, 0.03]

    def heavier(batch, world, random):
        batch.set_parameters(world, {"pendulum_mass": masses[world]})

    vector = gymnasium.make_vec("QubeSuite/Swingup-v0", num_envs=3, reset_hook=heavier)
    observations, _ = vector.reset(seed=SEEDS)
    singles = []
    for mass, seed in zip(masses + [None], SEEDS + [SEEDS[2]], strict=True):
        env = gymnasium.make("QubeSuite/Swingup-v0")
        if mass is not None:
            env.unwrapped.physics.set_parameters({"pendulum_mass": mass})
        env.reset(seed=seed)
        singles.append(env)
    for _ in range(50):
        observations, *_ = vector.step(np.full((3, 1), 2.0, np.float32))
        expected = [env.step(np.array([2.0], np.float32))[0] for env in singles]
        np.testing.assert_array_equal(observations, expected[:3])
    assert vector.unwrapped.batch.parameters(2)["pendulum_mass"] == 0.03
    assert not np.array_equal(observations[2], expected[3])  # the nominal pendulum swings differently


def test_record_episode_statistics_wrapper_works_on_it():
    env = gymnasium.wrappers.vector.RecordEpisodeStatistics(
        gymnasium.make_vec("QubeSuite/Swingup-v0", num_envs=2, time_limit=0.04))
    env.reset(seed=0)
    returns = np.zeros(2)
    for _ in range(10):
        _, rewards, _, truncated, info = env.step(np.zeros((2, 1), np.float32))
        returns += rewards
        if truncated.any():
            np.testing.assert_allclose(info["episode"]["r"], returns)
            assert (info["episode"]["l"] == 10).all()
            break
    else:
        pytest.fail("no episode ended")


def test_unknown_task_and_randomization_are_clear_errors():
    with pytest.raises(ValueError, match="valid tasks"):
        QubeVectorEnv("fly", 2)
    with pytest.raises(ValueError, match="randomization"):
        gymnasium.make_vec("QubeSuite/Swingup-v0", num_envs=2, randomization="default")


def test_a_world_given_a_calibration_runs_like_a_single_env_made_with_it():
    from qube_suite.calibration import calibration_file
    from qube_suite.devices.qube import parameters

    calibrated = parameters.REAL_QUBE_SERVO2
    assert {"latency_seconds", "voltage_deadzone", "cable_rest_angle", "cable_slack",
            "pendulum_encoder_offset"} <= set(parameters.effects_of(calibrated))
    sources = [calibrated, None, calibration_file.load(calibrated)]
    heavier = {"pendulum_mass": 0.03}  # then given to the last world by name: it keeps its effects

    def calibrate(batch, world, random):
        batch.set_parameters(world, sources[world])
        if world == 2:
            batch.set_parameters(world, heavier)

    vector = gymnasium.make_vec("QubeSuite/Swingup-v0", num_envs=3, reset_hook=calibrate)
    observations, _ = vector.reset(seed=SEEDS)
    singles = [gymnasium.make("QubeSuite/Swingup-v0", domain_kwargs={"parameters": source})
               for source in sources]
    singles[2].unwrapped.physics.set_parameters(heavier)
    expected = [env.reset(seed=seed)[0] for env, seed in zip(singles, SEEDS, strict=True)]
    np.testing.assert_array_equal(observations, expected)
    nominal = gymnasium.make("QubeSuite/Swingup-v0")
    nominal.reset(seed=SEEDS[0])
    rng = np.random.default_rng(1)
    for _ in range(150):
        actions = rng.uniform(-3.0, 3.0, (3, 1)).astype(np.float32)
        observations, *_ = vector.step(actions)
        expected = [env.step(action)[0] for env, action in zip(singles, actions, strict=True)]
        np.testing.assert_array_equal(observations, expected)
        uncalibrated = nominal.step(actions[0])[0]
    assert np.abs(uncalibrated - observations[0]).max() > 0.01  # the calibration changes the Qube
