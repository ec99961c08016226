"""Hyperparameters of `qube-suite train`, per algorithm, as plain data.

Starting points are rl-zoo3's tuned settings (DLR-RM/rl-baselines3-zoo,
`hyperparams/ppo.yml` and `hyperparams/sac.yml`) for the nearest tasks, the
pybullet pendulums (`InvertedPendulumSwingupBulletEnv-v0` and the
`HalfCheetahBulletEnv-v0` defaults it shares in sac.yml) and `Pendulum-v1`.
What we changed, and why, is commented beside each value; docs/reinforcement-learning.md
tells how the shipped policies were trained.
"""

from __future__ import annotations

from typing import Any

PPO: dict[str, Any] = {
    "num_envs": 64,            # zoo: 8; 64 native-vector worlds make a step cheap (many worlds per call)
    "history": 0,              # ours: past observations and voltages the policy sees (policies.history)
    "n_steps": 128,            # zoo: 2048; 64 x 128 = 8192 samples per update, the zoo's order (8 x 2048)
    "batch_size": 2048,        # zoo: 64; 4 minibatches per update: gradient steps dominate CPU time
    "n_epochs": 10,            # zoo
    "gamma": 0.998,            # zoo: 0.99; at 250 Hz, 1 / (1 - 0.998) = 500 steps (2 s), a swing-up's length
    "gae_lambda": 0.95,        # zoo
    "learning_rate": 3e-4,     # zoo: 2.5e-4
    "clip_range": 0.2,         # zoo
    "ent_coef": 0.0,           # zoo
    "max_grad_norm": 0.5,      # zoo (SB3 default)
    "use_sde": True,           # zoo's Pendulum-v1 and pybullet settings: state-dependent exploration
    "sde_sample_freq": 4,      # zoo: noise redrawn every 4 steps (16 ms), smoother than white noise
    "policy_kwargs": {"net_arch": {"pi": [64, 64], "vf": [64, 64]}, "activation_fn": "tanh",
                      "log_std_init": -1.0, "ortho_init": False},  # zoo pybullet: log_std -2, ortho off
}
"""PPO with observation and reward normalisation (VecNormalize, as the zoo's `normalize: true`)."""

SAC: dict[str, Any] = {
    "num_envs": 4,
    "history": 0,              # ours: as PPO's
    "learning_rate": 7.3e-4,   # zoo (pybullet defaults)
    "buffer_size": 300_000,    # zoo
    "batch_size": 256,         # zoo
    "ent_coef": "auto",        # zoo
    "gamma": 0.998,            # zoo: 0.98; see PPO
    "tau": 0.02,               # zoo
    "train_freq": 8,           # zoo
    "gradient_steps": 8,       # zoo
    "learning_starts": 10_000,  # zoo
    "use_sde": False,          # zoo: True; plain squashed Gaussian, whose mean the numpy policy runs
    "policy_kwargs": {"net_arch": [400, 300], "activation_fn": "relu"},  # zoo: [400, 300], relu
}
"""SAC with observation normalisation only (rewards are already in [0, 1])."""

EXPLORING_STARTS: dict[str, float] = {"swingup": 0.5, "swingup_follow": 0.5}
"""Task -> fraction of training episodes that start anywhere (`training.environments.ExploringStarts`:
half of those slowly, half on a swing with about the energy of rest upright) in simulation. Ours:
without them PPO learnt to pump the pendulum up but not to catch it (returns near 1400 of 2048 after
3 M steps, the pendulum drifting through upright), or to hang still (0.2 per step, no risk of hitting
the arm limit) under randomization. With them alone, from scratch, it settled on spinning the pendulum
round (about 1230 after 2.4 M steps). PPO's swing-up run (the chain `ppo:swingup_follow` starts
from) also starts from the balance run (`--init`), which it keeps and extends outwards."""

HYPERPARAMETERS: dict[str, dict[str, Any]] = {"ppo": PPO, "sac": SAC}
"""Algorithm name -> hyperparameters (`num_envs` and `history` are ours; the rest go to the SB3
constructor)."""
