"""Starting a training run from a previous one (`train(init=DIR)`), also when the new task observes more.

A run on a follow task, whose features are the plain task's six plus
[theta - theta_target, theta_target], can start from a run on the plain task:
the networks' extra inputs start with zero weights, so that the first policy acts
as the plain one did (the arm's goal at 0 instead of the target), and their
normalisation starts at mean 0, variance 1. Imports stable-baselines3 and torch.
"""

from __future__ import annotations

import pathlib
import pickle
from typing import Any

from stable_baselines3.common.vec_env import VecEnv, VecNormalize


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
