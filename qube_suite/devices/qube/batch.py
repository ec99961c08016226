"""A batch of simulated Qubes stepped together: one MuJoCo model per world, `mujoco.rollout` threads.

`QubeBatch(n)` holds n independent Qubes ("worlds"). Its accessors are those of the
domain interface (`qube_suite.domains.interface.QubePhysics`), each returning one
value per world as an array, so the tasks' formulas evaluate every world at once.
`step` advances all worlds by one control period in a single call to MuJoCo's
rollout on a persistent thread pool, which runs without the GIL. World i has its
own model, so its physical parameters can differ (`set_parameters`); worlds share
one model until their parameters are changed, which keeps nominal batches in cache.

Like the single `qube.Physics`, a batch takes a sensor, an actuator and a
step-duration model (`set_sensor_model`, ...): here effects on arrays with one row
per world (`qube_suite.randomization.Chain`), restarted for just the worlds
that start an episode. With a step-duration model each world's step is split
into its own number of equal timesteps (at most `qube.MAX_TIMESTEP`), set in its
own model, and the worlds taking the same number advance in one rollout call.

A world given a calibration (`set_parameters(world, "my_qube.yaml")`) gets its effects too, as
`qube.make_physics` gives them to one Qube: the latency and dead zone between command and motor,
the cable's rest angle and slack and the pendulum encoder's offset (`parameters.effects_of`).
"""

from __future__ import annotations

import copy
import os
from collections.abc import Mapping, Sequence
from typing import Any

import mujoco
import mujoco.rollout
import numpy as np

from qube_suite.angles import wrap_angle
from qube_suite.devices.qube import parameters as params
from qube_suite.devices.qube import simulation as qube
from qube_suite.domains.effects import Effects

_STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS.value
"""MuJoCo state layout of a world: time, qpos, qvel (the Qube has no other state)."""
_CONTROL = mujoco.mjtState.mjSTATE_CTRL.value

MIN_WORLDS_PER_THREAD = 8
"""Smaller batches step on the calling thread: handing them to the pool costs more than it saves."""


def physics_model(control_frequency: float) -> mujoco.MjModel:
    """The Qube's compiled model (`devices/qube/model.xml`, without the scene) for control at
    `control_frequency` (Hz).

    The scene (bench, lights, cameras, textures) is only drawn; without it a model takes
    9 kB instead of 5.5 MB, which matters with one model per world. The dynamics are
    those of `qube.make_physics`.
    """
    qube.check_control_frequency(control_frequency)
    model = mujoco.MjModel.from_xml_path(str(qube.MODEL_PATH))
    model.opt.timestep = qube.physics_timestep(control_frequency)
    return model


class QubeBatch:
    """`num_worlds` simulated Qubes with the domain interface's accessors, one value per world.

    Each world's measurement is exact (angles wrapped) unless a sensor model is set.
    `reset_world` measures the world afresh, as `qube.Physics.reset_to` does, and so
    does `measure_afresh(worlds)`, as `qube.Physics.reset_context` does on closing:
    a caller mirroring a single environment's reset calls both, so that a noisy
    sensor draws what the single environment's draws.

    Args:
        num_worlds: number of Qubes.
        control_frequency: control steps per second (Hz); one `step` is one control period.
        threads: threads of the rollout pool; default: the machine's CPU count.
    """

    UNMODELLED_PARAMETERS = qube.Physics.UNMODELLED_PARAMETERS

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

        ids = self._ids = qube.ElementIds(template)
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
        self.physics_error = np.zeros(num_worlds, dtype=bool)
        """Which worlds' simulation diverged in the last `step` (that step was undone for them): the
        batch's `physics_error`, one flag per world where one Qube's says why, or None."""
        self._worlds = np.arange(num_worlds)
        self._nominal_durations = np.full(num_worlds, self._substeps * template.opt.timestep)
        """Each world's control period as the physics steps cover it (s)."""
        self._effects = Effects()
        self._step_duration_model = None
        self._cables: np.ndarray | None = None
        """Each world's cable, rest angle and half-width of its slack band (rad), once one is calibrated."""
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

    def true_state(self) -> np.ndarray:
        """Exact [theta, alpha, dtheta, dalpha] of each world, angles wrapped, shape (num_worlds, 4)."""
        return self._exact(self._worlds)

    def time(self) -> np.ndarray:
        """Simulated time of each world since its episode started (s)."""
        return self._state[:, 0]

    def voltage(self) -> np.ndarray:
        """Motor voltages (V) held since the last `step`."""
        return self._voltage

    def set_voltage(self, volts: np.ndarray) -> None:
        """Command one voltage per world (V, already validated and limited), held from the next
        `step`: the domain interface's `set_voltage`, which the task's `before_step` calls."""
        self._voltage = volts

    def step(self) -> None:
        """Hold the commanded voltages (`set_voltage`) for one control period.

        All worlds advance in one rollout call (with a step-duration model, one per number of
        physics steps); then they are measured. A world whose simulation diverges (speeds
        beyond `qube.MAX_PLAUSIBLE_SPEED`, inf or NaN) goes back to its state before the
        step, its time advanced, and is marked in `physics_error`.
        """
        motor = self._effects.actuate(self._voltage)
        if self._step_duration_model is None:
            self._control[:, :, 0] = motor[:, None]
            self._pool.rollout(self._models, self._datas, self._state, self._control, control_spec=_CONTROL,
                               skip_checks=True, nstep=self._substeps, state=self._trajectory)
            end = self._trajectory[:, -1]
            self._undo_diverged(end, self._state)
            self._state[:] = end
        else:
            before = self._state.copy()
            self._step_for(self._step_duration_model(self._nominal_durations), motor)
            self._undo_diverged(self._state, before)
        self._measure()

    def reset_world(self, world: int, state: Sequence[float]) -> None:
        """Start `world`'s episode from [theta, alpha, dtheta, dalpha] at time 0, voltage 0 V.

        Restarts the world's actuator model (at 0 V) and sensor model (from this state).
        """
        theta, alpha, dtheta, dalpha = (float(x) for x in state)
        row = self._state[world]
        row[0] = 0.0
        row[self._theta], row[self._alpha] = theta, alpha
        row[self._dtheta], row[self._dalpha] = dtheta, dalpha
        self._voltage[world] = 0.0
        exact = wrap_angle(theta), wrap_angle(alpha), dtheta, dalpha
        rows = np.array([world])
        self._effects.restart_actuation(np.zeros(1), rows)
        if not self._effects.senses_exactly:
            exact = self._effects.restart(np.array([exact]), rows)[0].tolist()
        measured = self._measured
        measured[0][world], measured[1][world], measured[2][world], measured[3][world] = exact

    def measure_afresh(self, worlds: np.ndarray) -> None:
        """Measure `worlds` (indices) from their states again, restarting their sensor model."""
        if self._effects.sensor is None:
            return  # the measurement is current: only `step` and `reset_world` move a world
        measured = self._effects.restart(self._exact(worlds), worlds)
        for column in range(4):
            self._measured[column][worlds] = measured[:, column]

    # -- sensor, actuator and step-duration models ------------------------------------

    def set_sensor_model(self, sensor_model) -> None:
        """Measure through `sensor_model`; None: exactly.

        `sensor_model(exact) -> measured` is called after every `step` with the exact
        states (num_worlds, 4) (angles wrapped); `sensor_model.reset(exact, rows)`
        restarts worlds `rows` from their states `exact` (len(rows), 4) whenever a world
        starts (`reset_world`, `measure_afresh`) and returns their measurements. Setting
        it restarts it for every world now.
        """
        self._effects.sensor = sensor_model
        if sensor_model is None:
            self._measure()
        else:
            measured = self._effects.restart(self._exact(self._worlds))
            self._measured = [measured[:, column] for column in range(4)]

    def set_actuator_model(self, actuator_model) -> None:
        """Drive the motors with `actuator_model(volts) -> volts` on the (num_worlds,) commanded
        voltages, once per `step`; None: as commanded. `actuator_model.reset(volts, rows)`
        restarts worlds `rows` at 0 V in `reset_world`; setting it restarts it for every world
        from the voltages held now."""
        self._effects.actuator = actuator_model
        if actuator_model is not None:
            actuator_model.reset(self._voltage.copy())

    def set_step_duration_model(self, step_duration_model) -> None:
        """Make each world's `step` last `step_duration_model(durations) -> durations` (s, shape
        (num_worlds,)) instead of the control period; None: nominal. Gives every world a model
        of its own, whose timestep each step sets as `qube.Physics` does for one Qube."""
        self._step_duration_model = step_duration_model
        if step_duration_model is not None:
            self._options = [self._own_model(world).opt for world in range(self.num_worlds)]
        else:
            for model in self._models:
                model.opt.timestep = self._template.opt.timestep

    # -- per-world physical parameters ----------------------------------------------

    def parameters(self, world: int) -> Mapping[str, float]:
        """Physical parameters of `world`, by long name (a copy)."""
        return dict(self._parameters[world])

    def set_parameters(self, world: int, overrides: Mapping[str, float] | Any = None) -> None:
        """Set `world`'s parameters to the nominal ones updated by `overrides`, in place: by long
        name (the world keeps any calibrated effects it has, as one simulated Qube does), or a
        calibration or its file's path, whose effects replace the world's (`set_calibrated_effects`).

        Takes effect from the next `step`; the state is kept. Raises ValueError for an
        unknown name or an impossible value (the model is unchanged then).
        """
        values = params.values_of(overrides)
        model = self._own_model(world)
        self._parameters[world] = qube.write_parameters(model, self._scratch, values, self._ids)
        if overrides is not None and not isinstance(overrides, Mapping):
            self.set_calibrated_effects(world, params.effects_of(overrides))
        elif self._cables is not None:  # the cable's spring was rewritten: put its shape back
            qube.write_cable(model, self._ids, self._parameters[world]["cable_stiffness"],
                             *self._cable(world))

    def set_calibrated_effects(self, world: int, effects: Mapping[str, float]) -> None:
        """Give `world` a calibration's effects (`parameters.effects_of`; empty: none), as
        `qube.Physics.set_calibrated_effects` gives one Qube, and restart its command history."""
        stages = self._effects
        if self._cables is None:
            self._cables = np.zeros((self.num_worlds, 2))
            stages.calibrated_actuator = CalibratedActuations(self.num_worlds)
            stages.calibrated_sensor = PendulumEncoderOffsets(self.num_worlds)
        latency = effects.get("latency_seconds", 0.0) / self._nominal_durations[0]
        stages.calibrated_actuator.set(world, latency, effects.get("voltage_deadzone", 0.0))
        stages.calibrated_sensor.offsets[world] = effects.get("pendulum_encoder_offset", 0.0)
        self._cables[world] = effects.get("cable_rest_angle", 0.0), effects.get("cable_slack", 0.0)
        qube.write_cable(self._own_model(world), self._ids, self._parameters[world]["cable_stiffness"],
                         *self._cable(world))
        self._measure()

    def close(self) -> None:
        """Stop the rollout threads."""
        self._pool.close()

    # -- helpers ------------------------------------------------------------------------

    def _undo_diverged(self, after: np.ndarray, before: np.ndarray) -> None:
        """Mark in `physics_error` the worlds whose states `after` a step are implausible and give them
        back their positions and velocities `before` it (their time stays advanced)."""
        self.physics_error = ~qube.plausible(after[:, self._dtheta], after[:, self._dalpha])
        if self.physics_error.any():
            after[self.physics_error, 1:] = before[self.physics_error, 1:]

    def _own_model(self, world: int) -> mujoco.MjModel:
        """`world`'s model, copied from the shared one the first time it needs its own."""
        if self._models[world] is self._template:
            self._models[world] = copy.copy(self._template)
        return self._models[world]

    def _cable(self, world: int) -> tuple[float, float]:
        """`world`'s cable: its rest angle and the half-width of its slack band (rad)."""
        rest, slack = self._cables[world].tolist()
        return rest, slack

    def _step_for(self, durations: np.ndarray, motor: np.ndarray) -> None:
        """Advance each world by its own duration (s) with its motor voltage (V) held: equal timesteps
        of at most MAX_TIMESTEP set in its model, as `qube.Physics` does, and one rollout call for the
        worlds taking the same number of them."""
        nsteps, timesteps = qube.split_step(durations)
        for options, timestep in zip(self._options, timesteps.tolist(), strict=True):
            options.timestep = timestep
        for nstep in np.unique(nsteps).tolist():
            worlds = np.flatnonzero(nsteps == nstep)
            trajectory = np.empty((len(worlds), nstep, self._state.shape[1]))
            self._pool.rollout([self._models[world] for world in worlds.tolist()], self._datas,
                               self._state[worlds], np.repeat(motor[worlds, None, None], nstep, axis=1),
                               control_spec=_CONTROL, skip_checks=True, nstep=nstep, state=trajectory)
            self._state[worlds] = trajectory[:, -1]

    def _exact(self, worlds: np.ndarray) -> np.ndarray:
        """Exact [theta, alpha, dtheta, dalpha] of `worlds`, angles wrapped, shape (len(worlds), 4)."""
        state = self._state[worlds]
        return np.concatenate([wrap_angle(state[:, self._angle_columns]), state[:, self._velocity_columns]],
                              axis=1)

    def _measure(self) -> None:
        angles = wrap_angle(self._state[:, self._angle_columns])
        velocities = self._state[:, self._velocity_columns]
        if self._effects.senses_exactly:
            self._measured = [angles[:, 0], angles[:, 1], velocities[:, 0], velocities[:, 1]]
        else:
            measured = self._effects.measure(np.concatenate([angles, velocities], axis=1))
            self._measured = [measured[:, column] for column in range(4)]


class CalibratedActuations:
    """The array form of `qube.CalibratedActuation` for `num_worlds` Qubes, a calibrated actuator
    stage (`qube_suite.domains.effects`): each world's commands reach its motor `latency` control
    periods (a fraction allowed) later, through a dead zone; worlds never `set` pass as commanded."""

    def __init__(self, num_worlds: int):
        self.whole = np.zeros(num_worlds, dtype=np.intp)
        self.fraction = np.zeros(num_worlds)
        self.deadzone = np.zeros(num_worlds)
        self._history = np.zeros((num_worlds, 2))
        """Commands of each world, oldest first; the last column is the latest."""

    def set(self, world: int, latency: float, deadzone: float) -> None:
        """Give `world` a `latency` (control periods) and a `deadzone` (V), and restart it at 0 V."""
        self.whole[world] = int(np.floor(latency))
        self.fraction[world] = latency - self.whole[world]
        self.deadzone[world] = deadzone
        needed = int(self.whole.max()) + 2
        if needed > self._history.shape[1]:
            grown = np.zeros((len(self.whole), needed))
            grown[:, -self._history.shape[1]:] = self._history
            self._history = grown
        self._history[world] = 0.0

    def reset(self, volts: np.ndarray, rows: np.ndarray | None = None) -> None:
        """Forget the earlier commands of the worlds `rows` (None: all): `volts` (one per row) until new
        ones are due."""
        self._history[slice(None) if rows is None else rows] = np.asarray(volts)[:, None]

    def __call__(self, volts: np.ndarray) -> np.ndarray:
        """The voltages (num_worlds,) reaching the motors when `volts` are commanded now."""
        history = self._history
        history[:, :-1] = history[:, 1:]
        history[:, -1] = volts
        rows, last = np.arange(len(volts)), history.shape[1] - 1
        mixed = ((1.0 - self.fraction) * history[rows, last - self.whole]
                 + self.fraction * history[rows, last - 1 - self.whole])
        return np.sign(mixed) * np.maximum(np.abs(mixed) - self.deadzone, 0.0)


class PendulumEncoderOffsets:
    """The array form of `qube.PendulumEncoderOffset` for `num_worlds` Qubes, a calibrated sensor
    stage (`qube_suite.domains.effects`): each world's pendulum angle read `offsets` (rad) low,
    wrapped."""

    def __init__(self, num_worlds: int):
        self.offsets = np.zeros(num_worlds)

    def reset(self, exact: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """The reading of the `exact` states (len(rows), 4) of the worlds `rows` (None: all)."""
        return self._read(exact, self.offsets if rows is None else self.offsets[rows])

    def __call__(self, exact: np.ndarray) -> np.ndarray:
        """The reading of every world's `exact` state (num_worlds, 4)."""
        return self._read(exact, self.offsets)

    @staticmethod
    def _read(exact: np.ndarray, offsets: np.ndarray) -> np.ndarray:
        if not offsets.any():
            return exact
        read = np.array(exact, dtype=float)
        read[:, 1] = wrap_angle(read[:, 1] - offsets)
        return read
