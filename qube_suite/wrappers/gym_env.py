"""Any qube_suite dm_env environment as a Gymnasium environment."""

from __future__ import annotations

import os
import sys
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from qube_suite.environment import Environment
from qube_suite.media import DEFAULT_CAMERA, FrameRenderer
from qube_suite.pacing import RealTimePacer
from qube_suite.tasks.base import voltage_from_action

RENDER_MODES = ("human", "rgb_array")


def display_available() -> bool:
    """Whether a window can be opened (MuJoCo's viewer aborts the process when it cannot)."""
    if sys.platform != "linux":
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def action_space(spec) -> spaces.Box:
    """The float32 Box of a dm_env action spec (the motor voltage, V)."""
    return spaces.Box(np.float32(np.min(spec.minimum)), np.float32(np.max(spec.maximum)),
                      shape=spec.shape, dtype=np.float32)


def observation_space(spec) -> spaces.Box:
    """The flat float32 Box of a dm_env observation spec (an OrderedDict of arrays), keys in order."""
    lows, highs = [], []
    for array in spec.values():
        lows.append(np.broadcast_to(getattr(array, "minimum", -np.inf), array.shape))
        highs.append(np.broadcast_to(getattr(array, "maximum", np.inf), array.shape))
    return spaces.Box(np.concatenate(lows).astype(np.float32), np.concatenate(highs).astype(np.float32),
                      dtype=np.float32)


class QubeEnv(gymnasium.Env):
    """A Qube task with Gymnasium's API (obtain one with `to_gymnasium` or `gymnasium.make`).

    ## Spaces
    Action: Box(-voltage_limit, voltage_limit, (1,), float32), the motor voltage
    (V); values beyond the limit are clipped, NaN/inf or a shape other than (1,)
    (a plain number too) raise ValueError ("Action dimension mismatch" for a
    shape) and leave the environment unchanged (docs/conventions.md).
    Observation: Box of float32, the dm_env observation flattened in key order:
    [theta, alpha, dtheta, dalpha] (+ [theta_target] in follow tasks); angles in
    (-pi, pi], alpha = 0 upright. With `observation="trig"`: [cos theta, sin theta,
    cos alpha, sin alpha, dtheta, dalpha] (+ target).

    ## Reward and start
    The task's: see its class docstring (e.g. `help(qube_suite.devices.qube.tasks.Swingup)`) and
    the task table in docs/tasks.md. Rewards are per step, at most 1.

    ## Episode end
    `terminated` when the task's safe set is left (arm beyond +-90 degrees, and in
    balance tasks the pendulum beyond +-20 degrees), or when the simulation
    diverged (reward 0, `info["physics_error"]`); `truncated` at the time limit.
    Stepping after either, or after a step that raised (e.g. a hardware safety
    stop), without `reset()` raises RuntimeError.

    ## Info
    `time` (s), `voltage` (V, as commanded after clipping), `target` (rad, follow tasks),
    and `physics_error` (a message) in the step where the simulation diverged.
    With a randomization, `reset` adds what the episode drew: `parameters` (name ->
    value of each randomized physical parameter) and `effects` (effect name ->
    settings).

    ## Rendering
    `render_mode="rgb_array"` returns frames from `camera` ("front_oblique",
    "front" or "top") of `width` x `height` (`qube_suite.media.FrameRenderer`; the
    LED strip shows the LED's colour, and on hardware a digital twin shows the
    measured state); `"human"` opens MuJoCo's viewer (offered only where a display
    exists) and shows every control step at real time (`metadata["render_fps"]`, the control
    rate), as Gymnasium's MuJoCo environments do.

    Args:
        environment: a qube_suite dm_env environment (`suite.load`).
        render_mode: None, "rgb_array" or "human".
        width, height: frame size (pixels) for "rgb_array".
        camera: the camera for "rgb_array".
    """

    metadata = {"render_modes": list(RENDER_MODES), "render_fps": 250}

    def __init__(self, environment: Environment, render_mode: str | None = None,
                 width: int = 640, height: int = 480, camera: str = DEFAULT_CAMERA):
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode must be one of {RENDER_MODES} or None, got {render_mode!r}")
        if render_mode == "human" and not display_available():
            raise ValueError("render_mode='human' needs a display (DISPLAY is not set); "
                             "use render_mode='rgb_array' to get frames offscreen")
        self.environment = environment
        self._task, self._physics = environment.task, environment.physics  # fixed for its lifetime
        self.render_mode = render_mode
        self._frames = FrameRenderer(camera, int(width), int(height)) if render_mode == "rgb_array" else None
        self._viewer = None
        self._pacer = RealTimePacer()  # "human": one frame per control step, at real time
        self._closed = False
        self._follows_target = getattr(environment.task, "follows_target", False)
        self.metadata = {
            "render_modes": [mode for mode in RENDER_MODES if mode != "human" or display_available()],
            "render_fps": int(round(environment.control_frequency)),
        }

        self.action_space = action_space(environment.action_spec())
        self.observation_space = observation_space(environment.observation_spec())

    @property
    def task(self):
        return self._task

    @property
    def physics(self):
        return self._physics

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start an episode; `seed` reseeds the task's random state (same seed, same episode)."""
        super().reset(seed=seed)
        self.environment.start_episode(seed)
        if self.render_mode == "human":
            self.render()
            self._pacer.restart(self.physics.time())
        info = self._info()
        drawn = self.environment.randomization_sample
        if drawn is not None:
            info["parameters"], info["effects"] = drawn.parameters, drawn.effects
        return self._observation(), info

    def step(self, action):
        environment = self.environment
        if environment.needs_reset:
            if self._closed or environment.closed:
                raise RuntimeError("the environment is closed; make a new one to run episodes")
            raise RuntimeError("no episode is running (never reset, or the last one ended); "
                               "call reset() before step()")
        if not (type(action) is np.ndarray and action.shape == self._task.action_shape):
            try:
                voltage_from_action(action, self._task.voltage_limit, allow_number=False,
                                    shape=self._task.action_shape)
            except ValueError:
                self._physics.stop_motor()  # on hardware: 0 V before the refusal rises
                raise
        reward, discount = environment.advance(action)
        terminated = discount == 0.0
        truncated = discount == 1.0
        try:
            if self.render_mode == "human":
                self.render()
            info = self._info()
            if terminated and environment.physics_error is not None:
                info["physics_error"] = environment.physics_error
            return self._observation(), reward, terminated, truncated, info
        except BaseException:
            environment.stop_episode()  # on hardware: no voltage left on after a failure here
            raise

    def render(self):
        if self.environment.closed:
            raise RuntimeError("the environment is closed: nothing to render")
        if self.render_mode == "rgb_array":
            return self._frames.render(self.physics)
        if self.render_mode == "human":
            scene = self.physics.drawable()
            if self._viewer is None:
                from mujoco import viewer

                self._viewer = viewer.launch_passive(scene.model.ptr, scene.data.ptr)
            self._viewer.sync()
            if not getattr(self.physics, "paced_by_board", False):  # a board keeps its own time
                self._pacer.wait(self.physics.time())
        return None

    def close(self):
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None
        if self._frames is not None:
            self._frames.close()
        if not self._closed:
            self._closed = True
            self.environment.close()

    def __getstate__(self) -> dict:
        """Everything but the open viewer (a copy opens its own when it renders)."""
        state = dict(self.__dict__)
        state["_viewer"] = None
        return state

    def _observation(self) -> np.ndarray:
        return np.array(self._task.observation_values(self._physics), dtype=np.float32)

    def _info(self) -> dict[str, Any]:
        physics = self._physics
        info = {"time": physics.time(), "voltage": physics.voltage()}
        if self._follows_target:
            info["target"] = self._task.target
        return info


class StopMotorAtEpisodeEnd(gymnasium.Wrapper, gymnasium.utils.RecordConstructorArgs):
    """The outermost wrapper of the hardware ids: what `gymnasium.make` wraps around a hardware
    environment (its `TimeLimit` of `max_episode_steps` and any checker) cannot leave the motor driven.

    When a step ends the episode (terminated, or truncated by a wrapper's time limit), the board
    idles (0 V, amplifier off) before the step returns; when anything below raises, the motor is at
    0 V before the error rises. Wrappers a program adds around this one are outside its reach: the
    board's watchdog covers those.
    """

    def __init__(self, env: gymnasium.Env):
        gymnasium.utils.RecordConstructorArgs.__init__(self)
        gymnasium.Wrapper.__init__(self, env)

    def step(self, action):
        try:
            observation, reward, terminated, truncated, info = self.env.step(action)
        except BaseException:
            self.env.unwrapped.physics.stop_motor()
            raise
        if terminated or truncated:
            self.env.unwrapped.environment.stop_episode()
        return observation, reward, terminated, truncated, info


def to_gymnasium(environment: Environment, render_mode: str | None = None, **render_kwargs) -> QubeEnv:
    """Wrap a qube_suite dm_env `environment` as a Gymnasium environment.

    `render_kwargs`: `width`, `height`, `camera`.
    """
    return QubeEnv(environment, render_mode=render_mode, **render_kwargs)
