"""The simulated disk-loaded Qube: MuJoCo physics of `scene.xml` (this folder) in the disk's terms.

`make_physics(control_frequency, parameters)` builds a `Physics` whose timestep divides the
control period, with the parameter table (`parameters.py`, by long name) written into the
compiled model.
"""

from __future__ import annotations

import contextlib
import pathlib
from collections.abc import Mapping, Sequence
from typing import Any

import mujoco
import numpy as np
from dm_control import mujoco as dm_mujoco

from qube_suite.arguments import keywords_of
from qube_suite.devices.qube import parameters as shared_parameters
from qube_suite.devices.qube.simulation import check_control_frequency, physics_timestep
from qube_suite.devices.qube_disk import parameters as disk_parameters
from qube_suite.devices.qube_disk.conventions import MAX_SPEED, STATE_NAMES
from qube_suite.domains.effects import Effects
from qube_suite.domains.interface import SimulationLifecycle

FOLDER = pathlib.Path(__file__).resolve().parent
MODEL_PATH = FOLDER / "model.xml"
"""The disk-loaded Qube alone: body, joint, actuator, keyframe `rest`."""

SCENE_PATH = FOLDER / "scene.xml"
"""The disk-loaded Qube on a bench with lights and cameras."""


class Physics(SimulationLifecycle, dm_mujoco.Physics):
    """MuJoCo physics of the disk-loaded Qube with accessors that read like it.

    The domain interface of the disk (`DiskPhysics` in `qube_suite.devices.qube_disk.tasks`):
    `disk_angle`, `disk_velocity`, `qube_state`, `voltage`, `applied_voltage`, `set_voltage`,
    `set_led`, `led`, `reset_to`, `time`, `timestep`, `step`, `end_episode`, `drawable`, `close`;
    randomization's voltage effects through `set_actuator_model`.
    A step after which the disk turns implausibly fast (beyond `MAX_SPEED`, inf or NaN) is undone
    and `physics_error` says so until the next reset.
    """

    latency_steps = 0
    """A step applies its voltage at once."""

    state_names = STATE_NAMES
    """The entries of `qube_state()`: what recordings name their state columns."""

    physics_error: str | None = None

    def _reload_from_data(self, data) -> None:
        super()._reload_from_data(data)
        model = self.model.ptr
        self._model_ptr, self._data_ptr = model, self.data.ptr
        self._joint = model.joint("disk").id
        self._qpos_at, self._dof_at = model.jnt_qposadr[self._joint], model.jnt_dofadr[self._joint]
        self._led_rgba = model.geom_rgba[model.geom("led").id]
        self._led = tuple(float(x) for x in self._led_rgba[:3])
        self._voltage = 0.0
        self._effects = Effects()
        if not hasattr(self, "_parameters"):
            self._parameters = dict(disk_parameters.NOMINAL)

    # -- parameters -----------------------------------------------------------------

    @property
    def parameters(self) -> Mapping[str, float]:
        """Physical parameters in effect, by long name."""
        return dict(self._parameters)

    def set_parameters(self, overrides: Mapping[str, float] | None = None) -> None:
        """Set every parameter to its nominal value updated by `overrides` (by long name), in place.
        Raises ValueError for an unknown name or an impossible value; the model is unchanged then."""
        values = disk_parameters.resolve(overrides)
        write_parameters(self._model_ptr, values)
        self._parameters = values
        mujoco.mj_forward(self._model_ptr, self._data_ptr)

    # -- the disk's interface -------------------------------------------------------

    def disk_angle(self) -> float:
        """theta (rad), not wrapped."""
        return float(self._data_ptr.qpos[self._qpos_at])

    def disk_velocity(self) -> float:
        """dtheta/dt (rad/s), exact."""
        return float(self._data_ptr.qvel[self._dof_at])

    def qube_state(self) -> np.ndarray:
        """The disk-loaded Qube's state [theta, dtheta] (rad, rad/s), as a new array: what episode traces
        record (`conventions.STATE_NAMES`)."""
        return np.array([self.disk_angle(), self.disk_velocity()])

    def voltage(self) -> float:
        """Motor voltage (V) commanded by the last `set_voltage`."""
        return self._voltage

    def applied_voltage(self) -> float:
        """Motor voltage (V) the simulated motor receives: the command after actuator effects."""
        return float(self._data_ptr.ctrl[0])

    def set_voltage(self, volts: float) -> None:
        """Command `volts` to the motor until the next call."""
        self._voltage = volts
        self._data_ptr.ctrl[0] = self._effects.actuate(volts)

    def set_actuator_model(self, actuator_model) -> None:
        """Drive the motor with `actuator_model(volts) -> volts`, called once per `set_voltage`; None: as
        commanded. A `reset(volts)` method, if present, is called with 0 V when an episode starts
        (`qube_suite.domains.effects`)."""
        self._effects.actuator = actuator_model

    def motor_current(self) -> float:
        """Motor current (A), (V - km dtheta) / Rm; inductance neglected."""
        p = self._parameters
        return (self.applied_voltage() - p["motor_back_emf"] * self.disk_velocity()) / p["motor_resistance"]

    def set_led(self, rgb: Sequence[float]) -> None:
        """Colour the LED strip, (r, g, b) in [0, 1]."""
        self._led = rgb

    def led(self) -> tuple[float, float, float]:
        """The LED strip's (r, g, b)."""
        r, g, b = self._led
        return float(r), float(g), float(b)

    def drawable(self) -> Physics:
        """This physics with the LED colour written into the model, for renderers."""
        self._led_rgba[:3] = self._led
        return self

    def reset_to(self, state: Sequence[float]) -> None:
        """Set [theta, dtheta] exactly."""
        theta, dtheta = (float(x) for x in state)
        self.physics_error = None
        self._data_ptr.qpos[self._qpos_at] = theta
        self._data_ptr.qvel[self._dof_at] = dtheta
        mujoco.mj_forward(self._model_ptr, self._data_ptr)

    def step(self, nstep: int = 1) -> None:
        """Advance `nstep` physics timesteps with the voltage held; a diverged step is undone."""
        before, time = self.qube_state(), self._data_ptr.time
        mujoco.mj_step(self._model_ptr, self._data_ptr, nstep)
        speed = self.disk_velocity()
        if not abs(speed) <= MAX_SPEED:  # also NaN
            self.reset_to(before)
            self._data_ptr.time = time + nstep * self._model_ptr.opt.timestep
            self.physics_error = (f"the simulation diverged at t = {self._data_ptr.time:.3f} s "
                                  f"(speed {speed} rad/s); the step was undone")

    @contextlib.contextmanager
    def reset_context(self):
        """Time, state and control reset (0 V); the caller sets the start (`reset_to`)."""
        if self.closed:
            raise RuntimeError("the simulated disk is closed; make a new environment to run episodes")
        mujoco.mj_resetData(self._model_ptr, self._data_ptr)
        self._voltage = 0.0
        self._effects.restart_actuation()
        self.physics_error = None
        yield
        mujoco.mj_forward(self._model_ptr, self._data_ptr)


def write_parameters(model: mujoco.MjModel, values: Mapping[str, float]) -> None:
    """Write a full parameter table (by long name) into the compiled `model`, in place."""
    joint = model.joint("disk").id
    dof, body = model.jnt_dofadr[joint], model.body("disk").id
    mass, radius = values["disk_mass"], values["disk_radius"]
    model.body_mass[body] = mass
    model.body_inertia[body] = (0.25 * mass * radius**2, 0.25 * mass * radius**2,
                                disk_parameters.disk_inertia(mass, radius))
    model.dof_armature[dof] = values["rotor_inertia"] + values["hub_inertia"]
    model.dof_damping[dof] = values["disk_damping"]
    model.dof_frictionloss[dof] = values["disk_friction"]
    if values["disk_friction"] > 0.0:
        model.opt.disableflags &= ~mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    gain = values["motor_torque_constant"] / values["motor_resistance"]
    actuator = model.actuator("motor").id
    model.actuator_gainprm[actuator, 0] = gain
    model.actuator_biasprm[actuator, 2] = -gain * values["motor_back_emf"]


def make_physics(control_frequency: float = 250.0, parameters: Mapping[str, float] | Any = None) -> Physics:
    """A simulated disk-loaded Qube for control at `control_frequency` (Hz) with `parameters` by long
    name (see `qube_suite.devices.qube_disk.parameters`), or a calibration file's path."""
    check_control_frequency(control_frequency)
    physics = Physics.from_xml_path(str(SCENE_PATH))
    physics.model.opt.timestep = physics_timestep(control_frequency)
    physics.set_parameters(shared_parameters.values_of(parameters))
    return physics


DOMAIN_KWARGS = keywords_of(make_physics, skip=("control_frequency",))
"""Keys `suite.load`'s `domain_kwargs` may hold for this domain."""

