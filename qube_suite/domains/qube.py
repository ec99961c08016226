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

MIN_CONTROL_FREQUENCY = 10.0
MAX_CONTROL_FREQUENCY = 2000.0


class Physics(dm_mujoco.Physics):
    """MuJoCo physics of the Qube with accessors that read like the Qube.

    Implements `qube_suite.domains.interface.QubePhysics`.
    """

    # -- construction -------------------------------------------------------------

    def _reload_from_data(self, data) -> None:
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
        if not hasattr(self, "_parameters"):
            self._parameters = dict(params.NOMINAL)

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
        m, ids = self._model_ptr, self._ids
        arm, pendulum = ids["arm"], ids["pendulum"]

        jr = params.arm_inertia(p["arm_mass"], p["arm_length"])
        m.body_mass[arm] = p["arm_mass"]
        m.body_inertia[arm, 0] = m.body_inertia[arm, 2] = jr
        m.body_pos[pendulum] = (0.0, -p["arm_length"], 0.0)

        jp = params.pendulum_inertia(p["pendulum_mass"], p["pendulum_length"])
        m.body_mass[pendulum] = p["pendulum_mass"]
        m.body_ipos[pendulum] = (0.0, 0.0, p["pendulum_length"] / 2.0)
        m.body_inertia[pendulum] = (jp, jp, 0.5 * p["pendulum_mass"] * params.PENDULUM_ROD_RADIUS**2)

        m.dof_damping[self._arm_dof] = p["arm_damping"]
        m.dof_damping[self._pendulum_dof] = p["pendulum_damping"]
        m.dof_armature[self._arm_dof] = p["rotor_inertia"]
        m.dof_frictionloss[self._arm_dof] = p["arm_friction"]
        m.dof_frictionloss[self._pendulum_dof] = p["pendulum_friction"]
        m.jnt_stiffness[ids["arm_joint"]] = p["cable_stiffness"]

        motor = ids["motor"]
        m.actuator_gainprm[motor, 0] = p["motor_torque_constant"] / p["motor_resistance"]
        m.actuator_biasprm[motor, 2] = (
            -p["motor_torque_constant"] * p["motor_back_emf"] / p["motor_resistance"])
        m.opt.gravity[:] = (0.0, 0.0, -p["gravity"])

        # Drawing follows the lengths.
        half_arm = p["arm_length"] / 2.0
        m.geom_pos[ids["arm_geom"]] = (0.0, -half_arm, 0.0)
        m.geom_size[ids["arm_geom"], 1] = half_arm
        m.geom_pos[ids["encoder_geom"], 1] = -p["arm_length"] + 0.014
        m.geom_pos[ids["pendulum_geom"]] = (0.0, 0.0, p["pendulum_length"] / 2.0)
        m.geom_size[ids["pendulum_geom"], 1] = p["pendulum_length"] / 2.0

        state = self.qube_state()
        mujoco.mj_setConst(m, self._data_ptr)  # mass-dependent constants
        self._parameters = p
        self._set_state(state)

    # -- the domain interface -------------------------------------------------------

    def arm_angle(self) -> float:
        """Arm angle theta (rad) in (-pi, pi], 0 = centred at the front."""
        return wrap_angle(self._qpos[self._arm_qpos])

    def pendulum_angle(self) -> float:
        """Pendulum angle alpha (rad) in (-pi, pi], 0 = upright."""
        return wrap_angle(self._qpos[self._pendulum_qpos])

    def arm_velocity(self) -> float:
        """d theta / dt (rad/s)."""
        return float(self._qvel[self._arm_dof])

    def pendulum_velocity(self) -> float:
        """d alpha / dt (rad/s)."""
        return float(self._qvel[self._pendulum_dof])

    def qube_state(self) -> np.ndarray:
        """[theta, alpha, dtheta, dalpha] (rad, rad/s), angles wrapped."""
        return np.array([self.arm_angle(), self.pendulum_angle(),
                         self.arm_velocity(), self.pendulum_velocity()])

    def voltage(self) -> float:
        """Motor voltage (V) being applied."""
        return float(self._ctrl[0])

    def set_voltage(self, volts: float) -> None:
        """Apply `volts` to the motor until the next call."""
        self._ctrl[0] = volts

    def motor_current(self) -> float:
        """Motor current (A), (V - km dtheta) / Rm; the inductance is neglected."""
        p = self._parameters
        return (self.voltage() - p["motor_back_emf"] * self.arm_velocity()) / p["motor_resistance"]

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
        """Advance `nstep` physics timesteps (one MuJoCo call)."""
        mujoco.mj_step(self._model_ptr, self._data_ptr, nstep)

    # -- helpers ------------------------------------------------------------------

    def _set_state(self, state: Sequence[float]) -> None:
        theta, alpha, dtheta, dalpha = (float(x) for x in state)
        self._qpos[self._arm_qpos] = theta
        self._qpos[self._pendulum_qpos] = alpha
        self._qvel[self._arm_dof] = dtheta
        self._qvel[self._pendulum_dof] = dalpha
        mujoco.mj_forward(self._model_ptr, self._data_ptr)


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
