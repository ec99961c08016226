"""A diverging or non-finite simulation ends the episode cleanly, flagged, and the next reset works."""

import gymnasium
import numpy as np
import pytest

import qube_suite  # noqa: F401  (registers the Gymnasium ids)
from qube_suite import suite
from qube_suite.devices.qube.simulation import MAX_PLAUSIBLE_SPEED

UNSTABLE = {"arm_damping": 10.0}
"""An arm damping 2e6 times the nominal one: RK4 at 4 ms diverges within a step."""


def poison_nan(physics):
    physics.data.qvel[0] = np.nan


def poison_fast(physics):
    physics.data.qvel[1] = 2 * MAX_PLAUSIBLE_SPEED


def unstable(physics):
    physics.set_parameters(UNSTABLE)


@pytest.mark.parametrize("fault", [poison_nan, poison_fast, unstable])
@pytest.mark.parametrize("randomization", [None, "sim2real", "moderate"])
def test_dm_env_ends_the_episode_with_the_last_good_observation(fault, randomization):
    env = suite.load("qube", "swingup_follow", task_kwargs={"random": 1}, randomization=randomization)
    env.reset()
    for _ in range(5):
        timestep = env.step([1.0])
    fault(env.physics)
    timestep_after = env.step([1.0])
    assert timestep_after.last() and timestep_after.discount == 0.0 and timestep_after.reward == 0.0
    assert "diverged" in env.physics_error and env.step_count == 6
    for key, value in timestep_after.observation.items():
        assert np.isfinite(value).all()
        if randomization is None:
            np.testing.assert_array_equal(value, timestep.observation[key])  # the state before that step
    assert np.isfinite(env.physics.get_state()).all()
    assert env.physics.time() == pytest.approx(6 * 0.004, rel=0.06)  # moderate: 5 % control jitter
    env.physics.set_parameters({})  # the fault's cause removed, the next episode runs normally
    timestep = env.step([0.0])
    assert timestep.first() and env.physics_error is None
    for _ in range(50):
        timestep = env.step([1.0])
        assert timestep.mid() and np.isfinite(timestep.observation["state"]).all()


def test_control_jitter_steps_are_checked_too():
    env = suite.load("qube", "balance", task_kwargs={"random": 0},
                     randomization={"effects": {"control_jitter": {"fraction": 0.3}}})
    env.reset()
    env.step([0.0])
    unstable(env.physics)
    assert env.step([0.0]).discount == 0.0 and env.physics_error


def test_gymnasium_terminates_with_physics_error_in_info():
    env = gymnasium.make("QubeSuite/Rotor-v0", domain_kwargs={"parameters": UNSTABLE})
    observation, _ = env.reset(seed=0)
    step_observation, reward, terminated, truncated, info = env.step(np.array([2.0], np.float32))
    assert terminated and not truncated and reward == 0.0 and "diverged" in info["physics_error"]
    np.testing.assert_array_equal(step_observation, observation)
    with pytest.raises(RuntimeError, match="reset"):
        env.unwrapped.step(np.zeros(1, np.float32))
    env.unwrapped.physics.set_parameters({})
    observation, info = env.reset(seed=0)
    _, _, terminated, _, info = env.step(np.array([2.0], np.float32))
    assert not terminated and "physics_error" not in info and np.isfinite(observation).all()


JITTER = {"effects": {"control_jitter": {"fraction": 0.2}}}


@pytest.mark.parametrize("mode, randomization", [("NextStep", None), ("SameStep", None),
                                                 ("NextStep", JITTER)])
def test_vector_env_flags_the_diverged_world_and_the_others_go_on(mode, randomization):
    unstable_worlds = {1}

    def hook(batch, world, random):
        batch.set_parameters(world, UNSTABLE if world in unstable_worlds else {})

    vector = gymnasium.make_vec("QubeSuite/Swingup-v0", num_envs=3, reset_hook=hook, autoreset_mode=mode,
                                randomization=randomization)
    observations, _ = vector.reset(seed=[4, 5, 6])
    single = gymnasium.make("QubeSuite/Swingup-v0", randomization=randomization)
    single.reset(seed=6)
    action = np.full((3, 1), 1.5, np.float32)
    after, rewards, terminated, truncated, info = vector.step(action)
    np.testing.assert_array_equal(info["physics_error"], [False, True, False])
    np.testing.assert_array_equal(terminated, [False, True, False])
    assert rewards[1] == 0.0 and np.isfinite(after).all()
    assert np.isfinite(vector.unwrapped.batch.qube_state()).all()
    if mode == "NextStep":
        np.testing.assert_array_equal(after[1], observations[1])  # the state before the step
    else:
        np.testing.assert_array_equal(info["final_obs"][1], observations[1])
    np.testing.assert_array_equal(after[2], single.step(action[2])[0])  # other worlds unaffected
    unstable_worlds.clear()
    vector.unwrapped.batch.set_parameters(1, {})
    for _ in range(20):
        after, _, _, _, info = vector.step(action)
        assert "physics_error" not in info and np.isfinite(after).all()
        np.testing.assert_array_equal(after[2], single.step(action[2])[0])


def test_divergence_and_step_splitting_rules_give_one_answer_for_numbers_and_arrays():
    """One Qube and a batch share the rules: a number and an array entry get the same answer."""
    from qube_suite.devices.qube.simulation import MAX_TIMESTEP, plausible, split_step

    speeds = np.array([0.0, MAX_PLAUSIBLE_SPEED * 0.99, MAX_PLAUSIBLE_SPEED, np.inf, -np.inf, np.nan])
    together = plausible(speeds, -speeds)
    assert together.tolist() == [True, False, False, False, False, False]
    assert [bool(plausible(s, 0.0)) for s in speeds.tolist()] == [True, True, False, False, False, False]
    durations = np.array([0.5, 1.0, 1.0 + 1e-12, 1.5, 2.0, 2.5]) * MAX_TIMESTEP
    nsteps, timesteps = split_step(durations)
    assert nsteps.tolist() == [1, 1, 1, 2, 2, 3]
    assert (timesteps <= MAX_TIMESTEP * (1 + 1e-9)).all()  # a rounding error's excess takes no extra step
    np.testing.assert_allclose(nsteps * timesteps, durations, rtol=1e-15)
    for duration, nstep, timestep in zip(durations.tolist(), nsteps, timesteps, strict=True):
        assert split_step(duration) == (nstep, timestep)
