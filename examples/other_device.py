"""Declare another Quanser device and drive it through the same safe wrapper.

A device is a channel declaration (`qube_suite.hardware.Device`); `QuanserWrapper`
does the rest for any of them: opening, zeroing, the watchdog, safety stops and
the sampling loop. Here: a Qube-Servo 2 carrying Quanser's inertia-disk module
instead of the pendulum, so only the motor's encoder, its tachometer and its
current are read. The code runs on the substitute board (`board="simulated"`,
whose plant is the Qube with its pendulum: the disk's different inertia is not
simulated) and, unchanged but for `board="qube_servo2_usb"`, on a real Qube.

    python examples/other_device.py [--volts 1.0] [--short]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from qube_suite.hardware import Device, QuanserWrapper, conventions

INERTIA_DISK = Device(
    board_type="qube_servo2_usb",       # the same QUARC card as the pendulum module
    analog_outputs=(0,),                # motor voltage (V)
    digital_outputs=(0,),               # amplifier enable
    analog_inputs=(0,),                 # motor current (A)
    encoder_inputs=(0,),                # the motor's encoder only: the module has no second one
    other_inputs=(14000,),              # tachometer (counts/s)
    led_outputs=(11000, 11001, 11002),  # LED red, green, blue
    amplifier_fault_inputs=(0,),
    stall_warning_inputs=(1,),
    stall_error_inputs=(2,),
    arm_encoder=0,                      # the encoder watched by arm_limit
)
"""Qube-Servo 2 with the inertia-disk module."""


def step_response(volts: float, seconds: float, frequency: float = 500.0) -> tuple[np.ndarray, np.ndarray]:
    """Apply `volts` (V, the package's sign: positive turns counter-clockwise seen from above) for
    `seconds` and return the sample times (s) and the tachometer's speed (rad/s)."""
    samples = round(seconds * frequency)
    speeds = np.empty(samples)
    # The disk may turn freely: no arm limit.
    with QuanserWrapper(INERTIA_DISK, board="simulated", frequency=frequency, arm_limit=None) as disk:
        for k in range(samples):
            currents, encoders, others = disk.action([conventions.board_voltage(volts)], led=(0.0, 0.0, 1.0))
            speeds[k] = conventions.arm_velocity(float(others[0]))
        turned = math.degrees(conventions.arm_angle(int(encoders[0])))
    print(f"{volts:g} V for {seconds:g} s: turned {turned:.0f} deg, drew {abs(currents[0]):.3f} A at the end")
    return np.arange(samples) / frequency, speeds


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--volts", type=float, default=1.0, help="step voltage (V)")
    parser.add_argument("--short", action="store_true", help="0.2 s instead of 1 s")
    args = parser.parse_args(argv)
    times, speeds = step_response(args.volts, 0.2 if args.short else 1.0)
    last = times >= times[-1] - 0.05
    print(f"tachometer: {speeds[last].mean():.1f} rad/s over the last 50 ms, "
          f"fastest {np.abs(speeds).max():.1f} rad/s")


if __name__ == "__main__":
    main()
