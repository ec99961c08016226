"""The `wide` randomization preset covers the held-out plant ranges of a Qube nobody described."""

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
        assert wide.parameters[name].bounds(parameters.NOMINAL[name]) == (0.0, high), name


def test_wide_keeps_the_sim2real_effects():
    wide, sim2real = load("wide"), load("sim2real")
    assert set(wide.effects) == set(sim2real.effects) == {"quantization", "velocity_filter", "action_delay"}
    assert wide.effects == sim2real.effects


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
