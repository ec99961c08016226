"""Every camera frames the whole Qube in every pose: none of the Qube's pixels touches the frame's edge."""

import itertools
import math

import mujoco
import numpy as np
import pytest
from conftest import requires_offscreen_gl

from qube_suite.devices.qube import simulation as qube
from qube_suite.media import camera_names

POSES = list(itertools.product(np.linspace(-math.pi / 2, math.pi / 2, 5),   # the arm's whole safe range
                               np.linspace(-math.pi, math.pi, 9)))           # hanging, upright, sideways
"""(theta, alpha) poses, including upright (alpha 0) and hanging (alpha +-pi)."""


def qube_pixels(renderer, physics, camera: str) -> np.ndarray:
    """Bool mask of the pixels showing the Qube (any geom but the bench), from MuJoCo's segmentation."""
    bench = physics.model.geom("bench").id
    renderer.update_scene(physics.data.ptr, camera=camera)
    segmentation = renderer.render()
    geoms, types = segmentation[..., 0], segmentation[..., 1]
    return (types == mujoco.mjtObj.mjOBJ_GEOM) & (geoms >= 0) & (geoms != bench)


@pytest.mark.slow
@requires_offscreen_gl
@pytest.mark.parametrize("height, width", [(120, 160), (96, 96)], ids=["4:3", "square"])
def test_every_camera_frames_the_whole_qube_in_every_pose(height, width):
    physics = qube.make_physics()
    renderer = mujoco.Renderer(physics.model.ptr, height, width)
    renderer.enable_segmentation_rendering()
    cameras = camera_names(physics.model.ptr)
    assert set(cameras) == {"front_oblique", "front", "top"}
    cropped = []
    for camera, (theta, alpha) in itertools.product(cameras, POSES):
        physics.reset_to([theta, alpha, 0.0, 0.0])
        mask = qube_pixels(renderer, physics, camera)
        assert mask.sum() > 0.01 * mask.size  # the Qube is in view, not a speck
        if mask[0].any() or mask[-1].any() or mask[:, 0].any() or mask[:, -1].any():
            cropped.append((camera, round(math.degrees(theta)), round(math.degrees(alpha))))
    renderer.close()
    assert cropped == []
