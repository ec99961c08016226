"""The batched swing-up controller gives each world the per-world controller's voltage (within 1e-12 V)
through swings, catches, the energy adaptation, voltages other than its own, resets and resyncs, with one
design for all worlds or each world its own."""

import numpy as np
import pytest

from qube_suite import baselines
from qube_suite.conventions import ObservationLayout
from qube_suite.devices.qube import parameters
from qube_suite.devices.qube.controllers.batched import BatchedSwingup
from qube_suite.wrappers.vector_env import QubeVectorEnv

WORLDS = 6


DESIGNS = [{"latency_steps": 0},
           {"latency_steps": 2, "parameters": parameters.REAL_QUBE_SERVO2},
           {"latency_steps": 1, "parameters": {"pendulum_mass": 0.03, "motor_resistance": 6.5}},
           {"latency_steps": 3, "parameters": {"rotor_inertia": 2e-5, "arm_damping": 1e-3}}]
"""Designs of the teacher built for each world's plant (`imitation.Teachers(knows_plant=True)`)."""


def simulate(design, redesign=False, steps=1500, seed=0):
    """Per-world controllers and the batch, side by side, on simulated worlds, world w's controller in
    its episode e made with `design(w, e)` (keyword arguments of `baselines.make`); at a new episode a
    world's controller is reset, or with `redesign` made anew and given to the batch. The worst voltage
    difference (V), what the batch went through and how many designs it took up after the first."""
    def make(world, episode):
        return baselines.make("swingup", voltage_limit=3.0, **design(world, episode))

    episodes = np.zeros(WORLDS, int)
    controllers = [make(world, 0) for world in range(WORLDS)]
    batch = BatchedSwingup(make(0, 0), WORLDS)
    if redesign:
        for world in range(WORLDS):
            batch.redesign(world, make(world, 0))
        batch.reset(np.ones(WORLDS, bool))
    env = QubeVectorEnv("swingup", WORLDS, autoreset_mode="SameStep", randomization="wide")
    observations, _ = env.reset(seed=seed)
    random = np.random.default_rng(seed)
    start_energy = batch._energy_set.copy()
    worst, balanced, adapted = 0.0, np.zeros(WORLDS, bool), np.zeros(WORLDS, bool)
    for step in range(steps):
        states = observations[:, :4].astype(np.float64)
        if step == steps // 2:  # an angle jump without a reset: both restart their estimates
            states[0, 1] += 1.0
        expected = np.array([controller(row) for controller, row in zip(controllers, states, strict=True)])
        volts = batch(states)
        worst = max(worst, float(np.abs(volts - expected).max()))
        balanced |= np.array([controller.balancing for controller in controllers])
        adapted |= batch._energy_set != start_energy
        sent = np.where(random.random(WORLDS) < 0.8, expected, random.uniform(-3.0, 3.0, WORLDS))
        for controller, value in zip(controllers, sent, strict=True):
            controller.sent(float(value))
        batch.sent(sent)
        observations, _, terminated, truncated, _ = env.step(sent[:, None].astype(np.float32))
        restart = terminated | truncated | (random.random(WORLDS) < 0.002)
        for world in np.flatnonzero(restart):
            episodes[world] += 1
            if redesign:
                controllers[world] = make(world, episodes[world])
                batch.redesign(world, make(world, episodes[world]))
            else:
                controllers[world].reset()
        batch.reset(restart)
    env.close()
    return worst, balanced, adapted, int(episodes.sum()) if redesign else 0


@pytest.mark.parametrize("latency_steps", [0, 1])
def test_the_batch_gives_each_world_the_per_world_controllers_voltage(latency_steps):
    worst, balanced, adapted, _ = simulate(lambda world, episode: {"latency_steps": latency_steps})
    assert worst <= 1e-12
    assert balanced.any()  # the LQR caught
    assert adapted.any()  # an uncaught swing changed the set energy


def test_each_world_runs_its_own_design_and_takes_another_at_a_new_episode():
    worst, balanced, _, redesigned = simulate(
        lambda world, episode: DESIGNS[(world + episode) % len(DESIGNS)], redesign=True, seed=3)
    assert worst <= 1e-12
    assert balanced.any() and redesigned >= 5


def test_a_batch_refuses_what_it_cannot_run():
    with pytest.raises(ValueError, match="SwingupController"):
        BatchedSwingup(baselines.make("balance"), 2)
    with pytest.raises(ValueError, match="positive integer"):
        BatchedSwingup(baselines.make("swingup"), 0)
    with pytest.raises(ValueError, match=r"shape \(2, 4\)"):
        BatchedSwingup(baselines.make("swingup"), 2)(np.zeros((3, 4)))
    with pytest.raises(ValueError, match="voltage limit and control frequency"):
        BatchedSwingup(baselines.make("swingup"), 2).redesign(0, baselines.make("swingup", voltage_limit=5.0))
    with pytest.raises(ValueError, match="SwingupController"):
        BatchedSwingup(baselines.make("swingup"), 2).redesign(1, baselines.make("balance"))



def test_rows_of_trig_observations_split_as_each_observation_does():
    layout = ObservationLayout("trig", target=True)
    rows = np.random.default_rng(1).uniform(-1.0, 1.0, (5, layout.size))
    states, targets = layout.split_rows(rows)
    for row, state, target in zip(rows, states, targets, strict=True):
        expected_state, expected_target = layout.split(row)
        np.testing.assert_allclose(state, expected_state, rtol=0, atol=1e-15)
        assert target == expected_target
    with pytest.raises(ValueError, match=r"shape \(worlds, 7\)"):
        layout.split_rows(rows[:, :6])
