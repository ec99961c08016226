"""The simulated Aero 2: MuJoCo physics of `scene.xml` (this folder) in the Aero's terms.

`make_physics(control_frequency, parameters, configuration)` builds a `Physics` whose timestep
divides the control period, in the 2-DOF helicopter configuration or the 1-DOF pitch
configuration, with the parameter table (`parameters.py`, by long name) written into the compiled
model.

How the thrusters are modelled. Each rotor (motor rotor, hub and propeller) is a body on a hinge
joint of the beam, driven by a MuJoCo actuator that is the DC motor, torque kt (V - km w) / Rm,
so MuJoCo integrates the rotor speed (the first-order lag from voltage to speed, 0.15 s) and
applies the motor's reaction torque to the beam, and the spinning rotors' gyroscopic torques come
with the rigid-body dynamics. The propeller's aerodynamics, thrust kf w along the thrust site's z
axis and drag torque -kd w about the shaft, are forces from the air, not between rotor and beam:
no MuJoCo actuator or joint damping gives them (an actuator's force acts on its own transmission,
a joint's damping on both bodies it joins). `Physics.step` computes them from the rotor speeds
before every physics step and applies them to the rotor bodies (`xfrc_applied`), held over that
step.
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
from qube_suite.devices.aero2 import parameters as aero_parameters
from qube_suite.devices.aero2.conventions import (
    MAX_BODY_SPEED,
    MAX_ROTOR_SPEED,
    STATE_NAMES,
    check_configuration,
)
from qube_suite.devices.qube import parameters as shared_parameters
from qube_suite.devices.qube.simulation import check_control_frequency, physics_timestep
from qube_suite.domains.effects import Effects
from qube_suite.domains.interface import SimulationLifecycle

FOLDER = pathlib.Path(__file__).resolve().parent
MODEL_PATH = FOLDER / "model.xml"
"""The Aero 2 alone, 2-DOF configuration: bodies, joints, motors, keyframe `rest`."""

SCENE_PATH = FOLDER / "scene.xml"
"""The Aero 2 on a bench with lights and cameras."""

ROTOR_MASS = 0.01
"""Mass (kg) of each spinning assembly, part of the body's mass."""

BEAM_ROLL_INERTIA = 0.002
"""The beam's inertia (kg m^2) about its own axis: no joint turns it, any plausible value will do."""

ROTORS = ("front", "back")
"""The thrusters, in the order of the action and the rotor speeds."""


def mass_distribution(values: Mapping[str, float], configuration: str) -> dict[str, float]:
    """The beam's and the yoke's mass properties that make the whole body match the table.

    Returns `beam_mass` (kg), `beam_com_depth` (m below the pitch axis), `beam_inertia` (kg m^2,
    about its centre of mass, the same about its pitch and yaw axes) and `yoke_inertia` (kg m^2,
    about the yaw axis), so that the body (beam and rotors, rotors locked, level) has mass Mb, its
    centre of mass Dm below the pitch axis, inertia Jp about the pitch axis and, with the yoke, Jy
    about the yaw axis. Raises ValueError when the table leaves the beam or the yoke no inertia.
    """
    spin = aero_parameters.rotor_assembly_inertia(values)
    arm = values["thrust_arm"]
    beam_mass = values["body_mass"] - 2.0 * ROTOR_MASS
    depth = values["body_mass"] * values["center_of_mass_offset"] / beam_mass
    # Each rotor is a thin disc: its spin inertia about its shaft, half of it about the other axes.
    # The front shaft is vertical; the back one is along the pitch axis (2-DOF) or vertical (1-DOF).
    back_about_pitch = spin if configuration == "2dof" else 0.5 * spin
    back_about_yaw = 0.5 * spin if configuration == "2dof" else spin
    rotors_about_pitch = 2.0 * ROTOR_MASS * arm**2 + 0.5 * spin + back_about_pitch
    rotors_about_yaw = 2.0 * ROTOR_MASS * arm**2 + spin + back_about_yaw
    beam_inertia = values["pitch_inertia"] - beam_mass * depth**2 - rotors_about_pitch
    yoke_inertia = values["yaw_inertia"] - beam_inertia - rotors_about_yaw
    if beam_inertia <= BEAM_ROLL_INERTIA or yoke_inertia <= 0.0:
        raise ValueError(f"pitch_inertia {values['pitch_inertia']} and yaw_inertia {values['yaw_inertia']} "
                         "kg m^2 leave the beam or the yoke no inertia of their own: the yaw inertia must "
                         "exceed the pitch inertia by the rotors' share")
    return {"beam_mass": beam_mass, "beam_com_depth": depth, "beam_inertia": beam_inertia,
            "yoke_inertia": yoke_inertia}


class Physics(SimulationLifecycle, dm_mujoco.Physics):
    """MuJoCo physics of the Aero 2 with accessors that read like it.

    The Aero's domain interface (`Aero2Physics` in `qube_suite.devices.aero2.tasks`): `pitch`, `yaw`,
    `pitch_velocity`, `yaw_velocity`, `rotor_speeds`, `qube_state`, `voltage`, `applied_voltage`,
    `set_voltage`, `set_led`, `led`, `reset_to`, `time`, `step`, `end_episode`, `stop_motor`,
    `drawable`, `close`; randomization's voltage effects through `set_actuator_model`.
    A step after which the Aero moves implausibly fast (beyond `MAX_BODY_SPEED` or
    `MAX_ROTOR_SPEED`, inf or NaN) is undone and `physics_error` says so until the next reset.
    """

    latency_steps = 0
    """A step applies its voltages at once."""

    state_names = STATE_NAMES
    """The entries of `qube_state()`: what recordings name their state columns."""

    physics_error: str | None = None

    def _reload_from_data(self, data) -> None:
        super()._reload_from_data(data)
        model = self.model.ptr
        self._model_ptr, self._data_ptr = model, self.data.ptr
        names = [model.joint(i).name for i in range(model.njnt)]
        self.configuration = "2dof" if "yaw" in names else "pitch_only"
        pitch = model.joint("pitch").id
        self._pitch_q, self._pitch_v = model.jnt_qposadr[pitch], model.jnt_dofadr[pitch]
        if self.configuration == "2dof":
            yaw = model.joint("yaw").id
            self._yaw_q, self._yaw_v = model.jnt_qposadr[yaw], model.jnt_dofadr[yaw]
        rotors = [model.joint(f"{rotor}_rotor").id for rotor in ROTORS]
        self._rotor_joints = np.array(rotors)
        self._rotor_q = model.jnt_qposadr[rotors]
        self._rotor_v = model.jnt_dofadr[rotors]
        self._rotor_bodies = np.array([model.body(f"{rotor}_rotor").id for rotor in ROTORS])
        self._thrust_sites = np.array([model.site(f"{rotor}_thrust").id for rotor in ROTORS])
        self._motors = np.array([model.actuator(f"{rotor}_motor").id for rotor in ROTORS])
        self._led_rgba = model.geom_rgba[model.geom("led").id]
        self._led = tuple(float(x) for x in self._led_rgba[:3])
        self._voltage = np.zeros(2)
        self._effects = Effects()
        if not hasattr(self, "_parameters"):
            self._parameters = dict(aero_parameters.NOMINAL)

    # -- parameters -----------------------------------------------------------------

    @property
    def parameters(self) -> Mapping[str, float]:
        """Physical parameters in effect, by long name."""
        return dict(self._parameters)

    def set_parameters(self, overrides: Mapping[str, float] | None = None) -> None:
        """Set every parameter to its nominal value updated by `overrides` (by long name), in place.
        Raises ValueError for an unknown name or an impossible value; the model is unchanged then."""
        values = aero_parameters.resolve(overrides)
        write_parameters(self._model_ptr, values, self.configuration)
        self._parameters = values
        mujoco.mj_forward(self._model_ptr, self._data_ptr)

    # -- the Aero's interface -------------------------------------------------------

    def pitch(self) -> float:
        """Pitch (rad), positive front up, 0 level."""
        return float(self._data_ptr.qpos[self._pitch_q])

    def yaw(self) -> float:
        """Yaw (rad), positive counter-clockwise seen from above, not wrapped; 0 when locked."""
        return float(self._data_ptr.qpos[self._yaw_q]) if self.configuration == "2dof" else 0.0

    def pitch_velocity(self) -> float:
        """Pitch rate (rad/s), exact."""
        return float(self._data_ptr.qvel[self._pitch_v])

    def yaw_velocity(self) -> float:
        """Yaw rate (rad/s), exact; 0 when locked."""
        return float(self._data_ptr.qvel[self._yaw_v]) if self.configuration == "2dof" else 0.0

    def rotor_speeds(self) -> np.ndarray:
        """Front and back rotor speeds (rad/s), exact, as a new array of shape (2,)."""
        return self._data_ptr.qvel[self._rotor_v].copy()

    def qube_state(self) -> np.ndarray:
        """[pitch, yaw, pitch rate, yaw rate, front rotor speed, back rotor speed] (rad, rad/s), as a new
        array: what episode traces record (`conventions.STATE_NAMES`)."""
        return np.array([self.pitch(), self.yaw(), self.pitch_velocity(), self.yaw_velocity(),
                         *self._data_ptr.qvel[self._rotor_v]])

    def voltage(self) -> np.ndarray:
        """(front, back) voltages (V) commanded by the last `set_voltage`, as a new array."""
        return self._voltage.copy()

    def applied_voltage(self) -> np.ndarray:
        """(front, back) voltages (V) the simulated motors receive: the command after actuator effects."""
        return self._data_ptr.ctrl[self._motors].copy()

    def set_voltage(self, volts: Sequence[float] | np.ndarray) -> None:
        """Command the (front, back) voltages (V) until the next call. Raises ValueError unless `volts`
        is two finite numbers."""
        volts = np.array(volts, dtype=np.float64)
        if volts.shape != (2,) or not np.isfinite(volts).all():
            raise ValueError(f"the Aero takes two finite voltages (front, back), got {volts!r}")
        self._voltage = volts
        self._data_ptr.ctrl[self._motors] = self._effects.actuate(volts)

    def set_actuator_model(self, actuator_model) -> None:
        """Drive the motors with `actuator_model(volts) -> volts` (arrays of shape (2,)), called once per
        `set_voltage`; None: as commanded. A `reset(volts)` method, if present, is called with 0 V when
        an episode starts (`qube_suite.domains.effects`)."""
        self._effects.actuator = actuator_model

    def motor_currents(self) -> np.ndarray:
        """Front and back motor currents (A), (V - km w) / Rm; inductance neglected."""
        p = self._parameters
        return (self.applied_voltage() - p["motor_back_emf"] * self.rotor_speeds()) / p["motor_resistance"]

    def thrusts(self) -> np.ndarray:
        """Front and back propeller thrusts (N), kf w, along their thrust sites' z axes."""
        return self._parameters["thrust_constant"] * self.rotor_speeds()

    def set_led(self, rgb: Sequence[float]) -> None:
        """Colour the LED, (r, g, b) in [0, 1]."""
        self._led = rgb

    def led(self) -> tuple[float, float, float]:
        """The LED's (r, g, b)."""
        r, g, b = self._led
        return float(r), float(g), float(b)

    def drawable(self) -> Physics:
        """This physics with the LED colour written into the model, for renderers."""
        self._led_rgba[:3] = self._led
        return self

    def reset_to(self, state: Sequence[float]) -> None:
        """Set the state of `STATE_NAMES` exactly; the rotors' angles to 0. Raises ValueError for a state
        of another length, or with a yaw or yaw rate in the pitch-only configuration (yaw is locked)."""
        state = np.array(state, dtype=np.float64)
        if state.shape != (len(STATE_NAMES),) or not np.isfinite(state).all():
            raise ValueError(f"an Aero state is {len(STATE_NAMES)} finite numbers {STATE_NAMES}, "
                             f"got {state!r}")
        pitch, yaw, pitch_rate, yaw_rate, front, back = (float(x) for x in state)
        data = self._data_ptr
        if self.configuration == "2dof":
            data.qpos[self._yaw_q], data.qvel[self._yaw_v] = yaw, yaw_rate
        elif yaw != 0.0 or yaw_rate != 0.0:
            raise ValueError(f"the pitch-only Aero's yaw is locked: yaw and yaw rate must be 0, got {yaw}, "
                             f"{yaw_rate}")
        self.physics_error = None
        data.qpos[self._pitch_q], data.qvel[self._pitch_v] = pitch, pitch_rate
        data.qpos[self._rotor_q] = 0.0
        data.qvel[self._rotor_v] = (front, back)
        mujoco.mj_forward(self._model_ptr, data)

    def _apply_aerodynamics(self) -> None:
        """Thrust kf w along each thrust site's z axis and drag -kd w about each shaft, on the rotor
        bodies, from the rotor speeds and the pose now."""
        data, p = self._data_ptr, self._parameters
        speeds = data.qvel[self._rotor_v]
        thrust_axes = data.site_xmat[self._thrust_sites].reshape(-1, 3, 3)[:, :, 2]
        shaft_axes = data.xaxis[self._rotor_joints]
        forces = data.xfrc_applied[self._rotor_bodies]
        forces[:, :3] = p["thrust_constant"] * speeds[:, None] * thrust_axes
        forces[:, 3:] = -p["propeller_drag"] * speeds[:, None] * shaft_axes
        data.xfrc_applied[self._rotor_bodies] = forces

    def step(self, nstep: int = 1) -> None:
        """Advance `nstep` physics timesteps with the voltages held; a diverged step is undone."""
        before, time = self.qube_state(), self._data_ptr.time
        for _ in range(nstep):
            self._apply_aerodynamics()
            mujoco.mj_step(self._model_ptr, self._data_ptr)
        state = self.qube_state()
        body, rotors = np.abs(state[2:4]), np.abs(state[4:])
        if not (np.all(body <= MAX_BODY_SPEED) and np.all(rotors <= MAX_ROTOR_SPEED)):  # also NaN
            self.reset_to(before)
            self._data_ptr.time = time + nstep * self._model_ptr.opt.timestep
            self.physics_error = (f"the simulation diverged at t = {self._data_ptr.time:.3f} s "
                                  f"(state {state}); the step was undone")

    @contextlib.contextmanager
    def reset_context(self):
        """Time, state and controls reset (0 V); the caller sets the start (`reset_to`)."""
        if self.closed:
            raise RuntimeError("the simulated Aero is closed; make a new environment to run episodes")
        mujoco.mj_resetData(self._model_ptr, self._data_ptr)
        self._voltage = np.zeros(2)
        self._effects.restart_actuation(np.zeros(2))
        self.physics_error = None
        yield
        mujoco.mj_forward(self._model_ptr, self._data_ptr)


def write_parameters(model: mujoco.MjModel, values: Mapping[str, float], configuration: str) -> None:
    """Write a full parameter table (by long name) into the compiled `model` of `configuration`, in place."""
    masses = mass_distribution(values, configuration)
    beam, yoke = model.body("beam").id, model.body("yoke").id
    model.body_mass[beam] = masses["beam_mass"]
    model.body_ipos[beam] = (0.0, 0.0, -masses["beam_com_depth"])
    model.body_inertia[beam] = (BEAM_ROLL_INERTIA, masses["beam_inertia"], masses["beam_inertia"])
    model.body_inertia[yoke] = (masses["yoke_inertia"],) * 3
    spin = aero_parameters.rotor_assembly_inertia(values)
    for rotor in ROTORS:
        body = model.body(f"{rotor}_rotor").id
        axis = model.jnt_axis[model.joint(f"{rotor}_rotor").id]
        model.body_pos[body] = (values["thrust_arm"] if rotor == "front" else -values["thrust_arm"], 0.0, 0.0)
        model.body_inertia[body] = np.where(np.abs(axis) > 0.5, spin, 0.5 * spin)
        gain = values["motor_torque_constant"] / values["motor_resistance"]
        motor = model.actuator(f"{rotor}_motor").id
        model.actuator_gainprm[motor, 0] = gain
        model.actuator_biasprm[motor, 2] = -gain * values["motor_back_emf"]
    model.dof_damping[model.jnt_dofadr[model.joint("pitch").id]] = values["pitch_damping"]
    if configuration == "2dof":
        model.dof_damping[model.jnt_dofadr[model.joint("yaw").id]] = values["yaw_damping"]
    model.opt.gravity = (0.0, 0.0, -values["gravity"])


def compile_model(configuration: str = "2dof") -> mujoco.MjModel:
    """The scene compiled in `configuration`: "2dof" as `scene.xml` is; "pitch_only" with the yaw
    joint removed and the back thruster turned to lift (its shaft and thrust along the body's z axis)."""
    check_configuration(configuration)
    spec = mujoco.MjSpec.from_file(str(SCENE_PATH))
    if configuration == "pitch_only":
        spec.delete(spec.joint("yaw"))
        spec.key("rest").qpos = [0.0, 0.0, 0.0]
        spec.joint("back_rotor").axis = [0.0, 0.0, 1.0]
        spec.site("back_thrust").alt.zaxis = [0.0, 0.0, 1.0]
        spec.geom("back_shroud").alt.zaxis = [0.0, 0.0, 1.0]
        propeller = spec.geom("back_propeller")
        propeller.size, propeller.pos = [0.1, 0.012, 0.002], [0.0, 0.0, 0.01]
    return spec.compile()


def make_physics(control_frequency: float = 250.0, parameters: Mapping[str, float] | Any = None,
                 configuration: str = "2dof") -> Physics:
    """A simulated Aero 2 for control at `control_frequency` (Hz) with `parameters` by long name (see
    `qube_suite.devices.aero2.parameters`) or a calibration file's path, in `configuration`: "2dof"
    (the helicopter, default) or "pitch_only" (yaw locked, both thrusters lifting)."""
    check_control_frequency(control_frequency)
    physics = Physics.from_model(dm_mujoco.wrapper.MjModel(compile_model(configuration)))
    physics.model.opt.timestep = physics_timestep(control_frequency)
    physics.set_parameters(shared_parameters.values_of(parameters))
    return physics


DOMAIN_KWARGS = keywords_of(make_physics, skip=("control_frequency",))
"""Keys `suite.load`'s `domain_kwargs` may hold for this domain."""
