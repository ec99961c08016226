"""Imitation of a controller (DAgger): the teacher hears the voltage really sent, bad settings are
refused, a tiny run fits the teacher's labels and leaves a run PPO starts from with its actor frozen."""

import csv
import importlib.util
import json

import numpy as np
import pytest

from qube_suite import baselines, training
from qube_suite.policies import load_policy
from qube_suite.training import imitation

HAVE_RL = all(importlib.util.find_spec(name) for name in training.RL_EXTRA)
needs_rl = pytest.mark.skipif(not HAVE_RL, reason="needs the rl extra")

HANGING = np.array([0.0, np.pi, 0.0, 0.0])
UPRIGHT = np.array([0.0, 0.05, 0.0, 0.0])        # balancing: the LQR's voltages do not saturate
NEXT = np.array([0.0005, 0.052, 0.1, 0.5])       # a sample later


def trig(state):
    return np.array([np.cos(state[0]), np.sin(state[0]), np.cos(state[1]), np.sin(state[1]), *state[2:]])


def test_a_controller_told_the_voltage_really_sent_predicts_with_it():
    told, untold, agreed = (baselines.make("swingup", latency_steps=1) for _ in range(3))
    returned = [controller(UPRIGHT) for controller in (told, untold, agreed)][0]
    told.sent(3.0)  # a learner sent 3 V instead: the observer expects the arm to have moved on
    agreed.sent(returned)  # the voltage it returned: nothing changes
    first, second, third = told(NEXT), untold(NEXT), agreed(NEXT)
    assert second == third
    assert first < second - 0.3  # the LQR answers the push it now knows of


def test_teachers_label_each_world_and_restart_the_ones_asked():
    teachers = imitation.Teachers("swingup", 2, 3.0)
    first = teachers.labels(np.array([trig(UPRIGHT)] * 2))
    assert first.shape == (2,)
    expected = baselines.make("swingup", latency_steps=imitation.TEACHER_LATENCY_STEPS)(UPRIGHT)
    assert first[0] == first[1] == pytest.approx(expected)
    teachers.sent(np.array([3.0, -3.0]))
    apart = teachers.labels(np.array([trig(NEXT)] * 2))
    assert apart[0] < apart[1] - 0.6  # their observers heard different voltages
    fresh = baselines.make("swingup", latency_steps=imitation.TEACHER_LATENCY_STEPS)(NEXT)
    teachers.reset(np.array([False, True]), [{}, {}])
    assert teachers.labels(np.array([trig(NEXT)] * 2))[1] == pytest.approx(fresh)  # world 1 starts afresh


def test_the_swingup_teacher_is_designed_once_for_all_worlds(monkeypatch):
    import scipy.linalg

    solved = []
    solve = scipy.linalg.solve_discrete_are
    monkeypatch.setattr(scipy.linalg, "solve_discrete_are", lambda *args: solved.append(1) or solve(*args))
    baselines.make("swingup")
    once = len(solved)  # the LQR's and the observer's Riccati equations
    solved.clear()
    teachers = imitation.Teachers("swingup", 64, 3.0)
    assert len(solved) == once
    labels = teachers.labels(np.array([trig(UPRIGHT)] * 64))
    assert labels.shape == (64,) and np.all(labels == labels[0])
    solved.clear()
    knowing = imitation.Teachers("swingup", 3, 3.0, knows_plant=True)
    assert len(solved) == once  # the batch's first design, until each world's first episode
    solved.clear()
    knowing.reset(np.ones(3, bool), [{}, {}, {}])
    assert len(solved) == 3 * once  # each world its own plant: one design each


def test_teachers_that_know_the_plant_are_built_for_each_episodes_draw():
    heavy = {"parameters": {"pendulum_mass": 0.032, "motor_resistance": 10.0},
             "effects": {"action_delay": {"steps": np.int64(1)}}}
    teachers = imitation.Teachers("swingup", 2, 3.0, knows_plant=True)
    teachers.reset(np.array([True, True]), [heavy, {}])
    labels = teachers.labels(np.array([trig(UPRIGHT)] * 2))
    for_heavy = baselines.make("swingup", voltage_limit=3.0, latency_steps=1, parameters=heavy["parameters"])
    nominal = baselines.make("swingup", voltage_limit=3.0, latency_steps=0)  # no delay drawn: none
    assert labels[0] == pytest.approx(for_heavy(UPRIGHT)) and labels[1] == pytest.approx(nominal(UPRIGHT))
    assert abs(labels[0] - labels[1]) > 0.05  # a heavier pendulum on a weaker motor needs more voltage
    unaware = imitation.Teachers("swingup", 1, 3.0)
    unaware.reset(np.array([True]), [heavy])  # told the draw, but built for the nominal Qube
    assert unaware.labels(np.array([trig(UPRIGHT)]))[0] == pytest.approx(
        baselines.make("swingup", voltage_limit=3.0, latency_steps=imitation.TEACHER_LATENCY_STEPS)(UPRIGHT))


def test_teachers_are_built_with_their_settings():
    teachers = imitation.Teachers("ilqr", 1, 3.0, settings={"swing_up": "energy", "reference_speed": 2.0})
    hanging = np.array([0.0, np.pi, 0.0, 0.0])
    expected = baselines.make("swingup", voltage_limit=3.0, latency_steps=imitation.TEACHER_LATENCY_STEPS)
    assert teachers.labels(np.array([trig(hanging)]))[0] == pytest.approx(expected(hanging))
    knowing = imitation.Teachers("ilqr", 1, 3.0, knows_plant=True, settings={"reference_speed": 2.0})
    knowing.reset(np.array([True]), [{"parameters": {"pendulum_mass": 0.03}}])
    controller = knowing._controllers[0]
    assert controller.reference_speed == 2.0 and controller.observer.latency_steps == 0
    assert controller.model.gravity_torque == pytest.approx(0.03 * 9.81 * 0.129 / 2, rel=0.01)


def test_teachers_of_a_follow_task_read_its_target_from_the_features():
    teachers = imitation.Teachers("follow", 1, 3.0, target=True)
    balanced = np.zeros(4)
    features = np.append(trig(balanced), [-0.4, 0.4])  # [the six, theta - theta_target, theta_target]
    teacher = baselines.make("follow", voltage_limit=3.0, latency_steps=imitation.TEACHER_LATENCY_STEPS)
    expected = teacher(np.append(balanced, 0.4))  # its own layout: the state, then the target
    assert teachers.labels(features[None, :])[0] == pytest.approx(expected)
    assert abs(expected) > 1.0  # balanced with the arm at 0 and the target at 0 it sends 0 V


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"teacher": "juggler"}, "unknown teacher 'juggler'"),
    ({"teacher": "rotor"}, "not made for task 'swingup'"),
    ({"steps": 5, "iterations": 10}, "steps >= iterations >= 1"),
    ({"exploring_starts": 1.5}, "exploring_starts must be a fraction"),
    ({"teacher_knows_plant": "yes"}, "teacher_knows_plant must be True or False"),
    ({"epochs": 0}, "epochs must be a positive integer"),
    ({"minibatch": 512.0}, "minibatch must be a positive integer"),
    ({"teacher_settings": {"latency_steps": 2}}, "imitation sets latency_steps itself"),
    ({"teacher_settings": {"swing_up": "energy"}}, "'swingup' got an unexpected keyword argument 'swing_up'"),
    ({"randomization": "widest"}, "unknown randomization preset 'widest'"),
])
def test_bad_settings_are_refused_before_any_environment(kwargs, message):
    with pytest.raises(ValueError, match=message):
        imitation.imitate("swingup", **kwargs)


@pytest.mark.parametrize(("task_kwargs", "message"), [
    ({"target": "zigzag"}, "unknown target schedule 'zigzag'"), ({"random": 1}, "drop 'random'")])
def test_bad_task_settings_are_refused_before_any_environment(task_kwargs, message):
    with pytest.raises(ValueError, match=message):
        imitation.imitate("swingup_follow", teacher="follow", task_kwargs=task_kwargs)


@pytest.mark.slow
@needs_rl
def test_a_tiny_imitation_fits_the_teacher_and_ppo_starts_from_it_with_the_actor_frozen(tmp_path):
    small = {"num_envs": 4, "n_steps": 64, "batch_size": 256,
             "policy_kwargs": {"net_arch": {"pi": [32, 32], "vf": [32, 32]}, "activation_fn": "tanh",
                               "log_std_init": -1.0, "ortho_init": False}}
    run = imitation.imitate("swingup", steps=8192, iterations=2, history=2, out=tmp_path / "imitation",
                            hyperparameters=small, epochs=3, minibatch=1024, progress=False)
    rows = list(csv.DictReader((run / "imitation.csv").read_text().splitlines()))
    assert [float(row["beta"]) for row in rows] == [1.0, 0.5]
    assert int(rows[-1]["labels"]) == 8192
    record = json.loads((run / "training.json").read_text())
    assert record["teacher"] == "swingup" and record["randomization"] == "wide" and record["epochs"] == 3
    assert record["minibatch"] == 1024
    policy = load_policy(run / "policy.npz")
    assert policy.history == 2 and [w.shape[0] for w in policy.weights] == [32, 32, 1]
    # the fitted actor answers the teacher's first state as the teacher does, more closely than 0 V
    policy.reset()
    teacher = baselines.make("swingup", latency_steps=imitation.TEACHER_LATENCY_STEPS)
    assert abs(policy(HANGING) - teacher(HANGING)) < abs(teacher(HANGING))
    before = policy.weights[0].copy()
    result = training.train("swingup", steps=512, init=run, out=tmp_path / "ppo", evaluations=1,
                            eval_episodes=1, checkpoints=1, progress=False, hyperparameters={
                                "history": 2, "n_steps": 64, "num_envs": 4, "batch_size": 256,
                                "init_log_std": -4.0})
    after = load_policy(result.final_policy).weights[0]
    np.testing.assert_array_equal(after, before)  # within VALUE_WARMUP_STEPS the actor stays as imitated
    from stable_baselines3 import PPO

    log_std = PPO.load(result.directory / "model.zip", device="cpu").policy.log_std.detach().numpy()
    np.testing.assert_array_equal(log_std, np.full_like(log_std, -4.0))  # the imitation's was -1


@pytest.mark.slow
@needs_rl
def test_a_follow_task_is_imitated_on_its_target_schedule(tmp_path):
    small = {"num_envs": 2, "n_steps": 64, "batch_size": 128,
             "policy_kwargs": {"net_arch": {"pi": [16], "vf": [16]}, "activation_fn": "tanh",
                               "log_std_init": -1.0, "ortho_init": False}}
    sine = {"target": "sine", "target_frequency": 0.5}
    run = imitation.imitate("swingup_follow", teacher="follow", steps=1024, iterations=1, history=0,
                            out=tmp_path, hyperparameters=small, task_kwargs=sine, progress=False)
    assert json.loads((run / "training.json").read_text())["task_kwargs"] == sine
    policy = load_policy(run / "policy.npz")
    assert policy.tasks == ("swingup_follow",) and policy.weights[0].shape == (16, 8)  # sees the target
