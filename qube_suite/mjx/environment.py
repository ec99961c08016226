"""The Qube's tasks on MJX: a functional environment of one world, batched with `jax.vmap`.

`QubeMjx(task)` follows Brax's environment API (`reset(rng) -> State`,
`step(state, action) -> State`, `sys`, `observation_size`, `action_size`), so Brax's
training loop runs it as it is, with `Worlds.draw` as its domain randomization.
What the world does each control step is the numpy `qube` domain's: the action
(in [-1, 1]) times the task's voltage limit, through the actuator effects (delay,
offset, dead zone, saturation) to the motor of `qube.xml`; one control period of
MuJoCo's step (MJX, float32), jittered with `control_jitter`; the sensor effects
(quantization, velocity filter, noise, delay) on the exact state. The task object
itself (`qube_suite.tasks`) gives the reward, the safe set and the observation: its
formulas run on JAX arrays (`tasks.elementwise`), on the state of its processes
that the environment carries (`qube_suite.mjx.processes`), and its start
distribution (`tasks.starts`) is drawn with `jax.random`.

With `history=k` the observation is the policy's input with its last k observations
and voltages, laid out as `qube_suite.policies.history` lays them out, so that an
exported policy with that history runs on the numpy domains. With
`privileged_critic=True` the observation is Brax's dictionary of a policy part
(`"state"`) and a critic part (`"privileged_state"`: the policy's input, the exact
state and the world's drawn plant and effects), for PPO with an asymmetric critic.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from brax.envs.base import Env, State
from mujoco import mjx

from qube_suite.angles import wrap_angle
from qube_suite.conventions import MAX_VOLTAGE_LIMIT
from qube_suite.devices.qube import batch as qube_batch
from qube_suite.devices.qube import simulation as qube
from qube_suite.devices.qube import tasks as qube_tasks
from qube_suite.mjx import offered, processes
from qube_suite.mjx import worlds as world_draws
from qube_suite.policies import features
from qube_suite.policies.history import input_size
from qube_suite.randomization import config as randomization_config
from qube_suite.randomization.timing import ControlJitter
from qube_suite.tasks.starts import ClippedNormalStart, UniformStart
from qube_suite.velocity_filter import filtered_velocity


class MeasuredQube:
    """The domain interface's accessors (`domains.interface.QubePhysics`) on one world's measured
    state [theta, alpha, dtheta, dalpha] (JAX arrays), for the task's formulas."""

    def __init__(self, measured: jax.Array, time: jax.Array):
        self._measured, self._time = measured, time

    def arm_angle(self):
        return self._measured[0]

    def pendulum_angle(self):
        return self._measured[1]

    def arm_velocity(self):
        return self._measured[2]

    def pendulum_velocity(self):
        return self._measured[3]

    def time(self):
        return self._time


class QubeMjx(Env):
    """One simulated Qube running `task`, in JAX.

    Args:
        task: a name of `offered.TASKS`.
        randomization: a preset name, mapping or YAML path (`qube_suite.randomization.config`):
            `sys`, the world `reset` and `step` run unless a training loop swaps in others, is
            drawn from it with `seed`, and `draw_worlds` draws many.
        control_frequency: control steps per second (Hz).
        voltage_limit: largest motor voltage (V); default: the task's.
        seed: seeds the world draws of `draw_worlds`.
        history: the number of past observations and voltages the policy sees (0 for none).
        privileged_critic: give the critic the exact state and the world's plant (observation
            `{"state": ..., "privileged_state": ...}`).
        task_kwargs: the task's settings, e.g. a follow task's target schedule (`{"target": "sine"}`).
    """

    def __init__(self, task: str = "swingup", randomization="none", control_frequency: float = 250.0,
                 voltage_limit: float | None = None, seed: int = 0, history: int = 0,
                 privileged_critic: bool = False, task_kwargs: Mapping[str, Any] | None = None):
        offered.check_task(task)
        qube.check_control_frequency(control_frequency)
        if not (isinstance(history, int) and not isinstance(history, bool) and history >= 0):
            raise ValueError(f"history must be an integer >= 0, got {history!r}")
        self.history = history
        self.privileged_critic = bool(privileged_critic)
        limit = {} if voltage_limit is None else {"voltage_limit": voltage_limit}
        task_kwargs = dict(task_kwargs or {})
        for reserved in ("random", "observation", "worlds", "voltage_limit"):
            if reserved in task_kwargs:
                raise ValueError(f"task_kwargs: {reserved!r} is set by the environment, not the task's "
                                 "settings (draws come from the JAX key; voltage_limit is a keyword)")
        self.task = qube_tasks.SUITE[task](**limit, **task_kwargs)
        processes.check(self.task)
        self._features = features.trig(np.zeros((1, self.task_observation_size))).shape[1]
        self.task_name = task
        self.config = randomization_config.load(randomization)
        self.control_frequency = float(control_frequency)
        self.seed = int(seed)
        self._substeps = qube.substeps_per_control_period(control_frequency)
        longest = (1.0 + world_draws.max_jitter_fraction(self.config)) / control_frequency
        self._most_substeps = int(qube.split_step(longest)[0])
        self._line_lengths = {name: world_draws.max_delay_steps(self.config, name, control_frequency) + 1
                              for name in world_draws.DELAYS}
        self._effects = set(self.config.effects)
        self.sys, _ = world_draws.draw(self.config, None, self.seed, self.control_frequency)
        ids = qube.ElementIds(qube_batch.physics_model(control_frequency))
        self._ids = ids
        self._positions = jnp.array([ids.arm_qpos, ids.pendulum_qpos])
        self._velocities = jnp.array([ids.arm_dof, ids.pendulum_dof])

    # -- Brax's environment API ----------------------------------------------------

    @property
    def observation_size(self) -> int | dict[str, tuple[int]]:
        policy = input_size(self._features, self.history)
        if self.privileged_critic:
            critic = policy + EXACT_FEATURES + len(PRIVILEGED_PLANT)
            return {"state": (policy,), "privileged_state": (critic,)}
        return policy

    @property
    def action_size(self) -> int:
        return 1

    @property
    def backend(self) -> str:
        return "mjx"

    def draw_worlds(self, sys, rng: jax.Array):
        """Brax's `randomization_fn`: as many worlds as `rng` has keys, drawn from the config (world i
        from `seed + i`), and their `in_axes`. `sys` (this environment's own world) is not used."""
        return world_draws.draw(self.config, int(rng.shape[0]), self.seed, self.control_frequency)

    def reset(self, rng: jax.Array) -> State:
        """A new episode from the task's start distribution."""
        rng, start_key = jax.random.split(rng)
        return self.start(draw_start(self.task.start, start_key), rng)

    def start(self, state: jax.Array, rng: jax.Array) -> State:
        """An episode from [theta, alpha, dtheta, dalpha] (rad, rad/s) at time 0, 0 V."""
        data = mjx.make_data(self.sys.model)
        data = data.replace(qpos=data.qpos.at[self._positions].set(state[:2]),
                            qvel=data.qvel.at[self._velocities].set(state[2:]))
        rng, noise_key, task_key = jax.random.split(rng, 3)
        filtered = self._quantize(self.exact_state(data))  # the velocity filter settles on it
        measured = self._add_noise(filtered, noise_key)
        process = processes.first_process(self.task, MeasuredQube(measured, data.time), task_key)
        memory = {"filter": filtered,
                  "commands": jnp.zeros(self._line_lengths["action_delay"], data.ctrl.dtype),
                  "observations": jnp.tile(measured, (self._line_lengths["observation_delay"], 1)),
                  "task": process}
        info = {"rng": rng, "measured": measured, "memory": memory, "first_memory": memory}
        observation, reward, done = self.rules(measured, data.time, process)
        features = self.features(observation)
        past = jnp.tile(features, self.history)
        obs = self._observation(jnp.concatenate([features, past, jnp.zeros(self.history, features.dtype)]),
                                data)
        return State(pipeline_state=data, obs=obs, reward=jnp.zeros_like(reward), done=jnp.zeros_like(done),
                     metrics={}, info=info)

    def step(self, state: State, action: jax.Array) -> State:
        """One control period holding the voltage `action[0] * voltage_limit` (action clipped to
        [-1, 1], a non-finite action taken as 0)."""
        action = jnp.where(jnp.isfinite(action[0]), jnp.clip(action[0], -1.0, 1.0), 0.0)
        volts = action * self.task.voltage_limit
        data = state.pipeline_state
        info = dict(state.info)
        # an episode's first step: Brax's auto-reset puts back the first physics and observation, not
        # the info, so the memory is put back here as the episode's start left it
        fresh = data.time == 0.0
        memory = jax.tree.map(lambda first, last: jnp.where(fresh, first, last), info["first_memory"],
                              info["memory"])
        motor, memory["commands"] = self._actuate(volts, memory["commands"])
        data = data.replace(ctrl=jnp.reshape(motor, (1,)).astype(data.ctrl.dtype))
        data, info["rng"] = self._control_period(data, info["rng"])
        exact = self.exact_state(data)
        diverged = ~qube.plausible(exact[2], exact[3])
        info["rng"], noise_key, task_key = jax.random.split(info["rng"], 3)
        measured = self._quantize(exact)
        if "velocity_filter" in self._effects:
            last = memory["filter"]
            velocities = filtered_velocity(last[2:], measured[:2], last[:2], self.sys.filter_pole,
                                           self.sys.filter_gain)
            measured = jnp.concatenate([measured[:2], velocities])
            memory["filter"] = measured
        measured = self._add_noise(measured, noise_key)
        measured, memory["observations"] = self._delay_observation(measured, memory["observations"])
        time = self.episode_time(data)
        view = MeasuredQube(measured, time)
        memory["task"] = processes.next_process(self.task, memory["task"], view, task_key)
        info["measured"], info["memory"] = measured, memory
        observation, reward, done = self.rules(measured, time, memory["task"])
        done = jnp.where(diverged, 1.0, done)
        inputs = self._policy_inputs(state.obs, self.features(observation), volts)
        obs = jax.tree.map(lambda last, new: jnp.where(diverged, last, new), state.obs,
                           self._observation(inputs, data))
        return state.replace(pipeline_state=data, obs=obs, reward=reward, done=done, info=info)

    def exact_state(self, data: mjx.Data) -> jax.Array:
        """[theta, alpha, dtheta, dalpha] of a world (rad, rad/s), angles wrapped to (-pi, pi]."""
        return jnp.concatenate([wrap_angle(data.qpos[self._positions]), data.qvel[self._velocities]])

    def _control_period(self, data: mjx.Data, rng: jax.Array) -> tuple[mjx.Data, jax.Array]:
        """`data` after one control period of MuJoCo's step, and the world's key `rng` after its draws:
        the nominal period in `_substeps` equal steps, or with `control_jitter` a period drawn by the
        effect's own formula (`ControlJitter.jittered`) in the fewest equal steps of at most MAX_TIMESTEP
        (`qube.split_step`), as the numpy domain splits it; a batch runs the longest period's number of
        steps, masked."""
        if "control_jitter" not in self._effects:
            for _ in range(self._substeps):
                data = mjx.step(self.sys.model, data)
            return data, rng
        rng, key = jax.random.split(rng)
        duration = ControlJitter.jittered(1.0 / self.control_frequency, self.sys.jitter_fraction,
                                          jax.random.uniform(key, dtype=data.time.dtype))
        substeps, timestep = qube.split_step(duration)
        model = self.sys.model.replace(opt=self.sys.model.opt.replace(timestep=timestep))
        for substep in range(self._most_substeps):
            stepped = mjx.step(model, data)
            run = substep < substeps
            data = jax.tree.map(lambda new, old, run=run: jnp.where(run, new, old), stepped, data)
        return data, rng

    def episode_time(self, data: mjx.Data) -> jax.Array:
        """The episode's time (s) as the task's processes read it: whole control periods, so that float32
        steps of MuJoCo's clock do not move a scheduled change by a step; with `control_jitter`, MuJoCo's
        clock itself, as the numpy domain's `time()`."""
        if "control_jitter" in self._effects:
            return data.time
        return jnp.round(data.time * self.control_frequency) / self.control_frequency

    # -- the task's rules ------------------------------------------------------------

    def rules(self, measured: jax.Array, time: jax.Array, process=None
              ) -> tuple[jax.Array, jax.Array, jax.Array]:
        """The task's observation ([theta, alpha, dtheta, dalpha], and theta_target for a follow task),
        reward and done (1.0 outside the safe set) for one measured state [theta, alpha, dtheta, dalpha]
        and the state of its processes (`processes`), from the task object's own formulas."""
        view, task = MeasuredQube(measured, time), self.task.with_process(process)
        obs = jnp.stack([jnp.asarray(value, measured.dtype) for value in task.observation_values(view)])
        reward = jnp.asarray(task.get_reward(view), measured.dtype)
        done = 1.0 - jnp.asarray(task.in_safe_set(view), measured.dtype)
        return obs, reward, done

    # -- observations ----------------------------------------------------------------

    @property
    def task_observation_size(self) -> int:
        """Values in the task's observation: 4, or 5 with a follow target."""
        return 5 if self.task.follows_target else 4

    def features(self, observation: jax.Array) -> jax.Array:
        """The policy's features of the task's `observation`: the numpy policies' own feature map
        (`qube_suite.policies.features.trig`)."""
        return features.trig(observation[None])[0]

    def _policy_inputs(self, last_obs, features: jax.Array, volts: jax.Array) -> jax.Array:
        """The policy's input: `features` with the last input's features and voltages moved one step
        back and the voltage `volts` (V) just applied (`qube_suite.policies.history`'s layout)."""
        if not self.history:
            return features
        last = last_obs["state"] if self.privileged_critic else last_obs
        size, k = features.shape[0], self.history
        past = jnp.concatenate([last[:size], last[size:size * k]])
        voltages = jnp.concatenate([jnp.reshape(volts, (1,)).astype(last.dtype), last[size * (1 + k):-1]])
        return jnp.concatenate([features, past, voltages])

    def _observation(self, inputs: jax.Array, data: mjx.Data):
        """What the environment returns: the policy's `inputs`, or with a privileged critic Brax's
        dictionary of them and the critic's input (the inputs, the exact state as the task's features
        would give it, the world's plant and effects)."""
        if not self.privileged_critic:
            return inputs
        exact = self.exact_state(data)
        trig = jnp.stack([jnp.cos(exact[0]), jnp.sin(exact[0]), jnp.cos(exact[1]), jnp.sin(exact[1]),
                          exact[2], exact[3]])
        plant = jnp.stack([jnp.asarray(read(self.sys, self._ids), inputs.dtype)
                           for read in PRIVILEGED_PLANT.values()])
        critic = jnp.concatenate([inputs, trig.astype(inputs.dtype), plant])
        return {"state": inputs, "privileged_state": critic}

    # -- effects ---------------------------------------------------------------------

    def _actuate(self, volts: jax.Array, commands: jax.Array) -> tuple[jax.Array, jax.Array]:
        """The motor voltage (V) for the command `volts`, and the updated delay line (newest last)."""
        if "action_delay" in self._effects:
            volts, commands = _delayed(volts, commands, self.sys.delay_steps)
        if "voltage_offset" in self._effects:
            volts = volts + self.sys.voltage_offset
        if "dead_zone" in self._effects:
            volts = jnp.sign(volts) * jnp.maximum(jnp.abs(volts) - self.sys.dead_zone, 0.0)
        if "saturation" in self._effects:
            volts = jnp.clip(volts, -self.sys.saturation, self.sys.saturation)
        return volts, commands

    def _delay_observation(self, measured: jax.Array, observations: jax.Array) -> tuple[jax.Array, jax.Array]:
        """The measured state the task sees, and the updated delay line of measured states (newest last)."""
        if "observation_delay" not in self._effects:
            return measured, observations
        return _delayed(measured, observations, self.sys.observation_delay_steps)

    def _quantize(self, exact: jax.Array) -> jax.Array:
        if "quantization" not in self._effects:
            return exact
        q = self.sys.resolution
        return jnp.concatenate([wrap_angle(q * jnp.round(exact[:2] / q)), exact[2:]])

    def _add_noise(self, measured: jax.Array, key: jax.Array) -> jax.Array:
        if "observation_noise" not in self._effects:
            return measured
        noisy = measured + self.sys.noise_std * jax.random.normal(key, (4,), measured.dtype)
        return jnp.concatenate([wrap_angle(noisy[:2]), noisy[2:]])


def _delayed(signal: jax.Array, line: jax.Array, steps: jax.Array) -> tuple[jax.Array, jax.Array]:
    """`signal` of `steps` control steps before, from `line` (its past values along the first axis, newest
    last, as long as the longest delay plus one), and the line with `signal` added."""
    line = jnp.concatenate([line[1:], signal[None]])
    return line[line.shape[0] - 1 - steps], line


EXACT_FEATURES = 6
"""Features of the exact state the privileged critic sees: cos and sin of both angles, both velocities."""
PRIVILEGED_PLANT = {
    "arm_damping": lambda sys, ids: sys.model.dof_damping[ids.arm_dof],
    "pendulum_damping": lambda sys, ids: sys.model.dof_damping[ids.pendulum_dof],
    "arm_inertia": lambda sys, ids: sys.model.dof_armature[ids.arm_dof],
    "arm_friction": lambda sys, ids: sys.model.dof_frictionloss[ids.arm_dof],
    "pendulum_friction": lambda sys, ids: sys.model.dof_frictionloss[ids.pendulum_dof],
    "pendulum_mass": lambda sys, ids: sys.model.body_mass[ids.pendulum],
    "motor_gain": lambda sys, ids: sys.model.actuator_gainprm[ids.motor, 0],
    "cable_stiffness": lambda sys, ids: sys.model.jnt_stiffness[ids.arm_joint],
    "observation_delay_steps": lambda sys, ids: sys.observation_delay_steps,
    "delay_steps": lambda sys, ids: sys.delay_steps,
    "voltage_offset": lambda sys, ids: sys.voltage_offset,
    "dead_zone": lambda sys, ids: sys.dead_zone,
    "saturation": lambda sys, ids: jnp.minimum(sys.saturation, MAX_VOLTAGE_LIMIT),
    "jitter_fraction": lambda sys, ids: sys.jitter_fraction,
}
"""What the privileged critic knows of its world, by name: model fields the randomization draws
(`qube.write_parameters`) and the drawn effects (the saturation at most the largest voltage a task asks
for, which it is when the effect is off)."""


def draw_start(start: UniformStart | ClippedNormalStart, key: jax.Array) -> jax.Array:
    """A start state drawn with `jax.random` from the task's start distribution (`tasks.starts`)."""
    if isinstance(start, UniformStart):
        u = jax.random.uniform(key, (4,), minval=start.low, maxval=start.high)
        return jnp.asarray(start.scale) * u + jnp.asarray(start.offset)
    if isinstance(start, ClippedNormalStart):
        std = jnp.asarray(start.std)
        return jnp.clip(std * jax.random.normal(key, (4,)), -start.clip * std, start.clip * std)
    raise TypeError(f"no JAX draw for the start distribution {start!r}")
