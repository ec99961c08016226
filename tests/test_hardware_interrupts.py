"""Interrupts at any moment, inside board calls too, on both boards: the motor is at 0 V with the
amplifier off as soon as the interrupt surfaces, whatever a board query answered, and the board
keeps working for a program that catches the interrupt and goes on (IPython, Jupyter)."""

import contextlib
import random
import signal
import time

import numpy as np
import pytest
from hil_helpers import fake_quanser_sdk
from wall_clock import wall_clock_board_fixture  # noqa: F401

from qube_suite import suite
from qube_suite.hardware import MissedSamplesError, QubeServo2, WatchdogExpiredError

pytestmark = pytest.mark.timeout(300)

BOARD_METHODS = (
    "close", "task_create_reader", "task_set_buffer_overflow_mode", "task_start", "task_read",
    "task_get_buffer_overflows", "task_stop", "task_delete", "write_analog", "write_digital", "write_other",
    "set_encoder_counts", "watchdog_set_analog_expiration_state", "watchdog_set_digital_expiration_state",
    "watchdog_start", "watchdog_reload", "watchdog_is_expired", "watchdog_clear", "watchdog_stop")
"""Every call the wrapper makes on an open board."""


def load(**domain_kwargs):
    return suite.load("qube_hardware", "balance", task_kwargs={"random": 0, "voltage_limit": 10.0},
                      environment_kwargs={"time_limit": 0.2},
                      domain_kwargs={"board": "qube_servo2_usb", "check_encoders": False, **domain_kwargs})


def run_episodes(env, episodes=2):
    for _ in range(episodes):
        timestep = env.reset()
        while not timestep.last():
            timestep = env.step(np.array([2.0]))


@pytest.fixture(name="interrupting_sdk")
def interrupting_sdk_fixture(monkeypatch):
    """The substitute board as Quanser's SDK, raising KeyboardInterrupt as the `calls["interrupt_at"]`-th
    board call returns (a Ctrl-C that arrived inside that call); `calls["made"]` counts them."""
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


def assert_off(board, at):
    assert board is None or (board.applied_voltage == 0.0 and not board.amplifier_enabled), at


@pytest.mark.slow
def test_an_interrupt_returning_from_any_board_call_leaves_the_motor_off(interrupting_sdk):
    env = load()
    run_episodes(env, 1)
    opening = interrupting_sdk["made"]
    run_episodes(env, 1)
    episode = interrupting_sdk["made"] - opening
    env.close()
    draws = random.Random(0)
    for at in draws.sample(range(1, opening), 3):              # while the board opens
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
            run_episodes(env, 3)                               # episodes differ in length
        assert_off(env.physics.qube.board, at)
    interrupting_sdk["interrupt_at"] = None
    run_episodes(env, 1)                                       # caught: the program goes on
    env.close()
    assert_off(env.physics.qube.board, None)


class LyingHIL:
    """A board whose watchdog_is_expired answers something truthy that is not True (a stale reply)."""

    def watchdog_is_expired(self):
        return ("ok", 1)


@pytest.mark.parametrize("leave", ["idle", "close"])
def test_stopping_writes_0_volts_whatever_the_watchdog_query_answers(monkeypatch, leave):
    fake_quanser_sdk(monkeypatch)
    import quanser.hardware as hardware

    monkeypatch.setattr(hardware, "HIL", type("LyingHIL", (LyingHIL, hardware.HIL), {}))
    qube = QubeServo2(board="qube_servo2_usb")
    qube.open()
    qube.action([3.0])
    qube.action([3.0])
    getattr(qube, leave)()
    assert qube.board.applied_voltage == 0.0 and not qube.board.amplifier_enabled
    qube.close()


# -- the wall-clock board: real signals, landing inside board calls -----------------------------------

def test_the_double_is_atomic_under_an_interrupt_inside_a_call(wall_clock_board):
    from quanser.hardware import HIL, Clock

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGALRM, interrupt)
    card = HIL("qube_servo2_usb", "0")
    try:
        task = card.task_create_encoder_reader(1, np.array([0, 1], np.uint32), 2)
        card.task_start(task, Clock.HARDWARE_CLOCK_0, 250.0, HIL.INFINITE)
        counts = np.zeros(2, np.int32)
        for trial in range(20):
            signal.setitimer(signal.ITIMER_REAL, 0.001 + 0.0003 * trial)
            try:
                while True:                                    # blocks about 4 ms per sample
                    card.task_read_encoder(task, 1, counts)
            except KeyboardInterrupt:
                pass
            assert card.watchdog_is_expired() is False         # its own reply, not the read's
            assert type(card.task_get_buffer_overflows(task)) is int  # a count (a busy machine may overflow)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
        card.close()


@pytest.mark.slow
def test_ctrl_c_caught_during_resets_leaves_the_wall_clock_board_off(wall_clock_board):
    def interrupt(signum, frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGALRM, interrupt)
    env = load(check_encoders=True)
    try:
        for delay in random.Random(1).sample([0.05 * k for k in range(4, 60)], 6):
            signal.setitimer(signal.ITIMER_REAL, delay)
            try:                                               # what IPython and Jupyter do
                while True:     # a host loaded far beyond its cores may stop an episode safely: go on
                    with contextlib.suppress(MissedSamplesError, WatchdogExpiredError):
                        run_episodes(env, 1)
            except KeyboardInterrupt:
                pass
            state = wall_clock_board.state()
            assert state["applied_voltage"] == 0.0 and not state["amplifier_enabled"], delay
        time.sleep(0.3)
        state = wall_clock_board.state()
        assert state["applied_voltage"] == 0.0 and not state["amplifier_enabled"]
        run_episodes(env, 1)                                   # the board still answers in step
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
        env.close()
    assert wall_clock_board.state()["closed_cleanly"]


RUN = ["-m", "qube_suite.cli", "run", "--domain", "qube_hardware", "--board", "qube_servo2_usb",
       "--task", "balance", "--controller", "balance", "--episodes", "100"]


@pytest.mark.slow
def test_signals_to_the_cli_at_random_moments_close_the_board_at_once(wall_clock_board):
    import subprocess
    import sys

    from wall_clock import child_environment

    draws = random.Random(2)
    for signum in (signal.SIGTERM, signal.SIGINT, signal.SIGTERM, signal.SIGINT):
        child = subprocess.Popen([sys.executable, *RUN], env=child_environment(wall_clock_board),
                                 stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        try:
            deadline = time.monotonic() + 60
            while not (wall_clock_board.state() or {}).get("amplifier_enabled"):
                assert time.monotonic() < deadline and child.poll() is None
                time.sleep(0.01)
            time.sleep(draws.uniform(0.0, 3.0))               # in a reset or an episode
            child.send_signal(signum)
            _, errors = child.communicate(timeout=30)
        finally:
            child.kill()
        state = wall_clock_board.state()
        timing_stop = "samples at 250 Hz passed" in errors or "watchdog expired" in errors
        if not timing_stop:                     # on a host loaded far beyond its cores the run may stop
            assert child.returncode == (143 if signum == signal.SIGTERM else 130), errors  # by itself
        assert state["closed_cleanly"] and state["applied_voltage"] == 0.0 and not state["amplifier_enabled"]
