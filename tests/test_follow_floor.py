"""benchmarks/follow_floor.py: its planned crossings, their replay over a schedule's jumps, its targets."""

import importlib.util
import math
import pathlib
import sys

import numpy as np
import pytest

from qube_suite import baselines, suite
from qube_suite.evaluation import evaluate

SCRIPT = pathlib.Path(__file__).resolve().parents[1] / "benchmarks" / "follow_floor.py"
STEPS = {"target": "steps", "target_hold_time": 2.0}


@pytest.fixture(scope="module")
def floor():
    spec = importlib.util.spec_from_file_location("follow_floor_benchmark", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def shaped_table(floor, sizes, shapes):
    """A crossing table with the given relative error shapes instead of planned ones."""
    table = object.__new__(floor.CrossingTable)
    table.sizes = np.asarray(sizes)
    table.relative = np.asarray(shapes, dtype=float)
    return table


def test_a_planned_crossing_ends_at_the_target_at_rest_and_beats_the_controller_it_starts_from(floor):
    size, limit = math.radians(40.0), 3.0
    error, states = floor.plan_crossing(size, limit)
    assert error[0] == pytest.approx(size)
    assert error[-1] < math.radians(0.5) and np.abs(states[-1, 2:]).max() < 0.05
    assert np.abs(states[:, 1]).max() < math.radians(20.0)  # the balance tasks' limit
    controller = baselines.make("ilqr", voltage_limit=limit)
    state, closed_loop = np.array([-size / 2, 0.0, 0.0, 0.0]), []
    for _ in range(len(error)):
        closed_loop.append(abs(state[0] - size / 2))
        state = controller.kernel.step(state, controller.voltage_for(state, size / 2), floor.H)[0]
    assert error.sum() < 0.95 * sum(closed_loop)


def test_a_larger_voltage_limit_plans_a_faster_crossing(floor):
    size = math.radians(60.0)
    assert floor.plan_crossing(size, 5.0)[0].sum() < 0.95 * floor.plan_crossing(size, 3.0)[0].sum()


def test_each_jump_is_replayed_from_rest_at_the_target_before(floor):
    knots = floor.KNOTS + 1
    shape = np.zeros(knots)
    shape[:2] = (1.0, 0.5)
    table = shaped_table(floor, [0.5], [shape])
    targets = np.array([0.0] * 3 + [0.2] * 5 + [-0.1] * 4)
    expected = [0, 0, 0, 0.2, 0.1, 0, 0, 0, 0.3, 0.15, 0, 0]
    np.testing.assert_allclose(floor.planned_error(targets, table), expected, atol=1e-12)


def test_sizes_between_planned_ones_interpolate_their_shapes(floor):
    knots = floor.KNOTS + 1
    table = shaped_table(floor, [0.1, 0.2], [np.full(knots, 1.0), np.full(knots, 0.5)])
    np.testing.assert_allclose(table.error(0.15), 0.15 * 0.75)
    np.testing.assert_allclose(table.error(-0.05), 0.05)  # below the smallest: its shape
    with pytest.raises(ValueError, match="beyond the table"):
        table.error(0.3)


def test_the_recorder_reads_the_targets_evaluate_scores_against(floor):
    environment = suite.load("qube", "balance_follow", task_kwargs={"random": 0, **STEPS})
    recorder = floor.TargetRecorder(baselines.for_environment("follow", environment))
    result = evaluate(recorder, "qube", "balance_follow", episodes=2, seed=4, task_kwargs=STEPS)
    assert len(recorder.episodes) == 2 and result.follow_error is not None
    for episode, recorded in enumerate(recorder.targets()):
        direct = suite.load("qube", "balance_follow", task_kwargs={"random": 4 + episode, **STEPS})
        controller = baselines.for_environment("follow", direct)
        controller.reset()
        timestep, targets = direct.reset(), []
        while not timestep.last():
            timestep = direct.step(controller(timestep.observation))
            targets.append(direct.task.target)
        np.testing.assert_array_equal(recorded, targets)
        assert len(set(targets)) >= 4  # jumps at 0, 2, 4, 6 and 8 s


@pytest.mark.slow
def test_the_ilqr_controller_follows_2s_steps_no_closer_than_the_planned_crossings(floor):
    table = floor.CrossingTable(math.radians(120.0), 3.0)
    error, planned = floor.measure("ilqr", "qube", "balance_follow", {"target": "steps"}, 2, table)
    assert 0.0 < planned < error
