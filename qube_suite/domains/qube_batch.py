"""A batch of simulated Qubes stepped together: one MuJoCo model per world, `mujoco.rollout` threads.

`QubeBatch(n)` holds n independent Qubes ("worlds"). Its accessors are those of the
domain interface (`qube_suite.domains.interface.QubePhysics`), each returning one
value per world as an array, so the tasks' formulas evaluate every world at once.
`step` advances all worlds by one control period in a single call to MuJoCo's
rollout on a persistent thread pool, which runs without the GIL. World i has its
own model, so its physical parameters can differ (`set_parameters`); worlds share
one model until their parameters are changed, which keeps nominal batches in cache.
"""

from __future__ import annotations

import copy
import os
from collections.abc import Mapping, Sequence

import mujoco
import mujoco.rollout
import numpy as np

from qube_suite import parameters as params
from qube_suite.angles import wrap_angle
from qube_suite.domains import qube

_STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS.value
"""MuJoCo state layout of a world: time, qpos, qvel (the Qube has no other state)."""
_CONTROL = mujoco.mjtState.mjSTATE_CTRL.value

MIN_WORLDS_PER_THREAD = 8
"""Smaller batches step on the calling thread: handing them to the pool costs more than it saves."""


def physics_model(control_frequency: float) -> mujoco.MjModel:
    """The Qube's compiled model for control at `control_frequency` (Hz), without its textures.

    Textures are only drawn; without them a model takes 18 kB instead of 5.5 MB, which
    matters with one model per world. The dynamics are those of `qube.make_physics`.
    """
    qube.check_control_frequency(control_frequency)
    spec = mujoco.MjSpec.from_file(str(qube.MODEL_PATH))
    for texture in list(spec.textures):
        spec.delete(texture)
    for material in spec.materials:
        material.textures = [""] * len(material.textures)
    model = spec.compile()
    model.opt.timestep = qube.physics_timestep(control_frequency)
    return model


class QubeBatch:
    """`num_worlds` simulated Qubes with the domain interface's accessors, one value per world.

    Args:
        num_worlds: number of Qubes.
        control_frequency: control steps per second (Hz); one `step` is one control period.
        threads: threads of the rollout pool; default: the machine's CPU count.
    """

    def __init__(self, num_worlds: int, control_frequency: float = 250.0, threads: int | None = None):
        if not (isinstance(num_worlds, int) and not isinstance(num_worlds, bool) and num_worlds >= 1):
            raise ValueError(f"num_worlds must be a positive integer, got {num_worlds!r}")
        template = physics_model(control_frequency)
        self.num_worlds = num_worlds
        self._substeps = qube.substeps_per_control_period(control_frequency)
        self._template = template
        self._models = [template] * num_worlds
        self._parameters = [dict(params.NOMINAL) for _ in range(num_worlds)]
        self._scratch = mujoco.MjData(template)

        if threads is None:
            threads = os.cpu_count() or 1
        if not (isinstance(threads, int) and not isinstance(threads, bool) and threads >= 0):
            raise ValueError(f"threads must be a non-negative integer or None, got {threads!r}")
        if num_worlds < MIN_WORLDS_PER_THREAD * threads:
            threads = 0
        self._pool = mujoco.rollout.Rollout(nthread=threads)
        self._datas = [mujoco.MjData(template) for _ in range(max(threads, 1))]

        ids = qube.ElementIds(template)
        self._theta, self._alpha = 1 + ids.arm_qpos, 1 + ids.pendulum_qpos
        self._dtheta, self._dalpha = 1 + template.nq + ids.arm_dof, 1 + template.nq + ids.pendulum_dof
        self._angle_columns = [self._theta, self._alpha]
        self._velocity_columns = [self._dtheta, self._dalpha]
        mujoco.mj_resetData(template, self._scratch)
        start = np.empty(mujoco.mj_stateSize(template, _STATE))
        mujoco.mj_getState(template, self._scratch, start, _STATE)
        self._state = np.tile(start, (num_worlds, 1))
        """State of each world (time, qpos, qvel), one row per world."""
        self._trajectory = np.empty((num_worlds, self._substeps, start.size))
        self._control = np.zeros((num_worlds, self._substeps, template.nu))
        self._voltage = np.zeros(num_worlds)
        self.diverged = np.zeros(num_worlds, dtype=bool)
        """Which worlds' simulation diverged in the last `step` (that step was undone for them)."""
        self._measure()

    # -- the domain interface, one value per world ----------------------------------

    def arm_angle(self) -> np.ndarray:
        """Arm angles theta (rad) in (-pi, pi]."""
        return self._measured[0]

    def pendulum_angle(self) -> np.ndarray:
        """Pendulum angles alpha (rad) in (-pi, pi], 0 = upright."""
        return self._measured[1]

    def arm_velocity(self) -> np.ndarray:
        """d theta / dt (rad/s)."""
        return self._measured[2]

    def pendulum_velocity(self) -> np.ndarray:
        """d alpha / dt (rad/s)."""
        return self._measured[3]

    def qube_state(self) -> np.ndarray:
        """[theta, alpha, dtheta, dalpha] of each world, shape (num_worlds, 4)."""
        return np.stack(self._measured, axis=1)

    def time(self) -> np.ndarray:
        """Simulated time of each world since its episode started (s)."""
        return self._state[:, 0]

    def voltage(self) -> np.ndarray:
        """Motor voltages (V) held since the last `step`."""
        return self._voltage

    def step(self, volts: np.ndarray) -> None:
        """Hold `volts` (V, one per world, already validated and limited) for one control period.

        All worlds advance in one rollout call; then they are measured. A world whose
        simulation diverges (speeds beyond `qube.MAX_PLAUSIBLE_SPEED`, inf or NaN) goes
        back to its state before the step, its time advanced, and is marked in `diverged`.
        """
        self._voltage = volts
        self._control[:, :, 0] = volts[:, None]
        self._pool.rollout(self._models, self._datas, self._state, self._control, control_spec=_CONTROL,
                           skip_checks=True, nstep=self._substeps, state=self._trajectory)
        end = self._trajectory[:, -1]
        speeds = np.abs(end[:, self._dtheta]) + np.abs(end[:, self._dalpha])
        self.diverged = ~(speeds < qube.MAX_PLAUSIBLE_SPEED)  # also catches inf and NaN
        if self.diverged.any():
            end[self.diverged, 1:] = self._state[self.diverged, 1:]
        self._state[:] = end
        self._measure()

    def reset_world(self, world: int, state: Sequence[float]) -> None:
        """Start `world`'s episode from [theta, alpha, dtheta, dalpha] at time 0, voltage 0 V."""
        theta, alpha, dtheta, dalpha = (float(x) for x in state)
        row = self._state[world]
        row[0] = 0.0
        row[self._theta], row[self._alpha] = theta, alpha
        row[self._dtheta], row[self._dalpha] = dtheta, dalpha
        self._voltage[world] = 0.0
        measured = self._measured
        measured[0][world], measured[1][world] = wrap_angle(theta), wrap_angle(alpha)
        measured[2][world], measured[3][world] = dtheta, dalpha

    # -- per-world physical parameters ----------------------------------------------

    def parameters(self, world: int) -> Mapping[str, float]:
        """Physical parameters of `world`, by long name (a copy)."""
        return dict(self._parameters[world])

    def set_parameters(self, world: int, overrides: Mapping[str, float] | None = None) -> None:
        """Set `world`'s parameters to the nominal ones updated by `overrides`, in place.

        Takes effect from the next `step`; the state is kept. Raises ValueError for an
        unknown name or an impossible value (the model is unchanged then).
        """
        model = self._models[world]
        if model is self._template:
            model = copy.copy(self._template)
        self._parameters[world] = qube.write_parameters(model, self._scratch, overrides)
        self._models[world] = model

    def close(self) -> None:
        """Stop the rollout threads."""
        self._pool.close()

    # -- helpers ------------------------------------------------------------------------

    def _measure(self) -> None:
        angles = wrap_angle(self._state[:, self._angle_columns])
        velocities = self._state[:, self._velocity_columns]
        self._measured = [angles[:, 0], angles[:, 1], velocities[:, 0], velocities[:, 1]]
