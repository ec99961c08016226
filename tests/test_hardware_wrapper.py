"""QubeServo2 / QuanserWrapper: safe opening and closing, safety stops, and the real-board code path."""

import math
import sys
import time

import pytest
from hil_helpers import fake_quanser_sdk

from qube_suite.hardware import (
    AmplifierFaultError,
    ArmLimitError,
    MissedSamplesError,
    MotorStallError,
    QuanserSDKNotFoundError,
    QubeServo2,
    QubeServo3,
    WatchdogExpiredError,
    conventions,
)


def assert_motor_off(board):
    assert board.applied_voltage == 0.0 and not board.amplifier_enabled


@pytest.fixture
def fake_sdk(monkeypatch):
    """Quanser's `quanser.hardware` replaced by the substitute board, recording what is made and opened."""
    return fake_quanser_sdk(monkeypatch)


def test_constructing_opens_nothing(fake_sdk):
    qube = QubeServo2(board="qube_servo2_usb")
    assert qube.board is None and not qube.is_open and fake_sdk["created"] == []
    with pytest.raises(RuntimeError, match="not open"):
        qube.action(0.0)


def test_entering_enables_and_starts_sampling_with_the_boards_counts():
    with QubeServo2() as qube:
        board = qube.board
        assert board.is_valid() and board.amplifier_enabled and board.applied_voltage == 0.0
        start = board.time                                            # no rest check: no time passed
        assert start == 0.0 and not qube.encoders_zeroed
        currents, encoders, others = qube.action(1.0)
        assert encoders.tolist() == [0, 0] and board.time == pytest.approx(start, abs=1e-9)  # sample 0
        assert board.written_voltage == 1.0
        qube.action(1.0)
        assert board.time == pytest.approx(start + 0.004, abs=1e-9)
        for _ in range(25):
            _, encoders, _ = qube.action(1.0)
        assert encoders[0] > 0                                        # positive volts count the arm up


def test_leaving_after_an_exception_turns_the_motor_off():
    with pytest.raises(RuntimeError, match="controller crashed"), QubeServo2() as qube:
        qube.action(2.0)
        qube.action(2.0)
        raise RuntimeError("controller crashed")
    assert_motor_off(qube.board)
    assert not qube.board.is_valid() and qube.board.led == (1.0, 0.0, 0.0)


def test_leaving_after_keyboard_interrupt_turns_the_motor_off():
    with pytest.raises(KeyboardInterrupt), QubeServo2() as qube:
        qube.action(3.0)
        raise KeyboardInterrupt
    assert_motor_off(qube.board)
    assert not qube.board.is_valid()


def test_interrupt_during_cleanup_does_not_skip_the_other_steps(fake_sdk):
    class InterruptedLED(fake_sdk["class"]):
        def write_other(self, *args):
            raise KeyboardInterrupt                                   # a second Ctrl-C while closing

    sys.modules["quanser.hardware"].HIL = InterruptedLED
    with pytest.raises(KeyboardInterrupt), QubeServo2(board="qube_servo2_usb") as qube:
        qube.action(2.0)
    assert_motor_off(qube.board)
    assert not qube.board.is_valid()


def test_voltages_are_clipped_to_max_voltage():
    with QubeServo2(max_voltage=4.0) as qube:
        qube.action(20.0)
        assert qube.board.written_voltage == 4.0
        qube.action([-7.5])
        assert qube.board.written_voltage == -4.0


@pytest.mark.parametrize("led", [None, [0.0, 1.0, 0.0]])  # the compiled clear sample; the checks one by one
def test_readings_are_new_arrays_unless_the_buffers_are_asked_for(led):
    with QubeServo2() as qube:
        kept = qube.action([5.0], led)
        counts = kept[1].tolist()
        for _ in range(25):  # 0.1 s at 5 V: the arm turns
            later = qube.action([5.0], led)
            assert all(a is not b for a, b in zip(kept, later, strict=True))
        assert kept[1].tolist() == counts != later[1].tolist()  # what was returned stays as it was read
        buffers = qube.action([5.0], led, copy=False)
        first = buffers[1].tolist()
        for _ in range(25):
            again = qube.action([5.0], led, copy=False)
            assert all(a is b for a, b in zip(buffers, again, strict=True))
        assert again[1].tolist() != first  # the same arrays now hold the later sample


@pytest.mark.parametrize("bad", [math.nan, math.inf, [1.0, 2.0], "one volt", [[1.0]], None,
                                 [math.nan], [-math.inf], [True], (math.nan,)])
def test_invalid_voltages_write_zero_then_raise(bad):
    with QubeServo2() as qube:
        qube.action(2.0)
        assert qube.board.written_voltage == 2.0
        with pytest.raises(ValueError):
            qube.action(bad)
        assert qube.board.written_voltage == 0.0


@pytest.mark.parametrize("bad", [(0.0, 2.0, 0.0), (0.0, -0.1, 0.0), (math.nan, 0.5, 0.5),
                                 (0.0, 0.5, math.inf), (0.0, 0.5), (0.0, 0.5, 0.5, 0.5), [0.0, 2.0, 0.0]])
def test_invalid_led_writes_zero_then_raises(bad):
    with QubeServo2() as qube:
        qube.action(2.0, led=(0.0, 1.0, 0.0))
        assert qube.board.led == (0.0, 1.0, 0.0)
        with pytest.raises(ValueError, match="led"):
            qube.action(2.0, led=bad)
        assert qube.board.applied_voltage == 0.0


def test_amplifier_fault_stops_the_motor():
    with QubeServo2() as qube:
        qube.action(2.0)
        qube.board.set_amplifier_fault(True)
        with pytest.raises(AmplifierFaultError):
            qube.action(2.0)
        assert_motor_off(qube.board)


def test_stall_stops_the_motor():
    with QubeServo2(plant={"arm_friction": 1.0, "stall_time": 0.2}) as qube:
        start = qube.board.time
        acts_from = math.ceil(qube.board.plant["latency"] / 0.004)   # the first sample the voltage acts on
        with pytest.raises(MotorStallError):
            for step in range(100):
                qube.action(8.0)
                assert qube.stall_warning or step <= acts_from
        assert_motor_off(qube.board)
        assert qube.board.time - start == pytest.approx(0.2, abs=0.01)


def test_arm_beyond_its_limit_stops_the_motor():
    with QubeServo2(arm_limit=math.radians(100)) as qube:
        qube.action(2.0)
        qube.board.set_true_state([math.radians(101), math.pi, 0.0, 0.0])
        with pytest.raises(ArmLimitError, match="101 degrees"):
            qube.action(2.0)
        assert_motor_off(qube.board)
        assert qube.is_idle
        qube.resume()
        with pytest.raises(ArmLimitError):                             # again while it stays there
            qube.action(-2.0)
    with QubeServo2(arm_limit=None) as qube:
        qube.board.set_true_state([math.radians(170), math.pi, 0.0, 0.0])
        qube.action(0.5)
        assert qube.board.written_voltage == 0.5


@pytest.mark.slow
def test_watchdog_expires_when_the_loop_stalls():
    with QubeServo2(realtime=True, watchdog_timeout=0.05) as qube:
        for _ in range(5):
            qube.action(2.0)
        time.sleep(0.12)
        assert_motor_off(qube.board)                                  # zeroed by the board, not by Python
        with pytest.raises(WatchdogExpiredError):
            qube.action(2.0)
    assert_motor_off(qube.board)


@pytest.mark.slow
def test_missed_samples_are_counted_and_too_many_stop_the_motor():
    with QubeServo2(realtime=True, watchdog_timeout=0.15, max_missed_samples=None) as qube:
        qube.action(1.0)
        start = time.perf_counter()
        time.sleep(0.02)                                              # about 5 samples
        qube.action(1.0)
        elapsed = time.perf_counter() - start                         # more on a busy machine
        assert 3 <= qube.missed_samples <= elapsed * 250 + 1
    with QubeServo2(realtime=True, watchdog_timeout=0.15, max_missed_samples=10) as qube:
        qube.action(1.0)
        time.sleep(0.08)                                              # about 20 samples
        with pytest.raises(MissedSamplesError, match="samples"):
            qube.action(1.0)
        assert qube.board.applied_voltage == 0.0
        assert qube.missed_samples >= 15


@pytest.mark.slow
def test_realtime_runs_at_the_sample_rate():
    with QubeServo2(realtime=True) as qube:
        qube.action(0.0)
        start = time.perf_counter()
        for _ in range(100):
            qube.action(0.0)
        elapsed = time.perf_counter() - start
    assert 0.3 < elapsed < 1.0                                        # 0.4 s nominal; loose
    assert qube.missed_samples <= 20                                  # a busy machine may miss some


def test_real_board_path_drives_quanser_hil_class(fake_sdk):
    with QubeServo2(board="qube_servo2_usb", identifier="1") as qube:
        assert isinstance(qube.board, fake_sdk["class"]) and fake_sdk["opened"] == [("qube_servo2_usb", "1")]
        for _ in range(50):
            currents, encoders, others = qube.action(1.0)
        assert encoders[0] > 0 and currents[0] > 0 and others[0] > 0
    assert_motor_off(qube.board)
    assert not qube.board.is_valid()


def test_real_board_without_the_sdk_says_how_to_get_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "quanser", None)
    qube = QubeServo2(board="qube_servo2_usb")
    with pytest.raises(QuanserSDKNotFoundError, match="Quanser SDK") as error:
        qube.open()
    assert isinstance(error.value, ImportError) and "quanser_api" in str(error.value)
    assert not qube.is_open


def test_real_board_options_are_checked():
    with pytest.raises(ValueError, match="plant"):
        QubeServo2(board="qube_servo2_usb", plant={"arm_friction": 0.0})
    with pytest.raises(ValueError, match="real time"):
        QubeServo2(board="qube_servo2_usb", realtime=False)
    with pytest.raises(ValueError, match="qube_servo2_usb"):
        QubeServo2(board="qube_servo3_usb")
    with pytest.raises(ValueError, match="arm_frction"):
        QubeServo2(plant={"arm_frction": 0.0})


def test_qube_servo_3_configuration():
    with QubeServo3() as qube:
        qube.action(1.0)
        assert qube.board.plant["motor_resistance"] == 7.5


def test_readings_are_copies_and_encoders_can_be_reset():
    with QubeServo2() as qube:
        for _ in range(20):
            _, encoders, _ = qube.action(-1.0)
        assert encoders[0] < 0
        encoders[0] = 12345
        qube.reset_encoders([0])
        _, after, _ = qube.action(0.0)
        assert abs(after[0]) < 50 and after[0] != 12345
        assert conventions.arm_angle(int(after[0])) != qube.board.true_state()[0]  # counts from the new zero
