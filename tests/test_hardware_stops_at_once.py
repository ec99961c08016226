"""0 V at once, not at the watchdog's expiry: a time limit of Gymnasium's, a refused action, an
exception below the outermost wrapper, SIGTERM to a plain script; settings that would let the motor
outlive the watchdog's guarantees are refused; the garbage-collection hold-off ends with its holder."""

import gc
import signal
import subprocess
import sys
import textwrap

import gymnasium
import numpy as np
import pytest
from wall_clock import child_environment, wall_clock_board_fixture  # noqa: F401

import qube_suite  # noqa: F401  (registers the Gymnasium ids)
from qube_suite import suite
from qube_suite.hardware import QubeServo2
from qube_suite.wrappers import to_gymnasium

BAD_ACTIONS = [np.array([np.nan]), np.array([np.inf]), np.array([True]), np.array(["1"]),
               np.array([1j]), np.zeros(2), "1.0", None]


def assert_motor_off(board, amplifier=False):
    assert board.written_voltage == 0.0          # the amplifier acts on it after the plant's latency
    if not amplifier:
        assert board.applied_voltage == 0.0 and not board.amplifier_enabled  # disabling acts at once


def hardware_gym(**kwargs):
    return gymnasium.make("QubeSuite/BalanceHardware-v0", domain_kwargs={"check_encoders": False}, **kwargs)


def paced_gym(**kwargs):
    """A hardware env on the substitute paced by the wall clock, whose reset is short (hanging at rest);
    the missed-sample stop is off, as the hold-off of collections is under test, not the host's timing."""
    env = gymnasium.make("QubeSuite/SwingupHardware-v0", domain_kwargs={"check_encoders": False,
                                                                         "realtime": True}, **kwargs)
    env.unwrapped.physics.qube.max_missed_samples = None
    return env


def test_a_gymnasium_time_limit_idles_the_board_at_its_last_step():
    threshold = gc.get_threshold()
    env = paced_gym(max_episode_steps=20)
    env.reset(seed=0)
    board = env.unwrapped.physics.qube.board
    for step in range(20):
        _, _, terminated, truncated, _ = env.step(np.array([1.5], np.float32))
        assert not terminated and truncated == (step == 19)
        if step < 19:
            assert board.applied_voltage != 0.0
    assert_motor_off(board)
    assert gc.get_threshold() == threshold                  # the hold-off ended with the episode
    env.reset(seed=1)
    env.step(np.array([1.0], np.float32))
    env.close()


def test_an_exception_in_a_wrapper_below_the_outermost_stops_the_motor(monkeypatch):
    env = hardware_gym(max_episode_steps=50)
    env.reset(seed=0)
    board = env.unwrapped.physics.qube.board
    env.step(np.array([1.5], np.float32))
    step = gymnasium.wrappers.TimeLimit.step

    def failing(self, action):
        step(self, action)
        raise ArithmeticError("a wrapper's bug")

    monkeypatch.setattr(gymnasium.wrappers.TimeLimit, "step", failing)
    with pytest.raises(ArithmeticError):
        env.step(np.array([1.5], np.float32))
    assert_motor_off(board, amplifier=True)
    env.close()


@pytest.mark.parametrize("action", BAD_ACTIONS, ids=repr)
def test_a_refused_dm_env_action_writes_0_volts_and_the_next_drives(action):
    with suite.load("qube_hardware", "balance", task_kwargs={"random": 0},
                    domain_kwargs={"check_encoders": False}) as env:
        env.reset()
        env.step(np.array([2.0]))
        board = env.physics.qube.board
        with pytest.raises(ValueError):
            env.step(action)
        assert_motor_off(board, amplifier=True)
        env.step(np.array([2.0]))                                   # the episode goes on
        assert board.applied_voltage != 0.0


@pytest.mark.parametrize("action", BAD_ACTIONS + [np.float32(1.0), 1.0], ids=repr)
@pytest.mark.parametrize("make", ["gymnasium.make", "to_gymnasium", "SyncVectorEnv"])
def test_a_refused_gymnasium_action_writes_0_volts(action, make):
    if make == "gymnasium.make":
        env = hardware_gym()
    elif make == "to_gymnasium":
        env = to_gymnasium(suite.load("qube_hardware", "balance", domain_kwargs={"check_encoders": False}))
    else:
        env = gymnasium.vector.SyncVectorEnv([hardware_gym])
        action = [action]
    env.reset(seed=0)
    physics = env.envs[0].unwrapped.physics if make == "SyncVectorEnv" else env.unwrapped.physics
    env.step(np.array([[2.0]] if make == "SyncVectorEnv" else [2.0], np.float32))
    with pytest.raises(ValueError):
        env.step(action)
    assert_motor_off(physics.qube.board, amplifier=True)
    env.close()


def test_a_closed_gymnasium_hardware_environment_says_it_is_closed():
    env = hardware_gym()
    env.reset(seed=0)
    env.close()
    with pytest.raises(RuntimeError, match="closed"):
        env.step(np.zeros(1, np.float32))
    with pytest.raises(RuntimeError, match="closed"):
        env.reset(seed=0)


def test_full_collections_come_back_when_an_abandoned_environment_is_collected():
    threshold = gc.get_threshold()
    env = paced_gym()
    env.reset(seed=0)
    env.step(np.array([1.0], np.float32))
    board = env.unwrapped.physics.qube.board
    assert gc.get_threshold()[2] > 10**9
    del env
    gc.collect()
    assert gc.get_threshold() == threshold
    assert_motor_off(board)


@pytest.mark.parametrize("options, limit", [({"watchdog_timeout": 1e9}, "at most 0.15 s"),
                                            ({"watchdog_timeout": 0.2}, "MAX_WATCHDOG_TIMEOUT")])
def test_a_watchdog_that_would_outlast_its_guarantee_is_refused(options, limit):
    with pytest.raises(ValueError, match=limit):
        QubeServo2(**options)


@pytest.mark.parametrize("reset_timeout", [1e12, 121.0])
def test_a_reset_timeout_without_bound_is_refused(reset_timeout):
    with pytest.raises(ValueError, match="at most 120 s"):
        suite.load("qube_hardware", "balance", domain_kwargs={"reset_timeout": reset_timeout})


PLAIN_SCRIPT = textwrap.dedent("""
    import numpy as np
    from qube_suite import suite
    env = suite.load("qube_hardware", "balance", domain_kwargs={"board": "qube_servo2_usb",
                                                                "check_encoders": False})
    env.reset()
    for step in range(100000):
        env.step(np.array([2.0]))
        if step == 20:
            print("driving", flush=True)
""")


@pytest.mark.slow
def test_sigterm_to_a_plain_script_stops_the_motor_and_closes_the_board(wall_clock_board):
    child = subprocess.Popen([sys.executable, "-c", PLAIN_SCRIPT], env=child_environment(wall_clock_board),
                             stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == "driving"
        assert wall_clock_board.state()["amplifier_enabled"]
        child.send_signal(signal.SIGTERM)
        code = child.wait(30)
    finally:
        child.kill()
    state = wall_clock_board.state()
    assert code == 128 + signal.SIGTERM
    assert state["closed_cleanly"] and state["applied_voltage"] == 0.0 and not state["amplifier_enabled"]


def test_ctrl_c_during_the_collection_at_an_episodes_end_is_not_lost():
    # the collection that follows an episode runs finalizers; Ctrl-C raised inside one was reported and
    # dropped, so a loop of episodes ran on after the person pressed Ctrl-C
    class PressesCtrlC:
        def __del__(self):
            signal.raise_signal(signal.SIGINT)

    env = suite.load("qube_hardware", "swingup", task_kwargs={"random": 0},
                     environment_kwargs={"time_limit": 0.1}, domain_kwargs={"realtime": True})
    env.physics.qube.max_missed_samples = None  # the collection is under test, not the host's timing
    with env:
        env.reset()
        cycle = PressesCtrlC()
        cycle.itself = cycle  # freed by a full collection only
        del cycle
        with pytest.raises(KeyboardInterrupt):
            while True:
                env.step(np.zeros(1))
        assert_motor_off(env.physics.qube.board)
