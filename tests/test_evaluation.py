"""The evaluation harness and `qube-suite eval`."""

import json
import math

import numpy as np
import pytest

from qube_suite import baselines, cli, evaluate, suite
from qube_suite.angles import wrap_angle
from qube_suite.devices.qube.tasks import Balance, Dampen, Rotor, Swingup
from qube_suite.tasks.batch_safety import ProbeQubes

SETTLED = 500  # 2 s at 250 Hz


def test_success_rule_needs_the_final_two_seconds_at_the_goal():
    good = np.r_[np.zeros(1000, dtype=bool), np.ones(SETTLED, dtype=bool)]
    assert Swingup().succeeded(good, terminated=False, control_frequency=250)
    late_slip = good.copy()
    late_slip[-10] = False
    assert not Swingup().succeeded(late_slip, terminated=False, control_frequency=250)
    assert not Balance().succeeded(good, terminated=True, control_frequency=250)
    assert not Dampen().succeeded(good[:100], terminated=False, control_frequency=250)


@pytest.mark.parametrize(("task", "goal"), [(Swingup, 0.0), (Balance, 0.0), (Dampen, math.pi)])
def test_at_goal_is_the_pendulum_within_10_degrees_of_the_tasks_goal(task, goal):
    for offset, expected in [(9.9, True), (-9.9, True), (10.5, False), (-10.5, False)]:
        alpha = wrap_angle(goal + math.radians(offset))
        assert task().at_goal(ProbeQubes([1.2, alpha, 3.0, 5.0], 0.0, None)) is expected


def test_rotor_success_counts_revolutions():
    def spun(turns):
        rotor, qube = Rotor(), ProbeQubes([0.0, math.pi, 0.0, 0.0], 0.0, None)
        rotor.initialize_episode(qube)
        for alpha in np.linspace(math.pi, math.pi + (turns + 0.25) * 2 * math.pi, 40 * turns + 11)[1:]:
            qube.move_to([0.0, wrap_angle(alpha), 0.0, 0.0], 0.0)
            rotor.after_step(qube)
        return rotor

    assert spun(5).succeeded([False], terminated=True, control_frequency=250)
    assert not spun(4).succeeded([True] * 1000, terminated=False, control_frequency=250)


def test_evaluate_is_seeded_and_scores_a_controller():
    first = evaluate("balance", task="balance", episodes=2, seed=3)
    again = evaluate("balance", task="balance", episodes=2, seed=3)
    assert first.returns == again.returns and first.success_rate == 1.0
    assert first.mean_return > 2000 and len(first.step_times) == 2 * 2048


def test_evaluate_accepts_any_callable_and_reports_failure():
    result = evaluate(lambda observation: 3.0, task="balance", episodes=2, seed=0)
    assert result.success_rate == 0.0 and result.mean_return < 100
    assert result.policy == "function"


def test_follow_error_is_the_mean_arm_distance_from_the_target_after_two_seconds():
    result = evaluate("balance", task="balance_follow", episodes=1, seed=4)
    env = suite.load("qube", "balance_follow", task_kwargs={"random": 4})
    controller = baselines.for_environment("balance", env)
    timestep, distances = env.reset(), []
    while not timestep.last():
        timestep = env.step(controller(timestep.observation))
        distances.append(abs(timestep.observation["state"][0] - timestep.observation["target"][0]))
    assert len(distances) == 2048 and result.follow_error == pytest.approx(np.mean(distances[SETTLED:]))
    assert 0.3 < result.follow_error < 1.0                                # the arm stays near 0
    assert evaluate("balance", task="balance", episodes=1).follow_error is None


def test_follow_error_is_none_when_no_episode_lasts_two_seconds():
    result = evaluate(lambda observation: 3.0, task="balance_follow", episodes=1)
    assert result.follow_error is None and result.to_dict()["follow_error"] is None


def test_eval_json_schema(capsys):
    assert cli.main(["eval", "--task", "balance", "--controller", "balance", "--episodes", "2",
                     "--seed", "1", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert {"mean_return", "std_return", "success_rate", "episodes", "step_time_median_ms",
            "step_time_p99_ms", "returns", "domain", "task", "policy", "seed"} <= set(summary)
    assert summary["episodes"] == 2 and len(summary["returns"]) == 2 and summary["success_rate"] == 1.0
    assert 0 < summary["step_time_median_ms"] <= summary["step_time_p99_ms"]


@pytest.mark.parametrize("argv, message", [
    (["eval", "--task", "balance", "--controller", "pid"], "valid controllers"),
    (["eval", "--task", "balanse", "--controller", "balance"], "valid tasks"),
    (["eval", "--task", "balance", "--controller", "balance", "--episodes", "0"], "episodes"),
])
def test_eval_user_errors_are_one_line(capsys, argv, message):
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


UNREACHABLE = {"reset_voltage_limit": 0.05, "reset_timeout": 1.0}
"""A hardware domain whose reset cannot swing the pendulum up: every balance reset fails."""


def test_a_failed_reset_is_that_episodes_failure_not_a_crash():
    result = evaluate("balance", domain="qube_hardware", task="balance", episodes=2, seed=0,
                      domain_kwargs=UNREACHABLE)
    assert result.failed_resets == [0, 1]
    assert result.successes == [False, False] and result.returns == [0.0, 0.0]
    summary = result.to_dict()
    assert summary["failed_resets"] == [0, 1] and summary["step_time_median_ms"] is None


def test_the_episodes_around_a_failed_reset_count_as_they_ran(monkeypatch):
    from qube_suite.devices.qube import hardware

    reset_to, calls = hardware.Physics.reset_to, []

    def second_one_fails(physics, state):
        calls.append(state)
        if len(calls) == 2:
            raise hardware.ResetError("reset failed: could not swing up and hold upright")
        reset_to(physics, state)

    monkeypatch.setattr(hardware.Physics, "reset_to", second_one_fails)
    result = evaluate("balance", domain="qube_hardware", task="balance", episodes=3, seed=0)
    assert result.failed_resets == [1] and result.successes == [True, False, True]
    assert result.returns[1] == 0.0 and min(result.returns[0], result.returns[2]) > 2000


def test_other_hardware_errors_still_stop_the_evaluation(monkeypatch):
    from qube_suite.devices.qube import hardware

    def lost_zero(physics, state):
        raise hardware.EncoderCheckError("the pendulum hangs at rest but its encoder reads 3 counts")

    monkeypatch.setattr(hardware.Physics, "reset_to", lost_zero)
    with pytest.raises(hardware.EncoderCheckError):
        evaluate("balance", domain="qube_hardware", task="balance", episodes=2)


def test_eval_says_which_resets_failed(capsys, monkeypatch):
    monkeypatch.setattr(cli, "_hardware_domain_kwargs", lambda args: UNREACHABLE)
    assert cli.main(["eval", "--task", "balance", "--controller", "balance", "--episodes", "2",
                     "--domain", "qube_hardware", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "success 0 %" in out and "reset failed in 2 episodes (0, 1)" in out
