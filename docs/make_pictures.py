"""Render the pictures in docs/ (needs the `media` extra).

    MUJOCO_GL=osmesa python docs/make_pictures.py
"""

from __future__ import annotations

import pathlib

import imageio.v3 as iio
import mujoco

from qube_suite.domains import qube

HERE = pathlib.Path(__file__).resolve().parent


def render(state, path: pathlib.Path, led=(0.1, 0.9, 0.15), size=(360, 480)) -> None:
    """Write a front-oblique picture of the Qube in `state` [theta, alpha, dtheta, dalpha]."""
    physics = qube.make_physics()
    physics.reset_to(state)
    physics.set_led(led)
    renderer = mujoco.Renderer(physics.model.ptr, *size)
    renderer.update_scene(physics.data.ptr, camera="front_oblique")
    iio.imwrite(path, renderer.render())
    renderer.close()


def main() -> None:
    render([0.35, 0.12, 0.0, 0.0], HERE / "qube.png")


if __name__ == "__main__":
    main()
