"""The real-board code path against the wall-clock double of `quanser.hardware` (tests/doubles)."""

import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
from wall_clock import busy_core_fixture, child_environment, wall_clock_board_fixture  # noqa: F401

from qube_suite import suite
from qube_suite.hardware import QubeServo2, QubeServo3

U32 = np.uint32


def open_card():
    from quanser.hardware import HIL

    return HIL("qube_servo2_usb", "0")


# -- the double holds the real API's contract ------------------------------------------------

@pytest.mark.slow
def test_double_refuses_wrong_dtypes_and_argument_counts(wall_clock_board):
    card = open_card()
    try:
        with pytest.raises(TypeError, match="uint32"):
            card.write_analog(np.array([0]), 1, np.zeros(1))                       # int64 channels
        with pytest.raises(TypeError, match="float64"):
            card.write_analog(np.array([0], U32), 1, np.zeros(1, np.float32))
        with pytest.raises(TypeError, match="int8"):
            card.write_digital(np.array([0], U32), 1, np.ones(1, np.int32))
        with pytest.raises(TypeError, match="int32"):
            card.read_encoder(np.array([0, 1], U32), 2, np.zeros(2, np.int64))
        with pytest.raises(TypeError):
            card.write_analog(np.array([0], U32), np.zeros(1))                       # missing argument
        with pytest.raises(ValueError, match="fit"):
            card.write_analog(np.array([0], U32), 2, np.zeros(2))
    finally:
        card.close()


@pytest.mark.slow
def test_double_task_lifecycle_and_writes_after_close(wall_clock_board):
    from quanser.hardware import HIL, Clock, HILError

    card = open_card()
    task = card.task_create_encoder_reader(10, np.array([0, 1], U32), 2)
    counts = np.zeros(2, np.int32)
    with pytest.raises(HILError):
        card.task_read_encoder(task, 1, counts)                                    # not started
    card.task_start(task, Clock.HARDWARE_CLOCK_0, 250.0, HIL.INFINITE)
    assert card.task_read_encoder(task, 1, counts) == 1
    card.task_stop(task)
    card.task_delete(task)
    with pytest.raises(HILError):
        card.task_read_encoder(task, 1, counts)                                    # deleted
    card.close()
    with pytest.raises(HILError) as error:
        card.write_analog(np.array([0], U32), 1, np.zeros(1))
    assert str(error.value) == str(error.value.error_code)                         # the code only
    assert "not open" in error.value.get_error_message()


@pytest.mark.slow
def test_task_read_blocks_until_the_next_sample_and_samples_pile_up(wall_clock_board):
    from quanser.hardware import HIL, Clock, HILError
    from quanser.hardware.enumerations import BufferOverflowMode

    card = open_card()
    counts = np.zeros(2, np.int32)
    task = card.task_create_encoder_reader(5, np.array([0, 1], U32), 2)
    card.task_start(task, Clock.HARDWARE_CLOCK_0, 100.0, HIL.INFINITE)
    card.task_read_encoder(task, 1, counts)
    start = time.perf_counter()
    for _ in range(10):
        card.task_read_encoder(task, 1, counts)
    assert time.perf_counter() - start >= 0.085                                    # 10 samples at 100 Hz
    time.sleep(0.2)                                                                # 20 samples fall due
    start = time.perf_counter()
    with pytest.raises(HILError):                                  # by default an overflow is an error
        for _ in range(6):
            card.task_read_encoder(task, 1, counts)
    card.task_stop(task)
    card.task_delete(task)
    task = card.task_create_encoder_reader(5, np.array([0, 1], U32), 2)
    card.task_set_buffer_overflow_mode(task, BufferOverflowMode.OVERWRITE_ON_OVERFLOW)
    card.task_start(task, Clock.HARDWARE_CLOCK_0, 100.0, HIL.INFINITE)
    card.task_read_encoder(task, 1, counts)
    slept = time.perf_counter()
    time.sleep(0.2)
    waited = time.perf_counter() - slept
    start = time.perf_counter()
    for _ in range(5):                                                             # the buffer is full
        card.task_read_encoder(task, 1, counts)
    assert time.perf_counter() - start < 0.02
    assert card.task_get_buffer_overflows(task) >= round(waited * 100) - 5 - 2
    card.close()


@pytest.mark.slow
def test_watchdog_expires_on_the_wall_clock_and_applies_its_expiration_states(wall_clock_board):
    from quanser.hardware import HILError

    card = open_card()
    card.watchdog_set_analog_expiration_state(np.array([0], U32), 1, np.zeros(1))
    card.watchdog_set_digital_expiration_state(np.array([0], U32), 1, np.zeros(1, np.int32))
    card.write_digital(np.array([0], U32), 1, np.ones(1, np.int8))
    card.write_analog(np.array([0], U32), 1, np.array([2.0]))
    card.watchdog_start(0.05)
    assert wall_clock_board.state()["written_voltage"] == 2.0      # applied after the amplifier's latency
    time.sleep(0.15)                                                               # nobody calls the board
    state = wall_clock_board.state()
    assert state["applied_voltage"] == 0.0 and not state["amplifier_enabled"] and state["watchdog_expired"]
    assert not card.watchdog_reload()
    with pytest.raises(HILError):
        card.write_analog(np.array([0], U32), 1, np.array([1.0]))
    card.watchdog_clear()
    card.write_analog(np.array([0], U32), 1, np.array([0.0]))
    card.close()


# -- the package's real-board code path on it ---------------------------------------------------

@pytest.mark.slow
def test_wrapper_runs_on_the_wall_clock_board_with_a_busy_core(wall_clock_board, busy_core):
    with QubeServo2(board="qube_servo2_usb") as qube:
        for step in range(500):                                                    # 2 s at 250 Hz
            qube.action([0.5 if step < 50 else 0.0])
        assert wall_clock_board.state()["amplifier_enabled"]
    state = wall_clock_board.state()
    assert state["closed_cleanly"] and state["applied_voltage"] == 0.0 and not state["amplifier_enabled"]


@pytest.mark.slow
def test_qube_servo3_sets_quanser_card_options_on_a_real_board(wall_clock_board):
    with QubeServo3(board="qube_servo3_usb") as qube:
        qube.action([0.0])
        assert "pwm_en=0" in wall_clock_board.state()["card_options"]
        assert "deadband_compensation=" in wall_clock_board.state()["card_options"]


KILLED_CHILD = textwrap.dedent("""
    import sys, numpy as np
    from qube_suite.hardware import QubeServo2
    qube = QubeServo2(board="qube_servo2_usb")
    qube.open()
    for step in range(100000):
        qube.action([2.0 if (step // 25) % 2 == 0 else -2.0])   # the arm rocks to and fro
        if step == 50:
            print("driving", flush=True)
""")


@pytest.mark.slow
def test_a_process_killed_mid_episode_leaves_the_board_at_0_volts_with_the_amplifier_off(wall_clock_board):
    child = subprocess.Popen([sys.executable, "-c", KILLED_CHILD], env=child_environment(wall_clock_board),
                             stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == "driving"
        driven = wall_clock_board.state()
        assert driven["amplifier_enabled"] and abs(driven["applied_voltage"]) == 2.0
        child.send_signal(signal.SIGKILL)
        child.wait(5)
    finally:
        child.kill()
    time.sleep(0.25)                                               # the 0.1 s watchdog expires
    state = wall_clock_board.state()
    assert not state["closed_cleanly"] and state["watchdog_expired"]
    assert state["applied_voltage"] == 0.0 and not state["amplifier_enabled"]
    with QubeServo2(board="qube_servo2_usb") as qube:                              # the next run clears it
        qube.action([0.0])


@pytest.mark.slow
@pytest.mark.parametrize("task", ["balance", "swingup"])
def test_hardware_domain_resets_and_runs_on_the_wall_clock_board(wall_clock_board, busy_core, task):
    with suite.load("qube_hardware", task, task_kwargs={"random": 0}, environment_kwargs={"time_limit": 0.5},
                    domain_kwargs={"board": "qube_servo2_usb"}) as env:
        for _ in range(2):
            timestep = env.reset()
            while not timestep.last():
                timestep = env.step(np.zeros(1))
            state = wall_clock_board.state()
            assert state["applied_voltage"] == 0.0 and not state["amplifier_enabled"]   # idle between
            time.sleep(0.15)                                # a pause longer than the watchdog
    state = wall_clock_board.state()
    assert state["closed_cleanly"] and not state["amplifier_enabled"]


@pytest.mark.slow
def test_evaluate_goes_on_past_failed_resets_and_leaves_the_wall_clock_board_off(wall_clock_board, busy_core):
    from qube_suite import evaluate

    result = evaluate("balance", domain="qube_hardware", task="balance", episodes=2,
                      environment_kwargs={"time_limit": 0.5},
                      domain_kwargs={"board": "qube_servo2_usb", "reset_voltage_limit": 0.05,
                                     "reset_timeout": 0.5})                   # too weak to swing up
    assert result.failed_resets == [0, 1] and result.returns == [0.0, 0.0] and result.success_rate == 0.0
    state = wall_clock_board.state()
    assert state["applied_voltage"] == 0.0 and not state["amplifier_enabled"] and state["closed_cleanly"]
