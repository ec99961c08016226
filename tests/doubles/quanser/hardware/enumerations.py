"""Enumerations of Quanser's `quanser.hardware.enumerations` that the double knows.

Values from Quanser's documentation of `hil_task_set_buffer_overflow_mode`
(ERROR_ON_OVERFLOW 0, OVERWRITE_ON_OVERFLOW 1, DISCARD_ON_OVERFLOW 2) and of the
watchdog's digital expiration states (LOW, HIGH, TRISTATE, NO_CHANGE).
"""

import enum


class BufferOverflowMode(enum.IntEnum):
    ERROR_ON_OVERFLOW = 0
    OVERWRITE_ON_OVERFLOW = 1
    DISCARD_ON_OVERFLOW = 2


class DigitalState(enum.IntEnum):
    LOW = 0
    HIGH = 1
    TRISTATE = 2
    NO_CHANGE = 3
