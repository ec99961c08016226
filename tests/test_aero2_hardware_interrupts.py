"""The Aero 2 through the real-board code path (board="quanser_aero2_usb"): interrupts returning from
any board call, and Ctrl-C on the strict wall-clock test board, leave both motors at 0 V with both
amplifiers off, and the board goes on working for a program that catches the interrupt."""

import contextlib
import random
import signal
import time

import numpy as np
import pytest
from hil_helpers import fake_quanser_sdk
from wall_clock import wall_clock_board_fixture  # noqa: F401

from qube_suite import suite
from qube_suite.hardware import MissedSamplesError, WatchdogExpiredError

pytestmark = pytest.mark.timeout(300)

CARD = "quanser_aero2_usb"

BOARD_METHODS = (
    "close", "task_create_reader", "task_set_buffer_overflow_mode", "task_start", "task_read",
    "task_get_buffer_overflows", "task_stop", "task_delete", "write_analog", "write_digital", "write_other",
    "watchdog_set_analog_expiration_state", "watchdog_set_digital_expiration_state", "watchdog_start",
    "watchdog_reload", "watchdog_is_expired", "watchdog_clear", "watchdog_stop")
"""Every call the wrapper makes on an open Aero board."""


def load(time_limit=0.2):
    return suite.load("aero2_hardware", "hover", task_kwargs={"random": 0},
                      environment_kwargs={"time_limit": time_limit}, domain_kwargs={"board": CARD})


def run_episodes(env, episodes=2):
    for _ in range(episodes):
        timestep = env.reset()
        while not timestep.last():
            timestep = env.step(np.array([4.0, -3.0]))


def assert_off(board, at):
    assert board is None or (not np.any(board.applied_voltage) and not board.amplifier_enabled), at


@pytest.fixture(name="interrupting_sdk")
def interrupting_sdk_fixture(monkeypatch):
    """The substitute board as Quanser's SDK (the Aero's card makes the Aero's plant), raising
    KeyboardInterrupt as the `calls["interrupt_at"]`-th board call returns."""
    fake_quanser_sdk(monkeypatch)
    import quanser.hardware as hardware

    calls = {"made": 0, "interrupt_at": None}

    def interrupting(name):
        method = getattr(hardware.HIL, name)

        def call(self, *args):
            result = method(self, *args)
            calls["made"] += 1
            if calls["made"] == calls["interrupt_at"]:
                raise KeyboardInterrupt
            return result
        return call

    monkeypatch.setattr(hardware, "HIL", type("InterruptingHIL", (hardware.HIL,),
                                              {name: interrupting(name) for name in BOARD_METHODS}))
    return calls


def test_an_interrupt_returning_from_any_board_call_leaves_both_motors_off(interrupting_sdk):
    env = load()
    run_episodes(env, 1)
    opening = interrupting_sdk["made"]
    assert env.physics.qube.board.plant.channels.card_type == CARD      # the Aero's own plant
    run_episodes(env, 1)
    episode = interrupting_sdk["made"] - opening
    env.close()
    draws = random.Random(0)
    for at in draws.sample(range(1, opening), 4):              # while the board opens
        interrupting_sdk.update(made=0, interrupt_at=at)
        env = load()
        with pytest.raises(KeyboardInterrupt):
            run_episodes(env, 1)
        assert_off(env.physics.qube.board, at)
        env.close()
    env = load()
    run_episodes(env, 1)
    for at in draws.sample(range(1, episode), 12):             # in resets, steps and idling
        interrupting_sdk.update(made=0, interrupt_at=at)
        with pytest.raises(KeyboardInterrupt):
            run_episodes(env, 3)
        assert_off(env.physics.qube.board, at)
    interrupting_sdk["interrupt_at"] = None
    run_episodes(env, 1)                                       # caught: the program goes on
    env.close()
    assert_off(env.physics.qube.board, None)


def test_ctrl_c_on_the_wall_clock_board_leaves_both_motors_off(wall_clock_board):
    def interrupt(signum, frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGALRM, interrupt)
    env = load()
    try:
        for delay in random.Random(1).sample([0.05 * k for k in range(2, 30)], 5):
            signal.setitimer(signal.ITIMER_REAL, delay)
            try:                                               # what IPython and Jupyter do
                while True:     # a host loaded far beyond its cores may stop an episode safely: go on
                    with contextlib.suppress(MissedSamplesError, WatchdogExpiredError):
                        run_episodes(env, 1)
            except KeyboardInterrupt:
                pass
            state = wall_clock_board.state()
            assert not np.any(state["applied_voltage"]) and not state["amplifier_enabled"], delay
        time.sleep(0.3)
        state = wall_clock_board.state()
        assert not np.any(state["applied_voltage"]) and not state["amplifier_enabled"]
        assert len(state["true_state"]) == 6                   # the Aero's plant, on the board's own clock
        run_episodes(env, 1)                                   # the board still answers in step
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
        env.close()
    assert wall_clock_board.state()["closed_cleanly"]


def test_a_driving_process_that_dies_leaves_both_motors_to_the_watchdog(wall_clock_board):
    import subprocess
    import sys

    from wall_clock import child_environment

    script = ("import numpy as np, os\n"
              "from qube_suite import suite\n"
              f"env = suite.load('aero2_hardware', 'hover', domain_kwargs={{'board': '{CARD}'}})\n"
              "env.reset()\n"
              "for _ in range(50): env.step(np.array([6.0, -6.0]))\n"
              "print('driving', flush=True)\n"
              "os._exit(0)\n")                                  # dies without closing anything
    child = subprocess.run([sys.executable, "-c", script], env=child_environment(wall_clock_board),
                           capture_output=True, text=True, timeout=120)
    assert "driving" in child.stdout, child.stderr
    time.sleep(0.3)                                            # more than the 0.1 s watchdog
    state = wall_clock_board.state()
    assert state["watchdog_expired"] and not state["closed_cleanly"]
    assert not np.any(state["applied_voltage"]) and not state["amplifier_enabled"]
