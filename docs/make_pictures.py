"""Render the pictures in docs/: the Qube, and each task's start state (needs the `media` extra).

    MUJOCO_GL=osmesa python docs/make_pictures.py

A task's picture is what `env.reset()` followed by a render shows: the start state
drawn from the task's random state with `START_SEEDS[task]`, and the LED in the
colour of that state's reward (red low, green high), as the environment sets it.
The follow and sparse variants start as swingup, balance and dampen do, so these
four pictures cover every task.
"""

from __future__ import annotations

import pathlib

import imageio.v3 as iio

from qube_suite import media, suite
from qube_suite.devices.qube import simulation as qube

HERE = pathlib.Path(__file__).resolve().parent

START_SEEDS = {"swingup": 0, "balance": 0, "dampen": 3, "rotor": 0}
"""Task -> seed of the start state pictured (dampen's seed 3 starts the pendulum out to the side)."""

TASK_PICTURE_SIZE = (320, 240)
"""Width and height of the task pictures (pixels)."""


def render_qube(path: pathlib.Path) -> None:
    """The README's title picture: the Qube mid-swing, LED green."""
    physics = qube.make_physics()
    physics.reset_to([0.35, 0.12, 0.0, 0.0])
    physics.set_led((0.1, 0.9, 0.15))
    with media.FrameRenderer("front_oblique", width=480, height=360) as renderer:
        iio.imwrite(path, renderer.render(physics))


def render_task(task: str, seed: int, path: pathlib.Path) -> None:
    """`task`'s start state from seed `seed`, as the environment shows it after `reset()`."""
    env = suite.load("qube", task, task_kwargs={"random": seed})
    env.reset()
    width, height = TASK_PICTURE_SIZE
    with media.FrameRenderer("front_oblique", width=width, height=height) as renderer:
        iio.imwrite(path, renderer.render(env.physics))
    env.close()


def main() -> None:
    render_qube(HERE / "qube.png")
    folder = HERE / "tasks"
    folder.mkdir(exist_ok=True)
    for task, seed in START_SEEDS.items():
        render_task(task, seed, folder / f"{task}.png")


if __name__ == "__main__":
    main()
