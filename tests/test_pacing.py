"""RealTimePacer: simulated time kept with the wall clock, at a chosen speed, forgiving long stalls."""

import pytest

from qube_suite.pacing import RealTimePacer


class FakeClock:
    def __init__(self):
        self.now = 0.0
        self.slept = []

    def __call__(self):
        return self.now

    def sleep(self, seconds):
        self.slept.append(seconds)
        self.now += seconds


def test_steps_are_spread_over_their_simulated_time():
    clock = FakeClock()
    pacer = RealTimePacer(clock=clock, sleep=clock.sleep)
    for step in range(1, 251):
        clock.now += 0.001  # each step computes for 1 ms of a 4 ms period
        pacer.wait(step * 0.004)
    assert clock.now == pytest.approx(1.0)


@pytest.mark.parametrize("speed", [0.25, 2.0])
def test_speed_scales_the_wall_time(speed):
    clock = FakeClock()
    pacer = RealTimePacer(clock=clock, sleep=clock.sleep)
    pacer.set_speed(speed, 0.0)
    pacer.wait(1.0)
    assert clock.now == pytest.approx(1.0 / speed)


def test_a_stall_is_forgiven_rather_than_raced_through():
    clock = FakeClock()
    pacer = RealTimePacer(clock=clock, sleep=clock.sleep)
    pacer.wait(0.004)
    clock.now += 2.0  # the window was dragged for two seconds
    pacer.wait(0.008)
    pacer.wait(0.012)
    assert clock.slept[-1] == pytest.approx(0.004)  # back to one period per step


def test_speed_must_be_positive():
    with pytest.raises(ValueError, match="speed"):
        RealTimePacer(speed=0.0)
