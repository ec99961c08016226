"""`qube-suite train` and the export of SB3 policies to numpy; training tests skip without the `rl` extra."""

import gc
import importlib.util
import json
import warnings

import numpy as np
import pytest

from qube_suite import cli, training
from qube_suite.policies import load_policy

HAVE_RL = all(importlib.util.find_spec(name) for name in training.RL_EXTRA)
needs_rl = pytest.mark.skipif(not HAVE_RL, reason="needs the rl extra (stable-baselines3, torch, "
                                                    "tensorboard)")


def test_missing_rl_extra_is_a_one_line_error(monkeypatch, capsys):
    monkeypatch.setattr(training.importlib.util, "find_spec",
                        lambda name: None if name == "torch" else object())
    assert cli.main(["train", "--task", "balance", "--steps", "100"]) == 2
    error = capsys.readouterr().err.strip()
    assert "\n" not in error and "torch" in error and "torch==2.13.0" in error and "[rl]" in error


def test_bad_arguments_fail_before_training():
    with pytest.raises(ValueError, match="unknown algorithm"):
        training.train("balance", algo="dqn")
    with pytest.raises(ValueError, match="unknown domain/task"):
        training.train("juggle")
    with pytest.raises(ValueError, match="valid"):
        training.train("balance", randomization={"parameters": {"pendulum_weight": 1.0}})
    with pytest.raises(ValueError, match="init_log_std is the exploration noise of a warm start: give init"):
        training.train("balance", hyperparameters={"init_log_std": -4.0})
    with pytest.raises(ValueError, match="environment_kwargs got an unexpected keyword argument 'frequency'"):
        training.train("balance", environment_kwargs={"frequency": 50.0})


@needs_rl
def test_environment_settings_reach_the_training_worlds():
    from qube_suite.training.environments import raw_vec_env

    venv = raw_vec_env("position", 1, 0, domain="qube_disk", environment_kwargs={"control_frequency": 50.0,
                                                                                  "time_limit": 1.0})
    assert venv.envs[0].unwrapped.environment.control_frequency == 50.0
    venv.reset()
    steps = 0
    while not venv.step([[0.0]])[2][0]:
        steps += 1
    assert steps + 1 == 50  # one second at 50 Hz
    venv.close()
    with pytest.raises(ValueError, match="native vector environment runs at its defaults"):
        raw_vec_env("balance", 2, 0, environment_kwargs={"control_frequency": 50.0})


def observations(size, count=64):
    rng = np.random.default_rng(1)
    rows = rng.normal(size=(count, size)) * [0.6, 2.0, 5.0, 10.0, 0.8][:size]
    return rows.astype(np.float32)


@needs_rl
@pytest.mark.parametrize(("algo", "task"), [("ppo", "swingup"), ("ppo", "balance_follow"), ("sac", "dampen")])
def test_numpy_policy_matches_the_torch_policy(algo, task):
    import stable_baselines3
    from stable_baselines3.common.vec_env import VecNormalize

    from qube_suite.policies.features import trig
    from qube_suite.training import export
    from qube_suite.training.environments import make_vec_env

    venv = VecNormalize(make_vec_env(task, 2, seed=0), norm_reward=False)
    raw = observations(venv.unwrapped.observation_space.shape[0])
    venv.obs_rms.update(trig(raw).astype(np.float32) * 1.5 + 0.3)  # statistics away from (0, 1)
    kwargs = {"policy_kwargs": {"net_arch": [32, 16]}, "device": "cpu", "seed": 0}
    model = getattr(stable_baselines3, algo.upper())("MlpPolicy", venv, **kwargs)
    with __import__("torch").no_grad():  # move the weights off their initial values
        for parameter in model.policy.parameters():
            parameter.add_(0.3 * __import__("torch").randn_like(parameter))
    policy = export.from_sb3(model, venv.obs_rms.mean, venv.obs_rms.var, epsilon=venv.epsilon,
                             clip=venv.clip_obs, feature_map="trig", observation_size=raw.shape[1],
                             voltage_limit=3.0, task=task, training={})
    torch_actions, _ = model.predict(venv.normalize_obs(trig(raw).astype(np.float32)), deterministic=True)
    numpy_actions = policy.actions(raw)
    assert np.ptp(numpy_actions) > 0.1  # not all at one limit: the comparison means something
    np.testing.assert_allclose(numpy_actions, torch_actions[:, 0], atol=1e-4)
    venv.close()


@needs_rl
@pytest.mark.parametrize("algo", ["ppo", "sac"])
def test_train_cli_runs_a_tiny_training(tmp_path, capsys, algo):
    out = tmp_path / "run"
    assert cli.main(["train", "--task", "balance", "--algo", algo, "--steps", "300", "--seed", "3",
                     "--num-envs", "2", "--evaluations", "2", "--eval-episodes", "1", "--checkpoints", "2",
                     "--out", str(out)]) == 0
    assert "trained" in capsys.readouterr().out
    record = json.loads((out / "training.json").read_text())
    assert record["algo"] == algo and record["steps"] >= 300 and record["wall_time_s"] > 0
    assert "time/total_timesteps" in (out / "progress.csv").read_text().splitlines()[0]
    assert list(out.glob("events.out.tfevents.*")) and list((out / "checkpoints").glob("*.zip"))
    policy = load_policy(out / "policy.npz")
    assert policy.meta["algo"] == algo and policy.meta["training"]["seed"] == 3
    assert abs(policy([0.0, 0.1, 0.0, 0.0])) <= 3.0


@needs_rl
def test_training_closes_its_log_files(tmp_path):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        training.train("balance", steps=64, num_envs=1, evaluations=1, eval_episodes=1, checkpoints=1,
                       progress=False, hyperparameters={"n_steps": 64}, out=tmp_path)
        gc.collect()
    unclosed = [str(warning.message) for warning in caught if issubclass(warning.category, ResourceWarning)]
    assert unclosed == []


@pytest.mark.slow
@needs_rl
def test_training_on_the_hardware_substitute_and_with_randomization(tmp_path):
    for kwargs in ({"domain": "qube_hardware"}, {"randomization": "sim2real"}):
        result = training.train("balance", steps=200, num_envs=1, evaluations=1, eval_episodes=1,
                                checkpoints=1, progress=False, hyperparameters={"n_steps": 256},
                                out=tmp_path / kwargs.get("domain", "randomized"), **kwargs)
        assert result.steps == 256 and result.policy.exists()


@pytest.mark.slow
@needs_rl
def test_init_continues_from_a_previous_run(tmp_path):
    first = training.train("balance", steps=256, num_envs=1, evaluations=1, eval_episodes=1, checkpoints=1,
                           progress=False, hyperparameters={"n_steps": 256}, out=tmp_path / "first")
    before = load_policy(first.final_policy)
    second = training.train("swingup", steps=256, num_envs=1, evaluations=1, eval_episodes=1, checkpoints=1,
                            progress=False, hyperparameters={"n_steps": 256, "learning_rate": 0.0},
                            out=tmp_path / "second", init=first.directory)
    after = load_policy(second.final_policy)
    assert after.meta["training"]["init"] == str(first.directory)
    for old, new in zip(before.weights, after.weights, strict=True):
        np.testing.assert_array_equal(old, new)  # learning rate 0: the same network
    with pytest.raises(ValueError, match="not a finished training run"):
        training.train("swingup", init=tmp_path)


@needs_rl
def test_exploring_starts_start_some_episodes_anywhere():
    from qube_suite.devices.qube.controllers.model import RigidBodyModel
    from qube_suite.training.environments import ExploringStarts

    def hanging(random):
        return np.array([0.0, np.pi, 0.0, 0.0])

    random = np.random.RandomState(0)
    starts = np.array([ExploringStarts(hanging, 0.5)(random) for _ in range(2000)])
    anywhere = starts[:, 1] != np.pi
    assert 0.45 < anywhere.mean() < 0.55
    assert np.abs(starts[anywhere, 1]).min() < 0.1 and np.abs(starts[anywhere, 0]).max() <= 0.5
    swinging = anywhere & (starts[:, 2] == 0.0)  # the arm at rest: on a swing near upright energy
    assert 0.4 < swinging.sum() / anywhere.sum() < 0.6
    model = RigidBodyModel.from_parameters()
    energies = np.array([model.energy(alpha, 0.0, dalpha) for _, alpha, _, dalpha in starts[swinging]])
    low, high = (bound * model.swing_up_energy for bound in ExploringStarts.APPROACH_ENERGY)
    assert (energies >= low - 1e-12).all() and (energies <= high + 1e-12).all()
    assert np.abs(starts[swinging, 3]).max() > 15.0  # fast through hanging, slow near upright
    assert (np.array([ExploringStarts(hanging, 0.0)(random) for _ in range(20)])[:, 1] == np.pi).all()


@pytest.mark.slow
@needs_rl
def test_a_follow_task_starts_from_its_plain_task_with_the_target_weighted_zero(tmp_path):
    plain = training.train("swingup", steps=256, num_envs=1, evaluations=1, eval_episodes=1, checkpoints=1,
                           progress=False, hyperparameters={"n_steps": 256}, out=tmp_path / "plain")
    follow = training.train("swingup_follow", steps=256, num_envs=1, evaluations=1, eval_episodes=1,
                            checkpoints=1, progress=False, out=tmp_path / "follow", init=plain.directory,
                            hyperparameters={"n_steps": 256, "learning_rate": 0.0})
    before, after = load_policy(plain.final_policy), load_policy(follow.final_policy)
    assert after.tasks == ("swingup_follow",) and after.weights[0].shape == (64, 8)
    np.testing.assert_array_equal(after.weights[0][:, :6], before.weights[0])
    assert not after.weights[0][:, 6:].any()  # the target's features start with zero weights
    for old, new in zip(before.weights[1:], after.weights[1:], strict=True):
        np.testing.assert_array_equal(old, new)
    with pytest.raises(ValueError, match="more than this task's"):
        training.train("swingup", steps=256, num_envs=1, progress=False, out=tmp_path / "narrower",
                       init=follow.directory, hyperparameters={"n_steps": 256})


@pytest.mark.slow
@needs_rl
def test_ppo_starts_from_a_shipped_policy_on_a_target_schedule(tmp_path):
    shipped = load_policy("ppo:balance_follow")
    run = training.train("balance_follow", steps=256, num_envs=1, evaluations=1, eval_episodes=1,
                         checkpoints=1, progress=False, out=tmp_path / "steps", init="ppo:balance_follow",
                         task_kwargs={"target": "steps", "target_hold_time": 2.0},
                         hyperparameters={"n_steps": 256, "learning_rate": 0.0})
    after = load_policy(run.final_policy)
    assert after.meta["training"]["init"] == "ppo:balance_follow"
    assert after.meta["training"]["task_kwargs"] == {"target": "steps", "target_hold_time": 2.0}
    for old, new in zip(shipped.weights + shipped.biases, after.weights + after.biases, strict=True):
        np.testing.assert_allclose(new, old, rtol=1e-6, atol=1e-7)  # learning rate 0: the same actor
    np.testing.assert_allclose(after.observation_mean, shipped.observation_mean, rtol=1e-2, atol=1e-3)
    with pytest.raises(ValueError, match="only PPO"):
        training.train("balance_follow", algo="sac", init="ppo:balance_follow")
    with pytest.raises(ValueError, match="valid: jump"):
        training.train("balance_follow", task_kwargs={"target": "zigzag"})
