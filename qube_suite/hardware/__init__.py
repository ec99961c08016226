"""The hardware path: Quanser boards (real, or the compiled substitute) behind a safe wrapper.

    from qube_suite.hardware import QubeServo2

    with QubeServo2(frequency=250) as qube:              # board="simulated": the substitute
        currents, encoders, others = qube.action([0.5])   # volts in, raw board readings out

Modules: `quanser` (the wrapper and device declarations), `_hil_sim` (the
substitute board and its plant, compiled), `plant` (the plant's parameters),
`conventions` (board signals vs the package's angles), `estimation` (angles and
filtered velocities from encoder counts), `errors` (safety stops).
"""

from qube_suite.hardware.errors import (
    AmplifierFaultError,
    ArmLimitError,
    BoardIOError,
    BoardOpenError,
    EncoderGlitchError,
    HardwareError,
    MissedSamplesError,
    MotorStallError,
    NotAtRestError,
    QuanserSDKNotFoundError,
    ResetError,
    SafetyStopError,
    WatchdogExpiredError,
)
from qube_suite.hardware.estimation import StateEstimator, VelocityFilter
from qube_suite.hardware.quanser import (
    DEVICES,
    QUBE_SERVO_2,
    QUBE_SERVO_3,
    Device,
    QuanserWrapper,
    QubeServo2,
    QubeServo3,
)

__all__ = [
    "DEVICES", "QUBE_SERVO_2", "QUBE_SERVO_3", "AmplifierFaultError", "ArmLimitError", "BoardIOError",
    "BoardOpenError", "Device",
    "EncoderGlitchError", "HardwareError",
    "MissedSamplesError", "MotorStallError", "NotAtRestError", "QuanserSDKNotFoundError", "QuanserWrapper",
    "QubeServo2",
    "QubeServo3", "ResetError", "SafetyStopError", "StateEstimator", "VelocityFilter", "WatchdogExpiredError",
]
