"""The episode rules, once for one Qube and for a batch; batch tasks by construction; batch safety."""

import math

import numpy as np
import pytest

import qube_suite  # noqa: F401  (registers the Gymnasium ids)
from qube_suite import suite
from qube_suite.devices.qube import simulation as qube
from qube_suite.devices.qube.tasks import Swingup
from qube_suite.devices.qube.tasks.balance import Balance
from qube_suite.environment import Environment
from qube_suite.episode_rules import judge_step
from qube_suite.tasks import SUITE, BatchSafetyError, QubeTask, check_batch_safety, register
from qube_suite.tasks.base import voltage_from_action
from qube_suite.tasks.batch_safety import ProbeQubes
from qube_suite.wrappers import QubeVectorEnv, to_gymnasium

STATES = np.array([[0.1, 0.05, 0.0, 0.0],    # upright, safe
                   [0.2, 0.5, 1.0, 0.0],     # pendulum beyond balance's 20 degrees
                   [1.7, 0.0, 0.0, 0.0]])    # arm beyond 90 degrees


@pytest.mark.parametrize("diverged", [[False, False, False], [True, False, False]])
def test_judge_step_gives_a_batch_each_qubes_own_verdict(diverged):
    batch_task, batch = Balance(worlds=3), ProbeQubes(STATES, np.zeros(3), 3)
    steps = np.array([5, 10, 10])
    rewards, terminated, truncated = judge_step(batch_task, batch, np.array(diverged), steps, 10)
    for world, state in enumerate(STATES):
        reward, ended, cut = judge_step(Balance(), ProbeQubes(state, 0.0, None), diverged[world],
                                        [5, 10, 10][world], 10)
        assert (rewards[world], terminated[world], truncated[world]) == (reward, ended, cut)
        assert type(reward) is float and type(ended) is bool and type(cut) is bool
    assert terminated.tolist() == [diverged[0], True, True]
    assert truncated.tolist() == [False, False, False]  # world 0 has 5 of 10 steps; the others terminated
    alone = judge_step(Balance(), ProbeQubes(STATES[0], 0.0, None), False, 5, 10)[0]
    assert rewards[0] == (0.0 if diverged[0] else alone) and rewards[0] != rewards[1]


def test_judge_step_truncates_at_the_time_limit_unless_terminated():
    assert judge_step(Balance(), ProbeQubes(STATES[0], 0.0, None), False, 10, 10)[1:] == (False, True)
    assert judge_step(Balance(), ProbeQubes(STATES[2], 0.0, None), False, 10, 10)[1:] == (True, False)


def test_one_action_conversion_for_one_qube_and_a_batch():
    assert voltage_from_action(np.array([5.0]), 3.0) == 3.0
    np.testing.assert_array_equal(voltage_from_action([[5.0], [-1.0]], 3.0, worlds=2), [3.0, -1.0])
    with pytest.raises(ValueError, match="Action dimension mismatch"):
        voltage_from_action(np.zeros(2), 3.0, worlds=2)
    with pytest.raises(ValueError, match="finite"):
        voltage_from_action([[0.0], [math.nan]], 3.0, worlds=2)


class Reversed(Swingup):
    """Swing-up with the motor's wires swapped: the task's own `before_step` negates the action."""

    def before_step(self, action, physics):
        super().before_step(-np.asarray(action), physics)


@pytest.fixture
def reversed_task(monkeypatch):
    monkeypatch.setitem(SUITE._tasks, "reversed_swingup", Reversed)
    return "reversed_swingup"


def test_the_vector_env_applies_the_tasks_own_before_step(reversed_task):
    single = to_gymnasium(Environment(qube.make_physics(), Reversed(random=4)))
    vector = QubeVectorEnv(reversed_task, 2)
    vector.reset(seed=4)
    single.reset(seed=4)
    for volts in (1.0, 2.5, -3.0):
        observations, rewards, *_, info = vector.step(np.array([[volts], [volts]], dtype=np.float32))
        observation, reward, *_, single_info = single.step(np.array([volts], dtype=np.float32))
        assert info["voltage"][0] == single_info["voltage"] == -volts
        np.testing.assert_array_equal(observations[0], observation)
        assert rewards[0] == reward


def test_batch_tasks_are_made_by_a_constructor_and_keep_dm_controls_random():
    task = suite.make_task("qube", "swingup_follow", {"random": 7}, worlds=3)
    assert task.worlds == 3 and isinstance(task.random, np.random.RandomState)
    assert task.randoms[0] is task.random and len(task.randoms) == 3
    assert task.randoms[2].randint(1 << 30) == np.random.RandomState(9).randint(1 << 30)
    assert np.shape(task.target) == (3,)
    assert suite.make_task("qube", "swingup").worlds is None
    with pytest.raises(ValueError, match="worlds"):
        suite.load("qube", "swingup", task_kwargs={"worlds": 2})
    with pytest.raises(ValueError, match="integer seed"):
        Swingup(random=np.random.RandomState(0), worlds=2)


def test_overriding_get_termination_is_refused_with_the_hook_to_use():
    with pytest.raises(TypeError, match="in_safe_set"):
        class Stopping(Swingup):  # noqa: F841
            def get_termination(self, physics):
                return 0.0


class ArmBell(QubeTask):
    def initial_state(self, random):
        return np.array([random.uniform(-0.05, 0.05), math.pi, 0.0, 0.0])

    def get_reward(self, physics):
        return math.exp(-physics.arm_angle() ** 2)


def test_registering_a_task_written_with_math_exp_is_refused_naming_the_method():
    with pytest.raises(BatchSafetyError, match=r"task 'arm_bell': ArmBell\.get_reward is not batch-safe"):
        @register("custom")
        def arm_bell(**kwargs):
            return ArmBell(**kwargs)
    assert "arm_bell" not in SUITE


class ArmBellNumpy(ArmBell):
    def get_reward(self, physics):
        return np.exp(-physics.arm_angle() ** 2)


class BranchingSafeSet(ArmBellNumpy):
    def in_safe_set(self, physics):
        return bool(np.all(abs(physics.arm_angle()) < 1.0))  # one verdict for every world


def test_a_batch_answer_that_differs_from_each_qubes_is_refused():
    check_batch_safety(ArmBellNumpy)
    with pytest.raises(BatchSafetyError, match=r"BranchingSafeSet\.in_safe_set is not batch-safe: .* gave"):
        check_batch_safety(BranchingSafeSet)


def test_every_suite_task_is_batch_safe():
    for name, factory in SUITE.items():
        check_batch_safety(factory, name)
