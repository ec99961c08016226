"""Offscreen frames and mp4 videos of any Qube domain.

    from qube_suite import baselines, media, suite
    env = suite.load("qube", "balance", task_kwargs={"random": 0})
    env.reset()
    frame = media.FrameRenderer(camera="front", width=320, height=240).render(env.physics)
    traces = media.record_video(env, baselines.make("balance"), "balance.mp4", fps=50)

Frames come from `physics.drawable()`, so every domain renders the same way: the
simulation draws itself, the hardware domain draws a digital twin in its measured
state; the LED geom shows the LED colour. Videos need the `media` extra
(imageio-ffmpeg); frames need only an OpenGL library (offscreen: OSMesa or EGL).
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from typing import Any

import mujoco
import numpy as np

from qube_suite import extras
from qube_suite.capabilities import HasBoard
from qube_suite.episodes import EpisodeTrace, Policy, run_episode

DEFAULT_CAMERA = "front_oblique"
"""The camera of the documentation's pictures; the model also has "front" and "top"."""

DEFAULT_WIDTH, DEFAULT_HEIGHT = 640, 480
"""Frame size (pixels)."""


def camera_names(model: mujoco.MjModel) -> tuple[str, ...]:
    """The names of `model`'s cameras."""
    return tuple(model.camera(i).name for i in range(model.ncam))


class FrameRenderer:
    """RGB frames of a Qube domain's physics, offscreen, from one of the model's cameras.

    Args:
        camera: a camera of `scene.xml`: "front_oblique", "front" or "top".
        width, height: frame size (pixels), at most the model's offscreen buffer
            (1280 x 960).

    `render(physics)` returns a (height, width, 3) uint8 array. Use it as a
    context manager, or call `close()`, to free the OpenGL context.
    """

    def __init__(self, camera: str = DEFAULT_CAMERA, width: int = DEFAULT_WIDTH,
                 height: int = DEFAULT_HEIGHT):
        if not (isinstance(width, int) and isinstance(height, int) and width > 0 and height > 0):
            raise ValueError(f"frame width and height must be positive integers, got {width} x {height}")
        self.camera, self.width, self.height = camera, width, height
        self._renderer: mujoco.Renderer | None = None
        self._model: mujoco.MjModel | None = None

    def render(self, physics: Any) -> np.ndarray:
        """The frame of `physics` (any Qube domain) as it is now."""
        scene = physics.drawable()
        model = scene.model.ptr
        if model is not self._model:
            self._open(model)
        self._renderer.update_scene(scene.data.ptr, camera=self.camera)
        return self._renderer.render()

    def _open(self, model: mujoco.MjModel) -> None:
        cameras = camera_names(model)
        if self.camera not in cameras:
            raise ValueError(f"unknown camera {self.camera!r}; valid cameras: {', '.join(cameras)}")
        limit = (model.vis.global_.offwidth, model.vis.global_.offheight)
        if self.width > limit[0] or self.height > limit[1]:
            raise ValueError(f"frame size {self.width} x {self.height} exceeds the model's offscreen "
                             f"buffer of {limit[0]} x {limit[1]} pixels")
        self.close()
        self._renderer = mujoco.Renderer(model, self.height, self.width)
        self._model = model

    def close(self) -> None:
        """Free the OpenGL context (a later `render` opens a new one)."""
        if self._renderer is not None:
            self._renderer.close()
        self._renderer, self._model = None, None

    def __getstate__(self) -> dict:
        """The camera and size; a copy opens its own OpenGL context when it renders."""
        return {**self.__dict__, "_renderer": None, "_model": None}

    def __enter__(self) -> FrameRenderer:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()


def frame_due(step: int, control_frequency: float, fps: float) -> bool:
    """Whether control step `step` of an episode (at time step / control_frequency) starts a
    new video frame at `fps` frames per second; step 0 always does."""
    if step == 0:
        return True
    ratio = fps / control_frequency
    return math.floor(step * ratio + 1e-9) > math.floor((step - 1) * ratio + 1e-9)


class VideoWriter:
    """An mp4 file (H.264) written frame by frame; needs the `media` extra (imageio-ffmpeg).

    Args:
        path: the file to write.
        fps: frames per second of playback.
        quality: 0 (smallest) to 10 (best).

    Frames are (height, width, 3) uint8 arrays, all of one even size. Use it as a
    context manager, or call `close()` to finish the file.
    """

    def __init__(self, path: str | os.PathLike, fps: float, quality: float = 7.0):
        if not (math.isfinite(fps) and fps > 0):
            raise ValueError(f"fps must be a positive number, got {fps}")
        self._ffmpeg = extras.require("imageio_ffmpeg", "writing mp4 videos")
        self.path, self.fps, self.quality = os.fspath(path), float(fps), quality
        self.frames = 0
        self._size: tuple[int, int] | None = None
        self._writer = None

    def append(self, frame: np.ndarray) -> None:
        """Add `frame` (height, width, 3) uint8 at the end of the video."""
        frame = np.ascontiguousarray(frame, dtype=np.uint8)
        height, width = frame.shape[:2]
        if self._writer is None:
            if frame.ndim != 3 or frame.shape[2] != 3 or height % 2 or width % 2:
                raise ValueError(f"video frames must be (height, width, 3) with even sizes, "
                                 f"got {frame.shape}")
            self._size = (width, height)
            self._writer = self._ffmpeg.write_frames(
                self.path, self._size, fps=self.fps, quality=self.quality, codec="libx264",
                macro_block_size=1, ffmpeg_log_level="error")
            self._writer.send(None)
        elif (width, height) != self._size or frame.shape[2:] != (3,):
            raise ValueError(f"frame of shape {frame.shape} in a video of {self._size[0]} x {self._size[1]}")
        self._writer.send(frame)
        self.frames += 1

    def close(self) -> None:
        """Finish the file; a video without frames writes nothing."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()


class VideoRecorder:
    """A step hook (`run_episode(..., hooks=[recorder])`) that films episodes into one mp4.

    Renders only the control steps that fall on a frame at `fps`, so playback is at
    real speed; consecutive episodes follow each other in the file.

    Args:
        path: the mp4 file to write.
        fps: frames per second; None: one frame per control step (the control rate).
        camera, width, height: as `FrameRenderer`; width and height even.
    """

    def __init__(self, path: str | os.PathLike, fps: float | None = None, camera: str = DEFAULT_CAMERA,
                 width: int = DEFAULT_WIDTH, height: int = DEFAULT_HEIGHT):
        if fps is not None and not (math.isfinite(fps) and fps > 0):
            raise ValueError(f"fps must be a positive number, got {fps}")
        if width % 2 or height % 2:
            raise ValueError(f"video width and height must be even, got {width} x {height}")
        extras.require("imageio_ffmpeg", "writing mp4 videos")
        self.path, self.fps = path, fps
        self.renderer = FrameRenderer(camera, width, height)
        self.writer: VideoWriter | None = None

    def __call__(self, step: int, environment: Any) -> None:
        fps = self._fps(environment.control_frequency)
        if not frame_due(step, environment.control_frequency, fps):
            return
        if self.writer is None:
            self.writer = VideoWriter(self.path, fps)
        self.writer.append(self.renderer.render(environment.physics))

    def film(self, trace: EpisodeTrace, control_frequency: float) -> None:
        """Film an episode from its trace (measured states and LED colours) after it has run: how
        hardware episodes are filmed, since rendering takes longer than a sample."""
        from qube_suite.devices.qube import simulation as qube

        fps = self._fps(control_frequency)
        twin = qube.make_physics(control_frequency)
        try:
            for step in range(len(trace.time)):
                if frame_due(step, control_frequency, fps):
                    twin.reset_to(trace.state[step])
                    twin.set_led(trace.led[step])
                    if self.writer is None:
                        self.writer = VideoWriter(self.path, fps)
                    self.writer.append(self.renderer.render(twin))
        finally:
            twin.close()

    def _fps(self, rate: float) -> float:
        fps = rate if self.fps is None else self.fps
        if fps > rate + 1e-9:
            raise ValueError(f"fps {fps:g} exceeds the control rate of {rate:g} Hz: there are no more "
                             "frames than control steps")
        return fps

    @property
    def frames(self) -> int:
        """Frames written so far."""
        return 0 if self.writer is None else self.writer.frames

    def close(self) -> None:
        """Finish the file and free the renderer."""
        if self.writer is not None:
            self.writer.close()
        self.renderer.close()

    def __enter__(self) -> VideoRecorder:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()


def record_video(environment: Any, policy: Policy, path: str | os.PathLike, episodes: int = 1,
                 fps: float | None = None, camera: str = DEFAULT_CAMERA, width: int = DEFAULT_WIDTH,
                 height: int = DEFAULT_HEIGHT) -> list[EpisodeTrace]:
    """Run `episodes` episodes of `policy` on `environment` (a dm_env environment from
    `suite.load`, any domain) and film them into the mp4 `path`; return their traces.

    `fps`: frames per second (None: the control rate); `camera`, `width`, `height`:
    as `FrameRenderer`. Needs the `media` extra. On hardware the frames are rendered from each
    episode's trace after it has run, never inside the control loop.
    """
    with VideoRecorder(path, fps, camera, width, height) as recorder:
        if not films_after_episode(environment):
            return [run_episode(environment, policy, hooks=[recorder]) for _ in range(episodes)]
        traces = []
        for _ in range(episodes):
            traces.append(run_episode(environment, policy))
            recorder.film(traces[-1], environment.control_frequency)
        return traces


def films_after_episode(environment: Any) -> bool:
    """True if `environment`'s episodes must be filmed from their traces after they have run
    (hardware, where rendering inside the loop would miss samples)."""
    physics = environment.physics
    return isinstance(physics, HasBoard) and physics.paced_by_board


def write_video(path: str | os.PathLike, frames: Iterable[np.ndarray], fps: float) -> int:
    """Write `frames` ((height, width, 3) uint8, e.g. from a Gymnasium env's `render()`) to the
    mp4 `path` at `fps` frames per second; return the number written. Needs the `media` extra."""
    with VideoWriter(path, fps) as writer:
        for frame in frames:
            writer.append(frame)
    return writer.frames
