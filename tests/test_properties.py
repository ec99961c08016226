"""Property-based tests (hypothesis) over action sequences, board operations and configurations:
observations stay finite, rewards within [0, 1], the board never applies more than its limit and is
safe after any exception, and a config is either valid or a ValueError."""

import math

import gymnasium
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import qube_suite  # noqa: F401  (registers the Gymnasium ids)
from qube_suite import randomization, suite
from qube_suite.devices.qube.parameters import PARAMETERS
from qube_suite.hardware import QubeServo2, SafetyStopError

FEW = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])

volts = st.floats(allow_nan=True, allow_infinity=True, width=64)
actions = st.lists(volts, min_size=1, max_size=60)


@pytest.mark.slow
@FEW
@given(task=st.sampled_from(suite.TASKS_BY_DOMAIN["qube"]), observation=st.sampled_from(["state", "trig"]),
       preset=st.sampled_from([None, "moderate"]), seed=st.integers(0, 2**31 - 1), sequence=actions)
def test_any_action_sequence_keeps_observations_finite_and_rewards_in_range(task, observation, preset, seed,
                                                                          sequence):
    env = suite.load("qube", task, task_kwargs={"random": seed, "observation": observation},
                     environment_kwargs={"time_limit": 0.1}, randomization=preset)
    timestep = env.reset()
    for value in sequence:
        if not math.isfinite(value):
            steps = env.step_count
            with pytest.raises(ValueError):
                env.step(np.array([value]))
            assert env.step_count == steps
            continue
        timestep = env.step(np.array([value]))
        assert abs(env.physics.voltage()) <= env.task.voltage_limit
        if timestep.reward is not None:
            assert 0.0 <= timestep.reward <= 1.0
        for array in timestep.observation.values():
            assert np.isfinite(array).all()


@FEW
@given(seed=st.integers(0, 2**31 - 1), batch=st.lists(st.lists(volts, min_size=3, max_size=3),
                                                       min_size=1, max_size=30))
def test_vector_env_any_actions_finite_observations_and_rewards_in_range(seed, batch):
    env = gymnasium.make_vec("QubeSuite/Swingup-v0", num_envs=3, time_limit=0.05)
    env.reset(seed=seed)
    for row in batch:
        action = np.array(row)[:, None]
        if not np.isfinite(action).all():
            with pytest.raises(ValueError):
                env.step(action)
            continue
        observations, rewards, *_ = env.step(action)
        assert np.isfinite(observations).all() and ((rewards >= 0) & (rewards <= 1)).all()
    env.close()


BAD_INPUTS = [math.nan, math.inf, "2", None, [1.0, 2.0], True]

operations = st.one_of(
    st.tuples(st.just("action"), st.floats(-50, 50)),
    st.tuples(st.just("bad"), st.sampled_from(range(len(BAD_INPUTS)))),
    st.tuples(st.just("glitch"), st.integers(-4000, 4000)),
    st.tuples(st.just("amplifier_fault"), st.booleans()),
    st.tuples(st.just("block_arm"), st.booleans()),
    st.tuples(st.just("stall"), st.floats(0.0, 0.3)),
    st.tuples(st.just("resume"), st.none()),
)


@FEW
@given(max_voltage=st.floats(0.5, 10.0), program=st.lists(operations, min_size=1, max_size=80))
def test_board_never_exceeds_its_limit_and_is_safe_after_any_exception(max_voltage, program):
    with QubeServo2(max_voltage=max_voltage, plant={"stall_time": 0.05}) as qube:
        board = qube.board
        for operation, argument in program:
            try:
                if operation == "action":
                    qube.action(argument)
                elif operation == "bad":
                    qube.action(BAD_INPUTS[argument])
                elif operation == "glitch":
                    board.glitch_encoder(1, argument)
                elif operation == "amplifier_fault":
                    board.set_amplifier_fault(argument)
                elif operation == "block_arm":
                    board.block_arm(argument)
                elif operation == "stall":
                    board.stall(argument)
                else:
                    qube.resume()
            except SafetyStopError:
                assert board.applied_voltage == 0.0 and not board.amplifier_enabled and qube.is_idle
            except ValueError:
                assert board.written_voltage == 0.0
            except RuntimeError as error:
                assert "idle" in str(error) and qube.is_idle
            assert abs(board.applied_voltage) <= max_voltage
    assert board.applied_voltage == 0.0 and not board.amplifier_enabled and not qube.is_open


names = st.sampled_from([*PARAMETERS, "pendulum_mas", "gravity", "arm_friction"])
numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-5, 5), st.text(max_size=3),
                    st.none(), st.booleans())
distribution = st.fixed_dictionaries(
    {"distribution": st.sampled_from(["uniform", "normal", "loguniform", "beta"])},
    optional={"low": numbers, "high": numbers, "mean": numbers, "std": numbers, "relative": st.booleans(),
              "clip": st.lists(st.one_of(st.none(), st.floats(-2, 2)), min_size=2, max_size=2)})
effects = st.dictionaries(st.sampled_from([*randomization.EFFECTS, "noise"]),
                          st.one_of(st.booleans(), st.none(), st.dictionaries(st.sampled_from(
                              ["std", "steps", "voltage", "fraction", "cutoff", "counts_per_revolution"]),
                              st.one_of(numbers, distribution, st.lists(numbers, min_size=4, max_size=4)),
                              max_size=2)), max_size=3)
configs = st.one_of(
    st.fixed_dictionaries({}, optional={
        "parameters": st.dictionaries(names, st.one_of(numbers, distribution), max_size=3),
        "effects": effects}),
    st.dictionaries(st.text(max_size=5), numbers, max_size=2),
    st.sampled_from([*randomization.PRESETS, "strong"]), numbers)


@settings(max_examples=150, deadline=None)
@given(config=configs, seed=st.integers(0, 2**31 - 1))
def test_a_randomization_config_is_valid_or_a_value_error(config, seed):
    try:
        loaded = randomization.load(config)
    except ValueError:
        return
    drawn = randomization.sample(loaded, np.random.RandomState(seed))
    for value in drawn.parameters.values():
        assert math.isfinite(value)


@pytest.mark.slow
@FEW
@given(config=configs, seed=st.integers(0, 1000))
def test_an_environment_with_any_accepted_config_runs_with_finite_observations(config, seed):
    try:
        env = suite.load("qube", "balance", task_kwargs={"random": seed},
                         environment_kwargs={"time_limit": 0.04}, randomization=config)
    except ValueError:
        return
    timestep = env.reset()
    while not timestep.last():
        timestep = env.step(np.array([1.0]))
        assert np.isfinite(timestep.observation["state"]).all() and 0.0 <= timestep.reward <= 1.0
