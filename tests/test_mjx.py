"""The JAX backend (qube_suite.mjx) against the numpy domains: the same rules, physics, effects,
draws and policies. Runs on CPU with small batches (the `jax` extra; skipped without it)."""

from __future__ import annotations

import functools
import math
import pathlib
import re
from typing import NamedTuple

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("brax")
pytest.importorskip("mujoco.mjx")

import jax.numpy as jnp  # noqa: E402
import mujoco  # noqa: E402

from qube_suite import suite  # noqa: E402
from qube_suite.devices.qube import batch as qube_batch  # noqa: E402
from qube_suite.devices.qube import simulation as qube  # noqa: E402
from qube_suite.devices.qube import tasks as qube_tasks  # noqa: E402
from qube_suite.mjx import brax_compat, environment, offered, processes, training, worlds  # noqa: E402
from qube_suite.randomization import config as randomization_config  # noqa: E402
from qube_suite.randomization.sampling import sample  # noqa: E402
from qube_suite.tasks.follow import TargetState  # noqa: E402

EDGE_STATES = np.array([
    [0.0, 0.0, 0.0, 0.0], [0.0, math.pi, 0.0, 0.0], [0.3, -0.2, 1.0, -2.0],
    [math.radians(89.0), 0.1, 0.0, 0.0], [math.radians(91.0), 0.1, 0.0, 0.0],
    [-math.radians(91.0), 3.0, 5.0, 9.0], [0.1, math.radians(19.0), 0.0, 0.0],
    [0.1, math.radians(21.0), 0.0, 0.0], [-0.5, -math.radians(171.0), -3.0, 12.0],
    [0.05, math.radians(9.0), 0.0, 0.0], [0.05, math.radians(11.0), 0.0, 0.0],
])


WITHOUT_PROCESSES = [task for task in offered.TASKS if qube_tasks.SUITE[task]().process is None]
"""Offered tasks whose rules are formulas of the measured state alone."""
WITH_PROCESSES = {"rotor", "swingup_follow", "swingup_follow_sparse", "balance_follow",
                  "balance_follow_sparse"}
"""Offered tasks whose rules read processes too, each with a parity test of its own below."""


def test_every_offered_task_has_a_rule_parity_test():
    assert set(offered.TASKS) == set(WITHOUT_PROCESSES) | WITH_PROCESSES


@pytest.mark.parametrize("task", WITHOUT_PROCESSES)
def test_every_offered_tasks_rules_agree_with_the_numpy_task(task):
    env = environment.QubeMjx(task)
    numpy_task = qube_tasks.SUITE[task]()
    states = np.concatenate([EDGE_STATES, np.random.default_rng(0).uniform(
        [-1.7, -math.pi, -20, -40], [1.7, math.pi, 20, 40], (40, 4))])
    for state in states:
        obs, reward, done = env.rules(jnp.asarray(state, jnp.float32), jnp.float32(0.0))
        qube_ = environment.MeasuredQube(np.float32(state).tolist(), 0.0)  # Python floats: the numpy path
        expected_obs = np.array(numpy_task.observation_values(qube_))
        np.testing.assert_allclose(np.asarray(obs), expected_obs, rtol=1e-5, atol=1e-5)
        assert float(reward) == pytest.approx(float(numpy_task.get_reward(qube_)), abs=1e-5), state
        assert bool(done) == (not numpy_task.in_safe_set(qube_)), state


class StateQube(environment.MeasuredQube):
    """A numpy-path Qube whose measured state the test sets (Python floats), started by `reset_to`."""

    def __init__(self):
        super().__init__([0.0] * 4, 0.0)

    def reset_to(self, state):
        self.set(state, 0.0)

    def set(self, state, time):
        self._measured, self._time = [float(x) for x in np.float32(state)], float(time)


def _spinning_states(steps=400, seed=0):
    """Measured states whose pendulum angle turns one way, then back, then the other way, with jitter."""
    rng = np.random.default_rng(seed)
    rate = np.concatenate([np.full(steps // 2, 0.23), np.full(steps // 4, -0.3), np.full(steps // 4, -0.11)])
    alpha = math.pi + np.cumsum(rate + rng.normal(0.0, 0.05, steps))
    theta = np.concatenate([0.3 * np.sin(np.arange(steps - 20) / 40.0), np.linspace(0.3, 1.75, 20)])
    states = np.stack([theta, (alpha + math.pi) % (2 * math.pi) - math.pi, rng.normal(0, 2, steps),
                       rng.normal(0, 9, steps)], axis=1)
    return states


def _process_rules_run(env, states, start, key):
    """The JAX environment's observations, rewards, dones and process states over measured `states`,
    from `start`, as `QubeMjx.step` advances the task's processes."""
    period = 1.0 / env.control_frequency
    first = processes.first_process(env.task, environment.MeasuredQube(jnp.asarray(start, jnp.float32), 0.0),
                                    key)

    def body(process, inputs):
        index, state, key = inputs
        time = (index + 1) * period
        process = processes.next_process(env.task, process, environment.MeasuredQube(state, time), key)
        return process, (*env.rules(state, time, process), process)

    keys = jax.random.split(key, len(states))
    inputs = (jnp.arange(len(states)), jnp.asarray(states, jnp.float32), keys)
    _, (obs, reward, done, process) = jax.jit(lambda first: jax.lax.scan(body, first, inputs))(first)
    return np.asarray(obs), np.asarray(reward), np.asarray(done), process


def test_the_rotors_rules_and_revolution_count_agree_with_the_numpy_task():
    from qube_suite.episode_rules import judge_step

    env = environment.QubeMjx("rotor")
    states = _spinning_states()
    numpy_task, qube_ = qube_tasks.SUITE["rotor"](random=0), StateQube()
    numpy_task.initialize_episode(qube_)
    start = np.array(qube_._measured)
    obs, reward, done, process = _process_rules_run(env, states, start, jax.random.PRNGKey(0))
    expected_reward, expected_done, revolutions = [], [], []
    for step, state in enumerate(states, start=1):
        qube_.set(state, step / 250.0)
        rewarded, terminated, _ = judge_step(numpy_task, qube_, False, step, 2048)
        np.testing.assert_allclose(obs[step - 1], numpy_task.observation_values(qube_), rtol=1e-5, atol=1e-5)
        expected_reward.append(rewarded)
        expected_done.append(terminated)
        revolutions.append(numpy_task.revolutions)
    np.testing.assert_array_equal(reward, expected_reward)
    np.testing.assert_array_equal(done, expected_done)
    np.testing.assert_array_equal(np.asarray(process.revolutions), revolutions)
    assert sum(expected_reward) >= 6 and max(revolutions) >= 5 and any(expected_done)  # turns counted, an end
    final = env.task.with_process(jax.tree.map(lambda leaf: leaf[-1], process))
    assert final.revolutions == numpy_task.revolutions
    assert final.succeeded([], True, 250.0) == numpy_task.succeeded([], True, 250.0)


def _follow_states(steps, seed=0):
    """Measured states near upright, the arm swinging through +-1.2 rad, leaving +-90 degrees at the end."""
    rng = np.random.default_rng(seed)
    theta = np.concatenate([1.2 * np.sin(np.arange(steps - 10) / 90.0), np.linspace(1.2, 1.7, 10)])
    alpha = 0.4 * np.sin(np.arange(steps) / 37.0) + rng.normal(0.0, 0.02, steps)
    return np.stack([theta, alpha, rng.normal(0, 2, steps), rng.normal(0, 5, steps)], axis=1)


def _numpy_follow_run(task, task_kwargs, states, process_of_step=None):
    """The numpy task's observations, rewards and dones over measured `states` (time: step / 250 s); with
    `process_of_step`, its rules read that target state at each step instead of its own."""
    from qube_suite.episode_rules import judge_step

    numpy_task, qube_ = qube_tasks.SUITE[task](random=0, **task_kwargs), StateQube()
    numpy_task.initialize_episode(qube_)
    observations, rewards, dones = [], [], []
    for step, state in enumerate(states, start=1):
        qube_.set(state, step / 250.0)
        rewarded, terminated, _ = judge_step(numpy_task, qube_, False, step, 2048)
        if process_of_step is not None:
            judged = numpy_task.with_process(process_of_step(step - 1))
            rewarded, terminated = judged.get_reward(qube_), not judged.in_safe_set(qube_)
            observations.append(judged.observation_values(qube_))
        else:
            observations.append(numpy_task.observation_values(qube_))
        rewards.append(rewarded)
        dones.append(terminated)
    return np.array(observations), np.array(rewards), np.array(dones)


@pytest.mark.parametrize(("task", "task_kwargs"), [
    ("swingup_follow", {"target": "sine", "target_amplitude": 0.9, "target_frequency": 0.6}),
    ("swingup_follow_sparse", {"target": "sine"}),
    ("balance_follow", {"target": "fixed", "target_angle": -0.4}),
    ("balance_follow_sparse", {"target": "sine", "target_amplitude": 1.0, "target_frequency": 1.0}),
    ("swingup_follow", {"target": "file"}),
])
def test_a_follow_tasks_rules_and_timed_target_agree_with_the_numpy_task(task, task_kwargs, tmp_path):
    if task_kwargs["target"] == "file":
        path = tmp_path / "targets.csv"
        path.write_text("time,target\n0,0.1\n0.5,-0.4\n1.1,0.7\n")
        task_kwargs = {"target": str(path)}
    env = environment.QubeMjx(task, task_kwargs=task_kwargs)
    states = _follow_states(600)
    obs, reward, done, _ = _process_rules_run(env, states, states[0], jax.random.PRNGKey(0))
    expected_obs, expected_reward, expected_done = _numpy_follow_run(task, task_kwargs, states)
    np.testing.assert_allclose(obs, expected_obs, rtol=1e-5, atol=2e-5)
    np.testing.assert_allclose(reward, expected_reward, atol=1e-5)
    np.testing.assert_array_equal(done, expected_done)
    assert np.ptp(expected_reward) > 0.1 and any(expected_done)
    assert len(set(np.round(expected_obs[:, 4], 6))) >= (1 if task_kwargs.get("target") == "fixed" else 3)


@pytest.mark.parametrize("task_kwargs", [{"target": "steps", "target_hold_time": 0.8}, {"target": "jump"}])
def test_a_follow_tasks_rules_read_its_random_targets_as_the_numpy_task_does(task_kwargs):
    """A world draws its targets from its JAX key, so they differ from numpy's; the rules applied to them
    are the numpy task's, and the steps change exactly every hold time."""
    env = environment.QubeMjx("swingup_follow", task_kwargs=task_kwargs)
    states = _follow_states(700)
    obs, reward, done, process = _process_rules_run(env, states, states[0], jax.random.PRNGKey(5))
    values, changes = np.asarray(process.value, np.float64), np.asarray(process.next_change, np.float64)
    expected_obs, expected_reward, expected_done = _numpy_follow_run(
        "swingup_follow", task_kwargs, states,
        lambda step: TargetState(float(values[step]), float(changes[step])))
    np.testing.assert_allclose(obs, expected_obs, rtol=1e-5, atol=2e-5)
    np.testing.assert_allclose(reward, expected_reward, atol=1e-5)
    np.testing.assert_array_equal(done, expected_done)
    moments = np.flatnonzero(np.diff(values)) + 1  # index i: the step i + 1, at (i + 1) / 250 s
    if task_kwargs["target"] == "steps":
        np.testing.assert_array_equal(moments + 1, [200, 400, 600])  # every 0.8 s at 250 Hz
        assert np.max(np.abs(values)) <= math.radians(60.0)
    else:
        assert 2 <= len(moments) <= 12  # about twice a second over 2.8 s


@pytest.mark.parametrize("target", ["steps", "jump"])
def test_random_targets_are_drawn_from_the_schedules_distribution(target):
    env = environment.QubeMjx("swingup_follow", task_kwargs={"target": target})
    schedule = env.task.schedule
    start = environment.MeasuredQube(jnp.zeros(4, jnp.float32), 0.0)
    keys = jax.random.split(jax.random.PRNGKey(1), 4000)
    drawn = jax.vmap(lambda key: processes.first_process(env.task, start, key))(keys)
    numpy_schedule = qube_tasks.SUITE["swingup_follow"](target=target).schedule
    random = np.random.RandomState(1)
    expected = []
    for _ in range(4000):
        numpy_schedule.reset(0.0, random)
        expected.append(numpy_schedule.state)
    for jax_values, numpy_values in zip(drawn, zip(*expected, strict=True), strict=True):  # targets, changes
        jax_values, numpy_values = np.asarray(jax_values, np.float64), np.array(numpy_values)
        assert abs(jax_values.mean() - numpy_values.mean()) <= 0.05 * numpy_values.std() + 1e-6
        np.testing.assert_allclose(jax_values.std(), numpy_values.std(), rtol=0.05, atol=1e-6)
        assert jax_values.min() >= min(numpy_values.min(), 0.0) - 0.01 * schedule.amplitude
    targets = np.asarray(drawn.value)
    assert np.max(np.abs(targets)) <= schedule.amplitude and np.min(targets) < -0.98 * schedule.amplitude


def test_a_task_with_processes_the_backend_cannot_advance_is_refused(monkeypatch):
    class Counted(NamedTuple):
        count: float

    monkeypatch.setattr(type(qube_tasks.SUITE["swingup"]()), "process", property(lambda task: Counted(0.0)))
    with pytest.raises(ValueError, match="no transition for Swingup's processes"):
        environment.QubeMjx("swingup")


def test_a_task_the_backend_does_not_offer_is_refused_with_its_reason():
    with pytest.raises(ValueError, match="'nonsense' is not one of them"):
        offered.check_task("nonsense")
    assert set(offered.TASKS) | set(offered.NOT_OFFERED) == set(suite.TASKS_BY_DOMAIN["qube"])


def test_every_effect_is_applied_or_refused_with_a_reason():
    from qube_suite.randomization.catalog import EFFECTS

    assert set(worlds.EFFECTS) | set(worlds.UNSUPPORTED_EFFECTS) == set(EFFECTS)
    assert not set(worlds.EFFECTS) & set(worlds.UNSUPPORTED_EFFECTS)


def test_a_jittered_period_is_split_into_physics_steps_as_the_numpy_domain_splits_it():
    durations = np.array([0.0021, 0.0039999, 0.004, 0.0040001, 0.0056, 0.0079, 0.0081, 0.0119])
    steps, timestep = qube.split_step(jnp.asarray(durations, jnp.float32))
    expected_steps, expected_timestep = qube.split_step(durations)
    np.testing.assert_array_equal(np.asarray(steps), expected_steps)
    np.testing.assert_allclose(np.asarray(timestep), expected_timestep, rtol=1e-6)
    assert set(expected_steps.tolist()) == {1, 2, 3}


def test_control_jitter_lasts_the_drawn_periods_as_the_numpy_domain_steps_them():
    """Each control period is drawn by the effect's formula and split as the numpy domain splits it: the
    numpy domain, made to last the same periods, follows the same trajectory."""
    config = {"effects": {"control_jitter": {"fraction": 0.4}}}
    start, volts = np.array([0.1, math.pi - 0.2, 0.5, -1.0]), _voltages()
    env = environment.QubeMjx("swingup", randomization=config, voltage_limit=10.0)
    state = env.start(jnp.asarray(start, jnp.float32), jax.random.PRNGKey(0))

    def body(state, v):
        state = env.step(state, jnp.reshape(v / 10.0, (1,)))
        return state, (env.exact_state(state.pipeline_state), state.pipeline_state.time)

    _, (exact, times) = jax.jit(lambda s, v: jax.lax.scan(body, s, v))(state, jnp.asarray(volts, jnp.float32))
    durations = np.diff(np.concatenate([[0.0], np.asarray(times, np.float64)]))
    period = 1 / 250
    assert np.all((durations > 0.6 * period - 1e-6) & (durations < 1.4 * period + 1e-6))
    assert abs(durations.mean() - period) < 0.05 * period and durations.std() > 0.15 * period
    assert np.any(durations > period + 1e-5)  # some periods take two physics steps
    numpy_env = suite.load("qube", "swingup", task_kwargs={"voltage_limit": 10.0})
    numpy_env.reset()
    with numpy_env.physics.reset_context():
        numpy_env.physics.reset_to(start)
    replay = iter(durations.tolist())
    numpy_env.physics.set_step_duration_model(lambda nominal: next(replay))
    expected = []
    for v in volts:
        numpy_env.step(np.array([v]))
        expected.append(numpy_env.physics.true_state())
    np.testing.assert_allclose(np.asarray(exact), expected, atol=3e-3)
    np.testing.assert_allclose(numpy_env.physics.time(), float(times[-1]), rtol=1e-5)


@pytest.mark.parametrize("task", ["swingup", "balance", "dampen"])
def test_start_states_are_drawn_from_the_tasks_own_distribution(task):
    start = qube_tasks.SUITE[task]().start
    keys = jax.random.split(jax.random.PRNGKey(3), 4000)
    drawn = np.asarray(jax.vmap(lambda key: environment.draw_start(start, key))(keys))
    random = np.random.RandomState(3)
    expected = np.array([start.draw(random) for _ in range(4000)])
    assert np.all(drawn.min(axis=0) >= expected.min(axis=0) - 0.05 * expected.std(axis=0) - 1e-6)
    assert np.all(drawn.max(axis=0) <= expected.max(axis=0) + 0.05 * expected.std(axis=0) + 1e-6)
    assert np.all(abs(drawn.mean(axis=0) - expected.mean(axis=0)) <= 0.1 * expected.std(axis=0) + 1e-6)
    np.testing.assert_allclose(drawn.std(axis=0), expected.std(axis=0), rtol=0.08)


def _numpy_run(config, start, volts):
    """Exact and measured states of the numpy domain from `start` under `volts` (one per step)."""
    env = suite.load("qube", "swingup", task_kwargs={"observation": "trig", "voltage_limit": 10.0},
                     randomization=config)
    env.reset()
    with env.physics.reset_context():
        env.physics.reset_to(start)
    exact, measured = [], []
    for v in volts:
        assert not env.step(np.array([v])).last()  # the arm stays inside its limits
        exact.append(env.physics.true_state())
        measured.append([env.physics.arm_angle(), env.physics.pendulum_angle(), env.physics.arm_velocity(),
                         env.physics.pendulum_velocity()])
    return np.array(exact), np.array(measured)


def _jax_run(config, start, volts):
    env = environment.QubeMjx("swingup", randomization=config, voltage_limit=10.0)
    state = env.start(jnp.asarray(start, jnp.float32), jax.random.PRNGKey(0))

    def body(state, v):
        state = env.step(state, jnp.reshape(v / 10.0, (1,)))
        return state, (env.exact_state(state.pipeline_state), state.info["measured"])

    run = jax.jit(lambda state, volts: jax.lax.scan(body, state, volts))
    _, (exact, measured) = run(state, jnp.asarray(volts, jnp.float32))
    return np.asarray(exact), np.asarray(measured)


def _voltages(steps=150):
    t = np.arange(steps) / 250.0
    return 0.6 * np.sin(2 * math.pi * 5.0 * t) + 0.3 * np.sign(np.sin(2 * math.pi * 3.1 * t))


def test_mjx_world_follows_the_numpy_domain_nominal():
    start, volts = np.array([0.1, math.pi - 0.2, 0.5, -1.0]), _voltages()
    expected, _ = _numpy_run("none", start, volts)
    exact, measured = _jax_run("none", start, volts)
    np.testing.assert_allclose(exact, expected, atol=2e-3)
    np.testing.assert_allclose(measured, exact)


def test_mjx_world_follows_the_numpy_domain_with_parameters_and_effects():
    config = {"parameters": {"arm_friction": 1e-3, "pendulum_friction": 5e-5, "cable_stiffness": 1e-3,
                             "rotor_inertia": {"distribution": "uniform", "low": 1.5, "high": 1.5},
                             "arm_damping": {"distribution": "uniform", "low": 3.0, "high": 3.0}},
              "effects": {"quantization": True, "velocity_filter": True, "action_delay": {"steps": 2},
                          "voltage_offset": {"voltage": 0.3}, "dead_zone": {"voltage": 0.2}}}
    start, volts = np.array([0.0, math.pi, 0.0, 0.0]), _voltages()
    expected_exact, expected_measured = _numpy_run(config, start, volts)
    exact, measured = _jax_run(config, start, volts)
    np.testing.assert_allclose(exact, expected_exact, atol=3e-3)
    resolution = 2 * math.pi / 2048
    np.testing.assert_allclose(measured[:, :2], expected_measured[:, :2], atol=resolution * 1.01)
    np.testing.assert_allclose(measured[:, 2:], expected_measured[:, 2:], atol=0.2)
    assert np.allclose(measured[:, 0] / resolution, np.round(measured[:, 0] / resolution), atol=1e-3)
    assert not np.allclose(measured, exact, atol=1e-4)  # the effects are on


def test_observation_delay_and_saturation_follow_the_numpy_domain():
    config = {"effects": {"quantization": True, "observation_delay": {"steps": 3},
                          "voltage_offset": {"voltage": 0.3}, "saturation": {"voltage": 0.5}}}
    start, volts = np.array([0.0, math.pi, 0.0, 0.0]), 2.0 * _voltages()
    expected_exact, expected_measured = _numpy_run(config, start, volts)
    exact, measured = _jax_run(config, start, volts)
    np.testing.assert_allclose(exact, expected_exact, atol=3e-3)
    resolution = 2 * math.pi / 2048
    np.testing.assert_allclose(measured, expected_measured, atol=resolution * 1.01)
    # the task sees the state of three steps before, the start's until then
    np.testing.assert_allclose(measured[:2], np.tile(np.round(start / resolution) * resolution, (2, 1)),
                               atol=1e-5)
    np.testing.assert_allclose(measured[3:, :2], exact[:-3, :2], atol=resolution * 0.51)
    # the saturation binds: without it the arm turns further
    free, _ = _jax_run({"effects": {"quantization": True, "voltage_offset": {"voltage": 0.3}}}, start, volts)
    assert np.max(np.abs(free[:, 0] - exact[:, 0])) > 0.05


def test_delay_lines_are_as_long_as_the_longest_drawn_delay():
    config = randomization_config.load({"effects": {
        "action_delay": {"seconds": {"distribution": "uniform", "low": 0.0, "high": 0.012}},
        "observation_delay": {"steps": {"distribution": "uniform", "low": 1, "high": 4}}}})
    assert worlds.max_delay_steps(config, "action_delay", 250.0) == 3
    assert worlds.max_delay_steps(config, "observation_delay", 250.0) == 4
    assert worlds.max_delay_steps(config, "observation_delay", 500.0) == 4
    assert worlds.max_delay_steps(randomization_config.load("none"), "action_delay", 250.0) == 0
    batch, _ = worlds.draw(config, 6, 11, 250.0)
    for world in range(6):
        drawn = sample(config, np.random.RandomState(11 + world))
        assert int(batch.observation_delay_steps[world]) == drawn.effects["observation_delay"]["steps"]
        assert int(batch.delay_steps[world]) == round(drawn.effects["action_delay"]["seconds"] / 0.004)
    assert len(set(np.asarray(batch.observation_delay_steps).tolist())) > 1


def test_drawn_worlds_carry_the_numpy_draws_written_by_the_numpy_domain():
    config = randomization_config.load("sim2real")
    batch, axes = worlds.draw(config, 5, 7, 250.0)
    template = worlds.template_model(250.0, config)
    scratch = mujoco.MjData(template)
    ids = qube.ElementIds(template)
    for world in range(5):
        drawn = sample(config, np.random.RandomState(7 + world))
        model = qube_batch.physics_model(250.0)
        qube.write_parameters(model, scratch, drawn.parameters)
        assert float(batch.model.dof_armature[world, ids.arm_dof]) == pytest.approx(
            model.dof_armature[ids.arm_dof], rel=1e-6)
        assert float(batch.model.actuator_gainprm[world, ids.motor, 0]) == pytest.approx(
            model.actuator_gainprm[ids.motor, 0], rel=1e-6)
        assert float(batch.model.dof_frictionloss[world, ids.pendulum_dof]) == pytest.approx(
            model.dof_frictionloss[ids.pendulum_dof], rel=1e-5)
        assert float(batch.model.jnt_stiffness[world, ids.arm_joint]) == pytest.approx(
            model.jnt_stiffness[ids.arm_joint], rel=1e-6)
        assert int(batch.delay_steps[world]) == drawn.effects["action_delay"]["steps"]
    assert axes.model.body_mass == 0 and axes.model.opt.gravity is None and axes.delay_steps == 0
    assert set(jax.tree.leaves(axes.model)) == {0}  # the rest is shared (None)
    assert len(set(np.asarray(batch.model.body_mass[:, ids.pendulum]).tolist())) == 5


def test_the_numpy_policy_gives_the_brax_policys_actions():
    from brax.training.acme import running_statistics, specs
    from brax.training.agents.ppo import networks as ppo_networks

    network = ppo_networks.make_ppo_networks(6, 1, preprocess_observations_fn=running_statistics.normalize)
    normalizer = running_statistics.init_state(specs.Array((6,), jnp.dtype("float32")))
    samples = jax.random.normal(jax.random.PRNGKey(0), (500, 6)) * jnp.array([0.5, 0.5, 0.7, 0.7, 3.0, 9.0])
    normalizer = running_statistics.update(normalizer, samples + 0.2)
    params = (normalizer, network.policy_network.init(jax.random.PRNGKey(1)), None)
    act = ppo_networks.make_inference_fn(network)(params, deterministic=True)
    policy = training.export(params, "swingup", 3.0, {})
    states = np.random.default_rng(1).uniform([-1.5, -math.pi, -10, -30], [1.5, math.pi, 10, 30], (64, 4))
    env = environment.QubeMjx("swingup")
    observations = jnp.stack([env.features(env.rules(jnp.asarray(s, jnp.float32), 0.0)[0]) for s in states])
    expected, _ = act(observations, jax.random.PRNGKey(2))
    np.testing.assert_allclose(policy.actions(states), 3.0 * np.asarray(expected[:, 0]), atol=1e-4)


def test_the_gpu_training_pages_examples_run():
    page = (pathlib.Path(__file__).resolve().parent.parent / "docs" / "gpu-training.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", page, re.S)
    assert blocks
    for index, code in enumerate(blocks):
        exec(compile(code, f"docs/gpu-training.md python block {index}", "exec"), {})


def test_train_with_the_jax_backend_passes_a_follow_tasks_target_schedule(monkeypatch, tmp_path):
    from qube_suite import cli

    calls = []
    result = training.Result(tmp_path / "policy.npz", [(1, 0.0, 0.0)], 1.0)
    monkeypatch.setattr(training, "train", lambda task, **kwargs: calls.append((task, kwargs)) or result)
    assert cli.main(["train", "--task", "balance_follow", "--backend", "jax", "--steps", "1000", "--target",
                     "steps", "--target-hold-time", "1.5", "--out", str(tmp_path), "--quiet"]) == 0
    assert calls[0][0] == "balance_follow"
    assert calls[0][1]["task_kwargs"] == {"target": "steps", "target_hold_time": 1.5}


def test_device_put_replicated_stacks_one_copy_per_device():
    tree = {"a": jnp.arange(3.0), "b": (jnp.ones((2, 2)),)}
    replicated = brax_compat.device_put_replicated(tree, jax.devices())
    assert replicated["a"].shape == (len(jax.devices()), 3)
    np.testing.assert_array_equal(replicated["b"][0][0], np.ones((2, 2)))


def test_replicated_arrays_have_the_type_of_brax_pmapped_outputs():
    """Else Brax's training epoch and evaluation compile again when the first epoch's outputs come
    back as their inputs (an array's type carries its mesh's axis names)."""
    from brax.training.agents.ppo import train as ppo_train

    replicated = brax_compat.device_put_replicated({"a": jnp.arange(3.0)}, jax.devices())["a"]
    mapped = jax.pmap(lambda leaf: 2.0 * leaf, axis_name=ppo_train._PMAP_AXIS_NAME)(replicated)
    assert jax.typeof(mapped) == jax.typeof(replicated)


@pytest.mark.slow
@pytest.mark.parametrize("adaptive", [{}, {"history": 2, "privileged_critic": True}])
def test_training_on_the_backend_writes_a_policy_the_numpy_domains_run(tmp_path, adaptive):
    from qube_suite import evaluate
    from qube_suite.policies import mlp

    result = training.train("balance", steps=20_000, randomization="sim2real", out=tmp_path, progress=None,
                            hyperparameters={"num_envs": 16, "num_eval_envs": 4, "num_evals": 2,
                                             "batch_size": 16, "num_minibatches": 4, "unroll_length": 8,
                                             "num_updates_per_batch": 2, **adaptive})
    assert result.policy_path == tmp_path / "policy.npz" and (tmp_path / "training.json").is_file()
    assert len(result.evaluations) == 2
    assert mlp.load(result.policy_path).history == adaptive.get("history", 0)
    summary = evaluate(str(result.policy_path), domain="qube", task="balance", episodes=2, seed=0)
    assert len(summary.returns) == 2 and all(np.isfinite(summary.returns))


def test_an_episode_begun_by_brax_auto_reset_runs_as_a_fresh_one():
    """Brax's AutoResetWrapper puts back the first state's physics and observation but not its info:
    the velocity filter and the action delay line must not carry the last episode's values over."""
    from brax.envs.wrappers.training import AutoResetWrapper, EpisodeWrapper

    config = {"effects": {"velocity_filter": True, "observation_delay": {"steps": 2},
                          "action_delay": {"steps": 2}}}
    env = AutoResetWrapper(EpisodeWrapper(environment.QubeMjx("swingup", randomization=config), 6, 1))
    actions = jnp.asarray([0.9, -0.7, 0.8, -0.9, 0.6, 1.0], jnp.float32)[:, None]

    def body(state, action):
        state = env.step(state, action)
        return state, (state.info["measured"], state.obs)

    first = env.reset(jax.random.PRNGKey(3))
    _, (measured, obs) = jax.jit(lambda s: jax.lax.scan(body, s, jnp.concatenate([actions, actions])))(first)
    measured, obs = np.asarray(measured), np.asarray(obs)
    # the second episode starts at the first one's start and gets the same actions
    np.testing.assert_allclose(measured[7:], measured[1:6], atol=1e-6)
    np.testing.assert_allclose(obs[7:], obs[1:6], atol=1e-6)


def test_a_random_target_starts_again_in_an_episode_begun_by_brax_auto_reset():
    from brax.envs.wrappers.training import AutoResetWrapper, EpisodeWrapper

    task_kwargs = {"target": "steps", "target_hold_time": 0.012}  # a new target every 3 steps
    follow = environment.QubeMjx("swingup_follow", task_kwargs=task_kwargs)
    env = AutoResetWrapper(EpisodeWrapper(follow, 7, 1))

    def body(state, _):
        state = env.step(state, jnp.zeros(1))
        return state, (state.info["memory"]["task"], state.obs[-1])

    first = env.reset(jax.random.PRNGKey(3))
    _, (target, observed) = jax.jit(lambda s: jax.lax.scan(body, s, None, length=14))(first)
    changes = np.asarray(target.next_change)
    np.testing.assert_allclose(changes[:7], [0.012, 0.012, 0.024, 0.024, 0.024, 0.036, 0.036], atol=1e-6)
    np.testing.assert_allclose(changes[7:], changes[:7], atol=1e-6)  # the second episode's schedule
    values = np.asarray(target.value)
    assert values[7] == values[8] == values[0] != values[9]  # the first target, a new one at 0.012 s
    np.testing.assert_allclose(np.asarray(observed)[:6], values[:6])  # the observation's target


def test_the_rotors_count_starts_again_in_an_episode_begun_by_brax_auto_reset():
    from brax.envs.wrappers.training import AutoResetWrapper, EpisodeWrapper

    env = AutoResetWrapper(EpisodeWrapper(environment.QubeMjx("rotor"), 6, 1))
    actions = jnp.asarray([1.0, -1.0, 1.0, -1.0, 1.0, 1.0], jnp.float32)[:, None]

    def body(state, action):
        state = env.step(state, action)
        return state, state.info["memory"]["task"]

    first = env.reset(jax.random.PRNGKey(3))
    _, count = jax.jit(lambda s: jax.lax.scan(body, s, jnp.concatenate([actions, actions])))(first)
    turned = np.asarray(count.turned)
    assert np.all(turned[1:6] != 0.0)
    np.testing.assert_allclose(turned[7:], turned[1:6], atol=1e-6)
    np.testing.assert_allclose(np.asarray(count.last_alpha)[7:], np.asarray(count.last_alpha)[1:6], atol=1e-6)


def _brax_policy(observation_size, history, privileged=False, task_observation_size=4):
    """A Brax PPO policy with observation statistics for `observation_size`, its deterministic
    inference function and its export to a numpy policy of `history`."""
    from brax.training.acme import running_statistics, specs
    from brax.training.agents.ppo import networks as ppo_networks

    critic = {"value_obs_key": "privileged_state"} if privileged else {}
    network = ppo_networks.make_ppo_networks(observation_size, 1, **critic,
                                             preprocess_observations_fn=running_statistics.normalize)
    shapes = observation_size if privileged else {"state": (observation_size,)}
    normalizer = running_statistics.init_state(
        {key: specs.Array(shape, jnp.dtype("float32")) for key, shape in shapes.items()})
    samples = {key: jax.random.normal(jax.random.PRNGKey(i), (500, *shape)) * 0.3 + 0.1
               for i, (key, shape) in enumerate(shapes.items())}
    normalizer = running_statistics.update(normalizer, samples)
    if not privileged:
        normalizer = normalizer.replace(mean=normalizer.mean["state"], std=normalizer.std["state"],
                                        summed_variance=normalizer.summed_variance["state"])
    params = (normalizer, network.policy_network.init(jax.random.PRNGKey(1)), None)
    act = ppo_networks.make_inference_fn(network)(params, deterministic=True)
    return act, training.export(params, "swingup", 3.0, {}, history, task_observation_size)


@pytest.mark.parametrize("privileged", [False, True])
def test_a_policy_with_history_acts_alike_on_jax_and_numpy(privileged):
    """The JAX environment's history observation is the numpy policy's history input, step by step,
    with or without a privileged critic's part beside it."""
    history = 3
    env = environment.QubeMjx("swingup", voltage_limit=3.0, history=history, privileged_critic=privileged)
    act, policy = _brax_policy(env.observation_size, history, privileged)
    state = env.start(jnp.asarray([0.2, math.pi - 0.3, 1.0, -2.0], jnp.float32), jax.random.PRNGKey(0))

    def body(state, key):
        action, _ = act(state.obs, key)
        state = env.step(state, action)
        return state, (state.info["measured"], action[0])

    keys = jax.random.split(jax.random.PRNGKey(4), 60)
    first = state.info["measured"]
    _, (measured, actions) = jax.jit(lambda s: jax.lax.scan(body, s, keys))(state)
    observed = np.concatenate([np.asarray(first)[None], np.asarray(measured)[:-1]])
    volts = np.array([policy(observation) for observation in observed.astype(np.float64)])
    assert np.ptp(volts) > 0.3  # the voltages vary, so the history carries information
    np.testing.assert_allclose(volts, 3.0 * np.asarray(actions), atol=2e-4)
    assert policy.history == history


def test_a_follow_policy_acts_alike_on_jax_and_numpy():
    """The JAX environment's policy input for a follow task is the numpy policy's features of the task's
    observation with its target, step by step."""
    sine = {"target": "sine", "target_amplitude": 1.0, "target_frequency": 2.0}
    env = environment.QubeMjx("swingup_follow", voltage_limit=3.0, history=2, task_kwargs=sine)
    act, policy = _brax_policy(env.observation_size, 2, task_observation_size=5)
    state = env.start(jnp.asarray([0.2, math.pi - 0.3, 1.0, -2.0], jnp.float32), jax.random.PRNGKey(0))

    def body(state, key):
        action, _ = act(state.obs, key)
        observed = jnp.append(state.info["measured"], state.info["memory"]["task"].value)
        return env.step(state, action), (observed, action[0])

    keys = jax.random.split(jax.random.PRNGKey(4), 60)
    _, (observed, actions) = jax.jit(lambda s: jax.lax.scan(body, s, keys))(state)
    assert env.observation_size == 8 * 3 + 2 and policy.meta["observation_size"] == 5
    assert np.ptp(np.asarray(observed)[:, 4]) > 0.5  # the target moves
    volts = np.array([policy(observation) for observation in np.asarray(observed, np.float64)])
    np.testing.assert_allclose(volts, 3.0 * np.asarray(actions), atol=2e-4)


def test_the_privileged_critic_sees_the_exact_state_and_each_worlds_plant():
    config = {"parameters": {"pendulum_mass": {"distribution": "uniform", "low": 0.8, "high": 1.2}},
              "effects": {"quantization": True, "dead_zone": {"voltage": {"distribution": "uniform",
                                                                          "low": 0.0, "high": 0.3}}}}
    env = environment.QubeMjx("swingup", randomization=config, history=1, privileged_critic=True)
    plain = environment.QubeMjx("swingup", randomization=config, history=1)
    assert env.observation_size == {"state": (13,), "privileged_state": (13 + 6 + 14,)}
    batch, axes = env.draw_worlds(None, jax.random.split(jax.random.PRNGKey(0), 2))
    start = jnp.asarray([0.1, 3.0, 0.0, 0.0], jnp.float32)

    def first_steps(environment_, sys):
        environment_.sys = sys
        state = environment_.step(environment_.start(start, jax.random.PRNGKey(1)), jnp.ones(1))
        return state.obs, environment_.exact_state(state.pipeline_state)

    privileged_steps = jax.jit(functools.partial(first_steps, env))
    plain_steps = jax.jit(functools.partial(first_steps, plain))
    for world in range(2):
        sys = jax.tree.map(lambda leaf, axis, w=world: leaf if axis is None else leaf[w], batch, axes,
                           is_leaf=lambda leaf: leaf is None)
        obs, exact = privileged_steps(sys)
        plain_obs, _ = plain_steps(sys)
        np.testing.assert_array_equal(obs["state"], plain_obs)
        critic = np.asarray(obs["privileged_state"])
        np.testing.assert_array_equal(critic[:13], plain_obs)
        np.testing.assert_allclose(critic[13:19], [math.cos(exact[0]), math.sin(exact[0]), math.cos(exact[1]),
                                                   math.sin(exact[1]), exact[2], exact[3]], atol=1e-6)
        plant = dict(zip(environment.PRIVILEGED_PLANT, critic[19:], strict=True))
        ids = qube.ElementIds(qube_batch.physics_model(250.0))
        assert plant["pendulum_mass"] == pytest.approx(float(sys.model.body_mass[ids.pendulum]), rel=1e-6)
        assert plant["dead_zone"] == pytest.approx(float(sys.dead_zone), rel=1e-6)
    assert not np.allclose(np.asarray(batch.dead_zone)[0], np.asarray(batch.dead_zone)[1])


def test_task_settings_the_environment_sets_itself_are_refused():
    for reserved in ({"random": 3}, {"observation": "trig"}, {"voltage_limit": 5.0}):
        with pytest.raises(ValueError, match="set by the environment"):
            environment.QubeMjx("swingup_follow", task_kwargs=reserved)
    with pytest.raises(ValueError, match="unknown target schedule"):
        environment.QubeMjx("swingup_follow", task_kwargs={"target": "zigzag"})


def test_a_bad_history_is_refused():
    for bad in (-1, 2.5, True):
        with pytest.raises(ValueError, match="history must be an integer"):
            environment.QubeMjx("swingup", history=bad)
