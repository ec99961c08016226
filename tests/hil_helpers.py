"""A substitute board driven directly through the HIL API, as the hardware tests need it."""

from __future__ import annotations

import sys
import types

import numpy as np

from qube_suite.hardware import _hil_sim, conventions
from qube_suite.hardware.plant import ESTIMATED, named_plant

MOTOR = np.array([0], dtype=np.uint32)
ENCODERS = np.array([0, 1], dtype=np.uint32)
FLAGS = np.array([0, 1, 2], dtype=np.uint32)
TACHOMETER = np.array([14000], dtype=np.uint32)

ESTIMATED_PLANT = named_plant(ESTIMATED)
"""Every parameter of the estimated plant: the board's integrator with the values `plant.py` documents."""

CLEAN_PLANT = {**ESTIMATED_PLANT, "arm_friction": 0.0, "pendulum_friction": 0.0, "cable_stiffness": 0.0,
               "motor_inductance": 0.0, "bench_vibration": 0.0}
"""The plant reduced to the nominal model (what tests/reference_dynamics.py describes)."""


class Rig:
    """An open substitute board with the amplifier enabled and a reader task of every input running."""

    def __init__(self, plant=None, frequency=250.0, realtime=False, state=None, samples_in_buffer=1,
                 overflow_mode=_hil_sim.BufferOverflowMode.OVERWRITE_ON_OVERFLOW):
        self.board = _hil_sim.HIL("qube_servo2_usb", "0", plant=plant, realtime=realtime)
        if state is not None:
            self.board.set_true_state(state)
        self.board.write_digital(MOTOR, 1, np.array([1], dtype=np.int8))
        self.task = self.board.task_create_reader(samples_in_buffer, MOTOR, 1, ENCODERS, 2, FLAGS, 3,
                                                  TACHOMETER, 1)
        self.board.task_set_buffer_overflow_mode(self.task, overflow_mode)
        self.current = np.zeros(1)
        self.counts = np.zeros(2, dtype=np.int32)
        self.flags = np.zeros(3, dtype=np.int8)
        self.tachometer = np.zeros(1)
        self.board.task_start(self.task, _hil_sim.Clock.HARDWARE_CLOCK_0, frequency, _hil_sim.HIL.INFINITE)
        self.read()

    def read(self):
        """The next sample: (current A, counts, flags, tachometer counts/s), board signs."""
        self.board.task_read(self.task, 1, self.current, self.counts, self.flags, self.tachometer)
        return self.current[0], self.counts.copy(), self.flags.copy(), self.tachometer[0]

    def set_voltage(self, volts):
        """Apply the package's motor voltage `volts` (V)."""
        self.board.write_analog(MOTOR, 1, np.array([conventions.board_voltage(volts)]))

    def run(self, voltages):
        """True states after each zero-order-held package voltage, starting with the present one."""
        states = [self.board.true_state()]
        for v in voltages:
            self.set_voltage(v)
            self.read()
            states.append(self.board.true_state())
        return np.array(states)


def fake_quanser_sdk(monkeypatch) -> dict:
    """Install a `quanser.hardware` whose HIL is the substitute board; log what is made and opened."""
    log = {"created": [], "opened": []}

    class RecordingHIL(_hil_sim.HIL):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            log["created"].append(self)

        def open(self, card_type, card_identifier):
            log["opened"].append((card_type, card_identifier))
            super().open(card_type, card_identifier)

    quanser = types.ModuleType("quanser")
    hardware = types.ModuleType("quanser.hardware")
    enumerations = types.ModuleType("quanser.hardware.enumerations")
    hardware.HIL, hardware.HILError, hardware.Clock = RecordingHIL, _hil_sim.HILError, _hil_sim.Clock
    enumerations.BufferOverflowMode = _hil_sim.BufferOverflowMode
    quanser.hardware, hardware.enumerations = hardware, enumerations
    monkeypatch.setitem(sys.modules, "quanser", quanser)
    monkeypatch.setitem(sys.modules, "quanser.hardware", hardware)
    monkeypatch.setitem(sys.modules, "quanser.hardware.enumerations", enumerations)
    log["class"] = RecordingHIL
    return log
