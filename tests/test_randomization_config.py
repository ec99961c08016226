"""Randomization configs: loading, validation errors, presets, and what sampling draws."""

import math

import numpy as np
import pytest

from qube_suite import randomization
from qube_suite.devices.qube import parameters
from qube_suite.randomization import Distribution, load, sample, sample_parameters


def uniform(low, high, **options):
    return {"distribution": "uniform", "low": low, "high": high, **options}


def test_presets_load_and_none_randomizes_nothing():
    for name in randomization.PRESETS:
        assert isinstance(load(name), randomization.Randomization)
    none = load("none")
    assert none.parameters == {} and none.effects == {}
    random = np.random.RandomState(0)
    assert sample(none, random) == randomization.Sample({}, {}, None)
    assert random.uniform() == np.random.RandomState(0).uniform()  # nothing was drawn


def test_a_loaded_config_is_returned_as_is_and_order_does_not_matter():
    config = load({"parameters": {"gravity": uniform(0.9, 1.1), "arm_mass": uniform(0.9, 1.1)}})
    assert load(config) is config
    assert list(config.parameters) == ["arm_mass", "gravity"]  # the parameter table's order
    swapped = load({"parameters": {"arm_mass": uniform(0.9, 1.1), "gravity": uniform(0.9, 1.1)}})
    assert swapped == config


def test_yaml_file_reads_exponents_as_numbers(tmp_path):
    path = tmp_path / "config.yaml"
    path.write_text("parameters:\n"
                    "  arm_damping: {distribution: loguniform, low: 5e-1, high: 2}\n"
                    "  arm_friction: 1e-3\n"
                    "effects:\n"
                    "  quantization: true\n"
                    "  dead_zone: {voltage: 0.1}\n")
    config = load(path)
    assert config == load(str(path))
    assert config.parameters["arm_damping"] == Distribution("loguniform", low=0.5, high=2.0, relative=True)
    assert config.parameters["arm_friction"] == Distribution("uniform", low=1e-3, high=1e-3)
    assert config.effects == {"quantization": {"counts_per_revolution": 2048}, "dead_zone": {"voltage": 0.1}}


def test_effect_defaults():
    config = load({"effects": {"quantization": True, "velocity_filter": True, "action_delay": True,
                               "observation_delay": {"seconds": 0.008}, "saturation": False}})
    assert config.effects == {"quantization": {"counts_per_revolution": 2048},
                              "velocity_filter": {"cutoff": 50.0},
                              "observation_delay": {"seconds": 0.008},
                              "action_delay": {"steps": 1}}


@pytest.mark.parametrize("spec, message", [
    # misspelt names list the valid ones
    ({"parameters": {"pendulum_mas": uniform(0.9, 1.1)}},
     r"unknown parameter 'pendulum_mas'; valid parameters: motor_resistance, .*pendulum_mass, "),
    ({"effects": {"quantisation": True}},
     r"unknown effect 'quantisation'; valid effects: quantization, velocity_filter, observation_noise, "
     r"observation_delay, action_delay, voltage_offset, dead_zone, saturation, control_jitter"),
    ({"effects": {"quantization": {"counts": 1024}}},
     r"effects.quantization: unknown setting 'counts'; valid settings: counts_per_revolution"),
    ({"parameter": {}}, r"unknown randomization key 'parameter'; valid keys: parameters, effects"),
    ({"parameters": {"arm_mass": {"distribution": "gaussian", "mean": 1, "std": 0.1}}},
     r"parameters.arm_mass: 'distribution' must be one of uniform, normal, loguniform"),
    ({"parameters": {"arm_mass": uniform(0.9, 1.1, scale=2)}},
     r"unknown key 'scale' for a uniform distribution; valid keys: distribution, low, high, clip, relative"),
    ({"parameters": {"arm_mass": {"distribution": "normal", "mean": 1.0}}}, r"needs 'mean' and 'std'"),
    ("milder", r"unknown randomization preset 'milder'; valid presets: none, mild, moderate, sim2real, wide"),
    (42, r"randomization must be a preset name"),
    # impossible ranges
    ({"parameters": {"arm_mass": uniform(1.1, 0.9)}}, r"arm_mass: low \(1.1\) must not exceed high \(0.9\)"),
    ({"parameters": {"arm_mass": {"distribution": "normal", "mean": 1, "std": -0.1, "clip": [0.5, 2]}}},
     r"std must be >= 0"),
    ({"parameters": {"arm_damping": {"distribution": "loguniform", "low": 0.0, "high": 2.0}}},
     r"loguniform distribution needs 0 < low"),
    ({"parameters": {"pendulum_mass": uniform(0.0, 1.1)}},
     r"pendulum_mass: draws could reach 0 kg, but pendulum_mass must be > 0; narrow the range"),
    ({"parameters": {"pendulum_length": uniform(-0.1, 0.2, relative=False)}}, r"must be > 0"),
    ({"parameters": {"arm_length": {"distribution": "normal", "mean": 1.0, "std": 0.1}}},
     r"arm_length: draws could reach -inf m, but arm_length must be > 0; add clip bounds"),
    ({"parameters": {"arm_length": {"distribution": "normal", "mean": 1.0, "std": 0.1, "clip": [0, None]}}},
     r"must be > 0"),
    ({"parameters": {"arm_damping": uniform(-1.0, 1.0)}}, r"arm_damping must be >= 0"),
    ({"parameters": {"arm_friction": uniform(0.0, 2.0)}},
     r"arm_friction: the nominal value is 0, so relative draws would all be 0; give absolute values"),
    ({"parameters": {"arm_mass": uniform(0.9, 1.1, clip=[1.2, 1.0])}},
     r"lower bound 1.2 exceeds upper bound 1"),
    ({"parameters": {"arm_mass": uniform(0.9, 1.1, clip=[1.2, None])}}, r"excludes the whole range"),
    ({"parameters": {"arm_mass": uniform(0.9, 1.1, clip=0.5)}}, r"clip must be \[lower, upper\]"),
    ({"parameters": {"arm_mass": uniform(0.9, 1.1, relative="yes")}}, r"relative must be true or false"),
    ({"parameters": {"arm_mass": uniform(0.9, float("nan"))}}, r"arm_mass.high must be a finite number"),
    ({"parameters": {"gravity": "9.81"}},
     r"parameters.gravity must be a number \(m/s\^2\) or a distribution"),
    ({"effects": {"dead_zone": {"voltage": -0.1}}}, r"effects.dead_zone.voltage must be >= 0 V, got -0.1"),
    ({"effects": {"dead_zone": {"voltage": uniform(-0.1, 0.1)}}},
     r"dead_zone.voltage must be >= 0 V, got values in \[-0.1, 0.1\]"),
    ({"effects": {"dead_zone": True}}, r"effects.dead_zone needs 'voltage': the half-width of the dead band"),
    ({"effects": {"saturation": {"voltage": 0.0}}}, r"saturation.voltage must be > 0 V"),
    ({"effects": {"control_jitter": {"fraction": 0.8}}}, r"control_jitter.fraction must be in \[0, 0.5\]"),
    ({"effects": {"quantization": {"counts_per_revolution": 0}}}, r"counts_per_revolution must be in \[1, "),
    ({"effects": {"quantization": {"counts_per_revolution": 100.5}}}, r"must be an integer"),
    ({"effects": {"action_delay": {"steps": -1}}}, r"action_delay.steps must be in \[0, 2000\]"),
    ({"effects": {"action_delay": {"steps": uniform(0.5, 2)}}},
     r"takes an integer or \{distribution: uniform"),
    ({"effects": {"action_delay": {"steps": 1, "seconds": 0.004}}}, r"give 'steps' or 'seconds', not both"),
    ({"effects": {"action_delay": {"steps": uniform(0, 2, relative=True)}}}, r"unknown key 'relative'"),
    ({"effects": {"observation_noise": {"std": [0.1, 0.1]}}}, r"std must be a list of 4 numbers"),
    ({"effects": {"observation_noise": {"std": [0.1, 0.1, -1.0, 0.0]}}}, r"std must be >= 0"),
    ({"effects": {"observation_delay": "yes"}}, r"observation_delay must be true, false or a mapping"),
])
def test_bad_configs_are_clear_errors(spec, message):
    with pytest.raises(ValueError, match=message):
        load(spec)


def test_missing_yaml_file_is_an_error(tmp_path):
    with pytest.raises(FileNotFoundError):
        load(tmp_path / "missing.yaml")


def test_draws_respect_their_ranges():
    config = load({"parameters": {
        "pendulum_mass": uniform(0.8, 1.2),
        "arm_damping": {"distribution": "loguniform", "low": 0.1, "high": 10.0},
        "motor_resistance": {"distribution": "normal", "mean": 1.0, "std": 0.2, "clip": [0.9, 1.3]},
        "cable_stiffness": uniform(0.0, 2e-3, relative=False),
    }, "effects": {
        "action_delay": {"steps": uniform(1, 3)},
        "voltage_offset": {"voltage": {"distribution": "normal", "mean": 0.0, "std": 0.1,
                                       "clip": [-0.15, 0.15]}},
    }})
    random = np.random.RandomState(0)
    draws = [sample(config, random) for _ in range(3000)]
    values = {name: np.array([d.parameters[name] for d in draws]) for name in config.parameters}
    nominal = parameters.NOMINAL

    mass = values["pendulum_mass"] / nominal["pendulum_mass"]
    assert mass.min() >= 0.8 and mass.max() <= 1.2 and mass.min() < 0.81 and mass.max() > 1.19
    log_damping = np.log10(values["arm_damping"] / nominal["arm_damping"])
    assert log_damping.min() >= -1 and log_damping.max() <= 1 and abs(log_damping.mean()) < 0.05
    resistance = values["motor_resistance"] / nominal["motor_resistance"]
    assert resistance.min() == 0.9 and resistance.max() == 1.3  # clipped, and the clip is reached
    assert values["cable_stiffness"].min() >= 0.0 and values["cable_stiffness"].max() <= 2e-3
    steps = [d.effects["action_delay"]["steps"] for d in draws]
    assert set(steps) == {1, 2, 3} and all(isinstance(s, int) for s in steps)
    offsets = np.array([d.effects["voltage_offset"]["voltage"] for d in draws])
    assert offsets.min() == -0.15 and offsets.max() == 0.15
    for draw in draws[:50]:
        parameters.resolve(draw.parameters)  # every draw is a valid parameter set


def test_same_seed_same_sequence_different_seed_different():
    config = load("moderate")

    def sequence(seed):
        random = np.random.RandomState(seed)
        return [sample(config, random) for _ in range(5)]

    assert sequence(1) == sequence(1)
    assert sequence(1) != sequence(2)
    first = sequence(1)
    assert first[0] != first[1]  # redrawn every episode
    assert all(draw.seed is not None for draw in first)  # noise and jitter need a generator


def test_sample_parameters_is_a_pure_function_of_config_and_random_state():
    config = load("sim2real")
    assert sample_parameters(config, np.random.RandomState(5)) == sample_parameters(
        config, np.random.RandomState(5))
    assert set(sample_parameters(config, np.random.RandomState(5))) == set(config.parameters)


def test_presets_draw_valid_parameters_and_cover_the_accuracy_options():
    for name in randomization.PRESETS:
        config = load(name)
        random = np.random.RandomState(0)
        for _ in range(200):
            parameters.resolve(sample_parameters(config, random))
    sim2real = load("sim2real")
    for name in ("arm_friction", "pendulum_friction", "cable_stiffness"):
        lower, upper = sim2real.parameters[name].bounds(parameters.NOMINAL[name])
        assert lower == 0.0 and upper > 0.0
    assert {"quantization", "velocity_filter", "action_delay"} <= set(sim2real.effects)


def test_distribution_text():
    assert str(load("mild").parameters["arm_mass"]) == "x U(0.95, 1.05)"
    assert str(Distribution("normal", mean=0.0, std=0.1, clip=(-0.2, None))) == "N(0, 0.1) in [-0.2, ]"
    assert str(Distribution("uniform", low=0, high=2, integer=True)) == "U{0..2}"
    assert str(Distribution("loguniform", low=0.5, high=2.0, relative=True)) == "x logU(0.5, 2)"
    assert math.isinf(Distribution("normal", mean=0.0, std=1.0).bounds()[1])
