"""Randomization through suite.load and gymnasium.make: per-reset draws, reproducibility, logging."""

import gymnasium
import numpy as np
import pytest

import qube_suite  # noqa: F401  (registers the Gymnasium ids)
from qube_suite import baselines, randomization, suite
from qube_suite.devices.qube import parameters

MASSES = {"parameters": {
    "pendulum_mass": {"distribution": "uniform", "low": 0.8, "high": 1.2},
    "pendulum_length": {"distribution": "uniform", "low": 0.8, "high": 1.2},
}}

TEN_LINE_YAML = """\
# Domain randomization for the Qube: ten lines.
parameters:
  pendulum_mass: {distribution: uniform, low: 0.9, high: 1.1}
  arm_damping: {distribution: loguniform, low: 0.5, high: 2.0}
  arm_friction: {distribution: uniform, low: 0.0, high: 5e-4, relative: false}
effects:
  quantization: {counts_per_revolution: 2048}
  velocity_filter: true
  action_delay: {steps: {distribution: uniform, low: 0, high: 2}}
  observation_noise: {std: [0.001, 0.001, 0.02, 0.02]}
"""


def test_parameters_are_redrawn_at_every_reset_in_the_compiled_model():
    env = suite.load("qube", "balance", task_kwargs={"random": 0}, randomization=MASSES)
    model = env.physics.model.ptr
    body = env.physics.model.name2id("pendulum", "body")
    seen = set()
    for _ in range(5):
        env.reset()
        drawn = env.randomization_sample.parameters
        assert env.physics.model.ptr is model  # changed in place, never rebuilt
        assert env.physics.parameters["pendulum_mass"] == drawn["pendulum_mass"]
        assert model.body_mass[body] == drawn["pendulum_mass"]
        length = drawn["pendulum_length"]
        assert model.body_ipos[body][2] == pytest.approx(length / 2)  # centre of mass follows
        assert model.body_inertia[body][0] == pytest.approx(drawn["pendulum_mass"] * length**2 / 12)
        assert 0.8 * 0.024 <= drawn["pendulum_mass"] <= 1.2 * 0.024
        seen.add(drawn["pendulum_mass"])
    assert len(seen) == 5
    assert env.randomization == randomization.load(MASSES)


def test_same_seed_same_sequence_of_episodes_and_different_seed_different():
    def episodes(seed):
        env = suite.load("qube", "balance", task_kwargs={"random": seed}, randomization="moderate")
        record = []
        for _ in range(3):
            timestep = env.reset()
            record.append((env.randomization_sample, timestep.observation["state"].tolist()))
            for _ in range(20):
                record.append(env.step([0.3]).observation["state"].tolist())
        return record

    assert episodes(7) == episodes(7)
    assert episodes(7) != episodes(8)


def test_gymnasium_reset_info_logs_the_draws_and_seed_reproduces_them():
    env = gymnasium.make("QubeSuite/Swingup-v0", randomization="sim2real")
    _, info = env.reset(seed=3)
    assert set(info["parameters"]) == set(randomization.load("sim2real").parameters)
    assert info["effects"]["quantization"] == {"counts_per_revolution": 2048}
    assert info["effects"]["action_delay"]["steps"] in (0, 1)
    assert env.unwrapped.physics.parameters["arm_friction"] == info["parameters"]["arm_friction"]
    _, step_info = env.step(np.zeros(1, np.float32))[3:]
    assert "parameters" not in step_info  # logged once per episode
    _, again = env.reset(seed=3)
    assert again == info
    _, other = env.reset(seed=4)
    assert other["parameters"] != info["parameters"]
    _, next_episode = env.reset()
    assert next_episode["parameters"] != other["parameters"]


def test_none_preset_is_the_nominal_model_exactly():
    def trajectory(spec, task):
        env = suite.load("qube", task, task_kwargs={"random": 2}, randomization=spec)
        controller = baselines.make("balance")
        timestep = env.reset()
        states = [timestep.observation["state"]]
        while not timestep.last() and len(states) < 600:
            timestep = env.step(controller(timestep.observation) + 0.5 * np.sin(len(states) / 9))
            states.append(timestep.observation["state"])
        return np.array(states)

    for task in ("balance", "swingup_follow"):
        np.testing.assert_array_equal(trajectory("none", task), trajectory(None, task))

    nominal = gymnasium.make("QubeSuite/Dampen-v0")
    none = gymnasium.make("QubeSuite/Dampen-v0", randomization="none")
    a, info = none.reset(seed=5)
    np.testing.assert_array_equal(a, nominal.reset(seed=5)[0])
    assert info["parameters"] == {} and info["effects"] == {}
    for volts in np.linspace(-3, 3, 50):
        np.testing.assert_array_equal(none.step(np.array([volts], np.float32))[0],
                                      nominal.step(np.array([volts], np.float32))[0])
    assert dict(none.unwrapped.physics.parameters) == dict(parameters.NOMINAL)


def test_effects_alone_leave_the_model_and_unused_hooks_alone():
    env = suite.load("qube", "swingup", randomization={"effects": {"action_delay": {"steps": 1}}})
    masses = env.physics.model.body_mass.copy()
    env.reset()
    np.testing.assert_array_equal(env.physics.model.body_mass, masses)
    assert env.physics._effects.sensor is None and env.physics._step_duration_model is None
    assert env.physics._effects.actuator is not None
    plain = suite.load("qube", "swingup")
    plain.reset()
    assert plain.physics._effects.sensor is None and plain.physics._effects.actuator is None


def test_ten_line_yaml_file_end_to_end(tmp_path):
    path = tmp_path / "randomization.yaml"
    path.write_text(TEN_LINE_YAML)
    assert len(TEN_LINE_YAML.splitlines()) == 10

    env = suite.load("qube", "balance", task_kwargs={"random": 0}, randomization=str(path))
    timestep = env.reset()
    first_observation = timestep.observation["state"]
    drawn = env.randomization_sample
    assert set(drawn.parameters) == {"pendulum_mass", "arm_damping", "arm_friction"}
    assert drawn.effects["action_delay"]["steps"] in (0, 1, 2)
    controller = baselines.make("balance")
    while not timestep.last():
        timestep = env.step(controller(timestep.observation))
        assert np.isfinite(timestep.observation["state"]).all()

    gym_env = gymnasium.make("QubeSuite/Balance-v0", randomization=path)
    observation, info = gym_env.reset(seed=0)
    assert info["parameters"] == drawn.parameters  # the same seed draws the same episode
    np.testing.assert_array_equal(observation, first_observation.astype(np.float32))
    gym_env.step(gym_env.action_space.sample())
    gym_env.close()


def test_domains_must_support_what_is_randomized():
    with pytest.raises(ValueError, match="does not model motor_inductance"):
        suite.load("qube", "swingup", randomization={"parameters": {"motor_inductance": {
            "distribution": "uniform", "low": 0.9, "high": 1.1}}})

    class EffectsOnlyDomain:
        def set_sensor_model(self, model):
            pass

    config = randomization.load({"effects": {"observation_noise": {"std": [0.1] * 4}}})
    randomization.Randomizer(config, EffectsOnlyDomain(), 0.004)
    with pytest.raises(ValueError, match="cannot change physical parameters"):
        randomization.Randomizer(randomization.load("mild"), EffectsOnlyDomain(), 0.004)
    with pytest.raises(ValueError, match=r"cannot apply action_delay \(it has no set_actuator_model\)"):
        randomization.Randomizer(randomization.load({"effects": {"action_delay": True}}), EffectsOnlyDomain(),
                                 0.004)


def test_jitter_at_a_control_frequency_with_several_substeps():
    env = suite.load("qube", "rotor", environment_kwargs={"control_frequency": 100},
                     randomization={"effects": {"control_jitter": {"fraction": 0.3}}})
    env.reset()
    times = [0.0]
    for _ in range(200):
        env.step([0.0])
        times.append(env.physics.time())
    durations = np.diff(times)
    assert 0.007 - 1e-12 <= durations.min() < 0.0075 and 0.0125 < durations.max() <= 0.013 + 1e-12
    assert env.physics.timestep() == pytest.approx(0.01 / 3)  # the nominal timestep is kept


def test_effects_start_afresh_every_episode():
    env = suite.load("qube", "swingup", task_kwargs={"random": 0}, randomization={"effects": {
        "action_delay": {"steps": 2}, "observation_delay": {"steps": 1}}})
    for _ in range(3):
        timestep = env.reset()
        start = env.physics.true_state()
        np.testing.assert_array_equal(timestep.observation["state"], start)
        motor = []
        for volts in (1.0, 2.0, 3.0):
            timestep = env.step([volts])
            motor.append(float(env.physics.data.ctrl[0]))
        assert motor == [0.0, 0.0, 1.0]  # the delay line holds 0 V again, not the last episode's commands


def test_noise_after_a_reset_depends_on_the_seed_only():
    """An episode's noise stream starts at its first measurement, whether or not the effects were rebuilt."""
    noise = {"effects": {"observation_noise": {"std": [0.01, 0.01, 0.1, 0.1]},
                         "control_jitter": {"fraction": 0.2}}}
    fresh = gymnasium.make("QubeSuite/Rotor-v0", randomization=noise)
    used = gymnasium.make("QubeSuite/Rotor-v0", randomization=noise)
    used.reset(seed=5)
    used.step(np.zeros(1, np.float32))
    np.testing.assert_array_equal(used.reset(seed=3)[0], fresh.reset(seed=3)[0])  # kept effects, built ones
    volts = np.ones(1, np.float32)
    for _ in range(20):
        np.testing.assert_array_equal(used.step(volts)[0], fresh.step(volts)[0])
