"""The follow tasks' target schedules: keywords, their targets over time, batches, files, bad input."""

import math

import gymnasium
import numpy as np
import pytest
from test_vector_env import run_side_by_side

import qube_suite  # noqa: F401  (registers the Gymnasium ids)
from qube_suite import cli, suite
from qube_suite.tasks.follow import TARGET_LIMIT, read_target_file

DEG = math.pi / 180
PERIOD = 1 / 250


def targets_over(task_kwargs, steps, task="swingup_follow", episodes=1, action=0.0):
    """The observed target at every step of `episodes` episodes with a constant voltage."""
    env = suite.load("qube", task, task_kwargs={"random": 7, **task_kwargs})
    targets = []
    for _ in range(episodes):
        timestep = env.reset()
        targets.append(float(timestep.observation["target"][0]))
        for _ in range(steps):
            timestep = env.step([action])
            targets.append(float(timestep.observation["target"][0]))
            if timestep.last():
                break
    return np.array(targets)


def test_jump_is_the_default_schedule_and_keeps_its_draws():
    default = targets_over({}, 2047, episodes=2)
    assert np.array_equal(targets_over({"target": "jump"}, 2047, episodes=2), default)
    assert 8 < np.count_nonzero(np.diff(default)) < 50  # about twice a second over two 8 s episodes
    assert np.max(np.abs(default)) <= 80 * DEG


def test_steps_hold_each_target_for_the_hold_time_within_the_amplitude():
    targets = targets_over({"target": "steps", "target_hold_time": 2.0}, 2047)
    changes = np.flatnonzero(np.diff(targets)) + 1
    np.testing.assert_array_equal(changes, [500, 1000, 1500, 2000])  # every 2 s at 250 Hz
    assert np.max(np.abs(targets)) <= 60 * DEG  # default amplitude
    narrow = targets_over({"target": "steps", "target_hold_time": 0.5, "target_amplitude": 0.2}, 1000)
    assert np.count_nonzero(np.diff(narrow)) == 8 and np.max(np.abs(narrow)) <= 0.2


def test_sine_follows_its_formula_and_fixed_stays_put():
    targets = targets_over({"target": "sine", "target_amplitude": 0.5, "target_frequency": 0.25}, 1000)
    time = np.arange(len(targets)) * PERIOD
    np.testing.assert_allclose(targets, 0.5 * np.sin(2 * np.pi * 0.25 * time), atol=1e-9)
    default = targets_over({"target": "sine"}, 1000)
    time = np.arange(len(default)) * PERIOD
    np.testing.assert_allclose(default, 45 * DEG * np.sin(2 * np.pi * 0.2 * time), atol=1e-9)
    assert set(targets_over({"target": "fixed", "target_angle": -0.3}, 300)) == {-0.3}
    assert set(targets_over({"target": "fixed"}, 300)) == {0.0}


def test_a_target_file_is_read_as_a_piecewise_constant_sequence(tmp_path):
    path = tmp_path / "targets.csv"
    path.write_text("# arm targets for a lab exercise\ntime,target\n0,0.1\n0.5,-0.4\n1.0,0.7\n")
    targets = targets_over({"target": str(path)}, 400)
    np.testing.assert_array_equal(targets[:125], 0.1)
    np.testing.assert_array_equal(targets[125:250], -0.4)
    np.testing.assert_array_equal(targets[250:], 0.7)
    np.testing.assert_array_equal(read_target_file(path)[0], [0.0, 0.5, 1.0])


@pytest.mark.parametrize("text, message", [
    ("t,target\n0,0\n", "header"),
    ("time,target\n", "no rows"),
    ("time,target\n0.1,0\n", "start at 0"),
    ("time,target\n0,0\n1,0.1\n1,0.2\n", "line 4"),
    ("time,target\n0,2.0\n", "beyond"),
    ("time,target\n0,abc\n", "two numbers"),
    ("time,target\n0,nan\n", "finite"),
])
def test_malformed_target_files_are_refused_with_the_line(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        suite.load("qube", "balance_follow", task_kwargs={"target": str(path)})


@pytest.mark.parametrize("task_kwargs, message", [
    ({"target": "ramp"}, "valid: jump, steps, sine, fixed"),
    ({"target": "sine", "target_hold_time": 2.0}, "does not take target_hold_time"),
    ({"target": "fixed", "target_amplitude": 0.1}, "it takes target_angle"),
    ({"target": "steps", "target_hold_time": 0.0}, "positive"),
    ({"target": "sine", "target_frequency": -1.0}, "positive"),
    ({"target": "steps", "target_amplitude": 1.5}, "80 degrees"),
    ({"target": "fixed", "target_angle": math.inf}, "80 degrees"),
    ({"target": "missing.csv"}, "cannot be read"),
])
def test_bad_schedule_arguments_are_clear_errors(task_kwargs, message):
    with pytest.raises(ValueError, match=message):
        suite.load("qube", "swingup_follow", task_kwargs=task_kwargs)


def test_only_follow_tasks_take_a_target():
    for task in ("swingup", "balance", "rotor", "dampen"):
        with pytest.raises(ValueError, match="unexpected keyword argument .target.; valid: voltage_limit"):
            suite.load("qube", task, task_kwargs={"target": "sine"})


@pytest.mark.parametrize("kwargs", [{"target": "steps", "target_hold_time": 0.1},
                                    {"target": "sine", "target_frequency": 2.0},
                                    {"target": "fixed", "target_angle": 0.4}])
def test_native_vector_env_gives_single_envs_targets(kwargs):
    run_side_by_side("QubeSuite/SwingupFollow-v0", 200, time_limit=0.5, **kwargs)
    run_side_by_side("QubeSuite/BalanceFollowSparse-v0", 120, time_limit=0.3, **kwargs)


def test_native_vector_env_replays_a_target_file(tmp_path):
    path = tmp_path / "targets.csv"
    path.write_text("time,target\n0,0.2\n0.1,-0.2\n0.25,0.5\n")
    run_side_by_side("QubeSuite/SwingupFollow-v0", 200, time_limit=0.5, target=str(path))


def test_sparse_variants_follow_the_same_schedule():
    kwargs = {"target": "steps", "target_hold_time": 0.4}
    dense = targets_over(kwargs, 1000, task="swingup_follow")
    np.testing.assert_array_equal(targets_over(kwargs, 1000, task="swingup_follow_sparse"), dense)


def test_gymnasium_make_takes_the_schedule():
    env = gymnasium.make("QubeSuite/BalanceFollow-v0", target="fixed", target_angle=0.25)
    observation, info = env.reset(seed=0)
    assert observation[-1] == np.float32(0.25) and info["target"] == 0.25
    assert env.observation_space.high[-1] == np.float32(TARGET_LIMIT)
    with pytest.raises(ValueError, match="valid: jump"):
        gymnasium.make("QubeSuite/BalanceFollow-v0", target="zigzag")


def test_cli_eval_passes_the_schedule(capsys):
    code = cli.main(["eval", "--task", "balance_follow", "--controller", "balance", "--episodes", "1",
                     "--target", "fixed", "--target-angle", "0.3", "--json"])
    assert code == 0
    assert '"follow_error"' in capsys.readouterr().out
    assert cli.main(["eval", "--task", "balance_follow", "--controller", "balance", "--episodes", "1",
                     "--target", "sine", "--target-angle", "0.3"]) == 2
    assert "does not take target_angle" in capsys.readouterr().err
