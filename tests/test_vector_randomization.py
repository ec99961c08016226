"""Randomization in the vector environment: world i is the single environment with its seed, draw for draw."""

import gymnasium
import numpy as np
import pytest
from test_vector_env import SEEDS, spin_or_random

import qube_suite  # noqa: F401  (registers the Gymnasium ids)
from qube_suite.devices.qube import parameters
from qube_suite.wrappers import QubeVectorEnv

EVERYTHING = {
    "parameters": {
        "pendulum_mass": {"distribution": "uniform", "low": 0.8, "high": 1.2},
        "arm_length": {"distribution": "normal", "mean": 1.0, "std": 0.05, "clip": [0.9, 1.1]},
        "arm_damping": {"distribution": "loguniform", "low": 0.5, "high": 2.0},
        "arm_friction": {"distribution": "uniform", "low": 0.0, "high": 1e-3, "relative": False},
        "pendulum_friction": {"distribution": "uniform", "low": 0.0, "high": 5e-5, "relative": False},
        "cable_stiffness": 1e-3,
    },
    "effects": {
        "quantization": {"counts_per_revolution": {"distribution": "uniform", "low": 256, "high": 4096}},
        "velocity_filter": {"cutoff": {"distribution": "uniform", "low": 20.0, "high": 100.0}},
        "observation_noise": {"std": [0.002, 0.002, 0.05, 0.05]},
        "observation_delay": {"steps": {"distribution": "uniform", "low": 0, "high": 2}},
        "action_delay": {"steps": {"distribution": "uniform", "low": 0, "high": 3}},
        "voltage_offset": {"voltage": {"distribution": "normal", "mean": 0.0, "std": 0.05}},
        "dead_zone": {"voltage": {"distribution": "uniform", "low": 0.0, "high": 0.1}},
        "saturation": {"voltage": {"distribution": "uniform", "low": 2.0, "high": 3.0}},
        "control_jitter": {"fraction": {"distribution": "uniform", "low": 0.0, "high": 0.5}},
    },
}
"""Every parameter kind and every effect, each effect's settings drawn per episode where they can be."""


def assert_draws(vector_info, world, single_info):
    """World `world`'s draws in the vector info are the single environment's reset info."""
    assert vector_info["_parameters"][world] and vector_info["_effects"][world]
    for name, value in single_info["parameters"].items():
        assert vector_info["parameters"]["_" + name][world]
        assert vector_info["parameters"][name][world] == value
    for name, settings in single_info["effects"].items():
        for key, value in settings.items():
            assert vector_info["effects"][name][key][world] == value


def assert_same_world(batch, world, env):
    physics = env.unwrapped.physics
    np.testing.assert_array_equal(batch.true_state()[world], physics.true_state())
    np.testing.assert_array_equal(batch.qube_state()[world], physics.qube_state())  # measured
    assert batch.time()[world] == physics.time()


def run_side_by_side(env_id, randomization, steps, seeds=SEEDS, threads=None, **kwargs):
    """Step a randomized vector env and single envs with the same seeds, actions and randomization;
    compare states, observations, rewards, flags and draws at every step. Returns the episodes ended."""
    vector = gymnasium.make_vec(env_id, num_envs=len(seeds), randomization=randomization, threads=threads,
                                **kwargs)
    singles = [gymnasium.make(env_id, randomization=randomization, **kwargs) for _ in seeds]
    batch = vector.unwrapped.batch
    observations, info = vector.reset(seed=seeds)
    for i, (env, seed) in enumerate(zip(singles, seeds, strict=True)):
        observation, single_info = env.reset(seed=seed)
        np.testing.assert_array_equal(observations[i], observation)
        assert_draws(info, i, single_info)
        assert_same_world(batch, i, env)
    rng = np.random.default_rng(0)
    limit = float(vector.single_action_space.high[0])
    ended = [False] * len(seeds)
    episodes = 0
    for _ in range(steps):
        actions = spin_or_random(observations, rng, limit)
        observations, rewards, terminated, truncated, info = vector.step(actions)
        for i, env in enumerate(singles):
            if ended[i]:
                observation, single_info = env.reset()
                single = (observation, 0.0, False, False)
                assert_draws(info, i, single_info)
            else:
                single = env.step(actions[i])[:4]
                assert "_parameters" not in info or not info["_parameters"][i]
            np.testing.assert_array_equal(observations[i], single[0])
            assert (rewards[i], terminated[i], truncated[i]) == single[1:]
            assert_same_world(batch, i, env)
            ended[i] = single[2] or single[3]
            episodes += ended[i]
    vector.close()
    return episodes


@pytest.mark.parametrize(("randomization", "env_id"), [
    ("none", "QubeSuite/Swingup-v0"), ("mild", "QubeSuite/SwingupFollow-v0"),
    ("moderate", "QubeSuite/Rotor-v0"), ("sim2real", "QubeSuite/Balance-v0"),
    (EVERYTHING, "QubeSuite/Dampen-v0"), (EVERYTHING, "QubeSuite/Rotor-v0"),
], ids=["none", "mild", "moderate", "sim2real", "everything-dampen", "everything-rotor"])
def test_worlds_replay_single_envs_across_autoresets(randomization, env_id):
    assert run_side_by_side(env_id, randomization, 150, time_limit=0.16, voltage_limit=5.0) >= 3 * len(SEEDS)


def test_jitter_split_into_several_physics_steps_per_world():
    """At 100 Hz a period takes 3 physics steps; jitter makes each world's 2 to 4, in one rollout."""
    run_side_by_side("QubeSuite/BalanceFollow-v0", EVERYTHING, 80, time_limit=0.3, control_frequency=100.0)


@pytest.mark.slow
def test_many_worlds_on_the_thread_pool():
    run_side_by_side("QubeSuite/Swingup-v0", "sim2real", 40, seeds=list(range(20)), threads=2, time_limit=0.1)


def test_parameters_differ_across_worlds_and_are_redrawn_at_each_reset():
    env = gymnasium.make_vec("QubeSuite/Swingup-v0", num_envs=4, randomization="moderate")
    batch = env.unwrapped.batch
    _, info = env.reset(seed=0)
    first = info["parameters"]["pendulum_mass"].copy()
    assert len(set(first)) == 4 and info["_parameters"].all()
    assert set(info["parameters"]) == {name for config_name in env.unwrapped.randomization.parameters
                                       for name in (config_name, "_" + config_name)}
    for world in range(4):
        assert batch.parameters(world)["pendulum_mass"] == first[world]
        assert dict(batch.parameters(world)) != dict(parameters.NOMINAL)
    _, info = env.reset()
    assert not np.isin(info["parameters"]["pendulum_mass"], first).any()
    _, info = env.reset(seed=0)
    np.testing.assert_array_equal(info["parameters"]["pendulum_mass"], first)  # the seed reproduces them


def test_only_worlds_that_start_an_episode_draw():
    env = gymnasium.make_vec("QubeSuite/Swingup-v0", num_envs=3, randomization=EVERYTHING,
                             autoreset_mode="Disabled", time_limit=0.02)
    batch = env.unwrapped.batch
    _, info = env.reset(seed=SEEDS)
    before = [batch.parameters(world) for world in range(3)]
    for _ in range(5):
        _, _, _, truncated, step_info = env.step(np.zeros((3, 1), np.float32))
        assert "parameters" not in step_info
    assert truncated.all()
    _, info = env.reset(options={"reset_mask": np.array([False, True, False])})
    np.testing.assert_array_equal(info["_parameters"], [False, True, False])
    np.testing.assert_array_equal(info["effects"]["_action_delay"], [False, True, False])
    assert [batch.parameters(world) for world in (0, 2)] == [before[0], before[2]]
    assert batch.parameters(1) != before[1]
    assert batch.parameters(1)["pendulum_mass"] == info["parameters"]["pendulum_mass"][1]


@pytest.mark.parametrize("autoreset_mode", ["NextStep", "SameStep"])
def test_info_is_what_a_sync_vector_env_of_single_envs_gives(autoreset_mode):
    kwargs = {"num_envs": 3, "time_limit": 0.05, "randomization": "moderate"}
    native = gymnasium.make_vec("QubeSuite/SwingupFollow-v0", vectorization_mode="vector_entry_point",
                                autoreset_mode=autoreset_mode, **kwargs)
    mode = gymnasium.vector.AutoresetMode(autoreset_mode)
    sync = gymnasium.make_vec("QubeSuite/SwingupFollow-v0", vectorization_mode="sync",
                              vector_kwargs={"autoreset_mode": mode}, **kwargs)

    def assert_equal(got, expected):
        if isinstance(expected, dict):
            assert set(got) == set(expected)
            for key in expected:
                assert_equal(got[key], expected[key])
        elif expected.dtype == object:
            assert got.dtype == object and list(got) == list(expected)
        else:
            assert got.dtype == expected.dtype
            np.testing.assert_array_equal(got, expected)

    assert_equal(native.reset(seed=5)[1], sync.reset(seed=5)[1])
    restarts = 0
    for _ in range(40):
        actions = np.full((3, 1), 2.0, np.float32)
        got, expected = native.step(actions), sync.step(actions)
        for a, b in zip(got[:4], expected[:4], strict=True):
            np.testing.assert_array_equal(a, b)
        info = {key: value for key, value in expected[4].items() if key not in ("final_obs", "_final_obs")}
        assert_equal({key: got[4][key] for key in info}, info)
        restarts += int(expected[4].get("_parameters", np.zeros(3)).sum())
    assert restarts >= 6


BAD_CONFIGS = [
    "default",
    {"parameters": {"pendulum_mas": {"distribution": "uniform", "low": 0.9, "high": 1.1}}},
    {"effects": {"quantisation": True}},
    {"effects": {"control_jitter": {"fraction": 0.7}}},
    {"effects": {"action_delay": {"steps": 1, "seconds": 0.004}}},
    {"parameters": {"arm_mass": {"distribution": "normal", "mean": 1.0, "std": 0.1}}},
    {"parameter": {}},
    42,
]


@pytest.mark.parametrize("config", BAD_CONFIGS, ids=lambda config: repr(config)[:30])
def test_bad_configs_raise_the_single_environment_errors(config):
    with pytest.raises(ValueError) as single:
        gymnasium.make("QubeSuite/Swingup-v0", randomization=config)
    with pytest.raises(ValueError) as vector:
        gymnasium.make_vec("QubeSuite/Swingup-v0", num_envs=2, randomization=config)
    assert str(vector.value) == str(single.value)
    with pytest.raises(ValueError, match="does not model motor_inductance"):
        QubeVectorEnv("swingup", 2, randomization={"parameters": {"motor_inductance": 1e-3}})
    with pytest.raises(FileNotFoundError):
        QubeVectorEnv("swingup", 2, randomization="missing.yaml")


def test_a_reset_of_no_world_draws_nothing():
    env = gymnasium.make_vec("QubeSuite/Swingup-v0", num_envs=2, randomization=EVERYTHING)
    env.reset(seed=0)
    before = env.unwrapped.batch.qube_state()
    observations, info = env.reset(options={"reset_mask": np.zeros(2, bool)})
    assert "parameters" not in info
    np.testing.assert_array_equal(env.unwrapped.batch.qube_state(), before)
