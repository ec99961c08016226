"""A stable-baselines3 policy as a numpy policy file (needs torch)."""

from __future__ import annotations

from typing import Any

import numpy as np

from qube_suite.policies.mlp import FORMAT, MLPPolicy


def from_sb3(model: Any, observation_mean: np.ndarray, observation_var: np.ndarray, *, epsilon: float,
             clip: float, feature_map: str, observation_size: int, voltage_limit: float, task: str,
             training: dict[str, Any], history: int = 0, name: str = "policy") -> MLPPolicy:
    """The deterministic actor of a PPO or SAC `model` (an MLP policy) as an `MLPPolicy`.

    `observation_mean`, `observation_var`, `epsilon`, `clip`: the feature
    normalisation of training (VecNormalize's); `history`: past steps the network
    sees (`qube_suite.policies.history`); `training`: a JSON-ready record kept in
    the file.
    """
    from torch import nn

    policy = model.policy
    if hasattr(policy, "action_net"):  # PPO: MLP to the Gaussian's mean, in volts
        hidden, head, squash = policy.mlp_extractor.policy_net, policy.action_net, False
    else:  # SAC: MLP to the mean before tanh, scaled to the action range
        hidden, head, squash = policy.actor.latent_pi, policy.actor.mu, True
    if not isinstance(head, nn.Linear):
        raise ValueError("only plain linear action heads can be exported (train SAC without use_sde)")
    activations = {type(m) for m in hidden if not isinstance(m, nn.Linear)}
    names = {nn.Tanh: "tanh", nn.ReLU: "relu"}
    if len(activations) > 1 or not activations <= set(names):
        raise ValueError(f"only tanh or relu MLPs can be exported, got {activations}")
    layers = [m for m in hidden if isinstance(m, nn.Linear)] + [head]
    low, high = model.action_space.low, model.action_space.high
    if not np.allclose(-low, high):
        raise ValueError("the action space must be symmetric, +-voltage_limit")
    meta = {"format": FORMAT, "feature_map": feature_map, "activation": names[activations.pop()]
            if activations else "tanh", "squash": squash, "epsilon": float(epsilon), "clip": float(clip),
            "voltage_limit": float(voltage_limit), "observation_size": int(observation_size),
            "history": int(history), "task": task, "algo": type(model).__name__.lower(), "training": training}
    voltages = int(np.prod(model.action_space.shape))
    if voltages > 1:  # a device with several motors; one voltage stays the format's default
        meta["action_size"] = voltages
    weights = [layer.weight.detach().cpu().numpy() for layer in layers]
    biases = [layer.bias.detach().cpu().numpy() for layer in layers]
    return MLPPolicy(weights, biases, observation_mean, observation_var, meta, name=name)
