"""Controllers on the hardware path: the state observer, the latency prediction, and seeded runs
on the `qube_hardware` domain (quantised angles, filtered velocities, a sample of latency,
Coulomb friction and the cable's spring) at the default 3 V."""

import math

import numpy as np
import pytest
import scipy.linalg

from qube_suite import baselines, suite
from qube_suite.devices.qube import simulation as qube
from qube_suite.devices.qube.controllers import lqr
from qube_suite.devices.qube.controllers.linearization import linearize
from qube_suite.devices.qube.controllers.model import RigidBodyModel
from qube_suite.devices.qube.controllers.observer import StateObserver, kalman_gain
from qube_suite.evaluation import evaluate


def hardware_episode(task, controller_name, seed=0, time_limit=8.192, target=None):
    """Run a controller on `task` on the substitute board; the plant's true states (N x 4) after
    each step, the observations before it, the voltages sent and the final discount."""
    with suite.load("qube_hardware", task, task_kwargs={"random": seed},
                    environment_kwargs={"time_limit": time_limit}) as env:
        controller = baselines.for_environment(controller_name, env)
        controller.reset()
        timestep = env.reset()
        true_states, observations, voltages = [], [], []
        while not timestep.last():
            observation = timestep.observation
            if target is not None:
                observation = {"state": observation["state"], "target": np.array([target])}
            observations.append(observation["state"])
            voltages.append(controller(observation))
            timestep = env.step(voltages[-1])
            true_states.append(env.physics.qube.board.true_state())
        controller.close()
        return np.array(true_states), np.array(observations), np.array(voltages), timestep.discount


# -- the design pieces --------------------------------------------------------------------------


def test_the_domains_state_their_latency_and_controllers_are_built_with_it():
    assert qube.Physics.latency_steps == 0
    with suite.load("qube_hardware", "balance") as env:
        assert env.physics.latency_steps == 1
        controller = baselines.for_environment("swingup", env)
        assert controller.observer.latency_steps == 1
        assert controller.voltage_limit == env.task.voltage_limit


def test_kalman_gain_of_a_random_walk_is_the_textbook_one():
    """x' = x + w, y = x + v: the predicted variance solves P = P r / (P + r) + q."""
    q, r = 0.3, 2.0
    p = (q + math.sqrt(q * q + 4.0 * q * r)) / 2.0
    gain = kalman_gain(np.eye(1), np.eye(1), np.array([[q]]), np.array([[r]]))
    assert gain[0, 0] == pytest.approx(p / (p + r))


def delay_augmented_lqr(a, b, q, r, delay):
    """LQR gain on z = [x_k, u_(k-delay), ..., u_(k-1)] for x_(k+1) = a x_k + b u_(k-delay), cost on x."""
    n, m = a.shape[0], b.shape[1]
    size = n + delay * m
    a_z, b_z = np.zeros((size, size)), np.zeros((size, m))
    a_z[:n, :n], a_z[:n, n:n + m] = a, b
    a_z[n:size - m, n + m:] = np.eye((delay - 1) * m)  # the delay line shifts by one
    b_z[size - m:] = np.eye(m)
    q_z = scipy.linalg.block_diag(q, np.zeros((delay * m, delay * m)))
    s = scipy.linalg.solve_discrete_are(a_z, b_z, q_z, r)
    return np.linalg.solve(r + b_z.T @ s @ b_z, b_z.T @ s @ a_z)


def test_delay_augmented_lqr_of_a_scalar_plant_is_the_lqr_on_the_prediction():
    """x' = a x + b u_(k-1): by hand, u_k = -K x_(k+1) = -K (a x_k + b u_(k-1)), K the plain LQR's."""
    a, b, q, r = np.array([[1.2]]), np.array([[0.5]]), np.array([[1.0]]), np.array([[0.1]])
    s = scipy.linalg.solve_discrete_are(a, b, q, r)
    plain = (b * s * a / (r + b * b * s))[0, 0]
    np.testing.assert_allclose(delay_augmented_lqr(a, b, q, r, 1), [[plain * 1.2, plain * 0.5]], rtol=1e-9)


@pytest.mark.parametrize("delay", [1, 3])
def test_delay_augmented_lqr_of_the_qube_is_the_balance_gain_on_the_prediction(delay):
    """The optimum on the Qube with its delay line is K [A^N, A^(N-1) B, ..., B]: what the
    observer's prediction followed by the undelayed LQR computes."""
    physics = qube.make_physics(250.0)
    a, b = linearize(physics, np.zeros(4), 0.0, 1)
    q, r = np.diag(lqr.STATE_WEIGHTS), np.array([[lqr.VOLTAGE_WEIGHT]])
    gain = lqr.lqr_gain(250.0)
    predicted = np.hstack([gain @ np.linalg.matrix_power(a, delay)]
                          + [gain @ np.linalg.matrix_power(a, delay - 1 - i) @ b for i in range(delay)])
    np.testing.assert_allclose(delay_augmented_lqr(a, b, q, r, delay), predicted, rtol=1e-6, atol=1e-9)


def test_balance_controller_with_latency_answers_like_the_delay_augmented_lqr():
    physics = qube.make_physics(250.0)
    a, b = linearize(physics, np.zeros(4), 0.0, 1)
    augmented = delay_augmented_lqr(a, b, np.diag(lqr.STATE_WEIGHTS), np.array([[lqr.VOLTAGE_WEIGHT]]), 1)
    controller = baselines.make("balance", latency_steps=1, voltage_limit=100.0)
    controller.reset()
    x0 = np.array([0.02, 0.01, -0.05, 0.1])
    u0 = controller({"state": x0})
    assert u0 == pytest.approx(-(augmented @ np.append(x0, 0.0)).item(), rel=1e-3)
    physics.reset_to(x0)                        # over the first sample the voltage before the episode acts
    physics.step()
    x1 = physics.qube_state()
    u1 = controller({"state": x1})
    assert u1 == pytest.approx(-(augmented @ np.append(x1, u0)).item(), rel=1e-3)


@pytest.mark.slow
def test_latency_prediction_balances_through_a_delay_the_plain_lqr_cannot():
    """48 ms of action delay: the LQR told the latency balances every episode, without it none."""
    delay = 12
    delayed = {"effects": {"action_delay": {"steps": delay}}}
    told = evaluate(baselines.make("balance", latency_steps=delay), task="balance", episodes=2,
                    randomization=delayed)
    untold = evaluate(baselines.make("balance"), task="balance", episodes=2, randomization=delayed)
    assert told.success_rate == 1.0 and min(told.returns) > 2000
    assert untold.success_rate == 0.0


def test_observer_recovers_the_velocities_from_the_angles_alone():
    """Exact angles of a simulated swing; the observer starts with velocities 3 rad/s off."""
    physics = qube.make_physics(250.0)
    observer = StateObserver(RigidBodyModel.from_parameters(), 250.0)
    state = np.array([0.0, 2.5, 1.0, -4.0])
    physics.reset_to(state)
    errors = []
    for k in range(250):
        measured = physics.qube_state() + (np.array([0.0, 0.0, 3.0, -3.0]) if k == 0 else 0.0)
        estimate = observer(measured)
        errors.append(np.abs(estimate - physics.qube_state()))
        volts = 2.0 * math.sin(8.0 * k / 250.0)
        observer.command(volts)
        physics.set_voltage(volts)
        physics.step()
    assert np.max(errors[-50:]) < 1e-3                       # converged to the true state
    assert errors[0][2] > 2.9                                 # from a start 3 rad/s off


def test_observer_finds_an_unmodelled_constant_acceleration():
    """Angles of the model with extra constant accelerations b: the estimate converges to b, and
    the speeds carry no bias."""
    model = RigidBodyModel.from_parameters()
    observer = StateObserver(model, 250.0)
    extra = (6.0, -4.0)
    x, h = np.array([0.0, 3.0, 0.0, 0.0]), 1e-4
    for k in range(750):
        estimate = observer(x + np.array([0.0, 0.0, 1.0, 1.0]) * (k == 0))
        observer.command(0.5)
        for _ in range(40):                                   # 4 ms in fine steps under 0.5 V
            ddtheta, ddalpha = model.accelerations(x[1], x[2], x[3], 0.5)
            x = x + h * np.array([x[2], x[3], ddtheta + extra[0], ddalpha + extra[1]])
    np.testing.assert_allclose(observer.unmodelled_accelerations, extra, atol=0.1)
    np.testing.assert_allclose(estimate[2:], x[2:], atol=0.05)


def test_observer_restarts_from_a_measurement_no_motion_explains():
    observer = StateObserver(RigidBodyModel.from_parameters(), 250.0)
    observer(np.array([0.0, math.pi, 0.0, 0.0]))
    observer.command(0.0)
    jumped = np.array([0.5, 0.1, 2.0, -1.0])                 # a new episode without reset()
    np.testing.assert_allclose(observer(jumped), jumped)


# -- on the hardware path at 3 V ------------------------------------------------------------


def test_observer_tracks_the_plant_far_better_than_the_velocity_filter():
    """During a hardware swing-up: the controller's prediction of the next sample's speeds against the
    plant's, and the filtered speeds of the observation against the plant's at the same sample."""
    true_states, observations, voltages, _ = hardware_episode("swingup", "swingup", time_limit=3.0)
    observer = StateObserver(RigidBodyModel.from_parameters(), 250.0, latency_steps=1)
    predictions = []
    for observation, volts in zip(observations, voltages, strict=True):
        predictions.append(observer(observation))
        observer.command(volts)
    before = np.vstack([observations[:1], true_states[:-1]])  # the plant at each observation
    filter_error = np.sqrt(np.mean((observations[:, 2:] - before[:, 2:]) ** 2))
    observer_error = np.sqrt(np.mean((np.array(predictions)[:, 2:] - true_states[:, 2:]) ** 2))
    assert observer_error < filter_error / 4


def test_swingup_on_hardware_catches_and_holds_upright():
    true_states, _, voltages, discount = hardware_episode("swingup", "swingup", time_limit=5.0)
    upright = np.abs(true_states[:, 1]) < math.radians(10)
    assert discount == 1.0 and np.abs(true_states[:, 0]).max() < math.radians(70)
    assert upright[:round(2.0 * 250)].any()                  # up within 2 s
    first = int(np.argmax(upright))
    assert upright[first + 50:].all()                         # caught: never falls again
    assert np.abs(voltages).max() <= 3.0


def test_balance_on_hardware_holds_upright():
    true_states, _, _, discount = hardware_episode("balance", "balance", time_limit=4.0)
    assert discount == 1.0
    assert np.abs(true_states[:, 1]).max() < math.radians(5)
    assert np.abs(true_states[:, 0]).max() < math.radians(20)


@pytest.mark.parametrize("target", [0.5, -0.8])
def test_follow_on_hardware_settles_at_a_steady_target(target):
    """Despite Coulomb friction and the cable's spring, which the observer's torque estimate cancels."""
    true_states, _, _, discount = hardware_episode("balance", "follow", time_limit=4.0, target=target)
    assert discount == 1.0
    assert np.abs(true_states[-250:, 0] - target).max() < 0.08   # within 4.6 degrees over the last second


@pytest.mark.slow
def test_follow_on_hardware_swings_up_and_follows_the_moving_target():
    result = evaluate("follow", domain="qube_hardware", task="swingup_follow", episodes=2)
    assert result.success_rate == 1.0 and min(result.returns) > 1600
