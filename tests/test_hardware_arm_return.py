"""An arm left beyond the board's arm limit comes back at the next reset: towards the centre only,
slowly, and not against a hand that holds it."""

import math

import numpy as np
import pytest

from qube_suite import suite
from qube_suite.hardware import ArmLimitError, QubeServo2, conventions
from qube_suite.hardware.plant import ESTIMATED
from qube_suite.hardware.quanser import RETURN_VOLTAGE

BEYOND = math.radians(125.0)


def assert_motor_off(board):
    assert board.applied_voltage == 0.0 and not board.amplifier_enabled


def move_arm(board, theta):
    """Put the arm at `theta` at rest, the pendulum hanging (where the swing-up's start left it)."""
    board.set_true_state([theta, math.pi, 0.0, 0.0])


def stopped_at_the_limit(env, side=1.0):
    """Run an episode, then put the arm beyond the limit as a runaway would: the step stops."""
    env.reset()
    env.step(np.zeros(1))
    move_arm(env.physics.qube.board, side * BEYOND / 2)         # in two moves: not an encoder glitch
    env.step(np.zeros(1))
    move_arm(env.physics.qube.board, side * BEYOND)
    with pytest.raises(ArmLimitError):
        env.step(np.zeros(1))
    assert_motor_off(env.physics.qube.board)


def returned_from_beyond_the_limit(side, plant):
    """(arm, arm speed, voltage towards positive arm angles) at each `return_arm` call of the reset after
    an episode stopped with the arm beyond the limit on `side`, on the substitute with `plant`."""
    with suite.load("qube_hardware", "swingup", task_kwargs={"random": 0},
                    environment_kwargs={"time_limit": 0.2}, domain_kwargs={"plant": plant}) as env:
        stopped_at_the_limit(env, side)
        qube, board = env.physics.qube, env.physics.qube.board
        returned = []
        return_arm = qube.return_arm

        def logged(voltages, led=None, copy=True):
            result = return_arm(voltages, led, copy=copy)
            theta, _, dtheta, _ = board.true_state()
            returned.append((theta, dtheta, conventions.ARM_SIGN * voltages[0]))
            return result

        qube.return_arm = logged
        timestep = env.reset()
        while not timestep.last():
            timestep = env.step(np.zeros(1))
    return np.array(returned).T


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_a_reset_brings_back_an_arm_beyond_the_limit_towards_the_centre_slowly(side):
    # On the estimated plant. On the real Qube's (the default) its cable, stiffer beyond its slack band
    # against less arm friction, pulls the arm back at up to 6.5 rad/s (median 1.3 to 2.0), which
    # return_arm, pushing only towards the centre, does not brake: the test below.
    arm, speed, volts = returned_from_beyond_the_limit(side, ESTIMATED)
    beyond = np.abs(arm) > math.radians(120.0)
    assert beyond.sum() > 10
    assert np.all(volts[beyond] * arm[beyond] <= 0.0)                  # only towards the centre
    assert np.abs(volts).max() <= RETURN_VOLTAGE
    assert np.median(np.abs(speed)) < 1.5 and np.abs(speed).max() < 3.0  # slowly (the cable's spring
    assert np.abs(arm[-1]) < np.abs(arm[0]) - 1.0                       # pulls it in at 0 V too)


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_on_the_real_qubes_plant_a_reset_brings_back_an_arm_beyond_the_limit_towards_the_centre(side):
    arm, _, volts = returned_from_beyond_the_limit(side, "real_qube_servo2")
    beyond = np.abs(arm) > math.radians(120.0)
    assert beyond.sum() >= 5                                             # 8 and 10 samples, 2026-11-28
    assert np.all(volts[beyond] * arm[beyond] <= 0.0)                  # only towards the centre
    assert np.abs(volts).max() <= RETURN_VOLTAGE
    assert np.abs(arm[-1]) < np.abs(arm[0]) - 1.0


@pytest.mark.parametrize("speed, plant", [(20.0, "real_qube_servo2"), (-30.0, "real_qube_servo2"),
                                          (20.0, ESTIMATED), (-30.0, ESTIMATED), (50.0, ESTIMATED)])
def test_a_reset_catches_an_arm_that_left_its_safe_set_fast_before_it_coasts_past_the_limit(speed, plant):
    # a policy that throws the arm out at 20 to 30 rad/s: at 0 V it would coast past 120 degrees while the
    # reset settles the pendulum, and the board would stop with ArmLimitError instead of resetting. The
    # estimated plant's arm is caught from 50 rad/s; the real Qube's (the default) from 20 and 30 but not
    # from 35 to 50 (ArmLimitError, measured 2026-11-28; why is not measured).
    with suite.load("qube_hardware", "swingup", task_kwargs={"random": 0},
                    domain_kwargs={"plant": plant}) as env:
        env.reset()
        board = env.physics.qube.board
        board.set_true_state([math.copysign(math.radians(88.0), speed), math.pi, speed, 0.0])
        assert env.step(np.array([math.copysign(3.0, speed)])).last()
        env.reset()
        assert abs(env.physics.arm_angle()) < math.radians(10.0)
        assert board.amplifier_enabled  # reset, not stopped


def test_a_held_arm_is_not_pushed_against_its_holder():
    with suite.load("qube_hardware", "swingup", task_kwargs={"random": 0},
                    environment_kwargs={"time_limit": 0.2}) as env:
        stopped_at_the_limit(env)
        board = env.physics.qube.board
        board.block_arm(True)
        start = board.time
        with pytest.raises(ArmLimitError, match="held"):
            env.reset()
        assert_motor_off(board)
        assert board.time - start < 0.3
        board.block_arm(False)
        env.reset()                                                        # freed: it comes back


@pytest.mark.parametrize("volts, message", [(1.0, "towards the centre"), (-4.0, "towards the centre")])
def test_return_arm_refuses_a_voltage_away_from_the_centre_or_too_large(volts, message):
    with QubeServo2(max_encoder_speed=None) as qube:
        qube.action(0.0)
        move_arm(qube.board, BEYOND)
        with pytest.raises(ArmLimitError, match=message):
            qube.return_arm([conventions.board_voltage(volts)])
        assert_motor_off(qube.board)
        qube.resume()
        with pytest.raises(ArmLimitError, match="return_arm"):
            qube.action([0.0])                                              # action never drives it there
        qube.resume()
        qube.return_arm([conventions.board_voltage(-1.0)])                 # inwards, gently: allowed
        assert qube.board.written_voltage == conventions.board_voltage(-1.0)
