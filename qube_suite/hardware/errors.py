"""Exceptions of the hardware path.

Every safety stop of `QuanserWrapper` writes 0 V to the motor, disables the
amplifier and stops the watchdog first (the board idles until `resume()`), and
then raises one of the `SafetyStopError` subclasses below; none of them is
printed and ignored. A board that cannot be opened raises `BoardOpenError`; a
board error while setting it up or reading a sample raises `BoardIOError`, with
the text of Quanser's `get_error_message()`, chained to the board's own
exception (`quanser.hardware.HILError`, or `HILError` of the substitute board).
"""

from __future__ import annotations


class HardwareError(Exception):
    """Base class of the hardware path's own exceptions."""


class QuanserSDKNotFoundError(HardwareError, ImportError):
    """A real board was asked for but Quanser's Python HIL API is not installed."""


class BoardOpenError(HardwareError):
    """The board could not be opened (not connected, not powered, or in use); nothing was driven."""


class NotAtRestError(HardwareError):
    """The encoders were to be zeroed at open, but the Qube was moving; the board was closed again."""


class BoardIOError(HardwareError):
    """The board reported an error while it was set up or read (Quanser's error text in the message);
    the wrapper stopped the motor first, as for a safety stop."""


class ResetError(HardwareError):
    """A reset did not bring the device to its episode's start within the reset timeout; its motors
    are at 0 V (the board stays open, its amplifier off once the environment closes). The episode
    never started: `evaluate` counts it as failed."""


class SafetyStopError(HardwareError):
    """The wrapper stopped the motor (0 V, amplifier disabled) for the reason in the subclass."""


class AmplifierFaultError(SafetyStopError):
    """The amplifier reports a fault (digital input 0), e.g. thermal shutdown."""


class MotorStallError(SafetyStopError):
    """The amplifier reports a stall error (digital input 2) and has disabled itself."""


class ArmLimitError(SafetyStopError):
    """The arm is farther from the centre than the wrapper's `arm_limit`."""


class WatchdogExpiredError(SafetyStopError):
    """The board's watchdog expired: the loop was too slow and the board zeroed its outputs."""


class MissedSamplesError(SafetyStopError):
    """More consecutive samples than `max_missed_samples` passed without being read."""


class EncoderGlitchError(SafetyStopError):
    """An encoder count jumped farther between two samples than the Qube can turn: the position
    reference is lost, so the board must be reopened with the Qube at its start position."""
