"""The excitation experiment: one minute of motion that shows every identifiable parameter.

It runs through a suite environment, so the same code drives the simulation, the
substitute board and a real Qube, and it is recorded in the ordinary recording
format (`qube_suite.recording`; on hardware with the board's raw readings: encoder
counts and motor current). Three phases, each with the arm kept near the centre:

1. arm excitation, pendulum hanging (40 % of the time): a multisine voltage
   (0.2 to 3 Hz, random phases from `seed`) on top of a soft spring-damper that
   keeps the arm within about +-45 degrees. The motor current against the voltage
   separates the motor's resistance and back-EMF; the arm's response to the current
   gives its inertia, damping, Coulomb friction and the cable's spring.
2. energy pumping (35 %): a smooth pump, PUMP_VOLTAGE tanh(alpha' cos(alpha) / w),
   fading as the pendulum's energy nears that of swings of about 120 degrees from
   hanging, never over the top: the swing frequency gives the pendulum's length,
   its reaction on the arm its mass. (Smooth because the fit differentiates the
   angles: a bang-bang pump would put more into the accelerations than a 60 ms
   smoothing window can follow.)
3. free decay (25 %): 0 V, the pendulum's swing dies out by its own damping and
   friction while the arm is pushed about by the reaction.

Safety: the voltage never exceeds `EXCITATION_VOLTAGE` (6 V, 0.7 A on a nominal
Qube, far below the amplifier's 1.8 A limit) and a stiffer spring takes over beyond
`SAFE_ARM_ANGLE` (60 degrees), well inside the tasks' +-90 degrees.
"""

from __future__ import annotations

import datetime
import math
import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from qube_suite import suite
from qube_suite.capabilities import HasBoard
from qube_suite.devices.qube.controllers.model import RigidBodyModel
from qube_suite.recording import Recorder

EXCITATION_VOLTAGE = 6.0
"""Largest motor voltage of the experiment (V)."""
SAFE_ARM_ANGLE = math.radians(60.0)
"""Beyond this arm angle (rad) a stiff spring pulls the arm back."""
SAFETY_SPRING = 40.0
"""That spring (V/rad beyond SAFE_ARM_ANGLE)."""
ARM_SPRING = 8.0
"""Centring spring on the arm (V/rad) during the arm excitation."""
ARM_DAMPER = 0.4
"""Centring damper on the arm (V s/rad) during the arm excitation."""
MULTISINE_VOLTAGE = 2.5
"""RMS of the multisine (V) during the arm excitation."""
MULTISINE_FREQUENCIES = np.geomspace(0.2, 3.0, 9)
"""Frequencies of the multisine (Hz)."""
PUMP_ARM_SPRING = 3.0
"""Centring spring on the arm (V/rad) while pumping: softer, so as not to absorb the swing."""
PUMP_VOLTAGE = 5.0
"""Largest voltage of the pump (V)."""
PUMP_PHASE_SPEED = 1.0
"""w (rad/s): alpha' cos(alpha) at which the pump reaches 76 % of its voltage."""
PUMP_ENERGY = 0.75
"""Pendulum energy the pump stops at, as a fraction of 2 mp g l above hanging at rest (0.75: swings
to 120 degrees from hanging)."""
PHASES = (("arm excitation", 0.40), ("energy pumping", 0.35), ("free decay", 0.25))
"""The experiment's phases and their shares of its duration."""
EXPERIMENT = "qube_suite.calibration.experiment"
"""The recording header's `experiment` value that marks a calibration experiment."""
MAX_SECONDS = 60.0
"""Longest experiment (s of board time)."""


class Excitation:
    """The experiment's voltage as a function of time (s) and measured state (see the module).

    Args:
        seconds: the experiment's duration (s).
        seed: draws the multisine's phases.
    """

    def __init__(self, seconds: float, seed: int = 0):
        self.seconds = float(seconds)
        rng = np.random.default_rng(seed)
        self._phases = rng.uniform(0.0, 2.0 * math.pi, len(MULTISINE_FREQUENCIES))
        self._amplitude = MULTISINE_VOLTAGE * math.sqrt(2.0 / len(MULTISINE_FREQUENCIES))
        self._model = RigidBodyModel.from_parameters()
        shares = np.cumsum([share for _, share in PHASES])
        self.phase_ends = tuple(float(end) * self.seconds for end in shares)

    def phase(self, time: float) -> str:
        """Name of the phase at `time` (s)."""
        for (name, _), end in zip(PHASES, self.phase_ends, strict=True):
            if time < end:
                return name
        return PHASES[-1][0]

    def __call__(self, time: float, state: np.ndarray) -> float:
        """Motor voltage (V) at `time` (s) in `state` [theta, alpha, dtheta, dalpha]."""
        theta, alpha, dtheta, dalpha = (float(x) for x in state)
        phase = self.phase(time)
        if phase == "arm excitation":
            fade = min(1.0, time / 1.0, (self.phase_ends[0] - time) / 1.0)  # no step at either end
            signal = self._amplitude * float(np.sum(np.sin(2.0 * math.pi * MULTISINE_FREQUENCIES * time
                                                           + self._phases)))
            volts = fade * signal - ARM_SPRING * theta - ARM_DAMPER * dtheta
        elif phase == "energy pumping":
            model = self._model
            energy = (0.5 * model.pendulum_inertia * dalpha**2  # 0 hanging at rest, 1 upright at rest
                      + model.gravity_torque * (math.cos(alpha) + 1.0)) / model.swing_up_energy
            fade = min(max((PUMP_ENERGY - energy) / 0.1, 0.0), 1.0)
            volts = (fade * PUMP_VOLTAGE * math.tanh(dalpha * math.cos(alpha) / PUMP_PHASE_SPEED)
                     - PUMP_ARM_SPRING * theta - ARM_DAMPER * dtheta)
        else:
            volts = 0.0
        excess = abs(theta) - SAFE_ARM_ANGLE
        if excess > 0.0:
            volts -= math.copysign(SAFETY_SPRING * excess, theta) + ARM_DAMPER * dtheta
        return min(max(volts, -EXCITATION_VOLTAGE), EXCITATION_VOLTAGE)


def run(path: str | os.PathLike, domain: str = "qube_hardware",
        domain_kwargs: Mapping[str, Any] | None = None, seconds: float = MAX_SECONDS, seed: int = 0) -> str:
    """Run the excitation experiment on `domain` and record it to `path`; return the path.

    `domain_kwargs` go to `suite.load` untouched (board, device, plant, ...). The Qube
    starts hanging at rest (on hardware the reset controllers settle it first). If the
    experiment does not finish (a board error, a safety stop, Ctrl-C), the recording is removed.
    Raises ValueError for a duration outside (0, 60] s.
    """
    if not 0.0 < seconds <= MAX_SECONDS:
        raise ValueError(f"seconds must be in (0, {MAX_SECONDS:g}], got {seconds!r}")
    excitation = Excitation(seconds, seed)
    environment = suite.load(domain, "swingup",
                             task_kwargs={"random": seed, "voltage_limit": EXCITATION_VOLTAGE},
                             environment_kwargs={"time_limit": seconds}, domain_kwargs=domain_kwargs)
    metadata = {"experiment": EXPERIMENT, "domain": domain, "seed": seed, "seconds": seconds,
                "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
                **board_metadata(environment.physics)}
    try:
        with Recorder(path, environment, metadata=metadata):
            timestep = environment.reset(seed=seed)
            while not timestep.last():
                state = timestep.observation["state"]
                timestep = environment.step([excitation(environment.physics.time(), state)])
    except BaseException:
        os.remove(path)  # an unfinished experiment cannot calibrate: leave nothing behind
        raise
    finally:
        environment.close()
    return os.fspath(path)


def board_metadata(physics: Any) -> dict[str, Any]:
    """Board type, board name and identifier of a hardware domain's physics; the simulation's otherwise."""
    if not isinstance(physics, HasBoard):
        return {"board_type": "simulation", "board": "simulation", "identifier": None}
    qube = physics.qube
    return {"board_type": qube.device.board_type, "board": qube.board_name, "identifier": qube.identifier}
