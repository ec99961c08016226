"""`qube-suite check-board`: the guided bring-up finds a good Qube good, a miswired one not, and ends safe."""

import math
import sys

import numpy as np
import pytest
from hil_helpers import fake_quanser_sdk
from wall_clock import wall_clock_board_fixture  # noqa: F401

from qube_suite import cli
from qube_suite.hardware import _hil_sim
from qube_suite.hardware.bringup import check_board


def results(checks):
    return {check.name: check.passed for check in checks}


@pytest.mark.parametrize("device", ["qube_servo2", "qube_servo3"])
def test_a_good_substitute_passes_and_nothing_is_left_driven(device):
    checks = check_board(device=device, say=lambda line: None)
    assert results(checks) == {"amplifier": True, "LED": None, "encoder signs by hand": None,
                               "voltage pulse direction": True, "motor current sign": True,
                               "tachometer": True}


def test_the_hand_moves_are_checked_against_the_conventions(monkeypatch):
    log = fake_quanser_sdk(monkeypatch)
    answers = iter(["y", "y", "y"])

    def ask(prompt):
        board = log["created"][-1]
        theta, alpha, _, _ = board.true_state()
        if "turn the arm" in prompt:
            board.set_true_state([theta + math.radians(45), alpha, 0.0, 0.0])
        elif "turn the pendulum" in prompt:
            board.set_true_state([theta, alpha + math.radians(45), 0.0, 0.0])
        elif "go back" in prompt:
            board.set_true_state([0.0, math.pi, 0.0, 0.0])
        else:
            return next(answers)
        return ""

    checks = check_board(board="qube_servo2_usb", interactive=True, ask=ask, say=lambda line: None)
    assert all(results(checks).values()), checks
    assert {"arm encoder", "pendulum encoder", "LED red", "LED green", "LED blue"} <= set(results(checks))
    board = log["created"][-1]
    assert board.applied_voltage == 0.0 and not board.amplifier_enabled and not board.is_valid()


class MiswiredHIL(_hil_sim.HIL):
    """A Qube whose motor leads are swapped: the motor sees the opposite of what is written."""

    def write_analog(self, channels, num_channels, buffer):
        super().write_analog(channels, num_channels, -np.asarray(buffer))


def test_a_miswired_motor_fails_the_pulse_and_the_command_says_so(monkeypatch, capsys):
    fake_quanser_sdk(monkeypatch)
    monkeypatch.setattr(sys.modules["quanser.hardware"], "HIL", MiswiredHIL)
    assert cli.main(["check-board", "--board", "qube_servo2_usb", "--non-interactive"]) == 1
    out = capsys.readouterr().out
    assert "[FAILED] voltage pulse direction" in out and "closed the board" in out


@pytest.mark.slow
def test_check_board_on_a_real_boards_code_path(wall_clock_board, capsys):
    assert cli.main(["check-board", "--board", "qube_servo3_usb", "--non-interactive"]) == 0
    state = wall_clock_board.state()
    assert state["closed_cleanly"] and state["applied_voltage"] == 0.0 and not state["amplifier_enabled"]
