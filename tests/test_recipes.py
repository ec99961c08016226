"""Training recipes: the table is valid and matches the shipped policies' records, the listing
shows it, `qube-suite train --task T` runs T's recipe, and a tiny recipe runs and resumes."""

import dataclasses
import importlib.util
import json
import os

import numpy as np
import pytest

from qube_suite import cli, training
from qube_suite.calibration.calibration_file import Calibration
from qube_suite.devices.qube import parameters
from qube_suite.policies import load_policy, shipped
from qube_suite.training import calibrated, environments, imitation, recipes
from qube_suite.training.recipes import RECIPES, Recipe, Stage

HAVE_RL = all(importlib.util.find_spec(name) for name in training.RL_EXTRA)
needs_rl = pytest.mark.skipif(not HAVE_RL, reason="needs the rl extra")


@pytest.mark.parametrize("name", list(RECIPES))
def test_every_recipe_is_valid(name):
    recipes.check(RECIPES[name])


def test_every_shipped_policy_has_a_recipe_that_matches_its_training_record():
    for spec in shipped():
        recipe = RECIPES[spec.split(":", 1)[1]]
        last = recipe.stages[-1]
        record = load_policy(spec).meta["training"]
        assert record["task"] == last.task, spec
        # a calibrated stage trains under the randomization centred on its calibration file
        assert record["randomization"] == (last.randomization if last.calibration is None else "custom"), spec
        assert (record.get("calibration") is None) == (last.calibration is None), spec
        if last.calibration is not None:  # the same file; where the package lies differs by machine
            assert os.path.basename(record["calibration"]) == os.path.basename(last.calibration), spec
        assert record["seed"] == last.seed, spec
        assert record["steps"] <= last.steps + 8192, spec  # PPO rounds up to whole rollouts
        assert (record.get("init") is None) == (last.init is None), spec
        assert record.get("task_kwargs", {}) == last.task_kwargs, spec  # e.g. the target schedule
        if last.keep == "policy.npz":  # the final policy has the whole budget
            assert record["steps"] >= last.steps, spec


@pytest.mark.parametrize(("change", "message"), [
    ({"task": "juggle"}, "unknown task 'juggle'"),
    ({"init": "later"}, "init 'later' is not an earlier stage"),
    ({"steps": 0}, "steps must be a positive integer"),
    ({"keep": "model.zip"}, "keep must be one of policy.npz, best_policy.npz"),
    ({"randomization": "milder"}, "unknown randomization preset 'milder'"),
    ({"teacher": "juggler"}, "unknown teacher 'juggler'"),
    ({"teacher": "swingup", "keep": "best_policy.npz"}, "an imitation stage starts afresh"),
    ({"teacher_knows_plant": True}, "teacher_knows_plant and teacher_settings need a teacher"),
    ({"hyperparameters": {"epochs": 2}}, "'epochs' is a setting of an imitation stage"),
    ({"teacher": "swingup", "hyperparameters": {"iterations": 0}}, "iterations must be a positive integer"),
    ({"teacher": "swingup", "hyperparameters": {"epochs": 2.5}}, "epochs must be a positive integer"),
    ({"teacher": "ilqr", "teacher_settings": {"swing_up": "juggle"}}, "teacher_settings: unknown swing_up"),
    ({"task": "swingup_follow", "task_kwargs": {"target": "zigzag"}}, "unknown target schedule 'zigzag'"),
    ({"task": "swingup_follow", "task_kwargs": {"random": 3}}, "drop 'random'"),
    ({"backend": "tpu"}, "backend must be one of sb3, jax"),
    ({"backend": "jax", "task": "nonsense"}, "'nonsense' is not one of them"),
    ({"backend": "jax", "task": "swingup_follow", "task_kwargs": {"target": "zigzag"}},
     "unknown target schedule 'zigzag'"),
    ({"backend": "jax", "exploring_starts": 0.5}, "a jax stage trains from scratch"),
    ({"calibration": "no_such_qube.yaml"}, "calibration: .*no such calibration file"),
    ({"calibration": parameters.REAL_QUBE_SERVO2}, "a calibrated PPO stage fine-tunes an earlier stage"),
    ({"calibration": parameters.REAL_QUBE_SERVO2, "randomization": "wide"}, "not both"),
    ({"calibration": parameters.REAL_QUBE_SERVO2, "backend": "jax"}, "a jax stage trains from scratch"),
])
def test_a_bad_recipe_is_refused_naming_the_stage(change, message):
    stage = dataclasses.replace(Stage("only", "balance", 100, 1), **change)
    with pytest.raises(ValueError, match=message) as error:
        recipes.check(Recipe("bad", (stage,), "nothing"))
    assert "randomization" in message or "stage 'only'" in str(error.value)


def test_a_calibrated_stage_with_a_bad_file_stops_the_recipe_before_any_training(monkeypatch, tmp_path,
                                                                                  capsys):
    monkeypatch.setattr(training, "train", lambda task, **kwargs: pytest.fail("trained"))
    (tmp_path / "bad.yaml").write_text("parameters: {pendulum_mass: 0.03}\n")  # no calibration format
    for path in ("missing.yaml", tmp_path / "bad.yaml"):
        recipe = Recipe("for_my_qube", (Stage("first", "balance", 100, 1),
                                        Stage("mine", "balance", 100, 1, init="first", calibration=path)), "")
        with pytest.raises(ValueError, match="stage 'mine': calibration: .*(no such|not a qube_suite)"):
            recipes.run(recipe, out=tmp_path / "runs", progress=False)
    assert not (tmp_path / "runs").exists()
    monkeypatch.setitem(RECIPES, "for_my_qube", recipe)
    assert cli.main(["train", "--recipe", "for_my_qube", "--out", str(tmp_path / "runs")]) == 2
    assert "calibration:" in capsys.readouterr().err


class StopBeforeTrainingError(Exception):
    """Raised by the stand-in environment builder: the settings were seen, no training needed."""


@needs_rl
def test_a_calibrated_stage_builds_its_worlds_around_the_calibrated_qube(monkeypatch, tmp_path, capsys):
    latency = 0.006
    qube = Calibration(parameters=dict(parameters.NOMINAL, pendulum_mass=0.030, arm_damping=4e-4),
                       intervals={"pendulum_mass": (0.0299, 0.0302), "arm_damping": (3.9e-4, 4.1e-4)},
                       metadata={}, actuation={"latency_seconds": latency})
    path = qube.save(tmp_path / "my_qube.yaml")
    first = tmp_path / "runs" / "first"  # a finished first stage, not trained here
    first.mkdir(parents=True)
    for name in ("training.json", "model.zip", "vecnormalize.pkl"):
        (first / name).write_text("{}")
    built = []

    def build(task, num_envs, seed, **kwargs):
        built.append(kwargs)
        raise StopBeforeTrainingError

    monkeypatch.setattr(environments, "make_vec_env", build)
    recipe = Recipe("for_my_qube", (Stage("first", "balance", 100, 1),
                                    Stage("mine", "balance", 100, 1, init="first", calibration=path)), "")
    with pytest.raises(StopBeforeTrainingError):
        recipes.run(recipe, out=tmp_path / "runs", progress=False)
    drawn = built[0]["randomization"]
    assert drawn == calibrated.randomization_for(path)  # what `train --calibration` draws
    for name in ("pendulum_mass", "arm_damping"):
        assert drawn["parameters"][name]["low"] < qube.parameters[name] < drawn["parameters"][name]["high"]
    assert drawn["parameters"]["pendulum_mass"]["low"] > parameters.NOMINAL["pendulum_mass"]  # centred on it
    assert drawn["effects"]["action_delay"]["seconds"] == {"distribution": "uniform", "low": 0.0,
                                                           "high": 2 * latency}
    assert "randomization centred on the calibration" in capsys.readouterr().out
    monkeypatch.setitem(RECIPES, "for_my_qube", recipe)
    row = next(line for line in recipes.listing().splitlines() if line.startswith("| for_my_qube |"))
    assert "balance 0.0001 M → balance 0.0001 M (calibrated on my_qube.yaml)" in row


@needs_rl
def test_a_calibrated_imitation_stage_imitates_in_worlds_around_the_calibrated_qube(monkeypatch, tmp_path,
                                                                                    capsys):
    built = []

    def build(task, num_envs, seed, **kwargs):
        built.append(kwargs)
        raise StopBeforeTrainingError

    monkeypatch.setattr(environments, "make_vec_env", build)
    recipe = Recipe("imitated", (Stage("teach", "swingup", 100, 1, teacher="swingup",
                                       calibration=parameters.REAL_QUBE_SERVO2),), "")
    with pytest.raises(StopBeforeTrainingError):  # a teacher needs no earlier stage to start from
        recipes.run(recipe, out=tmp_path / "runs", progress=False)
    assert built[0]["randomization"] == calibrated.randomization_for(parameters.REAL_QUBE_SERVO2)
    assert "randomization centred on the calibration" in capsys.readouterr().out
    with pytest.raises(ValueError, match="not both"):
        imitation.imitate("swingup", "swingup", 100, randomization="wide",
                          calibration=parameters.REAL_QUBE_SERVO2)


@pytest.mark.parametrize("name", list(recipes.JAX_RECIPES))
def test_every_jax_recipe_is_valid(name):
    recipes.check(recipes.JAX_RECIPES[name])
    assert all(stage.backend == "jax" for stage in recipes.JAX_RECIPES[name].stages)


def test_train_with_the_jax_backend_runs_its_recipe_and_refuses_options_it_cannot_take(monkeypatch, tmp_path,
                                                                                         capsys):
    calls = []
    monkeypatch.setattr(recipes, "run",
                        lambda name, **kwargs: calls.append((name, kwargs["backend"])) or tmp_path)
    assert cli.main(["train", "--task", "swingup", "--backend", "jax"]) == 0
    assert calls == [("swingup", "jax")]
    assert cli.main(["train", "--task", "swingup", "--backend", "jax", "--algo", "sac"]) == 2
    refusal = "--backend jax takes --steps, --seed, --randomization, --target, --target-amplitude, " \
              "--target-hold-time, --target-frequency, --target-angle of one run, not --algo"
    assert refusal in capsys.readouterr().err
    assert cli.main(["train", "--list-recipes", "--backend", "jax"]) == 0
    assert "| swingup | swingup 60 M (sim2real_frictionless)" in capsys.readouterr().out


def test_listing_shows_every_recipe_with_its_steps_and_time(capsys):
    assert cli.main(["train", "--list-recipes"]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| ")][1:]
    assert [row.split(" | ")[0][2:] for row in rows] == list(RECIPES)
    for row, recipe in zip(rows, RECIPES.values(), strict=True):
        cells = row.split(" | ")
        assert cells[2] == f"{recipe.steps / 1e6:g} M" and cells[3] == f"{recipe.minutes:g} min"
    assert "swingup_follow 2 M imitating follow (sim2real, target=sine) → swingup_follow 1 M (sim2real, " \
           "target=sine)" in rows[list(RECIPES).index("swingup_follow_sine")]
    assert "| swingup 1.5 M imitating swingup (calibrated on real_qube_servo2.yaml) |" in rows[
        list(RECIPES).index("swingup")]


def test_train_with_a_task_alone_runs_its_recipe_and_with_options_one_run(monkeypatch, tmp_path):
    calls = []
    monkeypatch.setattr(recipes, "run", lambda name, **kwargs: calls.append(("recipe", name)) or tmp_path)
    result = training.TrainingResult(tmp_path, tmp_path, tmp_path, 1, 0.0, 0.0)
    monkeypatch.setattr(training, "train",
                        lambda task, **kwargs: calls.append(("train", task, kwargs["steps"])) or result)
    assert cli.main(["train", "--task", "swingup"]) == 0
    assert cli.main(["train", "--task", "swingup", "--steps", "1000"]) == 0
    assert cli.main(["train", "--recipe", "rotor", "--out", str(tmp_path)]) == 0
    assert cli.main(["train", "--task", "swingup_sparse"]) == 0  # no recipe: one run, default steps
    assert calls == [("recipe", "swingup"), ("train", "swingup", 1000), ("recipe", "rotor"),
                     ("train", "swingup_sparse", 2_000_000)]
    assert cli.main(["train", "--recipe", "rotor", "--steps", "5"]) == 2
    assert cli.main(["train"]) == 2


def test_a_stage_trains_and_imitates_with_its_task_settings(monkeypatch, tmp_path, capsys):
    steps = {"target": "steps", "target_hold_time": 3.0}
    recipe = Recipe("slow", (Stage("teach", "swingup_follow", 100, 1, teacher="follow", task_kwargs=steps,
                                   teacher_knows_plant=True, hyperparameters={"epochs": 3, "iterations": 2}),
                             Stage("learn", "swingup_follow", 100, 1, init="teach",
                                   task_kwargs={"target": "sine"})), "tracks")
    calls = {}
    monkeypatch.setattr(imitation, "imitate", lambda task, teacher, steps, **kwargs: calls.setdefault(
        "imitate", (kwargs["task_kwargs"], kwargs["teacher_knows_plant"], kwargs["epochs"],
                    kwargs["iterations"], kwargs["hyperparameters"])))
    monkeypatch.setattr(training, "train", lambda task, **kwargs: calls.setdefault(
        "train", kwargs["task_kwargs"]))
    recipes.run(recipe, out=tmp_path, progress=False)
    assert calls == {"imitate": (steps, True, 3, 2, {}), "train": {"target": "sine"}}  # DAgger's, not PPO's
    monkeypatch.setitem(RECIPES, "slow", recipe)
    row = next(line for line in recipes.listing().splitlines() if line.startswith("| slow |"))
    assert "swingup_follow 0.0001 M imitating follow built for each plant (target=steps, " \
           "target_hold_time=3.0) → " \
           "swingup_follow 0.0001 M (target=sine)" in row


@pytest.mark.slow
@needs_rl
def test_a_tiny_recipe_runs_stage_by_stage_and_resumes(tmp_path, capsys):
    tiny = Recipe("tiny", (
        Stage("first", "balance", 512, 0.1, hyperparameters={"n_steps": 256}),
        Stage("second", "swingup", 512, 0.1, init="first", randomization="wide", seed=2, exploring_starts=0.0,
              hyperparameters={"n_steps": 256, "history": 2}, keep="best_policy.npz")), "runs")
    kwargs = {"num_envs": 2, "evaluations": 1, "eval_episodes": 1, "checkpoints": 1}
    policy = recipes.run(tiny, out=tmp_path, progress=False, **kwargs)
    assert policy == tmp_path / "second" / "best_policy.npz" and policy.is_file()
    second = json.loads((tmp_path / "second" / "training.json").read_text())
    assert second["init"] == str(tmp_path / "first") and second["seed"] == 2
    assert second["randomization"] == "wide" and second["exploring_starts"] == 0.0
    assert load_policy(policy).history == 2
    first_record = (tmp_path / "first" / "training.json").stat().st_mtime_ns
    (tmp_path / "second" / "training.json").unlink()  # as if interrupted in the second stage
    capsys.readouterr()
    recipes.run(tiny, out=tmp_path, progress=False, **kwargs)
    assert "stage 1/2 first: finished" in capsys.readouterr().out
    assert (tmp_path / "first" / "training.json").stat().st_mtime_ns == first_record  # not rerun
    assert (tmp_path / "second" / "training.json").is_file()


@pytest.mark.slow
@needs_rl
def test_an_interrupted_run_resumes_from_its_latest_checkpoint(tmp_path):
    kwargs = {"num_envs": 2, "evaluations": 2, "eval_episodes": 1, "checkpoints": 2, "progress": False,
              "hyperparameters": {"n_steps": 256}}
    training.train("balance", steps=2048, out=tmp_path, **kwargs)
    checkpoints = tmp_path / "checkpoints"
    assert sorted(p.name for p in checkpoints.glob("*.zip")) == ["ppo_1024_steps.zip", "ppo_2048_steps.zip"]
    for name in ("ppo_2048_steps.zip", "ppo_vecnormalize_2048_steps.pkl", "training.json", "model.zip"):
        (checkpoints / name if "steps" in name else tmp_path / name).unlink()  # interrupted after 1024
    with np.load(tmp_path / "evaluations.npz") as evaluations:
        first = {key: evaluations[key][:1] for key in evaluations.files}
    np.savez(tmp_path / "evaluations.npz", **first)
    result = training.train("balance", steps=2048, out=tmp_path, resume=True, **kwargs)
    record = json.loads((tmp_path / "training.json").read_text())
    assert result.steps == 2048 and record["resumed_from_steps"] == 1024
    assert list(np.load(tmp_path / "evaluations.npz")["timesteps"]) == [1024, 2048]  # the first one kept
    fresh = training.train("balance", steps=512, out=tmp_path / "fresh", resume=True, **kwargs)
    assert fresh.steps == 512  # nothing to resume: a new run
