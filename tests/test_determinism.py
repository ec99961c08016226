"""Same seed, same trajectory: simulation with and without randomization, single and vector
environments, and the fast substitute board given the same actions."""

import gymnasium
import numpy as np
import pytest

import qube_suite  # noqa: F401  (registers the Gymnasium ids)
from qube_suite import randomization, suite
from qube_suite.hardware import QubeServo2

ACTIONS = np.random.default_rng(42).uniform(-3.0, 3.0, (150, 1))


def dm_trajectory(seed, preset, domain="qube", task="swingup_follow"):
    env = suite.load(domain, task, task_kwargs={"random": seed}, environment_kwargs={"time_limit": 0.2},
                     randomization=preset)
    rows = []
    timestep = env.reset()
    for action in ACTIONS:
        rows.append(np.concatenate([*timestep.observation.values(), [timestep.reward or 0.0]]))
        timestep = env.step(action)                                    # resets after each 50-step episode
    env.close()
    return np.array(rows)


@pytest.mark.parametrize("preset", [None, *randomization.PRESETS])
def test_dm_env_same_seed_same_trajectory(preset):
    np.testing.assert_array_equal(dm_trajectory(3, preset), dm_trajectory(3, preset))
    assert not np.array_equal(dm_trajectory(3, preset), dm_trajectory(4, preset))


@pytest.mark.parametrize("preset", [None, "moderate", "sim2real"])
def test_gymnasium_same_seed_same_trajectory_and_draws(preset):
    def run(seed):
        env = gymnasium.make("QubeSuite/BalanceFollow-v0", randomization=preset, time_limit=0.2)
        observation, info = env.reset(seed=seed)
        rows = [observation]
        for action in ACTIONS[:40]:
            observation, reward, terminated, truncated, _ = env.step(action.astype(np.float32))
            rows.append(np.append(observation, reward))
            if terminated or truncated:
                break
        return np.concatenate(rows), info.get("parameters")

    (first, drawn), (again, drawn_again) = run(11), run(11)
    np.testing.assert_array_equal(first, again)
    assert drawn == drawn_again


@pytest.mark.parametrize("preset", [None, *randomization.PRESETS])
def test_vector_env_same_seed_same_trajectory(preset):
    def run(seed):
        env = gymnasium.make_vec("QubeSuite/SwingupFollow-v0", num_envs=4, time_limit=0.1,
                                 randomization=preset)
        observations, _ = env.reset(seed=seed)
        rows = [observations]
        for action in ACTIONS[:60]:
            observations, rewards, *_ = env.step(np.tile(action, (4, 1)).astype(np.float32))
            rows.append(np.column_stack([observations, rewards]))
        env.close()
        return np.concatenate(rows, axis=1)

    np.testing.assert_array_equal(run(8), run(8))
    assert not np.array_equal(run(8), run(9))


def test_fast_substitute_board_is_deterministic_given_the_same_actions():
    def readings():
        rows = []
        with QubeServo2() as qube:
            for volts in ACTIONS[:, 0] * 2:
                currents, encoders, others = qube.action(volts)
                rows.append(np.concatenate([currents, encoders, others]))
            rows.append(qube.board.true_state())
        return np.concatenate(rows)

    np.testing.assert_array_equal(readings(), readings())


NOISY_SENSORS = {"effects": {"observation_noise": {"std": [0.01, 0.01, 0.1, 0.1]},
                             "action_delay": {"steps": {"distribution": "uniform", "low": 0, "high": 2}}}}
"""Effects the hardware domain takes (its plant's parameters are not randomized)."""


@pytest.mark.slow
@pytest.mark.parametrize("preset", [None, NOISY_SENSORS])
def test_hardware_domain_on_the_fast_substitute_is_deterministic_given_the_seed(preset):
    first = dm_trajectory(2, preset, "qube_hardware", "balance")[:60]
    np.testing.assert_array_equal(first, dm_trajectory(2, preset, "qube_hardware", "balance")[:60])
