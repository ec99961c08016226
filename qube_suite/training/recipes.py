"""Recipes: how each shipped policy is trained, as data, run in one command.

    from qube_suite.training import recipes
    recipes.RECIPES["swingup_follow"].steps      # 9500000 over four stages
    recipes.run("swingup_follow", out="runs/swingup_follow")   # runs/swingup_follow/<stage>/..., resumable

A recipe is a chain of training runs (`Stage`), each starting from an earlier
stage's run (`init`), with its own task, steps, randomization, exploring starts,
seed and hyperparameters, or a calibration to train for (`calibration`: the
randomization centred on a calibrated Qube, as `qube-suite train --calibration`);
its result is one policy file of its last stage
(`keep`: the final `policy.npz`, or `best_policy.npz`, the best periodic
evaluation's). `qube-suite train --task T` with no single-run option runs the
recipe named T; `qube-suite train --list-recipes` lists them. A stage whose
directory holds a finished run (`training.json`) is not run again, and an
interrupted stage continues from its latest checkpoint (`train(resume=True)`),
so an interrupted recipe resumes where it was, to within a checkpoint.

Expected wall times were measured by running each recipe on a 2-core machine,
one training job on one core while the other core trained too (PPO, 64 vector
worlds, 9 to 19 k steps/s; docs/transfer.md); a busier machine is slower.
"""

from __future__ import annotations

import dataclasses
import math
import os
import pathlib
from typing import Any

from qube_suite import baselines, suite
from qube_suite import randomization as randomization_configs
from qube_suite.calibration import calibration_file
from qube_suite.devices.qube.parameters import REAL_QUBE_SERVO2
from qube_suite.mjx import offered

KEEP = ("policy.npz", "best_policy.npz")


@dataclasses.dataclass(frozen=True)
class Stage:
    """One training run of a recipe: `train(task, steps=..., ...)` into `<recipe dir>/<name>`.

    `init`: the name of an earlier stage whose run this one starts from (or None);
    `exploring_starts`: the fraction of episodes that start anywhere (None: the
    task's default, `hyperparameters.EXPLORING_STARTS`); `keep`: the policy file
    this stage yields (`KEEP`); `minutes`: expected wall time. A stage with a
    `teacher` (a controller name) imitates it instead (`imitation.imitate`, DAgger,
    over `steps` steps, its history from `hyperparameters`; `exploring_starts`
    None: `imitation.EXPLORING_STARTS`; `teacher_knows_plant`: the teacher is built
    for each episode's drawn plant; `teacher_settings`: its controller's keyword
    arguments; `IMITATION_SETTINGS` in its `hyperparameters`: DAgger's iterations, the
    fit's epochs and minibatch, `imitate`'s defaults if absent). `task_kwargs`: the task's settings for
    training and evaluation, e.g. a follow task's target schedule
    (`{"target": "steps"}`, keywords of `qube_suite.tasks.follow`). `calibration`: a calibration
    file (`qube_suite.calibration`) to train for, instead of a `randomization`: the stage's PPO run
    draws its worlds from the randomization centred on that Qube (`calibrated.randomization_for`:
    its parameters, latency and dead zone), fine-tuning the stage it starts from (`init`), or
    imitating its `teacher` there.
    """

    name: str
    task: str
    steps: int
    minutes: float
    init: str | None = None
    randomization: str | None = None
    exploring_starts: float | None = None
    seed: int = 0
    hyperparameters: dict[str, Any] = dataclasses.field(default_factory=dict)
    keep: str = "policy.npz"
    teacher: str | None = None
    teacher_knows_plant: bool = False
    teacher_settings: dict[str, Any] = dataclasses.field(default_factory=dict)
    task_kwargs: dict[str, Any] = dataclasses.field(default_factory=dict)
    backend: str = "sb3"
    calibration: str | os.PathLike | None = None


IMITATION_SETTINGS = ("iterations", "epochs", "minibatch")
"""Hyperparameters of an imitation stage that go to `imitation.imitate` (DAgger's iterations, the fit's
passes and labels per gradient step), not to the model's PPO."""

BACKENDS = ("sb3", "jax")
"""Where a stage trains: stable-baselines3 on the numpy domains, or Brax on MJX (`qube_suite.mjx`)."""


@dataclasses.dataclass(frozen=True)
class Recipe:
    """Stages run in order; the policy is the last stage's `keep` file. `target`: what it reaches."""

    name: str
    stages: tuple[Stage, ...]
    target: str

    @property
    def steps(self) -> int:
        """Environment steps of all stages."""
        return sum(stage.steps for stage in self.stages)

    @property
    def minutes(self) -> float:
        """Expected wall time of all stages (min)."""
        return sum(stage.minutes for stage in self.stages)


IMITATION_ACTOR = {"net_arch": {"pi": [128, 128], "vf": [64, 64]}, "activation_fn": "tanh",
                   "log_std_init": -1.0, "ortho_init": False}
"""`policy_kwargs` of an imitation stage: a wider actor than PPO's default (64 x 64)."""
SMALL_PPO_STEPS = {"init_log_std": -4.0, "learning_rate": 3e-5, "clip_range": 0.1}
"""PPO after imitation: small exploration noise (gSDE log-std -4, the imitation's -1) and small
steps; with -1 or -2, or a learning rate of 1e-4, it undoes the imitated feedback."""



def imitated_for_the_real_qube(task: str, teacher: str, steps: int, minutes: float,
                               history: int = 0) -> Stage:
    """A stage imitating controller `teacher` on `task` in worlds drawn about the calibrated real
    Qube-Servo 2 (`REAL_QUBE_SERVO2`), with `history` past steps: how a controller that holds on a real
    Qube becomes a policy that does (`steps` environment steps, about `minutes` min)."""
    hyperparameters = {"policy_kwargs": IMITATION_ACTOR, **({"history": history} if history else {})}
    return Stage("imitation", task, steps, minutes, teacher=teacher, calibration=REAL_QUBE_SERVO2,
                 hyperparameters=hyperparameters)


GENTLE_ILQR = {"swing_up": "energy", "reference_speed": 2.0, "cost": {"lean_limit": math.radians(8.0)}}
"""`ilqr` as a teacher of steps: `swingup`'s energy swing-up (the planned one has not been learnt), a
2 rad/s reference ramp and an 8 degree lean limit, which keep the pendulum up under `sim2real`."""


RECIPES: dict[str, Recipe] = {recipe.name: recipe for recipe in (
    Recipe("balance", (
        Stage("balance", "balance", 500_000, 1.8),
        # the nominal policy fails a real Qube's 6 ms latency once its velocities are measured
        # (docs/calibration.md): fine-tuned for the calibrated real Qube-Servo 2
        Stage("real_qube", "balance", 500_000, 4.5, init="balance", calibration=REAL_QUBE_SERVO2)),
           "ppo:balance: 2040 in simulation, 100 % success on both domains, on the calibrated real Qube "
           "and on the real-Qube substitute"),
    Recipe("dampen", (Stage("dampen", "dampen", 700_000, 0.6, keep="best_policy.npz"),),
           "ppo:dampen: 1944 in simulation, 100 % success on both domains (best evaluation at 0.6 M steps)"),
    Recipe("balance_follow", (
        Stage("balance_follow_nominal", "balance_follow", 1_500_000, 1.1),
        Stage("balance_follow", "balance_follow", 1_000_000, 0.8, init="balance_follow_nominal",
              randomization="sim2real", keep="best_policy.npz")),
        "ppo:balance_follow: 1959 in simulation, 1950 on the substitute, 100 % success"),
    Recipe("swingup", (
        # PPO's swing-up (balance, then swing-up, then `sim2real`) and its fine-tunes fail a real Qube's
        # heavy arm and 6 ms latency (docs/calibration.md); the swingup controller, which swings that
        # Qube up, imitated without history. Small PPO steps from here undid it (1870 to 700 in 0.6 M steps).
        imitated_for_the_real_qube("swingup", "swingup", 1_500_000, 10),),
        "ppo:swingup: 1894 in simulation, 1885 on the substitute, 100 % success on both domains, on the "
        "calibrated real Qube measured as its board measures and on the real-Qube substitute"),
    Recipe("swingup_follow", (
        # PPO's swing-up chain with a follow stage failed a real Qube as ppo:swingup did; the follow
        # controller, which keeps a real Qube up, imitated in worlds about the calibrated real Qube-Servo 2,
        # with 8 past steps (without, 50 % on the real-Qube substitute)
        imitated_for_the_real_qube("swingup_follow", "follow", 1_500_000, 15, history=8),),
        "ppo:swingup_follow: 1816 in simulation, 1791 on the substitute, 100 % success on both domains "
        "and on the calibrated real Qube, 90 to 100 % on the real-Qube substitute"),
    Recipe("rotor", (
        # PPO's spinner (60 turns on the nominal model) made 1 to 5 on the real-Qube substitute, and
        # fine-tuned for the calibrated Qube, 1 to 2: the rotor controller, which spins a real Qube,
        # imitated in worlds about the calibrated real Qube-Servo 2
        imitated_for_the_real_qube("rotor", "rotor", 1_000_000, 8),),
        "ppo:rotor: 29 revolutions in simulation, 27 on the substitute, 28 on the real-Qube substitute, "
        "100 % success"),
    Recipe("swingup_adaptive", (
        # `swingup` built for each world's plant, imitated with 8 past steps under `wide` (which holds the
        # calibrated real Qube), the fit 2 passes in steps of 1024 labels; PPO from here undid the
        # imitation (docs/transfer.md)
        Stage("imitation", "swingup", 1_000_000, 5, teacher="swingup", randomization="wide",
              teacher_knows_plant=True,
              hyperparameters={"history": 8, "policy_kwargs": IMITATION_ACTOR, "epochs": 2,
                               "minibatch": 1024}),),
        "ppo:swingup_adaptive: 100 % success on each of 10 held-out plants (benchmarks/held_out.py), on the "
        "calibrated real Qube and on the real-Qube substitute"),
    Recipe("swingup_follow_sine", (
        # the follow controller's tracking, imitated on the sine: PPO on the task's reward alone
        # leaves the target (its arm term is small; docs/reinforcement-learning.md)
        Stage("imitation", "swingup_follow", 2_000_000, 5.2, teacher="follow", randomization="sim2real",
              task_kwargs={"target": "sine"},
              hyperparameters={"history": 8, "policy_kwargs": IMITATION_ACTOR}),
        Stage("ppo", "swingup_follow", 1_000_000, 1.2, init="imitation", randomization="sim2real",
              task_kwargs={"target": "sine"}, hyperparameters={"history": 8, **SMALL_PPO_STEPS})),
        "ppo:swingup_follow_sine: follows the 0.2 Hz +-45 degree sine (--target sine) to 0.03 rad "
        "on both domains, 100 % success"),
    Recipe("swingup_follow_steps", (
        # ilqr's crossings imitated on steps held 3 s; PPO from here on the task's reward gave the
        # tracking up (0.07 to 0.12 rad; docs/reinforcement-learning.md), so the actor is the imitation's
        Stage("imitation", "swingup_follow", 2_000_000, 16, teacher="ilqr", teacher_settings=GENTLE_ILQR,
              randomization="sim2real", task_kwargs={"target": "steps", "target_hold_time": 3.0},
              hyperparameters={"history": 8, "policy_kwargs": IMITATION_ACTOR}),),
        "ppo:swingup_follow_steps: follows steps held 3 s within +-60 degrees (--target steps "
        "--target-hold-time 3) to 0.07 to 0.09 rad on both domains, 97 to 100 % success"),
)}
"""Recipe name -> recipe; every shipped policy `ppo:<name>` has the recipe `<name>`."""

JAX_RECIPES: dict[str, Recipe] = {recipe.name: recipe for recipe in (
    Recipe("swingup", (Stage("swingup", "swingup", 60_000_000, 2, randomization="sim2real_frictionless",
                             backend="jax"),),
           "1825 in simulation, 1850 on the substitute, 100 % success; 106 s on one H200 "
           "(docs/gpu-training.md)"),
)}
"""The recipes of the JAX backend (`qube-suite train --task T --backend jax`), by name."""

RECIPES_BY_BACKEND = {"sb3": RECIPES, "jax": JAX_RECIPES}


def check(recipe: Recipe) -> None:
    """ValueError unless `recipe` can run: known tasks and task settings, inits naming earlier stages,
    loadable randomizations, positive steps, known kept files, unique stage names."""
    seen: set[str] = set()
    for stage in recipe.stages:
        where = f"recipe {recipe.name!r}, stage {stage.name!r}"
        if stage.name in seen:
            raise ValueError(f"{where}: a stage of that name comes earlier")
        if stage.backend not in BACKENDS:
            raise ValueError(f"{where}: backend must be one of {', '.join(BACKENDS)}, got {stage.backend!r}")
        if stage.backend == "jax":
            try:
                offered.check_task(stage.task)
            except ValueError as error:
                raise ValueError(f"{where}: {error}") from None
            if (stage.teacher is not None or stage.init is not None
                    or stage.exploring_starts is not None or stage.keep != "policy.npz"
                    or stage.calibration is not None):
                raise ValueError(f"{where}: a jax stage trains from scratch: no teacher, init, "
                                 "exploring_starts or calibration, and it keeps policy.npz")
        if stage.task not in suite.TASKS_BY_DOMAIN["qube"]:
            raise ValueError(f"{where}: unknown task {stage.task!r}")
        if stage.init is not None and stage.init not in seen:
            raise ValueError(f"{where}: init {stage.init!r} is not an earlier stage "
                             f"({', '.join(seen) or 'none'})")
        if not (isinstance(stage.steps, int) and stage.steps > 0):
            raise ValueError(f"{where}: steps must be a positive integer, got {stage.steps!r}")
        if stage.keep not in KEEP:
            raise ValueError(f"{where}: keep must be one of {', '.join(KEEP)}, got {stage.keep!r}")
        if stage.randomization is not None:
            randomization_configs.load(stage.randomization)
        if stage.calibration is not None:
            _check_calibration(stage, where)
        if "random" in stage.task_kwargs:
            raise ValueError(f"{where}: task_kwargs: the stage's seed seeds the environments; drop 'random'")
        try:
            suite.make_task("qube", stage.task, dict(stage.task_kwargs))
        except ValueError as error:
            raise ValueError(f"{where}: task_kwargs: {error}") from None
        if stage.teacher is not None and stage.teacher not in baselines.names():
            raise ValueError(f"{where}: unknown teacher {stage.teacher!r}; controllers: "
                             f"{', '.join(baselines.names())}")
        if stage.teacher is not None and (stage.init is not None or stage.keep != "policy.npz"):
            raise ValueError(f"{where}: an imitation stage starts afresh and keeps policy.npz")
        if (stage.teacher_knows_plant or stage.teacher_settings) and stage.teacher is None:
            raise ValueError(f"{where}: teacher_knows_plant and teacher_settings need a teacher")
        if stage.teacher is not None:
            try:
                baselines.make(stage.teacher, **stage.teacher_settings)
            except ValueError as error:
                raise ValueError(f"{where}: teacher_settings: {error}") from None
        for key in IMITATION_SETTINGS:
            value = stage.hyperparameters.get(key)
            if key in stage.hyperparameters and stage.teacher is None:
                raise ValueError(f"{where}: {key!r} is a setting of an imitation stage (one with a teacher)")
            if key in stage.hyperparameters and not (isinstance(value, int) and 1 <= value <= stage.steps):
                raise ValueError(f"{where}: {key} must be a positive integer, at most steps, got {value!r}")
        seen.add(stage.name)
    if not recipe.stages:
        raise ValueError(f"recipe {recipe.name!r} has no stages")


def _check_calibration(stage: Stage, where: str) -> None:
    """ValueError unless `stage` can train under its calibration: a calibration file, no randomization
    beside it, and an earlier stage to fine-tune or a teacher to imitate."""
    try:
        calibration_file.load(stage.calibration)
    except (ValueError, TypeError) as error:
        raise ValueError(f"{where}: calibration: {error}") from None
    if stage.randomization is not None:
        raise ValueError(f"{where}: give a randomization or a calibration to centre one on, not both")
    if stage.init is None and stage.teacher is None:  # `train` would fine-tune a shipped policy
        raise ValueError(f"{where}: a calibrated PPO stage fine-tunes an earlier stage: give init "
                         "(or a teacher to imitate)")


def finished(directory: pathlib.Path, backend: str = "sb3") -> bool:
    """Whether `directory` holds a finished training run of `backend`."""
    result = "model.zip" if backend == "sb3" else "policy.npz"
    return (directory / "training.json").is_file() and (directory / result).is_file()


def run(recipe: str | Recipe, out: str | pathlib.Path | None = None, progress: bool = True,
        backend: str = "sb3", **train_kwargs: Any) -> pathlib.Path:
    """Run `recipe` (a name of `RECIPES_BY_BACKEND[backend]` or a `Recipe`) into `out` (default
    `runs/<name>`, with `_jax` for the jax backend), one subdirectory per stage, skipping stages
    already finished there and continuing an interrupted sb3 stage from its latest checkpoint;
    return the kept policy file.

    `train_kwargs` go to every sb3 stage's `train` (e.g. `evaluations`, `num_envs`).
    """
    from qube_suite.training import imitation, train

    if isinstance(recipe, str):
        table = RECIPES_BY_BACKEND.get(backend)
        if table is None:
            raise ValueError(f"backend must be one of {', '.join(BACKENDS)}, got {backend!r}")
        if recipe not in table:
            raise ValueError(f"no {backend} recipe {recipe!r}; {backend} recipes: {', '.join(table)}")
        recipe = table[recipe]
    check(recipe)
    suffix = "_jax" if all(stage.backend == "jax" for stage in recipe.stages) else ""
    root = pathlib.Path(out or f"runs/{recipe.name}{suffix}")
    for number, stage in enumerate(recipe.stages, start=1):
        directory = root / stage.name
        if finished(directory, stage.backend):
            print(f"stage {number}/{len(recipe.stages)} {stage.name}: finished in {directory}, kept")
            continue
        drawn = (f"randomization centred on the calibration {stage.calibration}" if stage.calibration
                 else f"randomization {stage.randomization or 'none'}")
        print(f"stage {number}/{len(recipe.stages)} {stage.name}: {stage.task}, {stage.steps} steps, "
              f"{drawn} (about {stage.minutes:g} min)", flush=True)
        if stage.backend == "jax":
            from qube_suite.mjx import training as jax_training

            jax_training.train(stage.task, steps=stage.steps, randomization=stage.randomization or "none",
                               seed=stage.seed, out=directory, hyperparameters=dict(stage.hyperparameters),
                               progress=print if progress else None, task_kwargs=dict(stage.task_kwargs))
            continue
        if stage.teacher is not None:
            hyperparameters = dict(stage.hyperparameters)
            dagger = {key: hyperparameters.pop(key) for key in IMITATION_SETTINGS if key in hyperparameters}
            imitation.imitate(stage.task, stage.teacher, stage.steps, seed=stage.seed,
                              randomization=stage.randomization, calibration=stage.calibration,
                              out=directory,
                              history=hyperparameters.pop("history", 0), hyperparameters=hyperparameters,
                              **({} if stage.exploring_starts is None
                                 else {"exploring_starts": stage.exploring_starts}),
                              task_kwargs=dict(stage.task_kwargs),
                              teacher_knows_plant=stage.teacher_knows_plant,
                              teacher_settings=dict(stage.teacher_settings), progress=progress, **dagger)
            continue
        train(stage.task, steps=stage.steps, seed=stage.seed, randomization=stage.randomization,
              out=directory, init=None if stage.init is None else root / stage.init,
              exploring_starts=stage.exploring_starts, hyperparameters=dict(stage.hyperparameters),
              task_kwargs=dict(stage.task_kwargs), calibration=stage.calibration, progress=progress,
              resume=True, **train_kwargs)
    return root / recipe.stages[-1].name / recipe.stages[-1].keep


def _settings(stage: Stage) -> str:
    """A stage's randomization or calibration and task settings, in brackets ("" without any)."""
    given = ([stage.randomization] if stage.randomization else []) + (
        [f"calibrated on {os.path.basename(stage.calibration)}"] if stage.calibration else []) + [
        f"{key}={value}" for key, value in stage.task_kwargs.items()]
    return f" ({', '.join(given)})" if given else ""


def listing(backend: str = "sb3") -> str:
    """A table of `backend`'s recipes: name, stages, steps, expected wall time, target."""
    lines = ["| recipe | stages | steps | expected wall time | target |", "|---|---|---|---|---|"]
    for recipe in RECIPES_BY_BACKEND[backend].values():
        stages = " → ".join(f"{s.task} {s.steps / 1e6:g} M" + (f" imitating {s.teacher}" if s.teacher else "")
                            + (" built for each plant" if s.teacher_knows_plant else "") + _settings(s)
                            for s in recipe.stages)
        lines.append(f"| {recipe.name} | {stages} | {recipe.steps / 1e6:g} M | {recipe.minutes:g} min | "
                     f"{recipe.target} |")
    return "\n".join(lines)
