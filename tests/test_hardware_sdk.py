"""Quanser's SDK as users have it: older versions, a missing native library, its error texts."""

import builtins
import math
import sys
import time

import pytest
from hil_helpers import fake_quanser_sdk
from wall_clock import wall_clock_board_fixture  # noqa: F401

from qube_suite.hardware import BoardOpenError, QuanserSDKNotFoundError, QubeServo2, _hil_sim


def test_a_missing_native_library_gives_the_sdk_help(monkeypatch):
    real_import = builtins.__import__

    def failing_import(name, *args, **kwargs):
        if name.startswith("quanser"):
            raise OSError("libhil.so: cannot open shared object file: No such file or directory")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", failing_import)
    with pytest.raises(QuanserSDKNotFoundError, match="libhil.so.*Quanser SDK"):
        QubeServo2(board="qube_servo2_usb").open()


@pytest.mark.slow
def test_the_older_api_without_hil_infinite_runs(wall_clock_board, monkeypatch):
    from quanser.hardware import HIL

    monkeypatch.delattr(HIL, "INFINITE")
    with QubeServo2(board="qube_servo2_usb") as qube:
        for _ in range(10):
            qube.action([0.0])


@pytest.mark.slow
def test_open_errors_carry_quanser_error_text(wall_clock_board, monkeypatch):
    monkeypatch.delenv("QUBE_SUITE_BOARD_SERVER")                  # nothing connected
    with pytest.raises(BoardOpenError, match="no board is connected"):
        QubeServo2(board="qube_servo2_usb").open()


@pytest.mark.slow
def test_a_watchdog_left_expired_by_an_earlier_run_is_cleared_at_open(wall_clock_board):
    from quanser.hardware import HIL

    earlier = HIL("qube_servo2_usb", "0")
    earlier.watchdog_start(0.02)
    time.sleep(0.1)
    assert earlier.watchdog_is_expired()
    earlier.close()
    with QubeServo2(board="qube_servo2_usb") as qube:
        for _ in range(10):
            qube.action([0.5])
        assert wall_clock_board.state()["amplifier_enabled"]


class InterruptibleHIL(_hil_sim.HIL):
    """A substitute board on which the next analog write raises KeyboardInterrupt, once armed."""

    armed = False

    def write_analog(self, channels, num_channels, buffer):
        if InterruptibleHIL.armed:
            InterruptibleHIL.armed = False
            raise KeyboardInterrupt
        super().write_analog(channels, num_channels, buffer)


def test_an_interrupt_inside_idle_leaves_the_watchdog_guarding_the_outputs(monkeypatch):
    fake_quanser_sdk(monkeypatch)
    monkeypatch.setattr(sys.modules["quanser.hardware"], "HIL", InterruptibleHIL)
    qube = QubeServo2(board="qube_servo2_usb")
    qube.open()
    try:
        qube.action([-2.0])
        board = qube.board
        assert board.written_voltage == -2.0
        InterruptibleHIL.armed = True
        with pytest.raises(KeyboardInterrupt):
            qube.idle()
        board.stall(0.2)                                               # nobody acts: the watchdog expires
        assert board.applied_voltage == 0.0 and not board.amplifier_enabled
    finally:
        qube.close()


@pytest.mark.slow
def test_a_pendulum_still_swinging_at_open_keeps_the_boards_counts(wall_clock_board):
    """Run after run on one Qube: the next open finds the pendulum still swinging and must not zero
    its encoder there (the board went on counting since power-up)."""
    with QubeServo2(board="qube_servo2_usb") as qube:
        assert not qube.encoders_zeroed
    wall_clock_board.set_true_state([0.0, math.pi - 0.6, 0.0, 0.0])  # a hand on the Qube: a swing
    with QubeServo2(board="qube_servo2_usb") as qube:
        assert not qube.encoders_zeroed
        swing = []
        for _ in range(250):                                           # 1 s: more than a period
            _, counts, _ = qube.action([0.0])
            swing.append(counts[1])
    amplitude = max(abs(c) for c in swing) * 2 * math.pi / 2048
    assert 0.4 < amplitude < 0.62                                      # measured from hanging, as before


@pytest.mark.slow
def test_a_pendulum_resting_upright_at_open_reads_upright(wall_clock_board):
    """A run that leaves the pendulum resting upright (its friction holds it a while) must not make
    the next open take that rest for hanging."""
    with QubeServo2(board="qube_servo2_usb") as qube:
        qube.action([0.0])
    wall_clock_board.set_true_state([0.0, 0.0, 0.0, 0.0])
    with QubeServo2(board="qube_servo2_usb") as qube:
        _, counts, _ = qube.action([0.0])
    assert abs(abs(counts[1]) - 1024) <= 1                             # half a turn from hanging
