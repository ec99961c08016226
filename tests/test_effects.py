"""A domain's sensor and actuator chains (`qube_suite.domains.effects`): calibrated stage first, then the
randomized one; restarts reach each stage with the worlds they concern."""

import numpy as np
import pytest

from qube_suite.devices.qube import simulation as qube
from qube_suite.devices.qube.batch import QubeBatch
from qube_suite.domains.effects import Effects


class Recorder:
    """A stage that adds `shift` and records its calls."""

    def __init__(self, shift):
        self.shift, self.calls = shift, []

    def __call__(self, x):
        self.calls.append(("call", x))
        return x + self.shift

    def reset(self, x, rows=None):
        self.calls.append(("reset", x, None if rows is None else list(rows)))
        return x + 10 * self.shift


def test_an_empty_chain_passes_everything_through():
    effects = Effects()
    assert effects.senses_exactly
    assert effects.measure(1.5) == 1.5 and effects.actuate(2.5) == 2.5 and effects.restart(3.5) == 3.5
    effects.restart_actuation()


def test_the_calibrated_stage_acts_before_the_randomized_one():
    effects = Effects()
    effects.sensor = lambda x: 2.0 * x
    effects.calibrated_sensor = lambda x: x + 1.0
    effects.actuator = lambda v: 3.0 * v
    effects.calibrated_actuator = lambda v: v - 1.0
    assert not effects.senses_exactly
    assert effects.measure(1.0) == 4.0  # 2 (1 + 1), not 2 * 1 + 1
    assert effects.actuate(2.0) == 3.0  # 3 (2 - 1), not 3 * 2 - 1


def test_restarts_reach_every_stage_with_the_rows_they_concern():
    effects = Effects()
    effects.calibrated_sensor, effects.sensor = Recorder(1.0), Recorder(2.0)
    effects.calibrated_actuator, effects.actuator = Recorder(0.0), Recorder(0.0)
    assert effects.restart(0.0) == 30.0
    assert effects.restart(0.0, rows=np.array([3])) == 30.0
    assert effects.sensor.calls == [("reset", 10.0, None), ("reset", 10.0, [3])]
    effects.restart_actuation(0.0, rows=np.array([1]))
    effects.restart_actuation()
    for stage in (effects.calibrated_actuator, effects.actuator):
        assert stage.calls == [("reset", 0.0, [1]), ("reset", 0.0, None)]


def test_stages_without_reset_are_called_on_the_sensor_side_and_left_alone_on_the_actuator_side():
    effects = Effects()
    effects.sensor = lambda x: x + 1.0
    effects.actuator = lambda v: pytest.fail("an actuator without reset is not restarted")
    assert effects.restart(1.0) == 2.0
    effects.restart_actuation()


@pytest.mark.parametrize("batch", [False, True])
def test_a_calibrated_dead_zone_acts_before_a_randomized_actuator(batch):
    """What reaches the motor is the randomized stage applied to the calibrated one's output, on one Qube
    and in a batch alike."""
    effects = {"voltage_deadzone": 0.5}
    if batch:
        physics = QubeBatch(1)
        physics.set_calibrated_effects(0, effects)
        physics.set_actuator_model(Doubling())
        physics.reset_world(0, [0.0, np.pi, 0.0, 0.0])
        physics.set_voltage(np.array([2.0]))
        physics.step()
        applied = physics._control[0, 0, 0]
        physics.close()
    else:
        physics = qube.make_physics()
        physics.set_calibrated_effects(effects, 0.004)
        physics.set_actuator_model(Doubling())
        physics.set_voltage(2.0)
        applied = physics.applied_voltage()
        physics.close()
    assert applied == 3.0  # 2 (2 - 0.5), not 2 * 2 - 0.5


class Doubling:
    def __call__(self, volts):
        return 2.0 * volts

    def reset(self, volts, rows=None):
        pass
