"""Each sensor and actuator effect does what it says, in the environment and on arrays for n environments."""

import math

import numpy as np
import pytest

from qube_suite import randomization, suite
from qube_suite.randomization import (
    ActionDelay,
    Chain,
    ControlJitter,
    DeadZone,
    FilteredVelocity,
    ObservationDelay,
    ObservationNoise,
    Quantization,
    Saturation,
    Streams,
    VoltageOffset,
)

PERIOD = 0.004


def one_qube(effects):
    """A chain for one Qube, as a one-Qube domain gets it: settings as numbers, floats in and out."""
    return Chain(effects)


def run(effects, voltages, task="swingup", seed=0, frequency=250.0):
    """Observed states, exact states, motor voltages and times of an episode driven by `voltages`
    (until it ends)."""
    env = suite.load("qube", task, task_kwargs={"random": seed, "voltage_limit": 10.0},
                     environment_kwargs={"control_frequency": frequency},
                     randomization={"effects": effects} if effects is not None else None)
    timestep = env.reset()
    observed, exact = [timestep.observation["state"]], [env.physics.true_state()]
    motor, times = [], [0.0]
    for volts in voltages:
        timestep = env.step([volts])
        motor.append(float(env.physics.data.ctrl[0]))
        observed.append(timestep.observation["state"])
        exact.append(env.physics.true_state())
        times.append(env.physics.time())
        if timestep.last():
            break
    return np.array(observed), np.array(exact), np.array(motor), np.array(times)


VOLTAGES = 1.5 * np.sin(np.arange(200) * 0.07)


def test_action_delay_shifts_the_response_by_exactly_its_steps():
    _, delayed, motor, _ = run({"action_delay": {"steps": 2}}, VOLTAGES)
    _, shifted, _, _ = run(None, np.concatenate([[0.0, 0.0], VOLTAGES[:-2]]))
    np.testing.assert_array_equal(delayed, shifted)
    np.testing.assert_array_equal(motor, np.concatenate([[0.0, 0.0], VOLTAGES[:-2]]))
    _, undelayed, _, _ = run(None, VOLTAGES)
    assert np.abs(delayed - undelayed).max() > 0.01  # the delay really changes the motion


def test_delay_in_seconds_is_rounded_to_control_steps():
    _, in_seconds, _, _ = run({"action_delay": {"seconds": 0.0081}}, VOLTAGES[:50])
    _, in_steps, _, _ = run({"action_delay": {"steps": 2}}, VOLTAGES[:50])
    np.testing.assert_array_equal(in_seconds, in_steps)


def test_observation_delay_returns_the_state_of_k_steps_before():
    observed, exact, _, _ = run({"observation_delay": {"steps": 3}}, VOLTAGES)
    np.testing.assert_array_equal(observed[3:], exact[:-3])
    np.testing.assert_array_equal(observed[:3], np.repeat(exact[:1], 3, axis=0))  # the first until then


def test_quantization_makes_angles_multiples_of_the_resolution():
    counts = 512
    observed, exact, _, _ = run({"quantization": {"counts_per_revolution": counts}}, VOLTAGES)
    resolution = 2 * math.pi / counts
    multiples = observed[:, :2] / resolution
    np.testing.assert_allclose(multiples, np.round(multiples), atol=1e-9)
    error = np.angle(np.exp(1j * (observed[:, :2] - exact[:, :2])))  # the pendulum hangs at +-pi
    assert np.abs(error).max() <= resolution / 2 + 1e-12
    np.testing.assert_array_equal(observed[:, 2:], exact[:, 2:])  # velocities untouched
    assert len(np.unique(observed[:, 0])) > 10


def test_quantized_angles_stay_in_the_half_open_interval():
    x = np.array([[-math.pi, -math.pi + 1e-6, 0.0, 0.0], [math.pi - 1e-6, 1e-6, 0.0, 0.0]])
    y = Quantization(2048)(x)
    assert y[0, 0] == math.pi and y[0, 1] == math.pi and y[1, 0] == math.pi and y[1, 1] == 0.0


def test_dead_zone_suppresses_small_voltages_and_reduces_larger_ones():
    small = 0.25 * np.sign(np.sin(np.arange(100) * 0.2))
    _, exact, motor, _ = run({"dead_zone": {"voltage": 0.3}}, small)
    assert not motor.any()
    np.testing.assert_array_equal(exact, run(None, np.zeros(100))[1])  # as if no voltage was applied
    _, _, motor, _ = run({"dead_zone": {"voltage": 0.3}}, [1.0, -2.0, 0.3, -0.31])
    np.testing.assert_allclose(motor, [0.7, -1.7, 0.0, -0.01])


def test_offset_and_saturation_act_in_order_on_the_motor_voltage():
    _, _, motor, _ = run({"voltage_offset": {"voltage": 0.5}, "saturation": {"voltage": 2.0}},
                         [1.0, 3.0, -3.0, -1.0])
    np.testing.assert_allclose(motor, [1.5, 2.0, -2.0, -0.5])
    env = suite.load("qube", "swingup", randomization={"effects": {"saturation": {"voltage": 2.0}}})
    env.reset()
    env.step([2.9])
    assert env.physics.voltage() == 2.9  # the commanded voltage; the motor gets 2 V


def test_observation_noise_has_the_configured_std():
    std = np.array([0.01, 0.02, 0.3, 0.5])
    voltages = np.zeros(2000)
    observed, exact, _, _ = run({"observation_noise": {"std": std.tolist()}}, voltages, task="rotor")
    error = observed - exact
    error[:, :2] = np.angle(np.exp(1j * error[:, :2]))  # angles wrap at +-pi
    np.testing.assert_allclose(error.std(axis=0), std, rtol=0.06)
    assert np.abs(error.mean(axis=0)).max() < 4 * std.max() / math.sqrt(len(error))
    assert np.abs(observed[:, :2]).max() <= math.pi


def test_velocity_filter_lags_like_the_continuous_filter():
    """A constant speed from rest: the estimate rises as the continuous filter's 1 - exp(-50 t)."""
    speed, steps = 3.0, 100
    t = np.arange(steps + 1) * PERIOD
    angles = np.stack([speed * t, np.zeros_like(t)], axis=1)
    states = np.concatenate([angles, np.zeros_like(angles)], axis=1)  # exact velocity 0 at the start
    states[1:, 2] = speed
    velocity_filter = FilteredVelocity(50.0, PERIOD)
    estimates = [velocity_filter.reset(states[0])[2]] + [velocity_filter(x)[2] for x in states[1:]]
    analytic = speed * (1.0 - np.exp(-50.0 * t))
    np.testing.assert_allclose(estimates, analytic, rtol=1e-9, atol=1e-12)
    assert estimates[5] == pytest.approx(speed * (1 - math.exp(-1)))  # 63% after 1/a = 20 ms


def test_velocity_filter_matches_the_filter_frequency_response():
    frequency = 2 * math.pi * 2.0  # 2 Hz
    t = np.arange(2000) * PERIOD
    angle = 0.5 * np.sin(frequency * t)
    states = np.stack([angle, angle, np.zeros_like(t), np.zeros_like(t)], axis=1)
    velocity_filter = FilteredVelocity(50.0, PERIOD)
    velocity_filter.reset(states[0])
    estimates = np.array([velocity_filter(x)[2] for x in states[1:]])[1000:]
    response = 50.0 * 1j * frequency / (1j * frequency + 50.0)
    expected = 0.5 * np.abs(response) * np.sin(frequency * t[1001:] + np.angle(response))
    np.testing.assert_allclose(estimates, expected, atol=2e-3 * 0.5 * frequency)


def test_velocity_filter_in_the_environment_follows_full_turns():
    observed, exact, _, _ = run({"quantization": True, "velocity_filter": True}, np.zeros(400), task="dampen",
                                seed=3)
    assert np.ptp(exact[:, 1]) > 6.0 or np.abs(exact[:, 3]).max() > 1.0  # a real swing
    error = observed[50:, 2:] - exact[50:, 2:]
    assert np.abs(error).max() < 0.25 * np.abs(exact[:, 3]).max()
    assert np.abs(error).max() > 0.0


def test_control_jitter_changes_each_step_duration_within_bounds():
    _, _, _, times = run({"control_jitter": {"fraction": 0.2}}, np.zeros(1000), task="rotor")
    durations = np.diff(times)
    assert durations.min() >= 0.8 * PERIOD - 1e-12 and durations.max() <= 1.2 * PERIOD + 1e-12
    assert durations.min() < 0.82 * PERIOD and durations.max() > 1.18 * PERIOD
    assert durations.std() == pytest.approx(0.2 * PERIOD / math.sqrt(3), rel=0.1)  # uniform


def test_stochastic_effects_are_reproducible_from_the_task_seed():
    effects = {"observation_noise": {"std": [0.01, 0.01, 0.1, 0.1]}, "control_jitter": {"fraction": 0.1}}
    first = run(effects, VOLTAGES, seed=4)
    np.testing.assert_array_equal(first[0], run(effects, VOLTAGES, seed=4)[0])
    assert not np.array_equal(first[0], run(effects, VOLTAGES, seed=5)[0])


def test_all_effects_keep_observations_finite_and_bad_actions_change_nothing():
    everything = {"quantization": True, "velocity_filter": True, "observation_noise": {"std": [0.01] * 4},
                  "observation_delay": {"steps": 1}, "action_delay": {"steps": 2},
                  "voltage_offset": {"voltage": 0.1}, "dead_zone": {"voltage": 0.1},
                  "saturation": {"voltage": 2.0}, "control_jitter": {"fraction": 0.1}}
    env = suite.load("qube", "swingup", task_kwargs={"random": 0}, randomization={"effects": everything})
    other = suite.load("qube", "swingup", task_kwargs={"random": 0}, randomization={"effects": everything})
    env.reset()
    other.reset()
    for volts in VOLTAGES[:20]:
        env.step([volts])
        other.step([volts])
    for bad in (np.array([np.nan]), np.zeros(2), "a"):
        with pytest.raises(ValueError):
            env.step(bad)
    for volts in VOLTAGES[20:]:  # the bad actions reached no delay line and drew no noise
        a, b = env.step([volts]), other.step([volts])
        np.testing.assert_array_equal(a.observation["state"], b.observation["state"])
        assert np.isfinite(a.observation["state"]).all()
        if a.last():
            break


def test_effects_on_arrays_for_n_environments_match_one_at_a_time():
    """n Qubes at once, with per-environment settings, give the numbers of each Qube alone (a batch of one
    with its own settings, fed floats)."""
    rng = np.random.default_rng(0)
    states = rng.uniform(-4, 4, (60, 3, 4))
    volts = rng.uniform(-4, 4, (60, 3))
    durations = np.full((60, 3), PERIOD)
    delays, counts, cutoffs = np.array([0, 1, 3]), np.array([256, 1024, 2048]), np.array([20.0, 50.0, 100.0])
    stds = np.array([[0.1, 0.2, 0.3, 0.4], [0.0] * 4, [1.0, 1.0, 2.0, 2.0]])

    def chains(pick, chain, seed):
        """Sensor, actuator and timing chains; `pick` selects settings, `seed` the noise generator."""
        noise_rng, jitter_rng = np.random.RandomState(seed), np.random.RandomState(seed + 100)
        return (chain([Quantization(pick(counts)), FilteredVelocity(pick(cutoffs), PERIOD),
                       ObservationNoise(pick(stds), noise_rng), ObservationDelay(pick(delays))]),
                chain([ActionDelay(pick(delays)), VoltageOffset(pick(cutoffs) / 100),
                       DeadZone(pick(cutoffs) / 40), Saturation(pick(cutoffs) / 30)]),
                chain([ControlJitter(pick(cutoffs) / 250, jitter_rng)]))

    for i in range(3):
        # With one noise stream per environment, a batch of one row is compared with one Qube alone.
        batch = chains(lambda a, i=i: a[[i]], Chain, i)
        single = chains(lambda a, i=i: a[i], one_qube, i)
        for chain_batch, chain_single, signal in zip(batch, single, (states, volts, durations), strict=True):
            outputs_batch = [chain_batch.reset(signal[0, [i]])] + [chain_batch(x[[i]]) for x in signal[1:]]
            outputs_single = [chain_single.reset(signal[0, i].tolist())] + [chain_single(x[i].tolist())
                                                                            for x in signal[1:]]
            np.testing.assert_array_equal(np.array(outputs_batch)[:, 0], np.array(outputs_single))

    # Three at once with per-environment settings: noiseless, so the streams do not matter.
    sensor = Chain([Quantization(counts), FilteredVelocity(cutoffs, PERIOD), ObservationDelay(delays)])
    outputs = [sensor.reset(states[0])] + [sensor(x) for x in states[1:]]
    for i in range(3):
        single = one_qube([Quantization(counts[i]), FilteredVelocity(cutoffs[i], PERIOD),
                           ObservationDelay(delays[i])])
        expected = [single.reset(states[0, i].tolist())] + [single(x[i].tolist()) for x in states[1:]]
        np.testing.assert_array_equal(np.array(outputs)[:, i], np.array(expected))


def chains_for(settings, chain, rng):
    """Sensor, actuator and timing chains for settings (one value, or an array over environments);
    noise and jitter share `rng`, as in an environment."""
    return (chain([Quantization(settings["counts"]), FilteredVelocity(settings["cutoff"], PERIOD),
                   ObservationNoise(settings["std"], rng), ObservationDelay(settings["delay"])]),
            chain([ActionDelay(settings["delay"]), VoltageOffset(settings["offset"]),
                   DeadZone(settings["offset"] / 2), Saturation(settings["offset"] + 1.0)]),
            chain([ControlJitter(settings["fraction"], rng)]))


def test_n_environments_with_own_generators_and_redrawn_settings_match_one_at_a_time():
    """Noise and jitter from `Streams`, and one environment restarted with new settings (a longer delay
    line among them) by `set_rows` and `reset(x, rows)`: each environment is its one-Qube chains."""
    rng = np.random.default_rng(3)
    states, volts = rng.uniform(-4, 4, (80, 3, 4)), rng.uniform(-4, 4, (80, 3))
    episodes = [{"counts": 256, "cutoff": 20.0, "std": [0.1, 0.2, 0.3, 0.4], "delay": 0, "offset": 0.1,
                 "fraction": 0.1},
                {"counts": 1024, "cutoff": 50.0, "std": [0.0] * 4, "delay": 2, "offset": -0.2,
                 "fraction": 0.0},
                {"counts": 2048, "cutoff": 100.0, "std": [1.0, 1.0, 2.0, 2.0], "delay": 1, "offset": 0.3,
                 "fraction": 0.5},
                {"counts": 64, "cutoff": 5.0, "std": [0.5] * 4, "delay": 4, "offset": 0.5, "fraction": 0.3}]
    restart, seeds = 40, [11, 12, 13, 14]

    def stacked(dicts):
        return {key: np.array([d[key] for d in dicts]) for key in dicts[0]}

    generators = [np.random.RandomState(seed) for seed in seeds[:3]]
    batch = chains_for(stacked(episodes[:3]), Chain, Streams(generators))
    singles = [chains_for(episodes[i], one_qube, np.random.RandomState(seeds[i])) for i in range(3)]
    got, expected = [], [[], [], []]
    for step in range(80):
        x = (states[step], volts[step], np.full(3, PERIOD))
        if step == 0:
            got.append([chain.reset(signal) for chain, signal in zip(batch[:2], x, strict=False)])
        else:
            durations = batch[2](x[2])
            got.append([batch[0](x[0]), batch[1](x[1]), durations])
        if step == restart:  # after the step, environment 1 starts a new episode with the fourth settings
            rows = np.array([1])
            for chain, fresh in zip(batch, chains_for(stacked(episodes[3:]), Chain, None), strict=True):
                for effect, new in zip(chain.effects, fresh.effects, strict=True):
                    effect.set_rows(rows, new)
            generators[1].seed(seeds[3])
            for outputs, chain, signal in zip(got[-1], batch[:2], x, strict=False):  # timing has no memory
                outputs[1] = chain.reset(signal[rows], rows)[0]
            singles[1] = chains_for(episodes[3], one_qube, np.random.RandomState(seeds[3]))
        for i, (sensor, actuator, timing) in enumerate(singles):
            if step == 0 or (step == restart and i == 1):
                expected[i].append([sensor.reset(x[0][i].tolist()), actuator.reset(float(x[1][i]))])
            else:
                duration = timing(float(x[2][i]))
                expected[i].append([sensor(x[0][i].tolist()), actuator(float(x[1][i])), duration])
    for i in range(3):
        for step in range(80):
            for signal, value in enumerate(expected[i][step]):
                np.testing.assert_array_equal(got[step][signal][i], value, err_msg=f"env {i} step {step}")


def test_resetting_some_of_n_environments_keeps_the_others():
    states = np.random.default_rng(1).uniform(-3, 3, (10, 3, 4))
    delay = ObservationDelay(np.array([1, 2, 2]))
    delay.reset(states[0])
    for x in states[1:5]:
        delay(x)
    restart = np.array([1])
    assert np.array_equal(delay.reset(states[5][restart], restart), states[5][restart])
    out = delay(states[6])
    np.testing.assert_array_equal(out[1], states[5][1])  # restarted: its delay line holds its new state
    np.testing.assert_array_equal(out[0], states[4][0])  # kept: one step before
    np.testing.assert_array_equal(out[2], states[3][2])  # kept: two steps before

    noise = ObservationNoise(np.array([[0.0] * 4, [1.0] * 4, [0.0] * 4]), np.random.default_rng(0))
    noisy = noise.reset(states[0][[0, 2]], np.array([0, 2]))
    np.testing.assert_array_equal(noisy, states[0][[0, 2]])  # the noiseless environments' own std
    jitter = ControlJitter(np.array([0.0, 0.5]), np.random.default_rng(0))
    durations = jitter(np.full(2, PERIOD))
    assert durations[0] == PERIOD and durations[1] != PERIOD


def test_effects_do_not_modify_their_input():
    rng = np.random.default_rng(2)
    x = rng.uniform(-3, 3, 4)
    for effect in (Quantization(64), FilteredVelocity(50.0, PERIOD), ObservationNoise([0.1] * 4, rng),
                   ObservationDelay(2)):
        kept = x.copy()
        effect.reset(x)
        effect(x)
        effect(x)
        np.testing.assert_array_equal(x, kept)


def test_every_effect_is_in_the_catalog_with_documented_fields():
    assert list(randomization.EFFECTS) == [
        "quantization", "velocity_filter", "observation_noise", "observation_delay",
        "action_delay", "voltage_offset", "dead_zone", "saturation", "control_jitter"]
    for cls in randomization.EFFECTS.values():
        assert cls.signal in ("state", "voltage", "duration") and cls.__doc__
        assert all(field.unit and field.description for field in cls.fields.values())


def test_the_velocity_filter_effect_and_the_hardware_estimator_are_one_filter():
    """The effect, started at rest, gives the velocities the hardware's filter gives for the same angles."""
    from qube_suite.hardware import VelocityFilter

    angles = np.cumsum(np.random.default_rng(4).uniform(-0.05, 0.05, (100, 2)), axis=0)
    states = np.concatenate([angles, np.zeros_like(angles)], axis=1)
    effect, hardware = FilteredVelocity(30.0, PERIOD), VelocityFilter(PERIOD, cutoff=30.0)
    effect.reset(states[0])
    hardware(angles[0])
    for state, angle in zip(states[1:], angles[1:], strict=True):
        np.testing.assert_array_equal(effect(state)[2:], hardware(angle))


def test_one_qube_computes_on_python_floats(monkeypatch):
    """A one-Qube chain takes and gives floats and computes on them without numpy's array functions (a
    numpy call on one number costs about a microsecond, a step of the Qube ten)."""
    rng = np.random.RandomState(0)
    sensor = one_qube([Quantization(2048), FilteredVelocity(50.0, PERIOD), ObservationNoise([0.01] * 4, rng),
                       ObservationDelay(1)])
    actuator = one_qube([ActionDelay(1), VoltageOffset(0.1), DeadZone(0.2), Saturation(2.0)])
    timing = one_qube([ControlJitter(0.1, rng)])

    def no_arrays(*args, **kwargs):
        raise AssertionError("a numpy array function on one Qube's floats")

    for name in ("array", "asarray", "stack", "rint", "maximum", "copysign", "clip", "where"):
        monkeypatch.setattr(np, name, no_arrays)
    outputs = [*sensor.reset([0.1, 0.2, 0.3, 0.4]), *sensor([0.11, 0.19, 0.3, 0.4]),
               *sensor([0.12, 0.18, 0.3, 0.4]), actuator.reset(0.0), actuator(1.5), actuator(-3.0),
               timing(PERIOD)]
    assert [type(value) for value in outputs] == [float] * len(outputs)
