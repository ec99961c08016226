"""Model-derived controllers: LQR gains, balance, and swing-up at the default voltage limit."""

import math

import numpy as np
import pytest
import scipy.linalg
from reference_dynamics import FurutaPendulum

from qube_suite import baselines, parameters, suite
from qube_suite.baselines import lqr


def run_episode(task, controller, seed, **task_kwargs):
    env = suite.load("qube", task, task_kwargs={"random": seed, **task_kwargs})
    controller.reset()
    timestep = env.reset()
    episode_return, largest_arm_angle, upright_at = 0.0, 0.0, None
    while not timestep.last():
        timestep = env.step(controller(timestep.observation))
        episode_return += timestep.reward
        theta, alpha = timestep.observation["state"][:2]
        largest_arm_angle = max(largest_arm_angle, abs(theta))
        if upright_at is None and abs(alpha) < math.radians(10):
            upright_at = env.physics.time()
    return episode_return, env.step_count, timestep.discount, largest_arm_angle, upright_at


def test_lqr_gain_matches_the_closed_form_linear_model():
    p = parameters.resolve({})
    a_c, b_c = FurutaPendulum(p, 0.5 * p["pendulum_mass"] * parameters.PENDULUM_ROD_RADIUS**2
                              ).linearized_upright()
    block = np.zeros((5, 5))
    block[:4, :4], block[:4, 4:] = a_c, b_c
    discrete = scipy.linalg.expm(block * 0.004)
    a, b = discrete[:4, :4], discrete[:4, 4:]
    q, r = np.diag(lqr.STATE_WEIGHTS), np.array([[lqr.VOLTAGE_WEIGHT]])
    s = scipy.linalg.solve_discrete_are(a, b, q, r)
    expected = np.linalg.solve(r + b.T @ s @ b, b.T @ s @ a)
    np.testing.assert_allclose(lqr.lqr_gain(250.0), expected, rtol=1e-4)


def test_lqr_gain_depends_on_frequency_and_parameters():
    nominal = lqr.lqr_gain(250.0)
    assert not np.allclose(lqr.lqr_gain(500.0), nominal, rtol=1e-3)
    assert not np.allclose(lqr.lqr_gain(250.0, {"pendulum_mass": 0.03}), nominal, rtol=1e-3)


@pytest.mark.parametrize("seed", range(4))
def test_lqr_balances_for_a_whole_episode(seed):
    episode_return, steps, discount, _, _ = run_episode("balance", baselines.make("balance"), seed)
    assert steps == 2048 and discount == 1.0 and episode_return > 2000


def test_lqr_follows_the_target():
    episode_return, steps, _, _, _ = run_episode("balance_follow", baselines.make("balance"), 0)
    assert steps == 2048 and episode_return > 1700


def test_swingup_is_reachable_at_the_default_voltage_limit():
    """The evidence for the 3 V default: a swing-up that never leaves +-90 degrees."""
    controller = baselines.make("mpc", voltage_limit=3.0, seed=1)
    episode_return, steps, discount, largest_arm_angle, upright_at = run_episode("swingup", controller, 1)
    controller.close()
    assert steps == 2048 and discount == 1.0          # never terminated: |theta| stayed below 90 deg
    assert upright_at is not None and upright_at < 3.0
    assert largest_arm_angle < math.radians(80)
    assert episode_return > 1700


@pytest.mark.parametrize("observation, state, target", [
    ({"state": np.array([1.0, 2.0, 3.0, 4.0])}, [1, 2, 3, 4], 0.0),
    ({"state": np.array([1.0, 2.0, 3.0, 4.0]), "target": np.array([0.5])}, [1, 2, 3, 4], 0.5),
    (np.array([1.0, 2.0, 3.0, 4.0, 0.5], np.float32), [1, 2, 3, 4], 0.5),
    ([math.cos(1.0), math.sin(1.0), math.cos(2.0), math.sin(2.0), 3.0, 4.0], [1, 2, 3, 4], 0.0),
])
def test_controllers_read_every_observation_layout(observation, state, target):
    parsed_state, parsed_target = baselines.split_observation(observation)
    np.testing.assert_allclose(parsed_state, state, rtol=1e-6)
    assert parsed_target == pytest.approx(target)


def test_unknown_controller_lists_valid_names():
    with pytest.raises(ValueError, match="valid controllers: balance, mpc"):
        baselines.make("pid")
    with pytest.raises(ValueError, match="not a Qube observation"):
        baselines.split_observation(np.zeros(3))
