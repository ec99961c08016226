"""The scripts in examples/ run (their --short option keeps them fast)."""

import importlib.util
import pathlib

import pytest

EXAMPLES = pathlib.Path(__file__).resolve().parent.parent / "examples"


def load(name):
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_custom_task_reaches_its_goal(capsys, forget_new_tasks):
    load("custom_task").main(["--short", "--goal", "-30"])
    out = capsys.readouterr().out
    arm = float(out.split("arm at ")[1].split()[0])
    assert abs(arm + 30) < 3 and "of 250 steps" in out and "Gymnasium: observation (4,)" in out


def test_custom_task_checks_its_argument(forget_new_tasks):
    with pytest.raises(ValueError, match="within"):
        load("custom_task").ArmToAngle(goal=2.0)


def test_other_device_drives_the_substitute_board(capsys):
    load("other_device").main(["--short", "--volts", "-1"])
    out = capsys.readouterr().out
    turned = float(out.split("turned ")[1].split()[0])
    assert turned < -5 and "tachometer: -" in out  # negative volts turn clockwise


@pytest.mark.slow
def test_sb3_example_trains_or_says_how_to_install(capsys, tmp_path):
    example = load("train_sb3")
    if importlib.util.find_spec("stable_baselines3") is None:
        assert example.main(["--short"]) == 1
        assert "pip install torch==2.13.0" in capsys.readouterr().err
    else:
        assert example.main(["--short", "--plot", str(tmp_path / "ppo.png")]) == 0
        assert "PPO after 256 steps on balance" in capsys.readouterr().out
        assert (tmp_path / "ppo.png").stat().st_size > 10000


def test_custom_task_is_batch_safe(forget_new_tasks):
    from qube_suite.tasks import check_batch_safety

    check_batch_safety(load("custom_task").ArmToAngle)


def test_custom_task_runs_in_the_vector_env_like_single_envs(forget_new_tasks):
    import math

    import gymnasium
    import numpy as np

    load("custom_task")  # registers the task and its ids
    vector = gymnasium.make_vec("QubeSuite/ArmToAngle-v0", num_envs=2, goal=0.3)
    singles = [gymnasium.make("QubeSuite/ArmToAngle-v0", goal=0.3) for _ in range(2)]
    observations, _ = vector.reset(seed=5)
    for world, env in enumerate(singles):
        np.testing.assert_array_equal(observations[world], env.reset(seed=5 + world)[0])
    for volts in np.linspace(-2.0, 2.0, 30):
        observations, rewards, *_ = vector.step(np.full((2, 1), volts, np.float32))
        for world, env in enumerate(singles):
            observation, reward, *_ = env.step(np.array([volts], np.float32))
            np.testing.assert_array_equal(observations[world], observation)
            assert math.isclose(rewards[world], reward, rel_tol=1e-12)
    assert rewards.max() > 0.0
