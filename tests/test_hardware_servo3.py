"""The Qube-Servo 3 as a first-class device: substitute, real-board path, ids, CLI, controllers."""

import math

import gymnasium
import numpy as np
import pytest
from wall_clock import wall_clock_board_fixture  # noqa: F401

import qube_suite  # noqa: F401  (registers the Gymnasium ids)
from qube_suite import baselines, cli, suite
from qube_suite.evaluation import evaluate
from qube_suite.hardware import QUBE_SERVO_3, QubeServo3
from qube_suite.hardware.plant import BOARD_MOTORS

SERVO3 = {"device": "qube_servo3"}

CONTROLLER_FOR = {"swingup": "swingup", "swingup_sparse": "swingup", "balance": "balance",
                  "balance_sparse": "balance", "dampen": "dampen", "dampen_sparse": "dampen",
                  "rotor": "rotor", "swingup_follow": "follow", "balance_follow": "follow",
                  "swingup_follow_sparse": "follow", "balance_follow_sparse": "follow"}


@pytest.mark.slow
@pytest.mark.parametrize("task", suite.TASKS_BY_DOMAIN["qube_hardware"])
def test_every_task_and_its_controller_passes_on_a_qube_servo3_substitute(task):
    result = evaluate(CONTROLLER_FOR[task], domain="qube_hardware", task=task, episodes=1,
                      domain_kwargs=SERVO3)
    assert result.success_rate == 1.0, result.to_dict()


def test_the_substitute_runs_the_qube_servo3_motor():
    with suite.load("qube_hardware", "balance", domain_kwargs=SERVO3) as env:
        env.reset()
        plant = env.physics.qube.board.plant
        assert plant["motor_resistance"] == 7.5 and plant["rotor_inertia"] == 1.4e-6
        assert env.physics.design_parameters() == dict(BOARD_MOTORS["qube_servo3_usb"])
        controller = baselines.for_environment("balance", env)
        assert controller.model.base_inertia < baselines.make("balance").model.base_inertia  # lighter rotor


def test_the_pendulum_tachometer_reads_the_pendulum_speed():
    with QubeServo3() as qube:
        qube.action([0.0])
        qube.board.set_true_state([0.0, math.pi - 0.3, 0.0, 2.0])
        _, _, others = qube.action([0.0])
        speed = qube.board.true_state()[3]                              # the plant's, at that sample
        assert others.shape == (2,) and others[1] == pytest.approx(speed * 2048 / (2 * math.pi), rel=1e-9)
        assert qube.board.card_options == QUBE_SERVO_3.card_options
        assert "pwm_en=0" in QUBE_SERVO_3.card_options


def test_a_qube_servo3_card_names_its_device():
    kwargs = {"board": "simulated", "device": "qube_servo3"}
    with suite.load("qube_hardware", "balance", domain_kwargs=kwargs) as env:
        assert env.physics.device == "qube_servo3"
    with pytest.raises(ValueError, match="qube_servo2_usb"):
        suite.load("qube_hardware", "balance",
                   domain_kwargs={"board": "qube_servo3_usb", "device": "qube_servo2"})


@pytest.mark.slow
def test_a_real_qube_servo3_runs_through_the_gymnasium_id(wall_clock_board):
    env = gymnasium.make("QubeSuite/BalanceHardware-v0", time_limit=0.5,
                         domain_kwargs={"board": "qube_servo3_usb"})
    try:
        env.reset(seed=0)
        assert env.unwrapped.physics.device == "qube_servo3"
        for _ in range(20):
            env.step(np.zeros(1, np.float32))
        assert "deadband_compensation" in wall_clock_board.state()["card_options"]
    finally:
        env.close()
    assert wall_clock_board.state()["closed_cleanly"]


@pytest.mark.parametrize("command", [
    ["run", "--task", "balance", "--controller", "balance"],
    ["eval", "--task", "balance", "--controller", "balance", "--episodes", "1"],
])
def test_the_cli_runs_a_qube_servo3(command, capsys):
    assert cli.main([*command, "--domain", "qube_hardware", "--device", "qube_servo3"]) == 0


def test_device_without_the_hardware_domain_is_refused(capsys):
    assert cli.main(["run", "--task", "balance", "--controller", "balance", "--device", "qube_servo3"]) == 2
    assert "--domain qube_hardware" in capsys.readouterr().err
