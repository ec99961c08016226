"""dm_control's own suite tests (dm_control/suite/suite_test.py), re-created against `qube_suite.suite`
on both domains, and dm_control's wrappers on qube_suite environments.

Every check of suite_test.py applies except two: `test_visualize_reward` (dm_control's materials that
blend with the reward; the Qube shows its reward on its LED instead, tested in test_conformance.py),
and `_validate_control_range`'s [-1, 1] bounds, replaced by the voltage bounds (actions are volts:
docs/conventions.md).
"""

import numpy as np
import pytest
from conftest import requires_offscreen_gl
from dm_control.mujoco.wrapper.mjbindings import constants
from dm_control.rl import control
from dm_control.suite.wrappers import action_scale, pixels

from qube_suite import suite
from qube_suite.tasks.base import DEFAULT_VOLTAGE_LIMIT


def all_tasks(marks=None):
    """Every (domain, task) of the suite as pytest params, with `marks(domain, task)` applied."""
    marks = marks or (lambda domain, task: ())
    return [pytest.param(domain, task, marks=marks(domain, task), id=f"{domain}-{task}")
            for domain, task in suite.ALL_TASKS]


def uniform_random_policy(action_spec, random=None):
    lower = np.where(np.abs(action_spec.minimum) >= constants.mjMAXVAL, -1.0, action_spec.minimum)
    upper = np.where(np.abs(action_spec.maximum) >= constants.mjMAXVAL, 1.0, action_spec.maximum)
    random_state = np.random.RandomState(random)
    return lambda time_step: random_state.uniform(lower, upper)


def step_environment(env, policy, num_episodes=5, max_steps_per_episode=10):
    for _ in range(num_episodes):
        step_count = 0
        time_step = env.reset()
        yield time_step
        while not time_step.last():
            time_step = env.step(policy(time_step))
            step_count += 1
            yield time_step
            if step_count >= max_steps_per_episode:
                break


def make_trajectory(domain, task, seed, **trajectory_kwargs):
    env = suite.load(domain, task, task_kwargs={"random": seed})
    policy = uniform_random_policy(env.action_spec(), random=seed)
    return step_environment(env, policy, **trajectory_kwargs)


def test_constants():
    assert len(suite.ALL_TASKS) == sum(len(tasks) for tasks in suite.TASKS_BY_DOMAIN.values())
    assert set(suite.BENCHMARKING) | set(suite.SPARSE) == set(suite.ALL_TASKS)


@pytest.mark.parametrize("domain, task", all_tasks())
def test_components_have_names(domain, task):
    model = suite.load(domain, task).physics.model
    kinds = [("body", "nbody"), ("joint", "njnt"), ("geom", "ngeom"), ("site", "nsite"), ("camera", "ncam"),
             ("light", "nlight"), ("mesh", "nmesh"), ("hfield", "nhfield"), ("texture", "ntex"),
             ("material", "nmat"), ("equality", "neq"), ("tendon", "ntendon"), ("actuator", "nu"),
             ("sensor", "nsensor"), ("numeric", "nnumeric"), ("text", "ntext"), ("tuple", "ntuple")]
    for object_type, size_field in kinds:
        for index in range(getattr(model, size_field)):
            assert model.id2name(index, object_type) != "", f"unnamed {object_type} {index}"


@pytest.mark.parametrize("domain, task", all_tasks())
def test_model_has_at_least_2_cameras(domain, task):
    assert suite.load(domain, task).physics.model.ncam >= 2


def validate_observation(observation, observation_spec):
    observation = dict(observation)
    for name, spec in observation_spec.items():
        array = observation.pop(name)
        assert array.shape == spec.shape and array.dtype == spec.dtype
        assert np.all(np.isfinite(array)), f"{name!r} has non-finite values: {array!r}"
    assert not observation, f"observation arrays not in the spec: {observation!r}"


@pytest.mark.parametrize("domain, task", all_tasks())
def test_task_conforms_to_spec(domain, task):
    env = suite.load(domain, task)
    observation_spec, action_spec = env.observation_spec(), env.action_spec()
    # suite_test.py checks [-1, 1] here; the action is the voltage of each motor (docs/conventions.md),
    # within the task's default limit: 3 V on the Qube's modules.
    limit = np.full(env.task.action_shape, env.task.voltage_limit)
    np.testing.assert_array_equal(action_spec.minimum, -limit)
    np.testing.assert_array_equal(action_spec.maximum, limit)
    if domain.startswith("qube"):
        assert env.task.voltage_limit == DEFAULT_VOLTAGE_LIMIT
    for time_step in step_environment(env, uniform_random_policy(action_spec)):
        validate_observation(time_step.observation, observation_spec)
        if time_step.first():
            assert time_step.reward is None and time_step.discount is None
        else:
            assert isinstance(time_step.discount, float) and 0.0 <= time_step.discount <= 1.0
            assert isinstance(time_step.reward, float)
            if (domain, task) in suite.BENCHMARKING:
                assert 0.0 <= time_step.reward <= 1.0
    env.close()


@pytest.mark.slow
@pytest.mark.parametrize("domain, task", all_tasks())
def test_environment_is_deterministic(domain, task):
    for first, second in zip(make_trajectory(domain, task, seed=0), make_trajectory(domain, task, seed=0),
                             strict=True):
        assert first.step_type == second.step_type
        assert first.reward == second.reward and first.discount == second.discount
        for key in first.observation:
            np.testing.assert_array_equal(first.observation[key], second.observation[key])


@pytest.mark.parametrize("domain, task", all_tasks())
def test_task_supports_environment_kwargs(domain, task):
    env = suite.load(domain, task, environment_kwargs={"flat_observation": True})
    assert set(env.observation_spec()) == {control.FLAT_OBSERVATION_KEY}
    assert set(env.reset().observation) == {control.FLAT_OBSERVATION_KEY}
    env.close()


@pytest.mark.parametrize("domain, task", all_tasks())
def test_observation_arrays_dont_share_memory(domain, task):
    env = suite.load(domain, task)
    first = env.reset()
    second = env.step(np.zeros(env.action_spec().shape))
    for name, array in first.observation.items():
        assert not np.may_share_memory(array, second.observation[name])
    env.close()


CONSTANT_BY_DESIGN = {("aero2", "hover"): ("target", 0), ("aero2", "hover_sparse"): ("target", 0),
                      ("aero2_hardware", "hover"): ("target", 0),
                      ("aero2_hardware", "hover_sparse"): ("target", 0)}
"""The one constant observation element by design: the Aero's hover keeps the track task's layout
(pitch and yaw targets), its pitch target always 0 (level), so one policy's inputs serve both."""


@pytest.mark.slow
@pytest.mark.parametrize("domain, task", all_tasks())
def test_observations_dont_contain_constant_elements(domain, task):
    env = suite.load(domain, task)
    observations = {name: [] for name in env.observation_spec()}
    for time_step in make_trajectory(domain, task, seed=0, num_episodes=2, max_steps_per_episode=1000):
        for name, array in time_step.observation.items():
            observations[name].append(array)
    designed = CONSTANT_BY_DESIGN.get((domain, task))
    for name, arrays in observations.items():
        stacked = np.array(arrays)
        constant = np.all(stacked == stacked[0], axis=0)
        if designed is not None and designed[0] == name:
            assert np.all(stacked[:, designed[1]] == 0.0)  # the level pitch target, as documented
            constant[designed[1]] = False
        assert not np.any(constant), f"{name!r} has constant elements"


@pytest.mark.parametrize("domain, task", all_tasks())
def test_initial_state_is_randomized(domain, task):
    env = suite.load(domain, task, task_kwargs={"random": 42})
    first, second = env.reset().observation, env.reset().observation
    assert not all(np.all(first[key] == second[key]) for key in first), (first, second)
    env.close()


# -- dm_control's wrappers ------------------------------------------------------------------------


@pytest.mark.parametrize("domain", ["qube", "qube_hardware"])
def test_action_scale_wrapper_maps_minus_one_to_one_onto_the_voltage(domain):
    env = action_scale.Wrapper(suite.load(domain, "balance", task_kwargs={"random": 0}),
                               minimum=np.array([-1.0]), maximum=np.array([1.0]))
    reference = suite.load(domain, "balance", task_kwargs={"random": 0})
    env.reset()
    reference.reset()
    for scaled in (-1.0, 0.5, 1.0):
        timestep = env.step(np.array([scaled]))
        expected = reference.step(np.array([scaled * DEFAULT_VOLTAGE_LIMIT]))
        np.testing.assert_array_equal(timestep.observation["state"], expected.observation["state"])
        assert env.physics.voltage() == scaled * DEFAULT_VOLTAGE_LIMIT
    env.close()
    reference.close()


@pytest.mark.slow
@requires_offscreen_gl
def test_pixels_wrapper_adds_frames_of_the_qube():
    env = pixels.Wrapper(suite.load("qube", "swingup", task_kwargs={"random": 0}), pixels_only=False,
                         render_kwargs={"height": 48, "width": 64, "camera_id": "front"})
    assert env.observation_spec()["pixels"].shape == (48, 64, 3)
    first = env.reset().observation
    assert set(first) == {"state", "pixels"} and first["pixels"].std() > 5
    for _ in range(15):
        timestep = env.step(np.array([3.0]))
    assert not np.array_equal(timestep.observation["pixels"], first["pixels"])  # the Qube moved
    env.close()
