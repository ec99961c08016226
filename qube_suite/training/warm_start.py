"""Starting a training run from a previous one (`train(init=DIR)`), also when the new task observes more.

A run on a follow task, whose features are the plain task's six plus
[theta - theta_target, theta_target], can start from a run on the plain task:
the networks' extra inputs start with zero weights, so that the first policy acts
as the plain one did (the arm's goal at 0 instead of the target), and their
normalisation starts at mean 0, variance 1. A PPO run can also start from a
policy file (a shipped policy), which keeps the actor and its feature
normalisation but not the critic: that one starts afresh. Imports
stable-baselines3 and torch.
"""

from __future__ import annotations

import pathlib
import pickle
from typing import Any

from stable_baselines3.common.vec_env import VecEnv, VecNormalize

from qube_suite.policies import MLPPolicy


def _check_widening(init: pathlib.Path, old_size: int, new_size: int) -> None:
    if old_size > new_size:
        raise ValueError(f"init: {init} observes {old_size} features, more than this task's {new_size}")


def load_normalization(init: pathlib.Path, venv: VecEnv, gamma: float) -> VecNormalize:
    """`venv` normalised with the statistics the run in `init` left, extended by fresh ones for
    features it did not see; in training mode, discounting returns with `gamma`."""
    with open(init / "vecnormalize.pkl", "rb") as file:
        previous: VecNormalize = pickle.load(file)
    old_size, new_size = previous.observation_space.shape[0], venv.observation_space.shape[0]
    _check_widening(init, old_size, new_size)
    if old_size == new_size:
        previous.set_venv(venv)
        normalized = previous
    else:
        normalized = VecNormalize(venv, norm_reward=previous.norm_reward, clip_obs=previous.clip_obs,
                                  clip_reward=previous.clip_reward, epsilon=previous.epsilon)
        statistics = normalized.obs_rms
        statistics.mean[:old_size] = previous.obs_rms.mean
        statistics.var[:old_size] = previous.obs_rms.var
        statistics.count = previous.obs_rms.count
        normalized.ret_rms = previous.ret_rms
    normalized.training, normalized.gamma = True, gamma
    return normalized


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


def normalization_from_policy(policy: MLPPolicy, venv: VecEnv, gamma: float) -> VecNormalize:
    """`venv` normalised, in training mode, with the feature statistics `policy` was trained with."""
    size = venv.observation_space.shape[0]
    if policy.observation_mean.size != size:
        raise ValueError(f"init: policy {policy.name} observes {policy.observation_mean.size} features, "
                         f"this task {size}")
    normalized = VecNormalize(venv, gamma=gamma, norm_reward=True, clip_obs=float(policy.meta["clip"]),
                              epsilon=float(policy.meta["epsilon"]))
    normalized.obs_rms.mean[:] = policy.observation_mean
    normalized.obs_rms.var[:] = policy.observation_var
    normalized.obs_rms.count = 1e6  # statistics of a finished run: they move slowly from here
    return normalized


def model_from_policy(algorithm, policy: MLPPolicy, venv: VecEnv, seed: int, settings: dict[str, Any],
                      policy_kwargs: dict[str, Any]):
    """A fresh PPO model on `venv` whose actor is `policy`'s network (its hidden sizes and activation
    replace those of `policy_kwargs`); the critic has the same hidden sizes, newly initialised."""
    import torch

    if policy.meta["squash"]:
        raise ValueError(f"init: policy {policy.name} is not a PPO policy")
    hidden = [weight.shape[0] for weight in policy.weights[:-1]]
    activations = {"tanh": torch.nn.Tanh, "relu": torch.nn.ReLU}
    policy_kwargs = {**policy_kwargs, "net_arch": {"pi": hidden, "vf": hidden},
                     "activation_fn": activations[policy.meta["activation"]]}
    model = algorithm("MlpPolicy", venv, seed=seed, device="cpu", policy_kwargs=policy_kwargs, **settings)
    layers = [m for m in model.policy.mlp_extractor.policy_net if isinstance(m, torch.nn.Linear)]
    layers.append(model.policy.action_net)
    with torch.no_grad():
        for layer, weight, bias in zip(layers, policy.weights, policy.biases, strict=True):
            layer.weight.copy_(torch.as_tensor(weight))
            layer.bias.copy_(torch.as_tensor(bias))
    return model
