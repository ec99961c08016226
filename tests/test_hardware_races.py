"""A watchdog that expires between a check and a write (the process held up by a busy computer):
the board is safe (its expiration states), and the wrapper says so instead of a raw board error."""

from __future__ import annotations

import pytest
from hil_helpers import fake_quanser_sdk

from qube_suite.hardware import QubeServo2, WatchdogExpiredError


@pytest.fixture(name="held_up")
def held_up_fixture(monkeypatch):
    """A real-board SDK whose process is held up for 0.2 s just before its next `write_analog` once
    `held_up["armed"]` is set: the 0.1 s watchdog expires in between."""
    fake_quanser_sdk(monkeypatch)
    import quanser.hardware as hardware

    state = {"armed": False}

    class HeldUpHIL(hardware.HIL):
        def write_analog(self, *args):
            if state["armed"]:
                state["armed"] = False
                self.stall(0.2)
            return super().write_analog(*args)

    monkeypatch.setattr(hardware, "HIL", HeldUpHIL)
    return state


def test_an_expiry_between_a_sample_and_its_write_is_a_watchdog_stop(held_up):
    with QubeServo2(board="qube_servo2_usb") as qube:
        qube.action([1.0])
        held_up["armed"] = True
        with pytest.raises(WatchdogExpiredError, match="between a sample and its action"):
            qube.action([1.0])
        assert qube.is_idle and qube.board.applied_voltage == 0.0 and not qube.board.amplifier_enabled


def test_an_expiry_while_closing_closes_without_an_error(held_up):
    qube = QubeServo2(board="qube_servo2_usb")
    qube.open()
    qube.action([1.0])
    held_up["armed"] = True
    qube.close()                                    # the writes it refused were only to zero what it zeroed
    assert not qube.is_open and qube.board.applied_voltage == 0.0 and not qube.board.amplifier_enabled
