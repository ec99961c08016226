"""The substitute board with a device's own plant: two motors, four encoders, the wrapper's safety on
both outputs, the board's clock and watchdog unchanged."""

import math

import numpy as np
import pytest

from qube_suite.hardware import _hil_sim
from qube_suite.hardware.board_plant import BoardPlant, PlantChannels
from qube_suite.hardware.errors import WatchdogExpiredError
from qube_suite.hardware.quanser import Device, QuanserWrapper

TIME_CONSTANT = 0.05
"""Each toy motor's speed follows its voltage with this lag (s): d(speed)/dt = (V - speed) / tau."""

CHANNELS = PlantChannels(card_type="toy_twin_usb", analog_outputs=(0, 1), digital_outputs=(0, 1),
                         analog_inputs=(0, 1), encoder_inputs=(0, 1), other_inputs=(14000, 14001),
                         voltage_limit=12.0)

TOY = Device(board_type="toy_twin_usb", analog_outputs=(0, 1), digital_outputs=(0, 1), analog_inputs=(0, 1),
             encoder_inputs=(0, 1), other_inputs=(14000, 14001), led_outputs=(11000, 11001, 11002),
             amplifier_fault_inputs=(), stall_warning_inputs=(), stall_error_inputs=(), arm_encoder=None,
             radians_per_count=(0.01, 0.01))


class ToyPlant:
    """Two first-order motors, solved exactly; encoder counts of 0.01 rad, speeds in counts/s."""

    channels = CHANNELS

    def __init__(self):
        self.position = np.zeros(2)
        self.speed = np.zeros(2)
        self.calls = []

    def advance(self, seconds, volts, enabled):
        self.calls.append((seconds, volts.copy(), enabled.copy()))
        target = np.where(enabled, volts, self.speed)           # open circuit: the motor coasts
        decay = math.exp(-seconds / TIME_CONSTANT)
        moved = target * seconds + (self.speed - target) * TIME_CONSTANT * (1.0 - decay)
        self.position += np.where(enabled, moved, self.speed * seconds)
        self.speed = np.where(enabled, target + (self.speed - target) * decay, self.speed)

    def encoder_positions(self):
        return self.position / 0.01

    def analog_inputs(self):
        return self.speed * 0.001

    def other_inputs(self):
        return self.speed / 0.01

    def true_state(self):
        return np.concatenate([self.position, self.speed])

    def set_true_state(self, state):
        self.position, self.speed = np.array(state[:2]), np.array(state[2:])


def test_a_plant_with_the_protocol_is_recognised_and_a_dict_is_not():
    assert isinstance(ToyPlant(), BoardPlant)
    assert not isinstance({"arm_mass": 0.1}, BoardPlant)


def test_the_board_integrates_the_devices_plant_between_samples_exactly():
    plant = ToyPlant()
    with QuanserWrapper(TOY, frequency=100.0, plant=plant) as board:
        for _ in range(50):
            _, counts, others = board.action([3.0, -2.0])
        assert type(board.board.plant) is ToyPlant
    # 49 samples under (3, -2) V (the first action's sample was taken before it was written)
    t = 49 / 100.0
    expected = np.array([3.0, -2.0]) * (1.0 - math.exp(-t / TIME_CONSTANT))
    np.testing.assert_allclose(others / 100.0, expected, rtol=1e-9)
    moved = np.array([3.0, -2.0]) * (t - TIME_CONSTANT * (1.0 - math.exp(-t / TIME_CONSTANT)))
    np.testing.assert_array_equal(counts, np.floor(moved / 0.01))
    # the plant is called once per event (a sample or the watchdog's deadline), never per substep
    assert len(plant.calls) < 200


def test_refusals_idle_and_close_leave_both_motors_at_zero():
    plant = ToyPlant()
    board = QuanserWrapper(TOY, frequency=100.0, plant=plant)
    board.open()
    board.action([4.0, 5.0])
    np.testing.assert_array_equal(board.board.applied_voltage, [4.0, 5.0])
    with pytest.raises(ValueError, match="finite"):
        board.action([4.0, math.nan])
    np.testing.assert_array_equal(board.board.applied_voltage, [0.0, 0.0])
    with pytest.raises(ValueError, match="shape"):
        board.action([4.0])
    board.action([20.0, -20.0])                                     # clipped to max_voltage, both
    np.testing.assert_array_equal(board.board.applied_voltage, [10.0, -10.0])
    board.idle()
    np.testing.assert_array_equal(board.board.applied_voltage, [0.0, 0.0])
    assert not board.board.amplifier_enabled
    board.resume()
    board.action([1.0, 1.0])
    hil = board.board
    board.close()
    assert not hil.amplifier_enabled
    np.testing.assert_array_equal(hil.applied_voltage, [0.0, 0.0])


def test_the_watchdog_zeroes_both_outputs_and_disables_both_amplifiers():
    plant = ToyPlant()
    with QuanserWrapper(TOY, frequency=100.0, plant=plant, watchdog_timeout=0.035) as board:
        board.action([6.0, -6.0])
        board.board.stall(0.2)
        assert not board.board.amplifier_enabled
        seconds, volts, enabled = plant.calls[-1]
        assert not enabled.any() and not volts.any()
        with pytest.raises(WatchdogExpiredError):
            board.action([6.0, -6.0])
        # the plant ran under the voltages until the deadline exactly, not to the next sample
        driven = sum(s for s, v, e in plant.calls if e.all())
        assert driven == pytest.approx(0.035, abs=1e-9)


def test_the_channels_are_the_plants_and_its_card_is_checked():
    board = _hil_sim.HIL(plant=ToyPlant())
    with pytest.raises(_hil_sim.HILError, match="toy_twin_usb"):
        board.open("qube_servo2_usb", "0")
    board.open("toy_twin_usb", "0")
    with pytest.raises(_hil_sim.HILError, match="does not exist"):
        board.write_analog(np.array([2], dtype=np.uint32), 1, np.zeros(1))
    with pytest.raises(_hil_sim.HILError, match="does not exist"):
        board.read_digital(np.array([0], dtype=np.uint32), 1, np.zeros(1, dtype=np.int8))
    with pytest.raises(ValueError, match="Qube's arm"):
        board.block_arm(True)
    counts = np.zeros(1, dtype=np.int32)
    board.set_encoder_counts(np.array([1], dtype=np.uint32), 1, np.array([7], dtype=np.int32))
    board.read_encoder(np.array([1], dtype=np.uint32), 1, counts)
    assert counts[0] == 7
    board.close()


def test_an_unknown_card_is_refused():
    with pytest.raises(_hil_sim.HILError, match="unknown card type"):
        _hil_sim.HIL("no_such_card_usb", "0")


def test_a_wrapper_refuses_a_plant_of_another_card():
    with pytest.raises(ValueError, match="toy_twin_usb"):
        QuanserWrapper(dataclass_replace(TOY, board_type="other_usb"), plant=ToyPlant())


def dataclass_replace(device, **changes):
    import dataclasses

    return dataclasses.replace(device, **changes)
