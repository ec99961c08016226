"""Train a policy on a Qube task with stable-baselines3 and export it as a numpy policy file.

    from qube_suite.training import train
    result = train("swingup", algo="ppo", steps=2_000_000, seed=0, out="runs/swingup")
    result.policy                                    # runs/swingup/best_policy.npz

Needs the optional `rl` extra (stable-baselines3, torch, tensorboard), which this
package imports only inside `train`. A run's directory holds `progress.csv` and
TensorBoard event files (`tensorboard --logdir DIR`), `evaluations.npz`,
`checkpoints/` (model and VecNormalize statistics), `model.zip` and
`vecnormalize.pkl` at the end, `policy.npz` (the final policy),
`best_policy.npz` (the policy at its best periodic evaluation) and
`training.json` (settings, steps and wall time). `init=DIR` continues from the
model and normalisation statistics a previous run left in DIR, for a curriculum
(balance, then swing-up; swing-up, then swing-up with a moving target: see
`warm_start`) or to fine-tune with a randomization; `init` may also name a PPO
policy file or a shipped policy ("ppo:swingup"), whose actor the run starts from,
or an imitation run (`training.imitation`); in these two cases the actor stays
frozen while the new value network learns alone (`warm_start.VALUE_WARMUP_STEPS`).
The hyperparameter `history` (default 0) gives the policy the last k observations
and voltages (`qube_suite.policies.history`), for policies that adapt to the plant.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import pathlib
import time
from typing import Any

from qube_suite import policies, suite
from qube_suite import randomization as randomization_configs
from qube_suite.arguments import check_keywords
from qube_suite.training.hyperparameters import EXPLORING_STARTS, HYPERPARAMETERS

RL_EXTRA = ("stable_baselines3", "torch", "tensorboard")
INSTALL_HINT = "install torch==2.13.0 first (a CPU build), then `pip install 'qube_suite[rl]'`"


@dataclasses.dataclass
class TrainingResult:
    """What a training run left: its directory, policy files, steps and wall-clock time (s)."""

    directory: pathlib.Path
    policy: pathlib.Path
    final_policy: pathlib.Path
    steps: int
    wall_time: float
    best_mean_return: float


def require_rl() -> None:
    """ImportError, in one line saying how to install them, unless the `rl` extra's packages are present."""
    missing = [name for name in RL_EXTRA if importlib.util.find_spec(name) is None]
    if missing:
        raise ImportError(f"training needs {', '.join(missing)}: {INSTALL_HINT}")


def _describe(randomization: Any) -> Any:
    if randomization is None or isinstance(randomization, (str, pathlib.Path)):
        return None if randomization is None else str(randomization)
    return "custom"


def train(task: str, algo: str = "ppo", steps: int = 2_000_000, seed: int = 0, randomization: Any = None,
          domain: str = "qube", out: str | pathlib.Path | None = None, num_envs: int | None = None,
          domain_kwargs: dict[str, Any] | None = None, evaluations: int = 20, eval_episodes: int = 8,
          checkpoints: int = 10, progress: bool = True, hyperparameters: dict[str, Any] | None = None,
          init: str | pathlib.Path | None = None, exploring_starts: float | None = None,
          resume: bool = False, task_kwargs: dict[str, Any] | None = None,
          calibration: str | pathlib.Path | None = None,
          environment_kwargs: dict[str, Any] | None = None) -> TrainingResult:
    """Train `algo` ("ppo" or "sac") on `task` for `steps` environment steps and export the policy.

    PPO rounds `steps` up to whole rollouts (n_steps x num_envs).

    Args:
        task, domain, randomization, domain_kwargs: as `suite.load`; training and
            evaluation episodes use the task's default settings (250 Hz, 3 V).
        seed: seeds the networks, the exploration and the environments.
        out: run directory (default `runs/<algo>_<task>_<seed>`).
        num_envs: environments stepped together (default: the algorithm's `num_envs`).
        evaluations, eval_episodes: evaluate the deterministic policy this many times
            during training, over this many episodes each.
        checkpoints: save the model this many times during training.
        progress: show progress on stderr (a bar on a terminal, a line per 10 % otherwise).
        hyperparameters: overrides of `HYPERPARAMETERS[algo]`; and `init_log_std`: with
            `init`, the exploration noise's log-std to start from (default: a run's own;
            from a policy file, `policy_kwargs`' `log_std_init`). `history` defaults to
            the init's.
        environment_kwargs: the environments' `control_frequency` and `time_limit` (as
            `suite.load`); not on the pendulum's native vector environment (give `domain_kwargs`
            or train another domain).
        task_kwargs: task settings for training and evaluation, e.g. a follow task's
            target schedule (`{"target": "steps"}`); as `suite.load`, without `random`.
        init: directory of a previous run of `algo` on a task with the same
            observation layout, or the same without the follow target or without
            history; training starts from its `model.zip` and `vecnormalize.pkl`
            (the network's shape is that run's; every other hyperparameter is this
            run's). Or a PPO policy file or shipped policy name: its actor and
            normalisation, with a fresh value network (`warm_start.from_policy`);
            a policy with history needs the same history (the default).
        exploring_starts: fraction of training episodes that start anywhere, in
            simulation (default: the task's, `EXPLORING_STARTS`).
        resume: if `out` holds checkpoints of an interrupted run (with these
            settings), continue from the latest one to `steps` in all, its
            evaluations kept; otherwise start as usual.
        calibration: a calibration file (`qube_suite.calibration`) to train for, under
            a randomization centred on it (`calibrated.randomization_for`) instead of
            `randomization`; without `init`, PPO fine-tunes the task's shipped policy
            (the adaptive one if there is one, with its fine-tuning hyperparameters under
            `hyperparameters`: `calibrated.fine_tuning`).
    """
    if algo not in HYPERPARAMETERS:
        raise ValueError(f"unknown algorithm {algo!r}; valid: {', '.join(HYPERPARAMETERS)}")
    if domain not in suite.TASKS_BY_DOMAIN or task not in suite.TASKS_BY_DOMAIN[domain]:
        raise ValueError(f"unknown domain/task {domain}/{task}; see `qube-suite list`")
    if not (isinstance(steps, int) and steps > 0):
        raise ValueError(f"steps must be a positive integer, got {steps!r}")
    if calibration is not None:
        if randomization is not None:
            raise ValueError("give a randomization or a calibration to centre one on, not both")
        from qube_suite.training.calibrated import fine_tuning, randomization_for

        randomization = randomization_for(calibration)
        if init is None and algo == "ppo":
            init, hyperparameters = fine_tuning(task, hyperparameters)
    if randomization is not None:
        randomization_configs.load(randomization)  # a bad config fails here, before any environment
    if exploring_starts is not None and not 0.0 <= exploring_starts <= 1.0:
        raise ValueError(f"exploring_starts must be a fraction in [0, 1], got {exploring_starts!r}")
    task_kwargs = dict(task_kwargs or {})
    if "random" in task_kwargs:
        raise ValueError("task_kwargs: training seeds the environments itself (seed=); drop 'random'")
    suite.make_task(domain, task, task_kwargs)  # bad task settings fail here, before any environment
    environment_kwargs = dict(environment_kwargs or {})
    check_keywords(environment_kwargs, ("control_frequency", "time_limit"), "environment_kwargs")
    if init is not None and not pathlib.Path(init).is_dir() and policies.names_a_policy(init):
        if algo != "ppo":
            raise ValueError("init: only PPO runs start from a PPO policy file; give SAC a run directory")
        init = policies.load_policy(init)
    elif init is not None:
        init = pathlib.Path(init)
        missing = [name for name in ("model.zip", "vecnormalize.pkl") if not (init / name).is_file()]
        if missing:
            raise ValueError(f"init: {init} is not a finished training run (no {', '.join(missing)}) "
                             "nor a policy file")
    if (hyperparameters or {}).get("init_log_std") is not None and init is None:
        raise ValueError("init_log_std is the exploration noise of a warm start: give init")
    require_rl()
    if init is not None and "history" not in (hyperparameters or {}):  # the init's history goes on
        from qube_suite.training import warm_start

        history = init.history if isinstance(init, policies.MLPPolicy) else warm_start.run_history(init)
        hyperparameters = {**(hyperparameters or {}), "history": history}
    return _train(task, algo, steps, seed, randomization, domain, out, num_envs, domain_kwargs, evaluations,
                  eval_episodes, checkpoints, progress, {**HYPERPARAMETERS[algo], **(hyperparameters or {})},
                  init, exploring_starts, resume, task_kwargs, calibration, environment_kwargs)


def _train(task, algo, steps, seed, randomization, domain, out, num_envs, domain_kwargs, evaluations,
           eval_episodes, checkpoints, progress, hyperparameters, init, exploring_starts,
           resume, task_kwargs, calibration, environment_kwargs) -> TrainingResult:
    import stable_baselines3
    import torch
    from stable_baselines3.common.callbacks import CallbackList, CheckpointCallback, EvalCallback
    from stable_baselines3.common.logger import configure
    from stable_baselines3.common.vec_env import VecNormalize

    from qube_suite import devices
    from qube_suite.policies import save
    from qube_suite.training import export, warm_start
    from qube_suite.training.callbacks import FrozenUntil, OnNewBest, ProgressBar
    from qube_suite.training.environments import make_vec_env

    torch.set_num_threads(1)  # small networks: one thread is fastest, and leaves cores to the worlds
    out = pathlib.Path(out or f"runs/{algo}_{task}_{seed}")
    out.mkdir(parents=True, exist_ok=True)
    settings = dict(hyperparameters)
    num_envs = num_envs or settings.pop("num_envs")
    settings.pop("num_envs", None)
    history = settings.pop("history", 0)
    init_log_std = settings.pop("init_log_std", None)
    if algo == "ppo":  # minibatches no larger than a rollout
        settings["batch_size"] = min(settings["batch_size"], settings["n_steps"] * num_envs)
    env_kwargs = {"domain": domain, "randomization": randomization, "domain_kwargs": domain_kwargs,
                  "task_kwargs": task_kwargs, "environment_kwargs": environment_kwargs}
    if exploring_starts is None:
        exploring_starts = EXPLORING_STARTS.get(task, 0.0)
    starts = exploring_starts if domain == "qube" else 0.0
    feature_map = devices.domain(domain).device.feature_map
    venv = make_vec_env(task, num_envs, seed, feature_map=feature_map, exploring_starts=starts,
                        history=history, **env_kwargs)
    checkpoint = warm_start.latest_checkpoint(out / "checkpoints", algo) if resume else None
    if checkpoint is not None:
        venv = warm_start.load_checkpoint_normalization(checkpoint, venv)
    elif init is None:
        venv = VecNormalize(venv, gamma=settings["gamma"], norm_reward=algo == "ppo")
    elif isinstance(init, pathlib.Path):
        venv = warm_start.load_normalization(init, venv, settings["gamma"], history)
    eval_worlds = 1 if domain != "qube" else min(eval_episodes, 8)
    eval_venv = VecNormalize(make_vec_env(task, eval_worlds, seed + 100_000, feature_map=feature_map,
                                          history=history, **env_kwargs),
                             training=False, norm_reward=False)
    observation_size = venv.unwrapped.observation_space.shape[0]
    policy_kwargs = dict(settings.pop("policy_kwargs"))
    activations = {"tanh": torch.nn.Tanh, "relu": torch.nn.ReLU}
    policy_kwargs["activation_fn"] = activations[policy_kwargs["activation_fn"]]
    algorithm = getattr(stable_baselines3, algo.upper())
    frozen = []
    if checkpoint is not None:
        model = warm_start.load_checkpoint_model(algorithm, checkpoint, venv, seed, settings)
    elif init is None:
        model = algorithm("MlpPolicy", venv, seed=seed, device="cpu", policy_kwargs=policy_kwargs, **settings)
    elif isinstance(init, pathlib.Path):
        model = warm_start.load_model(algorithm, init, venv, seed, settings)
        if init_log_std is not None:  # a warm start's exploration noise, set afresh
            warm_start.set_log_std(model, init_log_std)
    else:
        model, venv = warm_start.from_policy(algorithm, init, venv, seed, settings, policy_kwargs, history)
        if init_log_std is not None:
            warm_start.set_log_std(model, init_log_std)
    if init is not None and (not isinstance(init, pathlib.Path) or warm_start.imitation_run(init)):
        frozen = [FrozenUntil(warm_start.actor_parameters(model), warm_start.VALUE_WARMUP_STEPS)]
    resumed = int(model.num_timesteps) if checkpoint is not None else 0
    model.set_logger(configure(str(out), ["csv", "tensorboard"]))
    source = None if init is None else str(init) if isinstance(init, pathlib.Path) else init.name
    record = {"algo": algo, "task": task, "domain": domain, "randomization": _describe(randomization),
              "calibration": None if calibration is None else str(calibration),
              "domain_kwargs": domain_kwargs, "task_kwargs": task_kwargs,
              **({"environment_kwargs": environment_kwargs} if environment_kwargs else {}),
              "seed": seed, "num_envs": num_envs,
              "init": source, "exploring_starts": starts, "resumed_from_steps": resumed,
              "hyperparameters": hyperparameters, "stable_baselines3": stable_baselines3.__version__}
    start = time.perf_counter()

    def export_to(path: pathlib.Path) -> None:
        training = {**record, "steps": int(model.num_timesteps), "wall_time_s": time.perf_counter() - start}
        save(export.from_sb3(model, venv.obs_rms.mean, venv.obs_rms.var, epsilon=venv.epsilon,
                             clip=venv.clip_obs, feature_map=feature_map, observation_size=observation_size,
                             voltage_limit=float(venv.action_space.high[0]), task=task, training=training,
                             history=history),
             path)

    rollout = settings["n_steps"] * num_envs if algo == "ppo" else num_envs
    total = -(-steps // rollout) * rollout  # PPO learns in whole rollouts

    def every(count: int) -> int:  # callback period in vector steps for `count` events per run
        return max(1, total // max(1, count) // num_envs)

    evaluation = EvalCallback(eval_venv, n_eval_episodes=eval_episodes, eval_freq=every(evaluations),
                              deterministic=True, log_path=str(out), verbose=0,
                              callback_on_new_best=OnNewBest(lambda: export_to(out / "best_policy.npz")))
    if resumed:
        warm_start.continue_evaluations(evaluation, out / "evaluations.npz")
    checkpointing = CheckpointCallback(every(checkpoints), str(out / "checkpoints"), name_prefix=algo,
                                       save_vecnormalize=True)
    callbacks = [*frozen, checkpointing, evaluation] + ([ProgressBar(total, evaluation)] if progress else [])
    try:
        model.learn(total_timesteps=max(total - resumed, 1), callback=CallbackList(callbacks),
                    reset_num_timesteps=not resumed)
        wall_time = time.perf_counter() - start
        model.save(out / "model.zip")
        venv.save(str(out / "vecnormalize.pkl"))
        export_to(out / "policy.npz")
    finally:
        venv.close()
        eval_venv.close()
        model.logger.close()  # its CSV and TensorBoard files
    best = out / "best_policy.npz"
    summary = {**record, "steps": int(model.num_timesteps), "wall_time_s": wall_time,
               "best_mean_return": float(evaluation.best_mean_reward)}
    (out / "training.json").write_text(json.dumps(summary, indent=2, default=str))
    return TrainingResult(out, best if best.exists() else out / "policy.npz", out / "policy.npz",
                          int(model.num_timesteps), wall_time, float(evaluation.best_mean_reward))


__all__ = ["HYPERPARAMETERS", "TrainingResult", "require_rl", "train"]
