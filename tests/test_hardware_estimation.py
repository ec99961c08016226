"""Velocity estimation: Quanser's 50 s/(s + 50) filter, discretised ramp-invariantly, and its lag."""

import math

import numpy as np
import pytest

from qube_suite.angles import wrap_angle
from qube_suite.hardware import StateEstimator, VelocityFilter, conventions

FREQUENCY = 250.0
PERIOD = 1 / FREQUENCY
WC = 50.0


def test_ramp_response_is_the_continuous_filters_at_every_sample():
    """For a ramp (piecewise linear) the ramp-invariant filter is exact: v (1 - exp(-wc t))."""
    speed, f = 3.0, VelocityFilter(PERIOD, channels=1)
    times = np.arange(200) / FREQUENCY
    estimates = [f([speed * t])[0] for t in times]
    np.testing.assert_allclose(estimates, speed * (1 - np.exp(-WC * times)), rtol=1e-12, atol=1e-12)
    assert estimates[-1] == pytest.approx(speed, rel=1e-12)             # no steady-state error


def test_ramp_lags_by_one_over_the_cutoff():
    """The estimate of a ramp trails by the area (v - estimate) dt / v = 1 / wc = 20 ms."""
    speed, f = 2.0, VelocityFilter(PERIOD, channels=1)
    times = np.arange(500) / FREQUENCY
    deficit = speed - np.array([f([speed * t])[0] for t in times])
    lag = np.trapezoid(deficit, times) / speed                          # the trapezoid rule adds 0.3 %
    assert f.lag == 0.02 and lag == pytest.approx(f.lag, rel=5e-3)


@pytest.mark.parametrize("hertz", [0.5, 1.7, 5.0, 20.0])
def test_sine_response_matches_the_analytic_one(hertz):
    """Steady state on a sine: gain 1 / sqrt(1 + (w/wc)^2), phase lag atan(w/wc) of the true velocity."""
    omega, f = 2 * math.pi * hertz, VelocityFilter(PERIOD, channels=1)
    times = np.arange(int(FREQUENCY * (4 + 4 / hertz))) / FREQUENCY
    estimates = np.array([f([math.sin(omega * t)])[0] for t in times])
    keep = times > 3.0                                                  # transient (20 ms) long gone
    basis = np.column_stack([np.cos(omega * times[keep]), np.sin(omega * times[keep])])
    a, b = np.linalg.lstsq(basis, estimates[keep], rcond=None)[0]       # estimate = a cos + b sin
    measured = complex(a, -b) / omega                                   # relative to d/dt sin = w cos
    analytic = 1 / (1 + 1j * omega / WC)
    assert abs(measured - f.frequency_response(omega)) < 1e-9
    assert abs(measured) == pytest.approx(abs(analytic), rel=1e-4)
    extra_delay = (-np.angle(measured) - math.atan(omega / WC)) / omega  # discretisation: T^2 wc / 12
    assert 0.0 <= extra_delay < 1e-4


def test_slow_sine_is_delayed_by_the_lag():
    omega = 2 * math.pi * 0.5
    delay = -np.angle(VelocityFilter(PERIOD).frequency_response(omega)) / omega
    assert delay == pytest.approx(1 / WC, rel=5e-3)


def test_state_estimator_maps_counts_and_filters_unwrapped_angles():
    estimator = StateEstimator(FREQUENCY)
    state = estimator([0, 0])
    np.testing.assert_array_equal(state, [0.0, math.pi, 0.0, 0.0])       # pendulum zeroed hanging
    rate = 8.0                                                          # counts per sample, crossing +-pi
    for k in range(1, 300):
        state = estimator([-5 * k, 1024 + rate * k])
    assert state[0] == pytest.approx(wrap_angle(conventions.arm_angle(-5 * 299)))
    assert -math.pi < state[1] <= math.pi
    speed = rate * conventions.RADIANS_PER_COUNT * FREQUENCY
    assert state[3] == pytest.approx(speed, rel=1e-9)                   # no spike from the wrap
    assert state[2] == pytest.approx(conventions.arm_angle(-5) * FREQUENCY, rel=1e-9)


def test_filter_checks_its_arguments():
    with pytest.raises(ValueError):
        VelocityFilter(0.0)
    with pytest.raises(ValueError):
        VelocityFilter(PERIOD)([1.0, 2.0, 3.0])


def test_state_estimator_gives_the_velocity_filters_numbers_bit_for_bit():
    counts = np.cumsum(np.random.default_rng(3).integers(-40, 41, size=(400, 2)), axis=0).astype(np.int32)
    estimator, reference = StateEstimator(FREQUENCY), VelocityFilter(1.0 / FREQUENCY)
    for k, sample in enumerate(counts):
        if k == 250:                                                    # a reset starts both afresh
            estimator.reset()
            reference.reset()
        angles = (conventions.arm_angle(int(sample[0])), conventions.pendulum_angle_unwrapped(int(sample[1])))
        expected = [wrap_angle(angles[0]), wrap_angle(angles[1]), *reference(angles)]
        assert estimator(sample).tolist() == expected
