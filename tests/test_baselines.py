"""Model-derived controllers: the model they use, LQR design, and each controller on its tasks."""

import math
import time

import numpy as np
import pytest
import scipy.linalg
from reference_dynamics import FurutaPendulum

from qube_suite import baselines, suite
from qube_suite.angles import wrap_angle
from qube_suite.conventions import ObservationLayout
from qube_suite.devices.qube import parameters
from qube_suite.devices.qube import simulation as qube
from qube_suite.devices.qube.controllers import dampen, lqr
from qube_suite.devices.qube.controllers.model import RigidBodyModel
from qube_suite.devices.qube.tasks import Dampen, Swingup
from qube_suite.environment import Environment
from qube_suite.evaluation import policy_for
from qube_suite.tasks import SUITE

ROBUSTNESS = [{"pendulum_mass": 1.2 * parameters.NOMINAL["pendulum_mass"]},
              {"arm_damping": 100 * parameters.NOMINAL["arm_damping"]},
              {"arm_friction": 2e-3}]
"""Plants the controllers are not designed for: they use the nominal model."""


def run_episode(task, controller, seed, **task_kwargs):
    env = suite.load("qube", task, task_kwargs={"random": seed, **task_kwargs})
    controller.reset()
    timestep = env.reset()
    episode_return, largest_arm_angle, upright_at = 0.0, 0.0, None
    while not timestep.last():
        timestep = env.step(controller(timestep.observation))
        episode_return += timestep.reward
        theta, alpha = timestep.observation["state"][:2]
        largest_arm_angle = max(largest_arm_angle, abs(theta))
        if upright_at is None and abs(alpha) < math.radians(10):
            upright_at = env.physics.time()
    return episode_return, env.step_count, timestep.discount, largest_arm_angle, upright_at


def trajectory(task, controller, physics_parameters=None, time_limit=8.192):
    """Run `controller` on `task` (a task object) on a Qube with `physics_parameters`.

    Returns the return, the final discount, the states after each step (N x 4)
    and the voltages applied.
    """
    env = Environment(qube.make_physics(250.0, physics_parameters), task, time_limit=time_limit)
    controller.reset()
    timestep = env.reset()
    episode_return, states, voltages = 0.0, [], []
    while not timestep.last():
        voltages.append(controller(timestep.observation))
        timestep = env.step(voltages[-1])
        episode_return += timestep.reward
        states.append(timestep.observation["state"])
    return episode_return, timestep.discount, np.array(states), np.array(voltages)


def starting_from(task_class, state):
    """A `task_class` task whose episodes start from `state` [theta, alpha, dtheta, dalpha]."""

    class Task(task_class):
        def initial_state(self, random):
            return np.array(state, dtype=np.float64)

    return Task(random=0)


def assert_swung_up_and_balanced(discount, states, within=3.0, arm_limit=70.0):
    upright = np.abs(states[:, 1]) < math.radians(10)
    assert discount == 1.0                                   # never left the arm's +-90 degrees
    assert np.abs(states[:, 0]).max() < math.radians(arm_limit)
    assert upright[:round(within * 250)].any()               # up within `within` seconds
    assert upright[-500:].all()                              # and still up for the last 2 s


# -- the closed-form model --------------------------------------------------------------


def largest_drift(model, physics_parameters, seconds=1.0):
    """Largest change of the model's energy (J) and angular momentum on an undamped, unpowered Qube."""
    physics = qube.make_physics(1000.0, {**physics_parameters, "arm_damping": 0.0, "pendulum_damping": 0.0,
                                         "motor_back_emf": 1e-12})
    state = np.array([0.3, 2.5, -4.0, 9.0])
    physics.reset_to(state)
    energy, momentum = model.energy(*state[1:]), model.angular_momentum(*state[1:])
    energy_drift = momentum_drift = 0.0
    for _ in range(round(seconds * 1000)):
        physics.step()
        state = physics.qube_state()
        energy_drift = max(energy_drift, abs(model.energy(*state[1:]) - energy))
        momentum_drift = max(momentum_drift, abs(model.angular_momentum(*state[1:]) - momentum))
    return energy_drift, momentum_drift


@pytest.mark.parametrize("overrides", [{}, {"pendulum_mass": 0.03, "arm_length": 0.1}])
def test_model_energy_and_momentum_are_conserved_by_the_simulated_qube(overrides):
    model = RigidBodyModel.from_parameters(overrides)
    energy_drift, momentum_drift = largest_drift(model, overrides)
    assert energy_drift < 1e-6 * model.swing_up_energy and momentum_drift < 1e-9


def test_model_conservation_detects_a_wrong_model():
    wrong = RigidBodyModel.from_parameters({"pendulum_length": 0.14})
    energy_drift, momentum_drift = largest_drift(wrong, {})
    assert energy_drift > 1e-3 * wrong.swing_up_energy and momentum_drift > 1e-6


def test_model_motor_work_torque_and_swing_centre():
    """dE/dt = tau dtheta, dp/dt = tau and dpsi/dt = p / M11 on the simulated Qube."""
    physics = qube.make_physics(2000.0, {"arm_damping": 0.0, "pendulum_damping": 0.0})
    model = RigidBodyModel.from_parameters()
    state = np.array([0.2, 2.0, 3.0, -6.0])
    torque = 0.01
    volts = model.voltage_for_torque(torque, state[2])
    assert model.torque_per_volt * (volts - model.back_emf * state[2]) == pytest.approx(torque)
    physics.reset_to(state)
    physics.set_voltage(volts)
    physics.step()
    after = physics.qube_state()
    dt, mid = physics.timestep(), 0.5 * (state + after)
    torque_mid = model.torque_per_volt * (volts - model.back_emf * mid[2])
    assert (model.energy(*after[1:]) - model.energy(*state[1:])) / dt == pytest.approx(
        torque_mid * mid[2], rel=1e-3)
    assert (model.angular_momentum(*after[1:]) - model.angular_momentum(*state[1:])) / dt == pytest.approx(
        torque_mid, rel=1e-3)
    centre_speed = (model.swing_centre(*after[:2]) - model.swing_centre(*state[:2])) / dt
    assert centre_speed == pytest.approx(model.angular_momentum(*mid[1:]) / model.arm_inertia(mid[1]),
                                         rel=1e-3)
    assert abs(model.swing_offset(math.pi / 2)) < math.radians(30)


def test_model_accelerations_match_the_simulated_qube():
    random = np.random.default_rng(0)
    for overrides in ({}, {"pendulum_mass": 0.03, "arm_length": 0.1, "arm_damping": 1e-3}):
        model, physics = RigidBodyModel.from_parameters(overrides), qube.make_physics(250.0, overrides)
        for _ in range(5):
            state = random.uniform([-1.5, -math.pi, -10.0, -30.0], [1.5, math.pi, 10.0, 30.0])
            volts = random.uniform(-5.0, 5.0)
            physics.reset_to(state)
            physics.set_voltage(volts)
            physics.forward()
            np.testing.assert_allclose(model.accelerations(*state[1:], volts), physics.data.qacc, rtol=1e-9)


def test_model_arm_torque_of_the_accelerations_at_rest_is_the_motors():
    model, physics = RigidBodyModel.from_parameters(), qube.make_physics(250.0)
    for alpha, volts in [(0.3, 2.0), (2.5, -1.0)]:
        physics.reset_to([0.0, alpha, 0.0, 0.0])
        physics.set_voltage(volts)
        physics.forward()
        assert model.arm_torque(alpha, *physics.data.qacc) == pytest.approx(model.torque_per_volt * volts)


# -- LQR design ---------------------------------------------------------------------------


def discrete_lqr(a_c, b_c, state_weights, period=0.004):
    """The discrete LQR gain (1 x 4) for continuous (A, B) held over `period` (s)."""
    block = np.zeros((5, 5))
    block[:4, :4], block[:4, 4:] = a_c, b_c
    discrete = scipy.linalg.expm(block * period)
    a, b = discrete[:4, :4], discrete[:4, 4:]
    q, r = np.diag(state_weights), np.array([[lqr.VOLTAGE_WEIGHT]])
    s = scipy.linalg.solve_discrete_are(a, b, q, r)
    return np.linalg.solve(r + b.T @ s @ b, b.T @ s @ a)


def test_lqr_gain_matches_the_closed_form_linear_model():
    p = parameters.resolve({})
    a_c, b_c = FurutaPendulum(p, 0.5 * p["pendulum_mass"] * parameters.PENDULUM_ROD_RADIUS**2
                              ).linearized_upright()
    np.testing.assert_allclose(lqr.lqr_gain(250.0), discrete_lqr(a_c, b_c, lqr.STATE_WEIGHTS), rtol=1e-4)


def test_lqr_gain_depends_on_frequency_and_parameters():
    nominal = lqr.lqr_gain(250.0)
    assert not np.allclose(lqr.lqr_gain(500.0), nominal, rtol=1e-3)
    assert not np.allclose(lqr.lqr_gain(250.0, {"pendulum_mass": 0.03}), nominal, rtol=1e-3)


def test_lqr_about_hanging_matches_the_closed_form_model():
    """The dampen controller's LQR: the reference model linearised at hanging by finite differences."""
    p = parameters.resolve({})
    reference = FurutaPendulum(p, 0.5 * p["pendulum_mass"] * parameters.PENDULUM_ROD_RADIUS**2)
    hanging = np.array([0.0, math.pi, 0.0, 0.0])
    a_c, b_c = np.zeros((4, 4)), np.zeros((4, 1))
    a_c[:2, 2:] = np.eye(2)
    for i in range(4):
        step = np.zeros(4)
        step[i] = 1e-6
        a_c[2:, i] = (np.subtract(reference.acceleration(hanging + step, 0.0),
                                  reference.acceleration(hanging - step, 0.0))) / 2e-6
    b_c[2:, 0] = np.subtract(reference.acceleration(hanging, 1e-6),
                             reference.acceleration(hanging, -1e-6)) / 2e-6
    gain, _ = lqr.lqr_design(250.0, None, dampen.STATE_WEIGHTS, pendulum_angle=math.pi)
    np.testing.assert_allclose(gain, discrete_lqr(a_c, b_c, dampen.STATE_WEIGHTS), rtol=1e-4)


def test_lqr_voltage_level_set_is_the_ellipsoid_where_the_lqr_stays_within_the_voltage():
    controller = baselines.make("balance")
    level = controller.level_for_voltage(8.5)
    k, s = controller.gain, controller.cost_matrix
    worst = np.linalg.solve(s, k)                      # the direction of largest |K x| on the ellipsoid
    worst *= math.sqrt(level / (worst @ s @ worst))
    assert controller.cost_to_go(worst) == pytest.approx(level)
    assert abs(k @ worst) == pytest.approx(8.5)
    random = np.random.default_rng(0).normal(size=(1000, 4))
    on_ellipsoid = random * np.sqrt(level / np.einsum("ni,ij,nj->n", random, s, random))[:, None]
    assert np.abs(on_ellipsoid @ k).max() <= 8.5 + 1e-9


@pytest.mark.parametrize("seed", range(4))
def test_lqr_balances_for_a_whole_episode(seed):
    episode_return, steps, discount, _, _ = run_episode("balance", baselines.make("balance"), seed)
    assert steps == 2048 and discount == 1.0 and episode_return > 2000


def test_lqr_follows_the_target():
    episode_return, steps, _, _, _ = run_episode("balance_follow", baselines.make("balance"), 0)
    assert steps == 2048 and episode_return > 1700


def test_swingup_is_reachable_at_the_default_voltage_limit():
    """The evidence for the 3 V default: a swing-up that never leaves +-90 degrees."""
    controller = baselines.make("mpc", voltage_limit=3.0, seed=1)
    episode_return, steps, discount, largest_arm_angle, upright_at = run_episode("swingup", controller, 1)
    controller.close()
    assert steps == 2048 and discount == 1.0          # never terminated: |theta| stayed below 90 deg
    assert upright_at is not None and upright_at < 3.0
    assert largest_arm_angle < math.radians(80)
    assert episode_return > 1700


# -- swing-up ------------------------------------------------------------------------------


@pytest.mark.parametrize("voltage_limit", [3.0, 5.0, 10.0])
def test_swingup_swings_up_and_balances(voltage_limit):
    for seed in range(2):
        controller = baselines.make("swingup", voltage_limit=voltage_limit)
        episode_return, discount, states, voltages = trajectory(
            SUITE["swingup"](random=seed, voltage_limit=voltage_limit), controller)
        assert_swung_up_and_balanced(discount, states, within=2.0)
        assert np.abs(voltages).max() <= voltage_limit
        assert episode_return > 1800


@pytest.mark.parametrize("physics_parameters", ROBUSTNESS)
def test_swingup_works_on_plants_it_was_not_designed_for(physics_parameters):
    _, discount, states, _ = trajectory(SUITE["swingup"](random=0), baselines.make("swingup"),
                                        physics_parameters)
    assert_swung_up_and_balanced(discount, states)


@pytest.mark.parametrize("start", [[0.0, math.pi, 0.0, 0.0],          # at rest, even against friction
                                   [0.9, -2.2, 2.6, -0.8],             # arm far out and moving out
                                   [-0.5, 0.4, 0.0, 6.0]])             # falling through upright
def test_swingup_recovers_from_any_state(start):
    _, discount, states, _ = trajectory(starting_from(Swingup, start), baselines.make("swingup"),
                                        {"arm_friction": 1e-3})
    assert_swung_up_and_balanced(discount, states, arm_limit=80.0)


def test_swingup_set_energy_adapts_to_a_pendulum_short_of_energy():
    """Friction and damping the model does not know leave the first swings short; the set energy rises."""
    controller = baselines.make("swingup")
    initial = controller.energy_set
    _, discount, states, _ = trajectory(SUITE["swingup"](random=0), controller,
                                        {"arm_friction": 2e-3, "arm_damping": 5e-4, "pendulum_damping": 5e-5})
    assert_swung_up_and_balanced(discount, states, within=6.0)
    assert controller.energy_set > initial
    controller.reset()
    assert controller.energy_set == initial


# -- dampen --------------------------------------------------------------------------------


def assert_at_rest_hanging(discount, states, seconds=2.0):
    final = states[-round(seconds * 250):]
    assert discount == 1.0
    assert np.abs([wrap_angle(alpha - math.pi) for alpha in final[:, 1]]).max() < math.radians(10)
    assert np.abs(final[:, 0]).max() < math.radians(20)
    assert np.abs(final[-1, 2:]).max() < 0.2                 # low speed at the end


@pytest.mark.parametrize("seed", range(3))
def test_dampen_brings_the_pendulum_to_rest_hanging(seed):
    episode_return, discount, states, _ = trajectory(SUITE["dampen"](random=seed), baselines.make("dampen"))
    assert_at_rest_hanging(discount, states, seconds=4.0)
    assert episode_return > 1800


@pytest.mark.parametrize("start", [[0.0, 0.01, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], [0.0, 2.0, 0.0, 20.0]])
def test_dampen_from_upright_and_from_a_revolving_pendulum(start):
    _, discount, states, _ = trajectory(starting_from(Dampen, start), baselines.make("dampen"))
    assert_at_rest_hanging(discount, states)


@pytest.mark.parametrize("start", [[0.0, 0.0, 0.0, 0.0], [0.3, 1e-3, 0.0, 0.0], [-0.2, -1e-3, 0.0, 0.0]])
def test_dampen_tips_a_pendulum_that_friction_holds_upright(start):
    # Coulomb friction of 5e-5 N m holds the pendulum within about 3e-3 rad of upright at rest
    # (m g l sin(alpha) below it): with no speed the energy law alone would leave it there.
    _, discount, states, _ = trajectory(starting_from(Dampen, start), baselines.make("dampen"),
                                        {"pendulum_friction": 5e-5})
    assert_at_rest_hanging(discount, states)


@pytest.mark.parametrize("physics_parameters", ROBUSTNESS)
def test_dampen_works_on_plants_it_was_not_designed_for(physics_parameters):
    _, discount, states, _ = trajectory(SUITE["dampen"](random=1), baselines.make("dampen"),
                                        physics_parameters)
    assert_at_rest_hanging(discount, states)


# -- rotor ----------------------------------------------------------------------------------


def test_rotor_keeps_the_pendulum_revolving():
    task = SUITE["rotor"](random=0)
    episode_return, discount, states, _ = trajectory(task, baselines.make("rotor"), time_limit=3.0)
    assert discount == 1.0 and np.abs(states[:, 0]).max() < math.radians(80)
    assert task.revolutions >= 2 and episode_return == task.revolutions


# -- follow --------------------------------------------------------------------------------


def test_follow_tracks_a_steady_target():
    """Balance with the target fixed at 0.5 rad: the arm settles there."""
    controller = baselines.make("follow")
    env = Environment(qube.make_physics(), SUITE["balance"](random=0))
    timestep = env.reset()
    arm = []
    for _ in range(1000):
        timestep = env.step(controller({"state": timestep.observation["state"], "target": np.array([0.5])}))
        arm.append(timestep.observation["state"][0])
    assert not timestep.last()
    assert np.abs(np.array(arm[-250:]) - 0.5).max() < 0.05     # within 3 degrees after 3 s


@pytest.mark.parametrize("task, least", [("balance_follow", 1700), ("swingup_follow", 1300)])
def test_follow_earns_its_targets_return(task, least):
    for seed in range(2):
        controller = baselines.make("follow")
        episode_return, steps, discount, largest_arm_angle, _ = run_episode(task, controller, seed)
        assert steps == 2048 and discount == 1.0 and largest_arm_angle < math.radians(85)
        assert episode_return > least


# -- every controller --------------------------------------------------------------------


def test_every_controller_names_suite_tasks_and_clips_its_output():
    random = np.random.default_rng(0)
    for name, cls in baselines.names().items():
        assert cls.name == name and cls.tasks and set(cls.tasks) <= set(SUITE)
        controller = baselines.make(name, voltage_limit=2.0)
        controller.reset()
        for _ in range(50):
            state = random.uniform([-1.5, -math.pi, -20.0, -40.0], [1.5, math.pi, 20.0, 40.0])
            volts = controller({"state": state, "target": random.uniform(-1.4, 1.4, 1)})
            assert isinstance(volts, float) and abs(volts) <= 2.0
        controller.close()


@pytest.mark.parametrize("name", ["balance", "swingup", "dampen", "follow", "rotor"])
def test_classical_controllers_are_cheap(name):
    controller = baselines.make(name)
    observation = {"state": np.array([0.1, 2.0, 1.0, 3.0]), "target": np.array([0.2])}
    times = []
    for _ in range(300):
        start = time.perf_counter()
        controller(observation)
        times.append(time.perf_counter() - start)
    assert np.median(times) < 1e-3


def test_mpc_spreads_its_planning_over_the_control_steps():
    """Every call while swinging up does a similar, bounded share of the planning (thread CPU time)."""
    controller = baselines.make("mpc")
    env = suite.load("qube", "swingup", task_kwargs={"random": 0})
    timestep = env.reset()
    times = []
    for _ in range(250):                                    # the first second: swinging, planning
        start = time.thread_time()
        volts = controller(timestep.observation)
        times.append(time.thread_time() - start)
        timestep = env.step(volts)
    controller.close()
    assert np.median(times) < 2e-3 and np.percentile(times, 90) < 2 * np.median(times) + 1e-3


def test_mpc_plans_with_a_stable_model_of_a_heavily_damped_qube():
    """The calibrated real Qube-Servo 2's damping puts its fastest modes near -250 /s, where one RK4 step
    of the 20 ms knot (|lambda| h = 5) diverges: the planner subdivides the knot for that model."""
    real = parameters.values_of(parameters.REAL_QUBE_SERVO2)
    assert baselines.make("mpc", parameters=real).planning_steps_per_knot == 3
    assert baselines.make("mpc").planning_steps_per_knot == 1  # the nominal model keeps one


def test_mpc_survives_planning_rollouts_that_diverge():
    """On the calibrated real Qube's simulation, the nominal planner's 20 ms rollouts from a fast spin
    diverged at step 1750 of this episode, and their NaN costs made a NaN voltage; a diverged rollout
    now costs infinitely much."""
    env = suite.load("qube", "swingup_follow", task_kwargs={"random": 4},
                     domain_kwargs={"parameters": parameters.REAL_QUBE_SERVO2})
    controller = baselines.for_environment("mpc", env)
    timestep = env.reset()
    while not timestep.last():
        volts = controller(timestep.observation)
        assert math.isfinite(volts)
        timestep = env.step(volts)
    controller.close()


COS_SIN = [math.cos(1.0), math.sin(1.0), math.cos(2.0), math.sin(2.0), 3.0, 4.0]


@pytest.mark.parametrize("layout, observation, state, target", [
    (ObservationLayout(), {"state": np.array([1.0, 2.0, 3.0, 4.0])}, [1, 2, 3, 4], 0.0),
    (ObservationLayout(), {"state": np.array([1.0, 2.0, 3.0, 4.0]), "target": [0.5]}, [1, 2, 3, 4], 0.5),
    (ObservationLayout(target=True), np.array([1.0, 2.0, 3.0, 4.0, 0.5], np.float32), [1, 2, 3, 4], 0.5),
    (ObservationLayout("trig"), COS_SIN, [1, 2, 3, 4], 0.0),
    (ObservationLayout("trig", target=True), [*COS_SIN, -0.5], [1, 2, 3, 4], -0.5),
])
def test_controllers_read_every_observation_layout(layout, observation, state, target):
    parsed_state, parsed_target = layout.split(observation)
    np.testing.assert_allclose(parsed_state, state, rtol=1e-6)
    assert parsed_target == pytest.approx(target)


@pytest.mark.parametrize("layout, observation", [
    (ObservationLayout(), np.zeros(5)),                       # a target the layout does not have
    (ObservationLayout(target=True), np.zeros(4)),            # no target
    (ObservationLayout(target=True), {"state": np.zeros(4)}),
    (ObservationLayout("trig"), np.zeros(4)),
    (ObservationLayout(), {"state": np.zeros(6)}),
])
def test_an_observation_of_another_layout_is_refused_not_guessed(layout, observation):
    with pytest.raises(ValueError, match="not an observation of layout"):
        layout.split(observation)


def test_controllers_and_policies_read_the_tasks_layout():
    env = suite.load("qube", "swingup_follow", task_kwargs={"observation": "trig", "random": 0})
    assert env.task.observation_layout == ObservationLayout("trig", target=True)
    controller = baselines.for_environment("mpc", env)
    assert controller.observation_layout == env.task.observation_layout
    assert baselines.make("follow").observation_layout == ObservationLayout(target=True)
    assert baselines.make("swingup").observation_layout == ObservationLayout()
    policy = policy_for("ppo:swingup_follow", env)
    assert policy.observation_layout == env.task.observation_layout
    timestep = env.reset()
    plain = policy_for("ppo:swingup_follow", suite.load("qube", "swingup_follow"))
    state, target = env.physics.qube_state(), env.task.target
    expected = plain({"state": state, "target": [target]})
    assert policy(timestep.observation) == pytest.approx(expected, abs=1e-9)


def test_unknown_controller_lists_valid_names():
    with pytest.raises(ValueError, match="valid controllers: balance, swingup, dampen, follow, rotor, mpc"):
        baselines.make("pid")
