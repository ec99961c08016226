"""Training for one Qube: a randomization centred on its calibration, and the whole loop on its board.

    from qube_suite.training import calibrated, train
    train("swingup", calibration="my_qube.yaml", steps=1_000_000)   # from ppo:swingup_adaptive
    report = calibrated.adapt("swingup", "qube_hardware", {"board": "qube_servo2_usb"})

`randomization_for` turns a calibration (`qube_suite.calibration`) into a
randomization config: every estimated parameter drawn uniformly from its 95 %
interval widened `WIDTH` times, and at least +-`MINIMUM_SPREAD` of the estimate
(an interval only says how well one recording pins the value; a Qube warms up,
its friction changes from run to run); the command delay from 0 to twice the
calibration's latency where it measured one (a real Qube-Servo 2's 6 ms defeats
`ppo:swingup_adaptive`, trained under delays of 0 or 1 step: docs/calibration.md);
the voltage's dead zone from 0 to twice the calibration's where it measured one;
the parameters a calibration does not estimate, and the other sensor and actuator
effects, as in the `sim2real` preset. Not drawn: the cable's rest angle and slack band
and the encoders' offsets (`effects_of` gives them to a simulation loaded with the
calibration file, not to training under a randomization).
`fine_tuning` says what a calibrated run starts from: the task's adaptive policy
(`ppo:<task>_adaptive`, observation history included) with the small steps of PPO after
imitation (`recipes.SMALL_PPO_STEPS`: small exploration noise, small steps), or else the
task's shipped policy. Fine-tuning the memoryless PPO swing-up (trained under `sim2real`) this
way made it worse on the held-out plants (docs/transfer.md); the adaptive policy already
swings them up, and keeps doing so.
`adapt` runs the loop a lab runs on a Qube nobody described: calibrate it (the
excitation experiment on its board), fine-tune a policy under the randomization
centred on that calibration, evaluate the policy before and after on the
board, and keep the better of the two.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import os
import pathlib
from collections.abc import Mapping
from typing import Any

from qube_suite.calibration.calibration_file import Calibration
from qube_suite.calibration.calibration_file import load as load_calibration
from qube_suite.randomization.presets import PRESETS
from qube_suite.training.recipes import SMALL_PPO_STEPS

WIDTH = 2.0
"""Each estimated parameter is drawn from its 95 % interval widened this many times about the estimate ..."""
MINIMUM_SPREAD = 0.1
"""... and from at least +-this fraction of the estimate."""
BASE_PRESET = "sim2real"
"""Ranges of the parameters a calibration does not estimate, and the sensor and actuator effects."""


def randomization_for(calibration: Calibration | str | os.PathLike, width: float = WIDTH,
                      minimum_spread: float = MINIMUM_SPREAD) -> dict[str, Any]:
    """A randomization config centred on `calibration` (a `Calibration` or the path of its file)."""
    if not (width > 0.0 and minimum_spread >= 0.0):
        raise ValueError(f"width must be > 0 and minimum_spread >= 0, got {width!r}, {minimum_spread!r}")
    if not isinstance(calibration, Calibration):
        calibration = load_calibration(calibration)
    config = copy.deepcopy(PRESETS[BASE_PRESET])
    for name, spec in calibration.randomization(width)["parameters"].items():
        value = calibration.parameters[name]
        spec["low"] = max(0.0, min(spec["low"], value * (1.0 - minimum_spread)))
        spec["high"] = max(spec["high"], value * (1.0 + minimum_spread))
        config["parameters"][name] = spec
    latency = calibration.actuation.get("latency_seconds", 0.0)
    if latency > 0.0:  # the Qube's measured latency at the centre, the preset's whole-step delays around it
        config["effects"]["action_delay"] = {
            "seconds": {"distribution": "uniform", "low": 0.0, "high": 2.0 * latency}}
    dead_zone = calibration.actuation.get("voltage_deadzone", 0.0)
    if dead_zone > 0.0:  # likewise the amplifier's measured dead zone
        config["effects"]["dead_zone"] = {
            "voltage": {"distribution": "uniform", "low": 0.0, "high": 2.0 * dead_zone}}
    return config


def fine_tuning(task: str, hyperparameters: Mapping[str, Any] | None = None
                ) -> tuple[str | None, dict[str, Any]]:
    """(init, hyperparameters) of a calibrated PPO run on `task` given no init: the shipped policy
    `ppo:<task>_adaptive` with its history and `SMALL_PPO_STEPS`, under `hyperparameters`; else the
    shipped `ppo:<task>` with `hyperparameters`; else (None: from scratch, `hyperparameters`)."""
    from qube_suite import policies

    given = dict(hyperparameters or {})
    adaptive = f"ppo:{task}_adaptive"
    if adaptive in policies.shipped():
        history = policies.load_policy(adaptive).history
        return adaptive, {"history": history, **SMALL_PPO_STEPS, **given}
    if f"ppo:{task}" in policies.shipped():
        return f"ppo:{task}", given
    return None, given


@dataclasses.dataclass
class AdaptReport:
    """What `adapt` did: the calibration file, the fine-tuned policy, and both policies' evaluation on
    the board (mean return, success rate, episodes); `kept` says which of the two to use."""

    calibration: pathlib.Path
    policy: pathlib.Path
    before: dict[str, float]
    after: dict[str, float]
    training_wall_time_s: float

    @property
    def kept(self) -> str:
        """The policy to use on this Qube: the fine-tuned one if it succeeded more often on the board, or
        as often with a higher mean return; else the one it started from. (Fine-tuning can also lose: in
        one of eight runs on held-out plants it let the arm drift while balancing, 45 % against 100 %.)"""
        score = {name: (result["success_rate"], result["mean_return"])
                 for name, result in (("before", self.before), ("after", self.after))}
        return str(self.after["policy"] if score["after"] > score["before"] else self.before["policy"])

    def table(self) -> str:
        """The evaluations as a Markdown table, and the policy kept."""
        rows = ["| policy | mean return | success |", "|---|---|---|"]
        for name, result in (("before", self.before), ("after", self.after)):
            rows.append(f"| {name}: {result['policy']} | {result['mean_return']:.0f} | "
                        f"{100 * result['success_rate']:.0f} % of {result['episodes']} |")
        return "\n".join([*rows, "", f"kept: {self.kept}"])


def adapt(task: str = "swingup", domain: str = "qube_hardware",
          domain_kwargs: Mapping[str, Any] | None = None, out: str | os.PathLike = "runs/adapt",
          init: str | None = None, steps: int = 1_000_000,
          seconds: float = 60.0, episodes: int = 10, seed: int = 0, progress: bool = True,
          **train_kwargs: Any) -> AdaptReport:
    """Calibrate the Qube of `domain` (`domain_kwargs`: its board) with a `seconds` experiment, fine-tune
    `init` (default: `fine_tuning(task)`'s, `ppo:swingup_adaptive` for the swing-up) for `steps` under
    `randomization_for` the calibration, in simulation, and evaluate both policies for `episodes`
    episodes on the board.

    Writes `out/calibration.yaml` (and its recording), the run `out/fine_tune`, and `out/adapt.json`.
    `train_kwargs` go to `train` (e.g. `num_envs`, `evaluations`, `hyperparameters`).
    """
    from qube_suite import calibration, policies
    from qube_suite.evaluation import evaluate
    from qube_suite.training import require_rl, train

    require_rl()  # before the board drives: the fine-tuning after the experiment needs it

    if init is None:
        init, train_kwargs["hyperparameters"] = fine_tuning(task, train_kwargs.get("hyperparameters"))
    if init is None or (init not in policies.shipped() and not pathlib.Path(init).exists()):
        raise ValueError(f"init: no policy {init!r} (shipped: {', '.join(policies.shipped())}); give --init")
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    kwargs = dict(domain_kwargs or {})
    calibrated = calibration.calibrate(domain, kwargs, seconds=seconds, seed=seed,
                                       recording=out / "calibration.jsonl")
    calibration_path = pathlib.Path(calibrated.save(out / "calibration.yaml"))
    result = train(task, steps=steps, seed=seed, calibration=calibration_path, init=init,
                   out=out / "fine_tune", progress=progress, **train_kwargs)

    def score(policy: str | os.PathLike) -> dict[str, Any]:
        run = evaluate(str(policy), domain=domain, task=task, episodes=episodes, seed=seed,
                       domain_kwargs=kwargs or None)
        return {"policy": str(policy), "mean_return": float(sum(run.returns) / len(run.returns)),
                "success_rate": float(sum(run.successes) / len(run.successes)), "episodes": episodes}

    report = AdaptReport(calibration_path, result.policy, score(init), score(result.policy), result.wall_time)
    (out / "adapt.json").write_text(json.dumps({**dataclasses.asdict(report), "kept": report.kept}, indent=2,
                                               default=str))
    return report
