"""A task written in one file, with keywords of its own, registered after import: it loads everywhere."""

import math

import gymnasium
import numpy as np
import pytest

import qube_suite
from qube_suite import suite
from qube_suite.arguments import UnknownKeywordError
from qube_suite.tasks import SUITE, QubeTask, register
from qube_suite.tasks.registry import task_keywords
from qube_suite.training import recipes
from qube_suite.wrappers import GYMNASIUM_IDS, HARDWARE_GYMNASIUM_IDS

NAME, ENV_ID, HARDWARE_ID = "arm_goal", "QubeSuite/ArmGoal-v0", "QubeSuite/ArmGoalHardware-v0"


class ArmGoal(QubeTask):
    """Hold the arm at `goal` (rad), the pendulum hanging."""

    def __init__(self, goal: float = 0.5, width: float = 0.1, **kwargs):
        super().__init__(**kwargs)
        self.goal, self.width = goal, width

    def initial_state(self, random):
        return np.array([random.uniform(-0.05, 0.05), math.pi, 0.0, 0.0])

    def get_reward(self, physics):
        return np.exp(-(((physics.arm_angle() - self.goal) / self.width) ** 2))


def arm_goal(**kwargs) -> ArmGoal:
    return ArmGoal(**kwargs)


@pytest.fixture
def registered(forget_new_tasks):
    """`arm_goal` registered as a user would, after import (and forgotten after the test)."""
    register("custom")(arm_goal)
    return NAME


def test_task_keywords_are_read_from_the_factory_through_to_the_task_class():
    assert task_keywords(arm_goal) == ("goal", "width", "voltage_limit", "observation", "random")
    assert task_keywords(ArmGoal) == task_keywords(arm_goal)
    assert suite.task_keywords("qube", "rotor") == ("voltage_limit", "observation", "random")
    schedule = ("target", "target_amplitude", "target_hold_time", "target_frequency", "target_angle")
    assert suite.task_keywords("qube", "swingup_follow_sparse") == (*schedule, "voltage_limit", "observation",
                                                                    "random")
    assert suite.task_keywords("qube", "swingup") == ("voltage_limit", "observation", "random")


def test_a_factory_passing_kwargs_on_must_name_its_task_class(forget_new_tasks):
    def unnamed(**kwargs):
        return ArmGoal(**kwargs)

    with pytest.raises(TypeError, match=r"annotate the task class it returns"):
        register("custom")(unnamed)
    assert "unnamed" not in SUITE


def test_a_task_with_keywords_of_its_own_loads_through_suite_load(registered):
    environment = suite.load("qube", registered, task_kwargs={"goal": 0.3, "random": 1})
    assert environment.task.goal == 0.3
    environment.reset()
    assert 0.0 <= environment.step([0.5]).reward <= 1.0
    environment.close()
    with pytest.raises(UnknownKeywordError, match=r"'gaol'; valid: goal, width, voltage_limit, observation, "
                                                  r"random$"):
        suite.load("qube", registered, task_kwargs={"gaol": 0.3})


def test_the_schedule_keywords_are_the_follow_tasks_alone():
    with pytest.raises(UnknownKeywordError, match=r"'target_amplitude'; valid: voltage_limit"):
        suite.load("qube", "balance", task_kwargs={"target_amplitude": 0.3})
    environment = suite.load("qube", "balance_follow", task_kwargs={"target": "fixed", "target_angle": 0.2})
    environment.reset()
    assert environment.task.target == 0.2
    environment.close()


def test_a_task_registered_after_import_is_listed_and_gets_its_gymnasium_ids(registered):
    assert all(registered in suite.TASKS_BY_DOMAIN[domain] for domain in ("qube", "qube_hardware"))
    assert ("qube_hardware", registered) in suite.ALL_TASKS
    assert GYMNASIUM_IDS[ENV_ID] == registered and HARDWARE_GYMNASIUM_IDS[HARDWARE_ID] == registered
    env = gymnasium.make(ENV_ID, goal=-0.2)
    assert env.unwrapped.task.goal == -0.2
    env.reset(seed=0)
    env.close()
    assert gymnasium.spec(HARDWARE_ID).kwargs == {"task": registered, "domain": "qube_hardware"}
    with pytest.raises(UnknownKeywordError, match="'gaol'"):
        gymnasium.make(ENV_ID, gaol=-0.2)


def test_a_task_registered_after_import_runs_in_the_vector_env_like_single_envs(registered):
    vector = gymnasium.make_vec(ENV_ID, num_envs=2, goal=-0.4)
    single = gymnasium.make(ENV_ID, goal=-0.4)
    observations, _ = vector.reset(seed=3)
    np.testing.assert_array_equal(observations[0], single.reset(seed=3)[0])
    for _ in range(20):
        observations, rewards, *_ = vector.step(np.full((2, 1), -1.0, np.float32))
        observation, reward, *_ = single.step(np.array([-1.0], np.float32))
        np.testing.assert_array_equal(observations[0], observation)
        assert math.isclose(rewards[0], reward, rel_tol=1e-12)
    vector.close()
    single.close()


def test_a_task_registered_after_import_is_evaluated_and_trained(registered):
    def to_04(observation):
        return -3.0 * (observation["state"][0] - 0.4)

    returns = [qube_suite.evaluate(to_04, task=registered, episodes=1, task_kwargs={"goal": goal},
                                   environment_kwargs={"time_limit": 1.0}).mean_return
               for goal in (0.4, -0.4)]
    assert returns[0] > 10 * returns[1]  # the goal given reached the task
    recipes.check(recipes.Recipe("arm_goal", (recipes.Stage("only", registered, steps=1000, minutes=1.0,
                                                            task_kwargs={"goal": 0.4}),), target="-"))
    from qube_suite.training import train

    with pytest.raises(ValueError, match="steps must be a positive integer"):  # past the task's check
        train(registered, steps=0)


@pytest.mark.slow
def test_a_task_registered_after_import_trains_and_its_policy_is_evaluated(registered, tmp_path):
    pytest.importorskip("stable_baselines3")
    from qube_suite.training import train

    result = train(registered, steps=512, num_envs=2, evaluations=1, eval_episodes=1, checkpoints=1,
                   progress=False, out=tmp_path, task_kwargs={"goal": 0.3},
                   hyperparameters={"n_steps": 128, "batch_size": 64})
    assert result.steps == 512 and result.policy.exists()
    scored = qube_suite.evaluate(str(result.policy), task=registered, episodes=1, task_kwargs={"goal": 0.3},
                                 environment_kwargs={"time_limit": 1.0})
    assert scored.task == registered and len(scored.returns) == 1
