"""Policies with observation history: the input layout, the numpy policy's memory, the policy file's
format, training's `VecHistory` against the numpy policy, and warm starts that add a history."""

import importlib.util
import json

import numpy as np
import pytest

from qube_suite import training
from qube_suite.policies import MLPPolicy, load, load_policy, save
from qube_suite.policies.features import trig
from qube_suite.policies.history import History, input_size

HAVE_RL = all(importlib.util.find_spec(name) for name in training.RL_EXTRA)
needs_rl = pytest.mark.skipif(not HAVE_RL, reason="needs the rl extra")


def test_history_inputs_are_current_then_past_features_then_past_voltages():
    history = History(2, worlds=1, feature_size=2)
    history.start(np.array([[1.0, 2.0]]))
    np.testing.assert_array_equal(history.inputs(np.array([[1.0, 2.0]])), [[1, 2, 1, 2, 1, 2, 0, 0]])
    history.push(np.array([[1.0, 2.0]]), np.array([0.5]))
    history.push(np.array([[3.0, 4.0]]), np.array([-0.5]))
    np.testing.assert_array_equal(history.inputs(np.array([[5.0, 6.0]])),
                                  [[5, 6, 3, 4, 1, 2, -0.5, 0.5]])
    assert input_size(6, 8) == 6 + 8 * 6 + 8


def echo_policy(history: int = 2, voltage_limit: float = 3.0) -> MLPPolicy:
    """A linear policy whose voltage is 2 V plus the voltage it applied one step before."""
    size = input_size(6, history)
    weight = np.zeros((1, size))
    weight[0, 6 * (1 + history)] = 1.0  # the last voltage
    meta = {"format": 2, "feature_map": "trig", "activation": "tanh", "squash": False, "epsilon": 0.0,
            "clip": 100.0, "voltage_limit": voltage_limit, "observation_size": 4, "history": history,
            "task": "swingup", "algo": "ppo"}
    return MLPPolicy([weight], [np.array([1.0])], np.zeros(size), np.ones(size), meta)


def test_a_policy_with_history_remembers_its_voltages_until_reset():
    policy = echo_policy()
    observation = [0.0, np.pi, 0.0, 0.0]
    assert [policy(observation) for _ in range(4)] == [1.0, 2.0, 3.0, 3.0]  # clipped at 3 V
    policy.reset()
    assert policy(observation) == 1.0
    batch = np.zeros((3, 4))
    np.testing.assert_array_equal(policy.actions(batch), [1.0, 1.0, 1.0])  # a new batch size restarts
    np.testing.assert_array_equal(policy.actions(batch), [2.0, 2.0, 2.0])


def test_policy_files_keep_the_history_and_refuse_mismatches(tmp_path):
    policy = echo_policy(history=3)
    again = load(save(policy, tmp_path / "echo.npz"))
    assert again.history == 3 and again.meta["format"] == 2
    observation = [0.1, 3.0, 0.0, 0.2]
    assert [again(observation) for _ in range(3)] == [policy(observation) for _ in range(3)]

    def written(**changes):
        meta = {**policy.meta, **changes}
        path = tmp_path / "bad.npz"
        arrays = {"weight_0": policy.weights[0], "bias_0": policy.biases[0],
                  "meta": np.array(json.dumps(meta)), "observation_mean": policy.observation_mean,
                  "observation_var": policy.observation_var}
        np.savez(path, **arrays)
        return path

    with pytest.raises(ValueError, match=r"format 3; this qube_suite reads formats 1, 2"):
        load(written(format=3))
    with pytest.raises(ValueError, match=r"must be 20 values .* 6 features and a history of 2, got 27"):
        load(written(history=2))
    with pytest.raises(ValueError, match="format 1 has no history"):
        load(written(format=1))
    with pytest.raises(ValueError, match="history must be an integer >= 0"):
        load(written(history=-1))


def test_shipped_format_1_policies_still_load_without_history():
    policy = load_policy("ppo:dampen")
    assert policy.meta["format"] == 1 and policy.history == 0


@needs_rl
def test_vec_history_gives_the_numpy_policy_inputs_also_across_episode_ends():
    """Step `VecHistory` with the numpy policy's own voltages: each world's inputs must equal those
    the numpy policy builds from the raw observations (same history, restarted at episode ends)."""
    from qube_suite.training.environments import VecHistory, make_vec_env, raw_vec_env

    length, worlds = 3, 2
    raw = raw_vec_env("balance", worlds, seed=4)
    venv = VecHistory(make_vec_env("balance", worlds, seed=4), length)
    inputs = venv.reset()
    observations = raw.reset()
    memory = History(length, worlds, 6)
    memory.start(trig(observations))
    ended = 0
    for step in range(700):  # balance episodes from a hanging-free start end early when they fall
        np.testing.assert_allclose(inputs, memory.inputs(trig(observations)), atol=1e-5)
        voltages = np.sin(0.05 * step + np.arange(worlds)) * 2.0
        inputs, _, dones, infos = venv.step(voltages[:, None].astype(np.float32))
        new_observations, _, raw_dones, raw_infos = raw.step(voltages[:, None].astype(np.float32))
        np.testing.assert_array_equal(dones, raw_dones)
        memory.push(trig(observations), voltages)
        for world in np.flatnonzero(dones):
            terminal = trig(raw_infos[world]["terminal_observation"][None, :])
            np.testing.assert_allclose(infos[world]["terminal_observation"],
                                       memory.inputs(terminal, [world])[0], atol=1e-5)
            ended += 1
        if np.any(dones):
            memory.start(trig(new_observations)[dones], dones)
        observations = new_observations
    assert ended > 0  # the episode ends were exercised
    venv.close()
    raw.close()


@needs_rl
def test_a_history_run_starts_from_a_run_without_and_acts_as_it_did(tmp_path):
    common = {"num_envs": 1, "evaluations": 1, "eval_episodes": 1, "checkpoints": 1, "progress": False}
    plain = training.train("balance", steps=256, hyperparameters={"n_steps": 256}, out=tmp_path / "plain",
                           **common)
    adaptive = training.train("balance", steps=256, out=tmp_path / "adaptive", init=plain.directory,
                              hyperparameters={"n_steps": 256, "learning_rate": 0.0, "history": 4}, **common)
    before, after = load_policy(plain.final_policy), load_policy(adaptive.final_policy)
    assert after.history == 4 and after.weights[0].shape[1] == input_size(6, 4)
    np.testing.assert_array_equal(after.weights[0][:, :6], before.weights[0])
    assert not after.weights[0][:, 6:].any()  # the history starts unweighted
    np.testing.assert_allclose(after.observation_var[6:12], after.observation_var[:6], rtol=0.25)  # not 1
    rng = np.random.default_rng(0)
    states = rng.normal(size=(5, 4)) * [0.3, 0.2, 1.0, 2.0]
    mean, var = after.observation_mean[:6].copy(), after.observation_var[:6].copy()
    before.observation_mean, before.observation_var = mean, var  # same statistics: the same policy
    before._scale = 1.0 / np.sqrt(var + before.meta["epsilon"])
    for _ in range(3):
        np.testing.assert_allclose(after.actions(states), before.actions(states), atol=1e-6)
        states = states + 0.05
    with pytest.raises(ValueError, match="has a history of 4 steps"):
        training.train("balance", steps=256, out=tmp_path / "other", init=adaptive.directory,
                       hyperparameters={"n_steps": 256, "history": 2}, **common)


@pytest.mark.slow
@needs_rl
def test_a_run_starts_from_a_shipped_policy_file_with_its_actor(tmp_path):
    from qube_suite.training import warm_start

    shipped = load_policy("ppo:swingup")
    result = training.train("swingup", steps=512, out=tmp_path / "run", init="ppo:swingup", num_envs=2,
                            evaluations=1, eval_episodes=1, checkpoints=1, progress=False,
                            hyperparameters={"n_steps": 256, "history": 2})
    assert result.steps < warm_start.VALUE_WARMUP_STEPS  # the actor stayed frozen
    policy = load_policy(result.final_policy)
    assert policy.history == 2 and policy.meta["training"]["init"] == "ppo:swingup"
    for i, (new, old) in enumerate(zip(policy.weights, shipped.weights, strict=True)):
        np.testing.assert_array_equal(new[:, :old.shape[1]], old)
        if i == 0:
            assert not new[:, old.shape[1]:].any()
    with pytest.raises(ValueError, match="only PPO runs start from a PPO policy file"):
        training.train("dampen", algo="sac", steps=256, init="ppo:dampen", out=tmp_path / "sac",
                       progress=False)
