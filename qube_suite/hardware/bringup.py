"""A guided bring-up of a Qube on its board: `qube-suite check-board`.

`check_board(...)` opens the board and, in order: checks the amplifier (enabled,
no fault, no stall flags); cycles the LED through red, green and blue; with a
person at the Qube (`interactive=True`), asks them to turn the arm and the
pendulum by hand and prints the signs the encoders see against the package's
conventions (θ positive counter-clockwise seen from above; α counting up as
encoder 1 counts up); applies a short, small voltage pulse (0.5 V for 0.2 s) and
checks that the arm turns the positive way and that the motor current has the
voltage's sign; compares the tachometer with the encoder's derivative over the
pulse; and closes the board with the motor at 0 V and the amplifier off, also
when a check fails or Ctrl-C lands. The board idles (0 V, amplifier off) while it
waits for the person.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np

from qube_suite.hardware import conventions
from qube_suite.hardware.quanser import DEVICES, SIMULATED, QuanserWrapper

PULSE_VOLTAGE = 0.5
"""Voltage (V, the package's sign) of the test pulse: above the dead zone, small enough to be safe."""

PULSE_TIME = 0.2
"""Length of the test pulse (s)."""

HAND_MOVE = math.radians(20.0)
"""How far (rad) a hand move must turn a joint to count."""

LED_COLOURS = {"red": (1.0, 0.0, 0.0), "green": (0.0, 1.0, 0.0), "blue": (0.0, 0.0, 1.0)}


@dataclasses.dataclass
class Check:
    """One step of the bring-up: its name, whether it passed (None: skipped) and what was seen."""

    name: str
    passed: bool | None
    detail: str


def check_board(board: str = SIMULATED, device: str = "qube_servo2", identifier: str = "0",
                frequency: float = 250.0, interactive: bool = False, ask: Callable[[str], str] = input,
                say: Callable[[str], None] = print, plant: dict[str, float] | None = None) -> list[Check]:
    """Run the bring-up (see the module docstring); `say` prints each result as it comes.

    `ask(prompt)` waits for the person (interactive only); `plant` sets the substitute's plant.
    Returns the checks; the board is closed at the end, whatever happened.
    """
    if device not in DEVICES:
        raise ValueError(f"unknown device {device!r}; valid: {', '.join(DEVICES)}")
    checks: list[Check] = []

    def report(name: str, passed: bool | None, detail: str) -> None:
        checks.append(Check(name, passed, detail))
        mark = "skipped" if passed is None else "ok" if passed else "FAILED"
        say(f"[{mark}] {name}: {detail}")

    options = {"plant": plant} if board == SIMULATED and plant is not None else {}
    qube = QuanserWrapper(DEVICES[device], board, identifier, frequency=frequency, arm_limit=math.radians(90),
                          **options)
    with qube:
        say(f"opened the {DEVICES[device].board_type} board {identifier!r} ({board})")
        _, _, _ = qube.action([0.0])
        flags = _digital_inputs(qube)
        fault = any(flags[c] for c in qube.device.amplifier_fault_inputs)
        stall = any(flags[c] for c in qube.device.stall_warning_inputs + qube.device.stall_error_inputs)
        report("amplifier", not fault and not stall,
               f"enabled; fault input {'set' if fault else 'clear'}, "
               f"stall inputs {'set' if stall else 'clear'}")
        for colour, rgb in LED_COLOURS.items():
            for _ in range(round(0.3 * frequency)):
                qube.action([0.0], led=rgb)
            if interactive:
                qube.idle()
                seen = ask(f"is the LED {colour}? [y/n] ").strip().lower()
                report(f"LED {colour}", seen.startswith("y"), f"the person saw {seen or 'nothing'}")
                qube.resume()
        if not interactive:
            report("LED", None, "cycled red, green, blue (non-interactive: nobody looked)")
        if interactive:
            qube.idle()
            _hand_check(qube, ask, report)
            qube.resume()
        else:
            report("encoder signs by hand", None, "non-interactive: nobody turned the arm or the pendulum")
        _pulse_check(qube, frequency, report)
    say("closed the board: 0 V, amplifier off")
    return checks


def _digital_inputs(qube: QuanserWrapper) -> dict[int, bool]:
    board, channels = qube.board, np.array(qube.device.digital_inputs, dtype=np.uint32)
    values = np.zeros(len(channels), dtype=np.int8)
    board.read_digital(channels, len(channels), values)
    return {int(c): bool(v) for c, v in zip(channels, values, strict=True)}


def _encoders(qube: QuanserWrapper) -> np.ndarray:
    board, channels = qube.board, np.array(qube.device.encoder_inputs, dtype=np.uint32)
    counts = np.zeros(len(channels), dtype=np.int32)
    board.read_encoder(channels, len(channels), counts)
    return counts


def _hand_check(qube: QuanserWrapper, ask, report) -> None:
    for joint, index, prompt, angle in (
            ("arm", 0, "turn the arm counter-clockwise (seen from above) by about 45 degrees and hold it",
             conventions.arm_angle),
            ("pendulum", 1, "turn the pendulum by about 45 degrees towards the side that the arm's counter-"
             "clockwise turn would swing it, and hold it", lambda c: conventions.PENDULUM_SIGN * c
             * conventions.RADIANS_PER_COUNT)):
        before = _encoders(qube)[index]
        ask(f"{prompt}, then press Enter ")
        after = _encoders(qube)[index]
        moved = angle(after) - angle(before)
        ask(f"let the {joint} go back to where it was, then press Enter ")
        if abs(moved) < HAND_MOVE:
            report(f"{joint} encoder", False, f"turned only {math.degrees(moved):.0f} degrees: "
                   "not moved, or the encoder is not connected")
        else:
            report(f"{joint} encoder", moved > 0, f"{math.degrees(moved):+.0f} degrees in the package's sign "
                   f"({after - before:+d} counts); expected positive")


def _pulse_check(qube: QuanserWrapper, frequency: float, report) -> None:
    steps = round(PULSE_TIME * frequency)
    volts = conventions.board_voltage(PULSE_VOLTAGE)
    thetas, currents, speeds = [], [], []
    for _ in range(steps):
        current, counts, others = qube.action([volts])
        thetas.append(conventions.arm_angle(int(counts[0])))
        currents.append(conventions.motor_current(float(current[0])))
        speeds.append(conventions.arm_velocity(float(others[0])))
    for _ in range(round(0.3 * frequency)):                        # let it stop
        qube.action([0.0])
    turned = thetas[-1] - thetas[0]
    report("voltage pulse direction", turned > 0, f"{PULSE_VOLTAGE:g} V for {PULSE_TIME:g} s turned the arm "
           f"{math.degrees(turned):+.1f} degrees; expected positive")
    mean_current = float(np.mean(currents))
    report("motor current sign", mean_current > 0, f"mean {1e3 * mean_current:+.0f} mA during the pulse; "
           "expected positive")
    derivative = np.gradient(np.array(thetas), 1.0 / frequency)
    tachometer = np.array(speeds)
    scale = max(float(np.max(np.abs(derivative))), 1e-6)
    error = float(np.median(np.abs(tachometer - derivative))) / scale
    report("tachometer", error < 0.25, f"median difference from the encoder's derivative {100 * error:.0f} % "
           f"of the peak speed {scale:.2f} rad/s; expected below 25 %")
