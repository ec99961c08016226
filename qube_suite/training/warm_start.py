"""Starting a training run from a previous one (`train(init=DIR)`), also when the new task observes more.

A run on a follow task, whose features are the plain task's six plus
[theta - theta_target, theta_target], can start from a run on the plain task:
the networks' extra inputs start with zero weights, so that the first policy acts
as the plain one did (the arm's goal at 0 instead of the target), and their
normalisation starts at mean 0, variance 1. In the same way a run with
observation history (`qube_suite.policies.history`, past inputs after the current
ones) can start from a run without: the history's normalisation starts as the
current features' and, for the voltages, as a uniform draw within the limits.

A run can also start from a policy file (`from_policy`), e.g. a shipped one: its
actor and normalisation are copied, the value network starts afresh and learns
alone, the actor frozen, for the first `VALUE_WARMUP_STEPS`, so that the first
updates do not follow a value function that knows nothing. The normalisation
stays the file's (`FixedStatistics`): it is the actor's input layer, and
running statistics that drift toward the new run's states (exploring starts,
another randomization) change what the actor does while it is frozen; so they
did, `ppo:swingup_adaptive`'s evaluations falling from 1751 to 915 within the
warm-up of a calibrated fine-tuning. The same holds for a
run that starts from an imitation run (`imitation_run`, `training.imitation`). Imports
stable-baselines3 and torch.

An interrupted run continues from its latest checkpoint (`latest_checkpoint`,
`train(resume=True)`): model, normalisation, step count and evaluations.
"""

from __future__ import annotations

import json
import pathlib
import pickle
from typing import Any

import numpy as np
from stable_baselines3.common.running_mean_std import RunningMeanStd
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

from qube_suite.policies.history import input_size
from qube_suite.policies.mlp import MLPPolicy

VALUE_WARMUP_STEPS = 400_000
"""Steps a run started from a policy file trains its value network only (about 50 PPO updates)."""


class FixedStatistics(RunningMeanStd):
    """Observation statistics that training does not update (`update` keeps them as they are)."""

    def __init__(self, mean: np.ndarray, var: np.ndarray):
        super().__init__(shape=np.shape(mean))
        self.mean, self.var = np.array(mean, dtype=np.float64), np.array(var, dtype=np.float64)

    def update(self, arr: np.ndarray) -> None:
        """Keeps the statistics: a policy file's normalisation is part of its policy."""


def imitation_run(init: pathlib.Path) -> bool:
    """Whether `init` holds a run of `training.imitation`, whose value network was never fitted."""
    record = init / "training.json"
    return record.is_file() and "teacher" in json.loads(record.read_text())


def _check_widening(init: pathlib.Path, old_size: int, new_size: int) -> None:
    if old_size > new_size:
        raise ValueError(f"init: {init} observes {old_size} features, more than this task's {new_size}")


def run_history(init: pathlib.Path) -> int:
    """The history length of the run in `init` (0 for runs without, or before histories existed)."""
    record = init / "training.json"
    if not record.is_file():
        return 0
    return int(json.loads(record.read_text()).get("hyperparameters", {}).get("history", 0))


def widen_statistics(mean: np.ndarray, var: np.ndarray, features: int, history: int,
                     voltage_limit: float) -> tuple[np.ndarray, np.ndarray]:
    """Normalisation statistics of `features` features and a `history`, from those of a run that saw
    the first `len(mean)` features and no history: unseen features mean 0, variance 1; past features
    as the current ones; past voltages those of a uniform draw within +-`voltage_limit` (V)."""
    size = input_size(features, history)
    new_mean, new_var = np.zeros(size), np.ones(size)
    new_mean[:len(mean)], new_var[:len(var)] = mean, var
    current = slice(0, features)
    for step in range(1, history + 1):
        block = slice(step * features, (step + 1) * features)
        new_mean[block], new_var[block] = new_mean[current], new_var[current]
    new_var[features * (1 + history):] = voltage_limit ** 2 / 3.0
    return new_mean, new_var


def load_normalization(init: pathlib.Path, venv: VecEnv, gamma: float, history: int = 0) -> VecNormalize:
    """`venv` (with `history` past steps) normalised with the statistics the run in `init` left,
    extended for inputs it did not see (`widen_statistics`); in training mode, discounting returns
    with `gamma`."""
    with open(init / "vecnormalize.pkl", "rb") as file:
        previous: VecNormalize = pickle.load(file)
    old_size, new_size = previous.observation_space.shape[0], venv.observation_space.shape[0]
    _check_history(init, run_history(init), history, old_size, new_size)
    _check_widening(init, old_size, new_size)
    if old_size == new_size:
        previous.set_venv(venv)
        normalized = previous
    else:
        normalized = VecNormalize(venv, norm_reward=previous.norm_reward, clip_obs=previous.clip_obs,
                                  clip_reward=previous.clip_reward, epsilon=previous.epsilon)
        statistics = normalized.obs_rms
        statistics.mean, statistics.var = widen_statistics(
            previous.obs_rms.mean, previous.obs_rms.var, _features(new_size, history), history,
            float(venv.action_space.high[0]))
        statistics.count = previous.obs_rms.count
        normalized.ret_rms = previous.ret_rms
    normalized.training, normalized.gamma = True, gamma
    return normalized


def _features(size: int, history: int) -> int:
    """Features per observation in `size` inputs with a `history` (inverse of `input_size`)."""
    return (size - history) // (1 + history)


def _check_history(init: pathlib.Path, old_history: int, history: int, old_size: int, new_size: int) -> None:
    if old_history and (old_history != history or old_size != new_size):
        raise ValueError(f"init: {init} has a history of {old_history} steps over {old_size} inputs; "
                         f"this run has {history} over {new_size}: start from a run without history, "
                         "or with the same")


def load_model(algorithm, init: pathlib.Path, venv: VecEnv, seed: int, settings: dict[str, Any]):
    """The model the run in `init` left, to go on training on `venv` with this run's `settings`
    (hyperparameters) and `seed`; widened with zero weights for features it did not see."""
    previous = algorithm.load(init / "model.zip", device="cpu")
    old_size, new_size = previous.observation_space.shape[0], venv.observation_space.shape[0]
    _check_widening(init, old_size, new_size)
    if old_size == new_size:
        model = algorithm.load(init / "model.zip", env=venv, device="cpu", custom_objects=settings)
        model.set_random_seed(seed)
        return model
    model = algorithm("MlpPolicy", venv, seed=seed, device="cpu", policy_kwargs=previous.policy_kwargs,
                      **settings)
    weights = model.policy.state_dict()
    for name, value in previous.policy.state_dict().items():
        if value.shape == weights[name].shape:
            weights[name].copy_(value)
        else:  # a first layer: (hidden, old_size) -> (hidden, new_size)
            weights[name].zero_()
            weights[name][:, :old_size] = value
    model.policy.load_state_dict(weights)
    return model


def from_policy(algorithm, policy: MLPPolicy, venv: VecEnv, seed: int, settings: dict[str, Any],
                policy_kwargs: dict[str, Any], history: int = 0):
    """A new PPO model on `venv` (with `history` past steps) and its normalisation, whose actor is
    that of `policy` (a policy file without history, same or fewer features, widened with zero
    weights for inputs the file did not see; or one with this `history` and these inputs, as it is),
    and its normalisation, fixed (`FixedStatistics`); the value network starts afresh (`policy_kwargs`).
    Returns (model, VecNormalize-wrapped venv)."""
    import torch

    if algorithm.__name__ != "PPO" or policy.meta["algo"] != "ppo" or policy.meta["squash"]:
        raise ValueError(f"init: only PPO runs start from a PPO policy file ({policy.name}: "
                         f"{policy.meta['algo']}, this run: {algorithm.__name__.lower()})")
    old_size, new_size = policy.observation_mean.shape[0], venv.observation_space.shape[0]
    features = _features(new_size, history)
    if policy.history and (policy.history != history or old_size != new_size):
        raise ValueError(f"init: {policy.name} has a history of {policy.history} steps over {old_size} "
                         f"inputs; this run has {history} over {new_size}: give it the same history")
    if old_size > features and not policy.history:
        raise ValueError(f"init: {policy.name} observes {old_size} features, more than this task's "
                         f"{features}")
    normalized = VecNormalize(venv, gamma=settings["gamma"], norm_reward=True,
                              clip_obs=float(policy.meta["clip"]), epsilon=float(policy.meta["epsilon"]))
    normalized.obs_rms = FixedStatistics(policy.observation_mean, policy.observation_var) if policy.history \
        else FixedStatistics(*widen_statistics(policy.observation_mean, policy.observation_var, features,
                                               history, policy.voltage_limit))
    hidden = [weight.shape[0] for weight in policy.weights[:-1]]
    activations = {"tanh": torch.nn.Tanh, "relu": torch.nn.ReLU}
    kwargs = {**policy_kwargs, "activation_fn": activations[policy.meta["activation"]],
              "net_arch": {"pi": hidden, "vf": policy_kwargs["net_arch"]["vf"]}}
    model = algorithm("MlpPolicy", normalized, seed=seed, device="cpu", policy_kwargs=kwargs, **settings)
    layers = [m for m in model.policy.mlp_extractor.policy_net if isinstance(m, torch.nn.Linear)]
    with torch.no_grad():
        for layer, weight, bias in zip([*layers, model.policy.action_net], policy.weights, policy.biases,
                                       strict=True):
            layer.weight.zero_()
            layer.weight[:, :weight.shape[1]] = torch.as_tensor(weight)
            layer.bias.copy_(torch.as_tensor(bias))
    return model, normalized


def set_log_std(model, log_std: float) -> None:
    """Sets every entry of a model's exploration log-std (natural log of the noise scale) to `log_std`."""
    import torch

    with torch.no_grad():
        model.policy.log_std.fill_(float(log_std))


def actor_parameters(model) -> list:
    """The parameters of a PPO model's actor (its MLP, action head and exploration noise)."""
    policy = model.policy
    return [*policy.mlp_extractor.policy_net.parameters(), *policy.action_net.parameters(), policy.log_std]


def latest_checkpoint(directory: pathlib.Path, algo: str) -> Checkpoint | None:
    """The (model, normalisation) files of the latest checkpoint in `directory` that has both, or None."""
    found = []
    for model in directory.glob(f"{algo}_*_steps.zip"):
        steps = model.stem.split("_")[-2]
        statistics = directory / f"{algo}_vecnormalize_{steps}_steps.pkl"
        if steps.isdigit() and statistics.is_file():
            found.append((int(steps), model, statistics))
    return max(found)[1:] if found else None


Checkpoint = tuple[pathlib.Path, pathlib.Path]
"""A checkpoint of an interrupted run: its model file and its normalisation statistics file."""


def load_checkpoint_normalization(checkpoint: Checkpoint, venv: VecEnv) -> VecNormalize:
    """`venv` normalised with a checkpoint's statistics, in training mode."""
    normalized = VecNormalize.load(str(checkpoint[1]), venv)
    normalized.training = True
    return normalized


def load_checkpoint_model(algorithm, checkpoint: Checkpoint, venv: VecEnv, seed: int,
                          settings: dict[str, Any]):
    """The model of a checkpoint, to go on training on `venv` with `settings`, its step count kept."""
    model = algorithm.load(checkpoint[0], env=venv, device="cpu", custom_objects=settings)
    model.set_random_seed(seed + model.num_timesteps)  # not the first session's noise again
    return model


def continue_evaluations(evaluation, path: pathlib.Path) -> None:
    """Let an `EvalCallback` extend the evaluations an interrupted run left in `path`, and beat their
    best."""
    if not path.is_file():
        return
    with np.load(path) as previous:
        evaluation.evaluations_timesteps = list(previous["timesteps"])
        evaluation.evaluations_results = [list(r) for r in previous["results"]]
        evaluation.evaluations_length = [list(n) for n in previous["ep_lengths"]]
    if evaluation.evaluations_results:
        evaluation.best_mean_reward = float(max(np.mean(r) for r in evaluation.evaluations_results))
