"""The simulated Qube: MuJoCo physics of `assets/qube.xml` in the Qube's own terms.

`make_physics(control_frequency, parameters)` builds a `Physics` whose timestep
divides the control period; `Physics.set_parameters` writes physical parameters
(by the long names of `qube_suite.parameters`) into the compiled model in place,
keeping derived quantities consistent (a longer pendulum moves its centre of
mass, inertia and drawing too).
"""

from __future__ import annotations

import math
import pathlib
import types
from collections.abc import Mapping, Sequence

import mujoco
import numpy as np
from dm_control import mujoco as dm_mujoco

from qube_suite import parameters as params
from qube_suite.angles import wrap_angle

MODEL_PATH = pathlib.Path(__file__).resolve().parent.parent / "assets" / "qube.xml"

MAX_TIMESTEP = 0.004
"""Largest physics timestep (s): RK4 at 4 ms keeps trajectories within 1e-5 rad of a
64x finer run over 2 s (benchmarks/timestep_convergence.py)."""

_PARAMETER_FIELDS = ("body_mass", "body_inertia", "body_pos", "body_ipos", "dof_damping", "dof_armature",
                     "dof_frictionloss", "jnt_stiffness", "actuator_gainprm", "actuator_biasprm",
                     "geom_pos", "geom_size")
"""The compiled model's arrays `set_parameters` writes (views kept, as a reset writes them often)."""

MIN_CONTROL_FREQUENCY = 10.0
MAX_CONTROL_FREQUENCY = 2000.0


class Physics(dm_mujoco.Physics):
    """MuJoCo physics of the Qube with accessors that read like the Qube.

    Implements `qube_suite.domains.interface.QubePhysics`. The Qube's state is
    measured once whenever the simulation moves (`step`, `reset_to`, `forward`)
    and the accessors return that measurement: in the nominal model it is the
    exact state with angles wrapped; a sensor model (`set_sensor_model`) can make
    it imperfect, an actuator model (`set_actuator_model`) can alter the voltage
    the motor receives, and a step-duration model (`set_step_duration_model`) can
    perturb how long each `step` lasts.
    """

    UNMODELLED_PARAMETERS = frozenset({"motor_inductance"})
    """Parameters `set_parameters` records but the simulation does not use: the motor's
    electrical time constant, Lm / Rm = 0.14 ms, is far below the 4 ms timestep."""

    _measurement_ready = False

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
        self._ids = {
            "arm": mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "arm"),
            "pendulum": mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "pendulum"),
            "arm_joint": mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "arm"),
            "pendulum_joint": mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "pendulum"),
            "motor": mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, "motor"),
            "arm_geom": mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "arm"),
            "encoder_geom": mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "pendulum_encoder"),
            "pendulum_geom": mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "pendulum"),
        }
        self._arm_qpos = int(model.jnt_qposadr[self._ids["arm_joint"]])
        self._pendulum_qpos = int(model.jnt_qposadr[self._ids["pendulum_joint"]])
        self._arm_dof = int(model.jnt_dofadr[self._ids["arm_joint"]])
        self._pendulum_dof = int(model.jnt_dofadr[self._ids["pendulum_joint"]])
        self._led_rgba = model.geom_rgba[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "led")]
        self._arrays = types.SimpleNamespace(**{name: getattr(model, name) for name in _PARAMETER_FIELDS})
        self._options = model.opt
        if not hasattr(self, "_parameters"):
            self._parameters = dict(params.NOMINAL)
        self._sensor_model = None
        self._sensor_reset = None
        self._actuator_model = None
        self._step_duration_model = None
        self._voltage = float(self._ctrl[0])
        self._measurement_ready = True
        self._measure_afresh()

    def copy(self, share_model: bool = False) -> Physics:
        new = super().copy(share_model=share_model)
        new._parameters = dict(self._parameters)
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
        p = params.resolve(dict(overrides or {}))
        a, ids = self._arrays, self._ids
        arm, pendulum = ids["arm"], ids["pendulum"]

        jr = params.arm_inertia(p["arm_mass"], p["arm_length"])
        a.body_mass[arm] = p["arm_mass"]
        a.body_inertia[arm, 0] = a.body_inertia[arm, 2] = jr
        a.body_pos[pendulum, 1] = -p["arm_length"]

        jp = params.pendulum_inertia(p["pendulum_mass"], p["pendulum_length"])
        a.body_mass[pendulum] = p["pendulum_mass"]
        a.body_ipos[pendulum, 2] = p["pendulum_length"] / 2.0
        a.body_inertia[pendulum] = (jp, jp, 0.5 * p["pendulum_mass"] * params.PENDULUM_ROD_RADIUS**2)

        a.dof_damping[self._arm_dof] = p["arm_damping"]
        a.dof_damping[self._pendulum_dof] = p["pendulum_damping"]
        a.dof_armature[self._arm_dof] = p["rotor_inertia"]
        a.dof_frictionloss[self._arm_dof] = p["arm_friction"]
        a.dof_frictionloss[self._pendulum_dof] = p["pendulum_friction"]
        constraint = int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
        if p["arm_friction"] or p["pendulum_friction"]:  # Coulomb friction is a constraint in MuJoCo
            self._options.disableflags &= ~constraint
        else:
            self._options.disableflags |= constraint
        a.jnt_stiffness[ids["arm_joint"]] = p["cable_stiffness"]

        motor = ids["motor"]
        a.actuator_gainprm[motor, 0] = p["motor_torque_constant"] / p["motor_resistance"]
        a.actuator_biasprm[motor, 2] = (
            -p["motor_torque_constant"] * p["motor_back_emf"] / p["motor_resistance"])
        self._options.gravity[2] = -p["gravity"]

        # Drawing follows the lengths.
        half_arm = p["arm_length"] / 2.0
        a.geom_pos[ids["arm_geom"], 1] = -half_arm
        a.geom_size[ids["arm_geom"], 1] = half_arm
        a.geom_pos[ids["encoder_geom"], 1] = -p["arm_length"] + 0.014
        a.geom_pos[ids["pendulum_geom"], 2] = p["pendulum_length"] / 2.0
        a.geom_size[ids["pendulum_geom"], 1] = p["pendulum_length"] / 2.0

        state = self._exact_state()
        mujoco.mj_setConst(self._model_ptr, self._data_ptr)  # mass-dependent constants
        self._parameters = p
        self._set_state(state)

    # -- the domain interface -------------------------------------------------------

    def arm_angle(self) -> float:
        """Measured arm angle theta (rad) in (-pi, pi], 0 = centred at the front."""
        return self._measured[0]

    def pendulum_angle(self) -> float:
        """Measured pendulum angle alpha (rad) in (-pi, pi], 0 = upright."""
        return self._measured[1]

    def arm_velocity(self) -> float:
        """Measured d theta / dt (rad/s)."""
        return self._measured[2]

    def pendulum_velocity(self) -> float:
        """Measured d alpha / dt (rad/s)."""
        return self._measured[3]

    def qube_state(self) -> np.ndarray:
        """Measured [theta, alpha, dtheta, dalpha] (rad, rad/s), angles wrapped."""
        return np.array(self._measured)

    def true_state(self) -> np.ndarray:
        """Exact [theta, alpha, dtheta, dalpha] of the simulation, angles wrapped."""
        return np.array(self._exact_state())

    def voltage(self) -> float:
        """Motor voltage (V) commanded by the last `set_voltage`."""
        return self._voltage

    def set_voltage(self, volts: float) -> None:
        """Command `volts` to the motor until the next call."""
        self._voltage = volts
        self._ctrl[0] = volts if self._actuator_model is None else self._actuator_model(volts)

    def set_sensor_model(self, sensor_model) -> None:
        """Measure through `sensor_model`; None: exactly.

        `sensor_model(exact) -> measured` is called after every `step` with the exact
        [theta, alpha, dtheta, dalpha] (angles wrapped) and returns the measured one
        (4 floats). If it has a `reset(exact) -> measured` method, that is called
        instead whenever the state is set directly (`reset_to`, `forward`,
        `set_parameters`, and now), so that a model with memory starts afresh.
        """
        self._sensor_model = sensor_model
        self._sensor_reset = getattr(sensor_model, "reset", sensor_model)
        self._measure_afresh()

    def set_actuator_model(self, actuator_model) -> None:
        """Drive the motor with `actuator_model(volts) -> volts`, called once per `set_voltage`;
        None: as commanded. If it has a `reset(volts)` method, `reset` calls it with 0 V."""
        self._actuator_model = actuator_model

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
        """Colour the LED strip, (r, g, b) in [0, 1]."""
        self._led_rgba[0], self._led_rgba[1], self._led_rgba[2] = rgb

    def led(self) -> tuple[float, float, float]:
        """The LED strip's (r, g, b)."""
        return float(self._led_rgba[0]), float(self._led_rgba[1]), float(self._led_rgba[2])

    def reset_to(self, state: Sequence[float]) -> None:
        """Set [theta, alpha, dtheta, dalpha] exactly."""
        self._set_state(state)

    def step(self, nstep: int = 1) -> None:
        """Advance `nstep` physics timesteps (one MuJoCo call), then measure."""
        if self._step_duration_model is None:
            mujoco.mj_step(self._model_ptr, self._data_ptr, nstep)
        else:
            self._step_for(self._step_duration_model(nstep * self._options.timestep))
        self._measure()

    def time(self) -> float:
        """Simulated time since the episode started (s)."""
        return self._data_ptr.time

    def forward(self) -> None:
        """Recompute derived quantities after the state was changed directly, then measure."""
        super().forward()
        if self._measurement_ready:
            self._measure_afresh()

    def reset(self, keyframe_id: int | None = None) -> None:
        """Reset time, state and control (dm_control's `Physics.reset`); the voltage is 0 V."""
        self._voltage = 0.0
        if hasattr(self._actuator_model, "reset"):
            self._actuator_model.reset(0.0)
        super().reset(keyframe_id)

    # -- helpers ------------------------------------------------------------------

    def _exact_state(self) -> tuple[float, float, float, float]:
        qpos, qvel = self._qpos.tolist(), self._qvel.tolist()
        return (wrap_angle(qpos[self._arm_qpos]), wrap_angle(qpos[self._pendulum_qpos]),
                qvel[self._arm_dof], qvel[self._pendulum_dof])

    def _measure(self) -> None:
        exact = self._exact_state()
        self._measured = exact if self._sensor_model is None else self._sensor_model(exact)

    def _measure_afresh(self) -> None:
        exact = self._exact_state()
        self._measured = exact if self._sensor_reset is None else self._sensor_reset(exact)

    def _step_for(self, duration: float) -> None:
        nominal_timestep = self._options.timestep
        nstep = max(1, math.ceil(duration / MAX_TIMESTEP - 1e-9))
        self._options.timestep = duration / nstep
        try:
            mujoco.mj_step(self._model_ptr, self._data_ptr, nstep)
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


def substeps_per_control_period(control_frequency: float) -> int:
    """Physics steps per control period so that the timestep is at most MAX_TIMESTEP."""
    return max(1, math.ceil(1.0 / (control_frequency * MAX_TIMESTEP) - 1e-9))


def make_physics(control_frequency: float = 250.0,
                 parameters: Mapping[str, float] | None = None) -> Physics:
    """A simulated Qube for control at `control_frequency` (Hz) with `parameters`."""
    check_control_frequency(control_frequency)
    physics = Physics.from_xml_path(str(MODEL_PATH))
    physics.model.opt.timestep = 1.0 / (control_frequency * substeps_per_control_period(control_frequency))
    if parameters:
        physics.set_parameters(parameters)
    return physics


def check_control_frequency(control_frequency: float) -> None:
    """Raise ValueError unless `control_frequency` (Hz) is within the supported range."""
    if not (isinstance(control_frequency, (int, float)) and not isinstance(control_frequency, bool)
            and MIN_CONTROL_FREQUENCY <= control_frequency <= MAX_CONTROL_FREQUENCY):
        raise ValueError(f"control_frequency must be a number in [{MIN_CONTROL_FREQUENCY:g}, "
                         f"{MAX_CONTROL_FREQUENCY:g}] Hz, got {control_frequency!r}")
