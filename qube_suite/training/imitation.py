"""Imitation of a model-based controller (DAgger): a warm start for policies that adapt to the plant.

    from qube_suite.training.imitation import imitate
    imitate("swingup", teacher="swingup", steps=3_000_000, randomization="wide", history=8,
            out="runs/imitation")             # runs/imitation/policy.npz, model.zip, vecnormalize.pkl

The model-based controllers (`qube_suite.devices.qube.controllers`) swing up and balance Qubes
whose parameters differ from their model by tens of percent: their observer
estimates, and their voltage cancels, the torques the model does not explain
(friction, the cable's spring), and the swing-up adapts its energy from swing to
swing. A network that sees the last steps' features and voltages
(`qube_suite.policies.history`) can learn to act as they do, and then goes on
learning from the task's reward (`train(init=DIR)`).

DAgger (Ross, Gordon and Bagnell, "A reduction of imitation learning and
structured prediction to no-regret online learning", AISTATS 2011): each
iteration rolls out, in the training randomization, a mixture that sends the
teacher's voltage with probability beta (1 in the first iteration, then falling
by `BETA_DECAY` per iteration) and the network's otherwise; the teacher labels
every state the mixture visits, its observer told the voltage really sent; the
network (the actor of a PPO model) is fitted to all labels so far by least
squares. The states a learner's own mistakes lead to are thus labelled too.

The run's directory is that of a training run (`model.zip`, `vecnormalize.pkl`,
`policy.npz`, `training.json`, and `imitation.csv` with each iteration's
loss and the mean return of its episodes), so that a PPO run can start from it
(`train(init=DIR, actor_warmup_steps=...)`: the value network, which imitation
does not fit, learns first). Imports stable-baselines3 and torch.

With `teacher_knows_plant`, each world's teacher is built, at the start of every
episode, for the plant the world drew: its physical parameters and its actuation
delay (a privileged teacher, as in Chen et al., "Learning by cheating", CoRL 2019;
Kumar et al., "RMA: Rapid motor adaptation for legged robots", RSS 2021). The
network still sees only the observations. A teacher whose model is far from the
plant can label states it cannot recover from: under `sim2real`, `ilqr` with an 8
degree lean limit, built for the nominal Qube with a step of latency, held the
pendulum up in 16 of 20 episodes of balance_follow on 3 s steps, and in 20 of 20
built for each episode's plant. With a 2 rad/s reference ramp as well, its student
on balance_follow kept the pendulum up in all of 30 episodes on both domains (the
nominal teacher's: 87 % in simulation); on swingup_follow it swung up worse
(docs/reinforcement-learning.md). On swingup under `wide`, the nominal `swingup` teacher's
student failed two held-out plants about the real Qube (82 % of their episodes; 90 % with
twice the steps); built for each world's plant, its student swung up all of them
(docs/transfer.md): the `swingup_adaptive` recipe's teacher.
"""

from __future__ import annotations

import csv
import functools
import json
import os
import pathlib
import time
from typing import Any

import numpy as np
import threadpoolctl

from qube_suite import baselines, suite
from qube_suite import randomization as randomization_configs
from qube_suite.conventions import ObservationLayout
from qube_suite.devices.qube.controllers import SwingupController
from qube_suite.devices.qube.controllers.batched import BatchedSwingup
from qube_suite.training.hyperparameters import HYPERPARAMETERS

BETA_DECAY = 0.5
"""The teacher's share of the voltages sent falls by this much per iteration after the first (to 0)."""
EPOCHS = 8
"""Passes over all labels so far after each iteration (`imitate`'s default)."""
MINIBATCH = 4096
"""Labels per gradient step (`imitate`'s default)."""
LEARNING_RATE = 1e-3
"""Adam's step size for the fit."""
EXPLORING_STARTS = 0.25
"""Fraction of the rollouts' episodes that start anywhere (`environments.ExploringStarts`): the
teacher also shows how to catch and recover, most episodes start as the task does."""
TEACHER_LATENCY_STEPS = 1
"""The teacher predicts its state one control step ahead, as on a board (the training randomization
delays the voltage by 0 or 1 step)."""


def imitate(task: str = "swingup", teacher: str = "swingup", steps: int = 2_000_000, iterations: int = 10,
            seed: int = 0, randomization: Any = "wide", out: str | pathlib.Path | None = None,
            history: int = 8, exploring_starts: float = EXPLORING_STARTS,
            hyperparameters: dict[str, Any] | None = None, task_kwargs: dict[str, Any] | None = None,
            teacher_knows_plant: bool = False, teacher_settings: dict[str, Any] | None = None,
            epochs: int = EPOCHS, minibatch: int = MINIBATCH, progress: bool = True,
            calibration: str | os.PathLike | None = None) -> pathlib.Path:
    """Fit a PPO actor with `history` past steps to controller `teacher` on `task` by DAgger, over
    `steps` environment steps in `iterations` iterations, each followed by `epochs` passes of the fit
    over all labels so far in steps of `minibatch` labels, in simulation under `randomization`, a
    fraction `exploring_starts` of the episodes starting anywhere; write a training run's files to
    `out` (default `runs/imitation_<task>_<seed>`) and return its directory.

    `hyperparameters`: overrides of `HYPERPARAMETERS["ppo"]`, for the model the actor lives in (its
    `policy_kwargs` set the network's size) and for a PPO run that starts from it. `task_kwargs`:
    the task's settings, e.g. a follow task's target schedule (`{"target": "steps"}`), as `train`'s.
    `teacher_knows_plant`: build each episode's teacher for the world's drawn parameters and delay.
    `teacher_settings`: keyword arguments of the teacher's controller (e.g. `ilqr`'s
    `{"swing_up": "energy", "reference_speed": 2.0}`). `calibration`: a calibration file to imitate
    for, with `randomization=None`: the randomization centred on it (`calibrated.randomization_for`, as
    `train(calibration=...)`), its path kept in the run's record.
    """
    if teacher not in baselines.names():
        raise ValueError(f"unknown teacher {teacher!r}; controllers: {', '.join(baselines.names())}")
    if task not in baselines.names()[teacher].tasks:
        raise ValueError(f"controller {teacher!r} is not made for task {task!r} "
                         f"(its tasks: {', '.join(baselines.names()[teacher].tasks)})")
    if not (isinstance(steps, int) and isinstance(iterations, int) and steps >= iterations >= 1):
        raise ValueError(f"need integers steps >= iterations >= 1, got steps={steps!r}, "
                         f"iterations={iterations!r}")
    for name, value in (("epochs", epochs), ("minibatch", minibatch)):
        if not (isinstance(value, int) and value >= 1):
            raise ValueError(f"{name} must be a positive integer, got {value!r}")
    teacher_settings = dict(teacher_settings or {})
    owned = {"control_frequency", "voltage_limit", "latency_steps", "parameters"} & set(teacher_settings)
    if owned:
        raise ValueError(f"teacher_settings: imitation sets {', '.join(sorted(owned))} itself")
    baselines.make(teacher, **teacher_settings)  # unknown or bad settings fail here
    if not isinstance(teacher_knows_plant, bool):
        raise ValueError(f"teacher_knows_plant must be True or False, got {teacher_knows_plant!r}")
    if not 0.0 <= exploring_starts <= 1.0:
        raise ValueError(f"exploring_starts must be a fraction in [0, 1], got {exploring_starts!r}")
    if calibration is not None:
        if randomization is not None:
            raise ValueError("give a randomization or a calibration to centre one on, not both")
        from qube_suite.training.calibrated import randomization_for

        randomization = randomization_for(calibration)
    if randomization is not None:
        randomization_configs.load(randomization)
    task_kwargs = dict(task_kwargs or {})
    if "random" in task_kwargs:
        raise ValueError("task_kwargs: imitation seeds the environments itself (seed=); drop 'random'")
    suite.make_task("qube", task, task_kwargs)  # bad task settings fail here, before any environment
    from qube_suite.training import require_rl

    require_rl()
    settings = {**HYPERPARAMETERS["ppo"], **(hyperparameters or {}), "history": history}
    out = pathlib.Path(out or f"runs/imitation_{task}_{seed}")
    return _imitate(task, teacher, steps, iterations, epochs, minibatch, seed, randomization, out,
                    exploring_starts, settings, task_kwargs, teacher_knows_plant, teacher_settings, progress,
                    None if calibration is None else str(calibration))


@functools.cache
def _blas_threads() -> threadpoolctl.ThreadpoolController:
    """The process's BLAS thread pools, found once."""
    return threadpoolctl.ThreadpoolController()


class Teachers:
    """One controller per world, built with `settings`: labels each world's current features, hears
    what was really sent.

    `knows_plant`: each episode's controller is built for the world's drawn plant (its reset info's
    `"parameters"` and `"effects"`' action delay); otherwise for the nominal Qube with
    `TEACHER_LATENCY_STEPS`. The `swingup` controller labels all worlds at once
    (`controllers.batched.BatchedSwingup`): designed once for the nominal Qube, or each world's
    design taken up by the batch at its new episode.
    """

    def __init__(self, name: str, worlds: int, voltage_limit: float, target: bool = False,
                 knows_plant: bool = False, settings: dict[str, Any] | None = None):
        self._name, self._voltage_limit, self._knows_plant = name, voltage_limit, knows_plant
        self._settings = dict(settings or {})
        self._target = target
        self._batch: BatchedSwingup | None = None
        design = self._build({})
        if type(design) is SwingupController and not target:
            self._batch = BatchedSwingup(design, worlds)
            self._controllers = []
        else:  # each its own: some controllers (ilqr's compiled kernel) cannot be copied
            self._controllers = [design, *(self._build({}) for _ in range(worlds - 1))]

    def _build(self, drawn: dict[str, Any]):
        """A controller for the nominal Qube, or (`knows_plant`) for the plant in reset info `drawn`.

        Its design solves Riccati equations of a few states: on one BLAS thread, which here takes a
        quarter of the time of two (30 against 120 ms a design on a busy 2-core machine)."""
        plant = {"latency_steps": TEACHER_LATENCY_STEPS}
        if self._knows_plant:
            delay = drawn.get("effects", {}).get("action_delay", {}).get("steps", 0)
            parameters = {name: float(value) for name, value in drawn.get("parameters", {}).items()}
            plant = {"latency_steps": int(delay), "parameters": parameters}
        with _blas_threads().limit(limits=1, user_api="blas"):
            controller = baselines.make(self._name, voltage_limit=self._voltage_limit, **self._settings,
                                        **plant)
        controller.observation_layout = ObservationLayout("trig", self._target)  # the learner's features
        return controller

    def labels(self, features: np.ndarray) -> np.ndarray:
        """The teachers' voltages (V) for each world's `trig` features (rows; in a follow task the
        trig observation's six, theta - theta_target, theta_target)."""
        if self._target:  # the trig observation: the six, then theta_target
            features = np.column_stack([features[:, :6], features[:, 7]])
        if self._batch is not None:
            return self._batch(ObservationLayout("trig").split_rows(features)[0])
        pairs = zip(self._controllers, features, strict=True)
        return np.array([controller(row) for controller, row in pairs])

    def sent(self, volts: np.ndarray) -> None:
        """Each world's voltage (V) really sent in answer to the features last labelled."""
        if self._batch is not None:
            self._batch.sent(volts)
            return
        for controller, value in zip(self._controllers, volts, strict=True):
            controller.sent(float(value))

    def reset(self, worlds: np.ndarray, reset_infos: list[dict[str, Any]]) -> None:
        """Start new episodes in the worlds of the boolean mask `worlds`, whose reset infos (what each
        world drew) are `reset_infos` (one per world, as SB3's `VecEnv.reset_infos`)."""
        if self._batch is not None:
            if self._knows_plant:
                for world in np.flatnonzero(worlds):
                    self._batch.redesign(world, self._build(reset_infos[world]))
            self._batch.reset(worlds)
            return
        for world in np.flatnonzero(worlds):
            if self._knows_plant:
                self._controllers[world] = self._build(reset_infos[world])
            self._controllers[world].reset()


def _imitate(task, teacher, steps, iterations, epochs, minibatch, seed, randomization, out, exploring_starts,
             settings, task_kwargs, teacher_knows_plant, teacher_settings, progress,
             calibration) -> pathlib.Path:
    import stable_baselines3
    import torch
    from stable_baselines3.common.running_mean_std import RunningMeanStd
    from stable_baselines3.common.vec_env import VecNormalize

    from qube_suite.policies import save
    from qube_suite.progress import Progress
    from qube_suite.training import export
    from qube_suite.training.environments import make_vec_env

    torch.set_num_threads(1)
    torch.manual_seed(seed)
    out.mkdir(parents=True, exist_ok=True)
    given, settings = dict(settings), dict(settings)
    num_envs, history = settings.pop("num_envs"), settings.pop("history")
    policy_kwargs = dict(settings.pop("policy_kwargs"))
    activations = {"tanh": torch.nn.Tanh, "relu": torch.nn.ReLU}
    policy_kwargs["activation_fn"] = activations[policy_kwargs["activation_fn"]]
    settings["batch_size"] = min(settings["batch_size"], settings["n_steps"] * num_envs)
    venv = make_vec_env(task, num_envs, seed, exploring_starts=exploring_starts, history=history,
                        randomization=randomization, task_kwargs=task_kwargs)
    normalized = VecNormalize(venv, gamma=settings["gamma"], norm_reward=True)
    model = stable_baselines3.PPO("MlpPolicy", normalized, seed=seed, device="cpu",
                                  policy_kwargs=policy_kwargs, **settings)
    policy = model.policy
    actor = [*policy.mlp_extractor.policy_net.parameters(), *policy.action_net.parameters()]
    optimizer = torch.optim.Adam(actor, lr=LEARNING_RATE)
    voltage_limit = float(venv.action_space.high[0])
    teachers = Teachers(teacher, num_envs, voltage_limit, target=suite.make_task("qube", task).follows_target,
                        knows_plant=teacher_knows_plant, settings=teacher_settings)
    statistics = RunningMeanStd(shape=venv.observation_space.shape)
    random = np.random.default_rng(seed)
    features = venv.venv.observation_space.shape[0] if history else venv.observation_space.shape[0]

    def normalize(inputs: np.ndarray) -> np.ndarray:
        return np.clip((inputs - statistics.mean) / np.sqrt(statistics.var + normalized.epsilon),
                       -normalized.clip_obs, normalized.clip_obs).astype(np.float32)

    def act(inputs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            latent = policy.mlp_extractor.forward_actor(torch.as_tensor(normalize(inputs)))
            return policy.action_net(latent).numpy()[:, 0].clip(-voltage_limit, voltage_limit)

    per_iteration = -(-steps // (iterations * num_envs))  # vector steps
    inputs_seen, labels_seen = [], []
    log = out / "imitation.csv"
    rows = []
    bar = Progress(per_iteration * num_envs * iterations, "step", "imitation") if progress else None
    start = time.perf_counter()
    observations = venv.reset()
    teachers.reset(np.ones(num_envs, bool), venv.unwrapped.reset_infos)
    for iteration in range(iterations):
        beta = 1.0 if iteration == 0 else max(0.0, 1.0 - BETA_DECAY * iteration)
        inputs = np.empty((per_iteration, num_envs, observations.shape[1]), np.float32)
        labels = np.empty((per_iteration, num_envs), np.float32)
        returns = []
        for step in range(per_iteration):
            inputs[step] = observations
            labels[step] = teachers.labels(observations[:, :features])
            sent = labels[step] if beta == 1.0 else np.where(random.random(num_envs) < beta, labels[step],
                                                             act(observations))
            teachers.sent(sent)
            observations, _, dones, infos = venv.step(sent[:, None])
            teachers.reset(dones, venv.unwrapped.reset_infos)
            returns += [info["episode"]["r"] for info in infos if "episode" in info]
            if bar is not None:
                bar.advance_to((iteration * per_iteration + step + 1) * num_envs)
        inputs, labels = inputs.reshape(-1, inputs.shape[2]), labels.reshape(-1)
        statistics.update(inputs)
        inputs_seen.append(inputs)
        labels_seen.append(labels)
        loss = _fit(policy, optimizer, normalize(np.concatenate(inputs_seen)), np.concatenate(labels_seen),
                    random, epochs, minibatch)
        done = (iteration + 1) * per_iteration * num_envs
        rows.append({"iteration": iteration, "beta": beta, "steps": done,
                     "labels": sum(len(x) for x in labels_seen), "loss_v2": loss,
                     "mean_return": float(np.mean(returns)) if returns else float("nan"),
                     "episodes": len(returns), "wall_time_s": time.perf_counter() - start})
        with open(log, "w", newline="") as file:
            writer = csv.DictWriter(file, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
    if bar is not None:
        bar.close()
    normalized.obs_rms = statistics
    wall_time = time.perf_counter() - start
    record = {"algo": "ppo", "task": task, "domain": "qube", "randomization":
              randomization if isinstance(randomization, str) or randomization is None else "custom",
              "calibration": calibration, "seed": seed, "num_envs": num_envs, "teacher": teacher,
              "iterations": iterations, "epochs": epochs, "minibatch": minibatch,
              "exploring_starts": exploring_starts, "task_kwargs": task_kwargs,
              "teacher_knows_plant": teacher_knows_plant, "teacher_settings": teacher_settings,
              "hyperparameters": given,
              "steps": iterations * per_iteration * num_envs, "wall_time_s": wall_time,
              "final_loss_v2": rows[-1]["loss_v2"], "stable_baselines3": stable_baselines3.__version__}
    save(export.from_sb3(model, statistics.mean, statistics.var, epsilon=normalized.epsilon,
                         clip=normalized.clip_obs, feature_map="trig",
                         observation_size=venv.unwrapped.observation_space.shape[0],
                         voltage_limit=voltage_limit, task=task, training=record, history=history),
         out / "policy.npz")
    model.save(out / "model.zip")
    normalized.save(str(out / "vecnormalize.pkl"))
    (out / "training.json").write_text(json.dumps(record, indent=2, default=str))
    venv.close()
    return out


def _fit(policy, optimizer, inputs: np.ndarray, labels: np.ndarray, random: np.random.Generator,
         epochs: int, minibatch: int) -> float:
    """`epochs` passes, in steps of `minibatch` labels, of least squares of the actor's mean voltage on
    `labels`; the last pass's mean loss."""
    import torch

    inputs, labels = torch.as_tensor(inputs), torch.as_tensor(labels)
    for _ in range(epochs):
        order = torch.as_tensor(random.permutation(len(labels)))
        total = 0.0
        for batch in order.split(minibatch):
            mean = policy.action_net(policy.mlp_extractor.forward_actor(inputs[batch]))[:, 0]
            loss = torch.nn.functional.mse_loss(mean, labels[batch])
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            total += loss.item() * len(batch)
    return total / len(labels)
