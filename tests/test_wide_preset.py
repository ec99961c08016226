"""The `wide` randomization preset covers the held-out plant ranges of a Qube nobody described, and the
calibrated real Qube-Servo 2."""

import numpy as np

from qube_suite.devices.qube import parameters
from qube_suite.randomization import load, sample_parameters

HELD_OUT_RELATIVE = {"pendulum_mass": 0.30, "pendulum_length": 0.10, "motor_resistance": 0.25,
                     "motor_torque_constant": 0.15, "rotor_inertia": 0.30}
"""Parameter -> half-width of its held-out range, relative to the nominal value."""
HELD_OUT_ABSOLUTE = {"arm_friction": 4e-3, "pendulum_friction": 2e-4, "cable_stiffness": 4e-3}
"""Parameter -> upper end of its held-out range, from 0 (N m, N m, N m/rad)."""


def test_wide_covers_every_held_out_range():
    wide = load("wide")
    for name, half_width in HELD_OUT_RELATIVE.items():
        nominal = parameters.NOMINAL[name]
        lower, upper = wide.parameters[name].bounds(nominal)
        assert lower <= (1 - half_width) * nominal * (1 + 1e-12), name
        assert upper >= (1 + half_width) * nominal * (1 - 1e-12), name
    for name, high in HELD_OUT_ABSOLUTE.items():
        lower, upper = wide.parameters[name].bounds(parameters.NOMINAL[name])
        assert lower == 0.0 and upper >= high, name


def test_wide_holds_the_calibrated_real_qube_and_its_effects():
    """Every parameter the recordings of a real Qube-Servo 2 calibrated, and its latency and dead zone, lie
    inside `wide`'s ranges, as they lie inside `real_qube`'s."""
    wide, real_qube = load("wide"), load("real_qube")
    calibrated = parameters.values_of(parameters.REAL_QUBE_SERVO2)
    for name, distribution in wide.parameters.items():
        lower, upper = distribution.bounds(parameters.NOMINAL[name])
        assert lower <= calibrated[name] <= upper, name
    assert set(wide.effects) == set(real_qube.effects)
    for name in ("action_delay", "voltage_offset", "dead_zone"):
        assert wide.effects[name] == real_qube.effects[name], name
    effects = parameters.effects_of(parameters.REAL_QUBE_SERVO2)
    assert effects["latency_seconds"] <= wide.effects["action_delay"]["seconds"].high
    assert effects["voltage_deadzone"] <= wide.effects["dead_zone"]["voltage"].high


def test_wide_draws_valid_plants_that_fill_the_ranges():
    wide = load("wide")
    random = np.random.RandomState(3)
    draws = [sample_parameters(wide, random) for _ in range(400)]
    for draw in draws:
        parameters.resolve(draw)
    masses = np.array([d["pendulum_mass"] for d in draws]) / parameters.NOMINAL["pendulum_mass"]
    assert masses.min() < 0.75 and masses.max() > 1.25  # the draws reach the ends, not just the middle
    friction = np.array([d["arm_friction"] for d in draws])
    assert friction.min() < 2e-4 and friction.max() > 3.8e-3
