"""The simulated Qube: MuJoCo physics of `devices/qube/scene.xml` (the Qube of `devices/qube/model.xml` on its
bench) in the Qube's own terms.

`make_physics(control_frequency, parameters)` builds a `Physics` whose timestep
divides the control period; `Physics.set_parameters` writes physical parameters
(by the long names of `qube_suite.devices.qube.parameters`) into the compiled model in place,
keeping derived quantities consistent (a longer pendulum moves its centre of
mass, inertia and drawing too).
"""

from __future__ import annotations

import contextlib
import functools
import math
import pathlib
import zlib
from collections.abc import Mapping, Sequence
from typing import Any

import mujoco
import numpy as np
from dm_control import mujoco as dm_mujoco
from dm_control.mujoco import wrapper as dm_wrapper

from qube_suite.angles import wrap_angle
from qube_suite.arguments import is_number, keywords_of
from qube_suite.devices.qube import parameters as params
from qube_suite.domains.effects import Effects
from qube_suite.domains.interface import MeasuredState, SimulationLifecycle

MODEL_PATH = pathlib.Path(__file__).resolve().parent / "model.xml"
"""The Qube alone: bodies, joints, actuator, keyframes `hanging` and `upright`."""

SCENE_PATH = MODEL_PATH.with_name("scene.xml")
"""The Qube on a bench with lights, cameras and textures: what a simulated Qube renders."""

MAX_TIMESTEP = 0.004
"""Largest physics timestep (s): RK4 at 4 ms keeps trajectories within 3.5e-4 rad of a
64x finer run over 2 s of chaotic swinging (benchmarks/timestep_convergence.py)."""

MIN_CONTROL_FREQUENCY = 10.0
MAX_CONTROL_FREQUENCY = 2000.0

MAX_PLAUSIBLE_SPEED = 1e4
"""Largest |d theta / dt| + |d alpha / dt| (rad/s) of a simulation that has not diverged: 40 times
the motor's no-load speed at 10 V (238 rad/s). MuJoCo's automatic reset is off in model.xml, so a
diverged state stays (huge, inf or NaN) and fails this check."""


REWARD_MATERIALS = ("self", "effector", "target")
"""The materials dm_control's reward visualisation colours (`Physics.show_reward`; the pendulum is "self")."""

class Physics(MeasuredState, SimulationLifecycle, dm_mujoco.Physics):
    """MuJoCo physics of the Qube with accessors that read like the Qube.

    Implements `qube_suite.domains.interface.QubePhysics`. The Qube's state is
    measured once whenever the simulation moves (`step`, `reset_to`, `forward`)
    and the accessors return that measurement: in the nominal model it is the
    exact state with angles wrapped; a sensor model (`set_sensor_model`) can make
    it imperfect, an actuator model (`set_actuator_model`) can alter the voltage
    the motor receives, and a step-duration model (`set_step_duration_model`) can
    perturb how long each `step` lasts.

    A step after which the simulation has diverged (speeds beyond
    MAX_PLAUSIBLE_SPEED, inf or NaN, e.g. from extreme parameters) is undone: the
    Qube is put back in the state before it and `physics_error` says what happened,
    until the next reset.
    """

    latency_steps = 0
    """A step applies its voltage at once (`interface.QubePhysics.latency_steps`); randomization's
    `action_delay` adds its steps, unknown to controllers."""

    physics_error: str | None = None
    """Why the last `step` was undone (the simulation diverged), or None."""

    UNMODELLED_PARAMETERS = frozenset({"motor_inductance"})
    """Parameters `set_parameters` records but the simulation does not use: the motor's
    electrical time constant, Lm / Rm = 0.14 ms, is far below the 4 ms timestep."""

    _measurement_ready = False
    _parameters_written = False
    _cable = None

    # -- construction -------------------------------------------------------------

    def _reload_from_data(self, data) -> None:
        self._measurement_ready = False
        super()._reload_from_data(data)
        model = self.model.ptr
        self._model_ptr = model
        self._data_ptr = self.data.ptr
        self._qpos = self._data_ptr.qpos
        self._qvel = self._data_ptr.qvel
        self._ctrl = self._data_ptr.ctrl
        ids = self._ids = ElementIds(model)
        self._arm_qpos, self._pendulum_qpos = ids.arm_qpos, ids.pendulum_qpos
        self._arm_dof, self._pendulum_dof = ids.arm_dof, ids.pendulum_dof
        self._led_rgba = model.geom_rgba[ids.led_geom]
        self._led = tuple(float(x) for x in self._led_rgba[:3])
        self._options = model.opt
        if not hasattr(self, "_parameters"):
            self._parameters = dict(params.NOMINAL)
        if not hasattr(self, "_effects"):
            self._effects = Effects()
        self._effects.sensor = self._effects.actuator = None
        self._step_duration_model = None
        self._voltage = float(self._ctrl[0])
        self._measurement_ready = True
        self._measure_afresh()

    # -- pickling and copying -------------------------------------------------------

    _REBUILT_ATTRIBUTES = frozenset({
        "_contexts_lock", "_contexts", "_data", "_warnings", "_warnings_before", "_new_warnings", "_named",
        "_model_ptr", "_data_ptr", "_qpos", "_qvel", "_ctrl", "_ids", "_arm_qpos", "_pendulum_qpos",
        "_arm_dof", "_pendulum_dof", "_led_rgba", "_options", "_measurement_ready"})
    """Attributes that unpickling rebuilds from the model and data; every other attribute (parameters,
    sensor, actuator and step-duration models, the measurement, the voltage, the LED) is pickled."""

    def __getstate__(self) -> dict:
        """The model (as its XML and parameters where that rebuilds it exactly, else in full), MuJoCo's
        integration state and the Python state: a copy continues bit-identically.

        Raises TypeError after `close()`: the data is freed then.
        """
        if self.closed:
            raise TypeError("a closed simulated Qube cannot be pickled or copied: its MuJoCo data was "
                            "freed by close(); copy the environment before closing it")
        model, data = self._model_ptr, self._data_ptr
        recipe = ModelRecipe(SCENE_PATH.read_text(), MODEL_PATH.read_text(), model.opt.timestep,
                             self._parameters if self._parameters_written else None,
                             self._led_rgba.tolist(), self._ids.led_geom)
        state = {key: value for key, value in self.__dict__.items() if key not in self._REBUILT_ATTRIBUTES}
        state["model"] = recipe if recipe.rebuilds(model) else model
        state["integration_state"] = integration_state(model, data)
        return state

    def __setstate__(self, state: dict) -> None:
        state = dict(state)
        model = state.pop("model")
        saved = state.pop("integration_state")
        if isinstance(model, ModelRecipe):
            model = model.build()
        data = dm_wrapper.MjData(dm_wrapper.MjModel(model))
        set_integration_state(model, data.ptr, saved)
        super().__setstate__(data)  # dm_control: rendering lock, warnings, `_reload_from_data`
        self.__dict__.update(state)

    def copy(self, share_model: bool = False) -> Physics:
        new = super().copy(share_model=share_model)
        new._parameters = dict(self._parameters)
        new._led = self._led
        if hasattr(self, "_calibration"):
            new.set_calibrated_effects(*self._calibration)
        return new

    # -- parameters ---------------------------------------------------------------

    @property
    def parameters(self) -> Mapping[str, float]:
        """Physical parameters in effect, by long name (read-only view)."""
        return dict(self._parameters)

    def set_parameters(self, overrides: Mapping[str, float] | None = None) -> None:
        """Set every parameter to its nominal value, updated by `overrides`, in place.

        Raises ValueError for an unknown name or an impossible value; the model is
        unchanged then.
        """
        state = self._exact_state()
        self._parameters = write_parameters(self._model_ptr, self._data_ptr, overrides, self._ids)
        if self._cable is not None:
            write_cable(self._model_ptr, self._ids, self._parameters["cable_stiffness"], *self._cable)
        self._parameters_written = True
        self._set_state(state)

    def set_calibrated_effects(self, effects: Mapping[str, float], control_period: float) -> None:
        """Reproduce a calibration's effects (`parameters.effects_of`; empty: none), unknown to
        controllers like randomization's: its latency (s, a fraction of a control period allowed) and
        voltage dead zone between a command and the motor, the cable's rest angle, the pendulum
        encoder's offset. They act before any randomization effects. `control_period`: s."""
        self._calibration = (dict(effects), control_period)
        latency, deadzone = effects.get("latency_seconds", 0.0), effects.get("voltage_deadzone", 0.0)
        offset = effects.get("pendulum_encoder_offset", 0.0)
        self._effects.calibrated_actuator = (CalibratedActuation(latency / control_period, deadzone)
                                             if latency or deadzone else None)
        self._effects.calibrated_sensor = PendulumEncoderOffset(offset) if offset else None
        self._cable = (effects.get("cable_rest_angle", 0.0), effects.get("cable_slack", 0.0))
        write_cable(self._model_ptr, self._ids, self._parameters["cable_stiffness"], *self._cable)
        self._measure_afresh()

    # -- the domain interface -------------------------------------------------------

    def true_state(self) -> np.ndarray:
        """Exact [theta, alpha, dtheta, dalpha] of the simulation, angles wrapped."""
        return np.array(self._exact_state())

    def applied_voltage(self) -> float:
        """Motor voltage (V) the simulated motor receives: the command after actuator effects."""
        return float(self._ctrl[0])

    def set_voltage(self, volts: float) -> None:
        """Command `volts` to the motor until the next call."""
        self._voltage = volts
        self._ctrl[0] = self._effects.actuate(volts)

    def set_sensor_model(self, sensor_model) -> None:
        """Measure through `sensor_model`; None: exactly.

        `sensor_model(exact) -> measured` is called after every `step` with the exact
        [theta, alpha, dtheta, dalpha] (angles wrapped) and returns the measured one
        (4 floats). If it has a `reset(exact) -> measured` method, that is called
        instead whenever the state is set directly (`reset_to`, `forward`,
        `set_parameters`, and now), so that a model with memory starts afresh. It measures
        after any calibrated effects (`qube_suite.domains.effects`).
        """
        self._effects.sensor = sensor_model
        self._measure_afresh()

    def set_actuator_model(self, actuator_model) -> None:
        """Drive the motor with `actuator_model(volts) -> volts`, called once per `set_voltage`;
        None: as commanded. If it has a `reset(volts)` method, `reset` calls it with 0 V. It acts
        after any calibrated effects (`qube_suite.domains.effects`)."""
        self._effects.actuator = actuator_model

    def set_step_duration_model(self, step_duration_model) -> None:
        """Make each `step` last `step_duration_model(duration) -> duration` (s) instead of its
        nominal duration (`nstep` timesteps); None: nominal.

        The perturbed duration is covered in equal timesteps of at most MAX_TIMESTEP, so
        the timestep still divides every step and the integration stays as accurate.
        """
        self._step_duration_model = step_duration_model

    def motor_current(self) -> float:
        """Motor current (A), (V - km dtheta) / Rm at the motor's terminals; inductance neglected."""
        p = self._parameters
        speed = float(self._qvel[self._arm_dof])
        return (float(self._ctrl[0]) - p["motor_back_emf"] * speed) / p["motor_resistance"]

    def set_led(self, rgb: Sequence[float]) -> None:
        """Colour the LED strip, (r, g, b) in [0, 1]; the model's geom takes it at the next `draw_led`."""
        self._led = rgb

    def show_reward(self, reward: float) -> None:
        """dm_control's reward colours (a task's `visualize_reward`): each of `REWARD_MATERIALS` blended
        from its `_default` to its `_highlight` colour by reward^4, the reward clipped to [0, 1]."""
        blend = min(max(float(reward), 0.0), 1.0) ** 4
        colours = self.named.model.mat_rgba
        for name in REWARD_MATERIALS:
            colours[name] = blend * colours[f"{name}_highlight"] + (1.0 - blend) * colours[f"{name}_default"]

    def led(self) -> tuple[float, float, float]:
        """The LED strip's (r, g, b)."""
        r, g, b = self._led
        return float(r), float(g), float(b)

    def draw_led(self) -> None:
        """Write the LED colour into the model for drawing (`render` does; so must other renderers)."""
        self._led_rgba[:3] = self._led

    def drawable(self) -> Physics:
        """This physics, with the LED colour written into the model, for renderers."""
        self.draw_led()
        return self

    def render(self, *args, **kwargs):
        """dm_control's `Physics.render`, showing the current LED colour. RuntimeError after `close()`."""
        if self.closed:
            raise RuntimeError("the simulated Qube is closed: nothing to render")
        self.draw_led()
        return super().render(*args, **kwargs)

    def reset_to(self, state: Sequence[float]) -> None:
        """Set [theta, alpha, dtheta, dalpha] exactly."""
        self.physics_error = None
        self._set_state(state)

    def step(self, nstep: int = 1) -> None:
        """Advance `nstep` physics timesteps (one MuJoCo call), then measure.

        If the simulation diverges, the step is undone and `physics_error` set.
        """
        before = self._exact
        if self._step_duration_model is None:
            mujoco.mj_step(self._model_ptr, self._data_ptr, nstep)
        else:
            self._step_for(self._step_duration_model(nstep * self._options.timestep))
        exact = self._exact_state()
        if not plausible(exact[2], exact[3]):
            self._undo_step(before, exact)
            return
        self._exact = exact
        self._measured = self._effects.measure(exact)

    def forward(self) -> None:
        """Recompute derived quantities after the state was changed directly, then measure."""
        super().forward()
        if self._measurement_ready:
            self._measure_afresh()

    def reset(self, keyframe_id: int | None = None) -> None:
        """Reset time, state and control (dm_control's `Physics.reset`); the voltage is 0 V."""
        self._restart_actuation()
        super().reset(keyframe_id)

    @contextlib.contextmanager
    def reset_context(self):
        """dm_control's reset context without its extra passes: time, state and control are reset
        (0 V), the caller sets the start (e.g. `reset_to`), then one `mj_forward` and a fresh
        measurement. RuntimeError after `close()`."""
        if self.closed:
            raise RuntimeError("the simulated Qube is closed; make a new environment to run episodes")
        mujoco.mj_resetData(self._model_ptr, self._data_ptr)
        self._restart_actuation()
        self.physics_error = None
        yield
        mujoco.mj_forward(self._model_ptr, self._data_ptr)
        self._measure_afresh()

    # -- helpers ------------------------------------------------------------------

    def _exact_state(self) -> tuple[float, float, float, float]:
        qpos, qvel = self._qpos.tolist(), self._qvel.tolist()
        return (wrap_angle(qpos[self._arm_qpos]), wrap_angle(qpos[self._pendulum_qpos]),
                qvel[self._arm_dof], qvel[self._pendulum_dof])

    def _restart_actuation(self) -> None:
        self._voltage = 0.0
        self._effects.restart_actuation()

    def _measure_afresh(self) -> None:
        self._exact = exact = self._exact_state()
        self._measured = self._effects.restart(exact)

    def _undo_step(self, before: tuple[float, float, float, float], diverged: Sequence[float]) -> None:
        """Put the Qube back in the state `before` a step that diverged, and say so in `physics_error`."""
        time = self._data_ptr.time
        self._set_state(before)
        self._data_ptr.time = time
        self.physics_error = (f"the simulation diverged at t = {time:.3f} s (state {list(diverged)}); "
                              "the step was undone")

    def _step_for(self, duration: float) -> None:
        nominal_timestep = self._options.timestep
        nstep, self._options.timestep = split_step(duration)
        try:
            mujoco.mj_step(self._model_ptr, self._data_ptr, int(nstep))
        finally:
            self._options.timestep = nominal_timestep

    def _set_state(self, state: Sequence[float]) -> None:
        theta, alpha, dtheta, dalpha = (float(x) for x in state)
        self._qpos[self._arm_qpos] = theta
        self._qpos[self._pendulum_qpos] = alpha
        self._qvel[self._arm_dof] = dtheta
        self._qvel[self._pendulum_dof] = dalpha
        mujoco.mj_forward(self._model_ptr, self._data_ptr)
        self._measure_afresh()


class CalibratedActuation:
    """The voltage that reaches the motor `latency` control periods (a fraction allowed) after it
    was commanded, through a dead zone of `deadzone` V: a command u acts as sign(u) max(|u| - deadzone,
    0). A fractional latency f acts, averaged over a period, as (1 - f) of the latest due command
    and f of the one before (as `calibration.fit.delayed_voltage`)."""

    def __init__(self, latency: float, deadzone: float):
        self.whole = int(math.floor(latency))
        self.fraction = latency - self.whole
        self.deadzone = deadzone
        self.reset()

    def reset(self, volts: float = 0.0) -> None:
        """Forget earlier commands: 0 V until new ones are due."""
        self._history = [volts] * (self.whole + 2)

    def __call__(self, volts: float) -> float:
        history = self._history
        history.pop(0)
        history.append(volts)
        mixed = (1.0 - self.fraction) * history[-1 - self.whole] + self.fraction * history[-2 - self.whole]
        return math.copysign(max(abs(mixed) - self.deadzone, 0.0), mixed)


class PendulumEncoderOffset:
    """What an encoder offset `offset` (rad; true angle = encoder angle + offset) makes of the exact
    state: the pendulum's angle read `offset` low, wrapped."""

    def __init__(self, offset: float):
        self.offset = offset

    def __call__(self, exact: Sequence[float]) -> tuple[float, float, float, float]:
        theta, alpha, dtheta, dalpha = exact
        return theta, wrap_angle(alpha - self.offset), dtheta, dalpha


class ElementIds:
    """Indices of the Qube's named bodies, joints, actuator and geoms in a compiled model."""

    def __init__(self, model: mujoco.MjModel):
        def find(kind, name):
            return mujoco.mj_name2id(model, kind, name)

        body, joint, geom = mujoco.mjtObj.mjOBJ_BODY, mujoco.mjtObj.mjOBJ_JOINT, mujoco.mjtObj.mjOBJ_GEOM
        self.arm, self.pendulum = find(body, "arm"), find(body, "pendulum")
        self.arm_joint, self.pendulum_joint = find(joint, "arm"), find(joint, "pendulum")
        self.motor = find(mujoco.mjtObj.mjOBJ_ACTUATOR, "motor")
        self.arm_geom, self.pendulum_geom = find(geom, "arm"), find(geom, "pendulum")
        self.encoder_geom = find(geom, "pendulum_encoder")
        self.led_geom = find(geom, "led")
        self.cable_tendon = find(mujoco.mjtObj.mjOBJ_TENDON, "cable")
        self.arm_qpos = int(model.jnt_qposadr[self.arm_joint])
        self.pendulum_qpos = int(model.jnt_qposadr[self.pendulum_joint])
        self.arm_dof = int(model.jnt_dofadr[self.arm_joint])
        self.pendulum_dof = int(model.jnt_dofadr[self.pendulum_joint])


def write_parameters(model: mujoco.MjModel, data: mujoco.MjData,
                     overrides: Mapping[str, float] | None = None,
                     ids: ElementIds | None = None) -> dict[str, float]:
    """Write the nominal parameters updated by `overrides` into `model` in place; return them all.

    Keeps derived quantities consistent (inertias, centres of mass, drawing) and
    recomputes MuJoCo's mass-dependent constants using `data` (any MjData of a model
    of the same sizes) as scratch. `ids`: the model's `ElementIds`, if known. Raises
    ValueError for an unknown name or an impossible value; the model is unchanged then.
    """
    p = params.resolve(dict(overrides or {}))
    m, ids = model, ids or ElementIds(model)
    arm, pendulum = ids.arm, ids.pendulum

    jr = params.arm_inertia(p["arm_mass"], p["arm_length"])
    m.body_mass[arm] = p["arm_mass"]
    m.body_inertia[arm, 0] = m.body_inertia[arm, 2] = jr
    m.body_pos[pendulum, 1] = -p["arm_length"]

    jp = params.pendulum_inertia(p["pendulum_mass"], p["pendulum_length"])
    m.body_mass[pendulum] = p["pendulum_mass"]
    m.body_ipos[pendulum, 2] = p["pendulum_length"] / 2.0
    m.body_inertia[pendulum] = (jp, jp, 0.5 * p["pendulum_mass"] * params.PENDULUM_ROD_RADIUS**2)

    m.dof_damping[ids.arm_dof] = p["arm_damping"]
    m.dof_damping[ids.pendulum_dof] = p["pendulum_damping"]
    m.dof_armature[ids.arm_dof] = p["rotor_inertia"]
    m.dof_frictionloss[ids.arm_dof] = p["arm_friction"]
    m.dof_frictionloss[ids.pendulum_dof] = p["pendulum_friction"]
    constraint = int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    if p["arm_friction"] or p["pendulum_friction"]:  # Coulomb friction is a constraint in MuJoCo
        m.opt.disableflags &= ~constraint
    else:
        m.opt.disableflags |= constraint
    m.jnt_stiffness[ids.arm_joint] = p["cable_stiffness"]

    m.actuator_gainprm[ids.motor, 0] = p["motor_torque_constant"] / p["motor_resistance"]
    m.actuator_biasprm[ids.motor, 2] = (
        -p["motor_torque_constant"] * p["motor_back_emf"] / p["motor_resistance"])
    m.opt.gravity[2] = -p["gravity"]

    # Drawing follows the lengths.
    half_arm = p["arm_length"] / 2.0
    m.geom_pos[ids.arm_geom, 1] = -half_arm
    m.geom_size[ids.arm_geom, 1] = half_arm
    m.geom_pos[ids.encoder_geom, 1] = -p["arm_length"] + 0.014
    m.geom_pos[ids.pendulum_geom, 2] = p["pendulum_length"] / 2.0
    m.geom_size[ids.pendulum_geom, 1] = p["pendulum_length"] / 2.0

    mujoco.mj_setConst(m, data)  # mass-dependent constants
    return p


def write_cable(model: mujoco.MjModel, ids: ElementIds, stiffness: float, rest: float, slack: float) -> None:
    """Make the encoder cable of `model` pull the arm towards `rest` (rad) with `stiffness` (N m/rad)
    beyond a band of half-width `slack` (rad) around it, slack within: the arm joint's own spring when
    `slack` is 0, else the tendon "cable" (`model.xml`), whose spring has that dead band."""
    tendon = ids.cable_tendon
    if slack > 0.0:
        model.jnt_stiffness[ids.arm_joint] = 0.0
        model.tendon_stiffness[tendon] = stiffness
        model.tendon_lengthspring[tendon] = (rest - slack, rest + slack)
    else:
        model.jnt_stiffness[ids.arm_joint] = stiffness
        model.tendon_stiffness[tendon] = 0.0
    model.qpos_spring[ids.arm_qpos] = rest


class ModelRecipe:
    """How to rebuild a Qube's compiled model: the scene's XML and the Qube's it includes (stored
    compressed), timestep (s), physical parameters (None: the XML's, never written) and LED colour;
    a few kB where the compiled model is 5.5 MB (mostly textures)."""

    def __init__(self, scene_xml: str, qube_xml: str, timestep: float, parameters: Mapping[str, float] | None,
                 led_rgba: Sequence[float], led_geom: int):
        self.xml = zlib.compress(scene_xml.encode(), 9)
        self.qube_xml = zlib.compress(qube_xml.encode(), 9)
        self.timestep = float(timestep)
        self.parameters = None if parameters is None else dict(parameters)
        self.led_rgba, self.led_geom = list(led_rgba), int(led_geom)

    def build(self) -> mujoco.MjModel:
        """The compiled model."""
        model = mujoco.MjModel.from_xml_string(zlib.decompress(self.xml).decode(),
                                               assets={MODEL_PATH.name: zlib.decompress(self.qube_xml)})
        model.opt.timestep = self.timestep
        if self.parameters is not None:
            write_parameters(model, mujoco.MjData(model), self.parameters)
        model.geom_rgba[self.led_geom] = self.led_rgba
        return model

    def rebuilds(self, model: mujoco.MjModel) -> bool:
        """Whether `build()` gives exactly `model` (byte for byte): False if anything else in it was
        changed directly."""
        return np.array_equal(_model_bytes(self.build()), _model_bytes(model))


def _model_bytes(model: mujoco.MjModel) -> np.ndarray:
    buffer = np.empty(mujoco.mj_sizeModel(model), np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return buffer


INTEGRATION_STATE = mujoco.mjtState.mjSTATE_INTEGRATION
"""The part of MjData a simulation's future depends on (time, positions, velocities, controls, ...)."""


def integration_state(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """MuJoCo's integration state of `data`, a float64 array."""
    state = np.empty(mujoco.mj_stateSize(model, INTEGRATION_STATE))
    mujoco.mj_getState(model, data, state, INTEGRATION_STATE)
    return state


def set_integration_state(model: mujoco.MjModel, data: mujoco.MjData, state: np.ndarray) -> None:
    """Put `data` in the integration state `state`, with every derived quantity recomputed."""
    mujoco.mj_setState(model, data, state, INTEGRATION_STATE)
    mujoco.mj_forward(model, data)
    mujoco.mj_setState(model, data, state, INTEGRATION_STATE)  # in case forward touched any of it


def substeps_per_control_period(control_frequency: float) -> int:
    """Physics steps per control period so that the timestep is at most MAX_TIMESTEP."""
    return max(1, math.ceil(1.0 / (control_frequency * MAX_TIMESTEP) - 1e-9))


def split_step(duration):
    """A control step lasting `duration` (s; a number or an array, one per Qube) split into the fewest
    equal physics steps of at most MAX_TIMESTEP: (their number, their timestep in s), numbers or arrays
    (numpy's, or JAX's for `qube_suite.mjx`)."""
    steps = duration / MAX_TIMESTEP - 1e-9
    if type(steps) is np.ndarray:
        nstep = np.maximum(1, np.ceil(steps)).astype(np.intp)
    elif hasattr(steps, "__array_namespace__"):  # JAX arrays
        namespace = steps.__array_namespace__()
        nstep = namespace.maximum(1, namespace.ceil(steps)).astype(namespace.int32)
    else:  # one Qube: Python's ceil, 20x faster than numpy's on a number (a jittered step 1.19x -> 1.03x)
        nstep = max(1, math.ceil(steps))
    return nstep, duration / nstep


def plausible(arm_velocity, pendulum_velocity):
    """Whether a simulation with these velocities (rad/s; numbers or arrays, one per Qube) has not
    diverged: |d theta / dt| + |d alpha / dt| below MAX_PLAUSIBLE_SPEED, False for inf and NaN."""
    return abs(arm_velocity) + abs(pendulum_velocity) < MAX_PLAUSIBLE_SPEED


def physics_timestep(control_frequency: float) -> float:
    """Physics timestep (s): the control period divided into `substeps_per_control_period` steps."""
    return 1.0 / (control_frequency * substeps_per_control_period(control_frequency))


@functools.lru_cache(maxsize=1)
def _scene_model() -> dm_wrapper.MjModel:
    """The scene (`SCENE_PATH`) compiled once per process: compiling takes tens of milliseconds, a copy
    (what each physics gets) a few microseconds."""
    return dm_wrapper.MjModel.from_xml_path(str(SCENE_PATH))


def make_physics(control_frequency: float = 250.0, parameters: Mapping[str, float] | Any = None) -> Physics:
    """A simulated Qube for control at `control_frequency` (Hz) with `parameters`: by long name, or
    a calibration (`Calibration` or its file's path; see `qube_suite.devices.qube.parameters.values_of`)."""
    check_control_frequency(control_frequency)
    overrides = params.values_of(parameters)
    physics = Physics.from_model(_scene_model().copy())
    physics.model.opt.timestep = physics_timestep(control_frequency)
    if overrides:
        physics.set_parameters(overrides)
    effects = params.effects_of(parameters)
    if effects:
        physics.set_calibrated_effects(effects, 1.0 / control_frequency)
    return physics


DOMAIN_KWARGS = keywords_of(make_physics, skip=("control_frequency",))
"""Keys `suite.load`'s `domain_kwargs` may hold for this domain."""


def check_control_frequency(control_frequency: float) -> None:
    """Raise ValueError unless `control_frequency` (Hz) is within the supported range."""
    if not (is_number(control_frequency)
            and MIN_CONTROL_FREQUENCY <= control_frequency <= MAX_CONTROL_FREQUENCY):
        raise ValueError(f"control_frequency must be a number in [{MIN_CONTROL_FREQUENCY:g}, "
                         f"{MAX_CONTROL_FREQUENCY:g}] Hz, got {control_frequency!r}")
