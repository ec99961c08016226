"""The substitute board as a HIL board: Quanser's API semantics, encoders, tasks, watchdog, time."""

import math
import time

import numpy as np
import pytest
from hil_helpers import ENCODERS, MOTOR, Rig

from qube_suite.hardware import _hil_sim, conventions

HIL, HILError, Clock = _hil_sim.HIL, _hil_sim.HILError, _hil_sim.Clock

COUNT = conventions.RADIANS_PER_COUNT


def test_constructor_opens_only_with_a_card_type():
    assert not HIL().is_valid()
    board = HIL("qube_servo2_usb", "0")
    assert board.is_valid()
    board.close()
    assert not board.is_valid()
    with pytest.raises(HILError, match="not open"):
        board.read_encoder(ENCODERS, 2, np.zeros(2, np.int32))
    with pytest.raises(HILError, match="unknown card"):
        HIL("q8_usb", "0")


def test_encoders_read_zero_at_power_up_with_the_pendulum_hanging():
    board = HIL("qube_servo2_usb", "0")
    counts = np.ones(2, np.int32)
    board.read_encoder(ENCODERS, 2, counts)
    assert counts.tolist() == [0, 0]
    assert conventions.pendulum_angle_unwrapped(counts[1]) == math.pi == board.true_state()[1]


@pytest.mark.parametrize("seed", range(5))
def test_encoder_angles_are_whole_counts_of_2pi_over_2048(seed):
    rng = np.random.default_rng(seed)
    board = HIL("qube_servo2_usb", "0")
    counts = np.zeros(2, np.int32)
    for theta, alpha in rng.uniform(-3.0, 3.0, size=(20, 2)):
        board.set_true_state([theta, alpha, 0.0, 0.0])
        board.read_encoder(ENCODERS, 2, counts)
        arm = conventions.arm_angle(counts[0])
        pendulum = conventions.pendulum_angle_unwrapped(counts[1])
        for steps in (arm / COUNT, (pendulum - math.pi) / COUNT):
            assert steps == pytest.approx(round(steps), abs=1e-9)
        assert 0.0 <= arm - theta < COUNT                              # counts = floor(-theta / COUNT)
        assert 0.0 <= math.remainder(alpha - pendulum, 2 * math.pi) < COUNT


def test_one_revolution_has_2048_readings():
    board = HIL("qube_servo2_usb", "0")
    counts = np.zeros(2, np.int32)
    readings = set()
    for turn in np.linspace(0.0, 2 * math.pi, 20000, endpoint=False):   # counts up from 0 on both
        board.set_true_state([-turn, math.pi + turn, 0.0, 0.0])
        board.read_encoder(ENCODERS, 2, counts)
        readings.add((int(counts[0]), int(counts[1])))
    assert len({arm for arm, _ in readings}) == len({pendulum for _, pendulum in readings}) == 2048


def test_encoders_count_edges_and_can_be_reset():
    board = HIL("qube_servo2_usb", "0")
    counts = np.zeros(2, np.int32)
    board.set_true_state([0.0, math.pi + 0.4 * COUNT, 0.0, 0.0])
    board.read_encoder(ENCODERS, 2, counts)
    assert counts[1] == 0                                              # less than one count: no edge
    board.set_true_state([0.0, math.pi + 1.2 * COUNT, 0.0, 0.0])
    board.read_encoder(ENCODERS, 2, counts)
    assert counts[1] == 1
    board.set_encoder_counts(np.array([1], np.uint32), 1, np.array([100], np.int32))
    board.read_encoder(ENCODERS, 2, counts)
    assert counts.tolist() == [0, 100]
    board.set_true_state([0.0, math.pi + 2.2 * COUNT, 0.0, 0.0])
    board.read_encoder(ENCODERS, 2, counts)
    assert counts[1] == 101


def test_positive_board_voltage_counts_the_arm_up_and_turns_theta_negative():
    rig = Rig(plant={"arm_friction": 0.0})
    rig.board.write_analog(MOTOR, 1, np.array([1.0]))
    for _ in range(50):
        current, counts, _, tachometer = rig.read()
    assert counts[0] > 0 and current > 0 and tachometer > 0
    assert conventions.motor_current(current) < 0
    assert rig.board.true_state()[0] < 0 and rig.board.true_state()[2] < 0
    assert conventions.arm_velocity(tachometer) == pytest.approx(rig.board.true_state()[2])
    assert conventions.arm_angle(counts[0]) == pytest.approx(rig.board.true_state()[0], abs=COUNT)


def test_task_samples_at_its_frequency_in_simulated_time():
    rig = Rig(frequency=500.0)
    assert rig.board.time == 0.0                                       # the first sample is at the start
    for k in range(1, 11):
        rig.read()
        assert rig.board.time == pytest.approx(k / 500.0)


def test_finite_task_ends_and_channels_are_checked():
    board = HIL("qube_servo2_usb", "0")
    task = board.task_create_encoder_reader(4, ENCODERS, 2)
    board.task_start(task, Clock.HARDWARE_CLOCK_0, 100.0, 3)
    counts = np.zeros(8, np.int32)
    assert [board.task_read_encoder(task, 1, counts) for _ in range(4)] == [1, 1, 1, 0]
    with pytest.raises(HILError, match="another task"):
        board.task_start(board.task_create_encoder_reader(1, ENCODERS, 2), Clock.HARDWARE_CLOCK_0, 100.0, -1)
    board.task_stop(task)
    board.task_delete(task)
    with pytest.raises(HILError, match="not a task"):
        board.task_read_encoder(task, 1, counts)
    with pytest.raises(HILError, match="channel 2"):
        board.read_encoder(np.array([2], np.uint32), 1, counts)
    with pytest.raises(HILError, match="not finite"):
        board.write_analog(MOTOR, 1, np.array([math.nan]))
    with pytest.raises(HILError, match="buffer"):
        board.read_encoder(ENCODERS, 2, np.zeros(1, np.int32))


def test_watchdog_expiry_zeroes_the_outputs_and_locks_them():
    rig = Rig()
    board = rig.board
    board.write_analog(MOTOR, 1, np.array([2.0]))
    board.watchdog_set_analog_expiration_state(MOTOR, 1, np.zeros(1))
    board.watchdog_set_digital_expiration_state(MOTOR, 1, np.array([_hil_sim.DigitalState.LOW], np.int32))
    board.watchdog_start(0.05)
    for _ in range(10):                                                # 40 ms, reloaded: alive
        rig.read()
        assert board.watchdog_reload()
    for _ in range(12):                                                # 48 ms without reload
        rig.read()
    assert board.applied_voltage == 2.0 and not board.watchdog_is_expired()
    rig.read()                                                         # 52 ms: expired
    assert board.watchdog_is_expired() and board.applied_voltage == 0.0 and not board.amplifier_enabled
    assert not board.watchdog_reload()
    with pytest.raises(HILError, match="watchdog"):
        board.write_analog(MOTOR, 1, np.array([1.0]))
    board.watchdog_clear()
    assert board.applied_voltage == 0.0                                # clearing does not restore outputs
    board.write_analog(MOTOR, 1, np.array([1.0]))                      # writes work again


def test_realtime_task_follows_the_wall_clock_at_250_hz():
    rig = Rig(realtime=True)
    start = time.perf_counter()
    for _ in range(50):
        rig.read()
    elapsed = time.perf_counter() - start
    # Never faster than the wall clock; how much slower depends on the machine's load, so
    # the upper bounds are loose (tests/benchmarks measure the jitter, not the tests).
    assert 0.19 < elapsed < 5.0                                        # 0.2 s nominal
    assert rig.board.time <= time.perf_counter() - start + 0.01
    assert rig.board.time >= 0.19


def test_samples_missed_in_realtime_overflow_the_task_buffer():
    start = time.perf_counter()
    overwrite = Rig(realtime=True)
    time.sleep(0.05)                                                   # about 12 samples fall due
    overwrite.read()
    elapsed = time.perf_counter() - start                              # more on a busy machine
    assert 8 <= overwrite.board.task_get_buffer_overflows(overwrite.task) <= elapsed * 250 + 2
    assert 0.045 <= overwrite.board.time <= elapsed                    # the newest sample was read
    strict = Rig(realtime=True, overflow_mode=_hil_sim.BufferOverflowMode.ERROR_ON_OVERFLOW)
    time.sleep(0.02)
    with pytest.raises(HILError, match="overflow"):
        strict.read()


@pytest.mark.parametrize("mode, newest", [(_hil_sim.BufferOverflowMode.OVERWRITE_ON_OVERFLOW, True),
                                           (_hil_sim.BufferOverflowMode.DISCARD_ON_OVERFLOW, False)])
def test_full_buffer_keeps_the_newest_or_the_oldest_sample(mode, newest):
    rig = Rig(realtime=True, state=[0.0, 0.3, 0.0, 0.0], overflow_mode=mode)
    start = rig.counts[1]                                               # the sample at the start
    time.sleep(0.1)                                                     # the pendulum falls meanwhile
    counts = rig.read()[1]
    fallen = abs(counts[1] - start) * COUNT > 0.05
    assert fallen == newest


def test_realtime_plant_keeps_moving_between_calls():
    start = time.perf_counter()
    rig = Rig(realtime=True, state=[0.0, 0.3, 0.0, 0.0])
    time.sleep(0.1)
    assert rig.board.true_state()[1] > 0.35                             # fell while nobody called
    assert 0.095 <= rig.board.time <= time.perf_counter() - start


def test_led_outputs():
    board = HIL("qube_servo2_usb", "0")
    board.write_other(np.array([11000, 11001, 11002], np.uint32), 3, np.array([0.2, 1.5, 0.0]))
    assert board.led == (0.2, 1.0, 0.0)
