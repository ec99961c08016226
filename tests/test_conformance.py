"""dm_env's conformance checker on every task, and rendering (Gymnasium's, SB3's and shimmy's checks:
test_third_party.py)."""

import unittest

import gymnasium
import numpy as np
import pytest
from conftest import requires_offscreen_gl
from dm_env import test_utils

import qube_suite  # noqa: F401  (registers the Gymnasium ids)
from qube_suite import suite
from qube_suite.wrappers import GYMNASIUM_IDS


def _dm_env_conformance_case(task):
    class Case(test_utils.EnvironmentTestMixin, unittest.TestCase):
        def make_object_under_test(self):
            return suite.load("qube", task, task_kwargs={"random": 0})

        def make_action_sequence(self):
            # Full voltage one way drives the arm out of its safe set: the episode ends
            # and the mixin checks the LAST step and the reset that follows.
            for _ in range(400):
                yield np.array([3.0])

    Case.__name__ = Case.__qualname__ = f"TestDmEnvConformance_{task}"
    return Case


for _task in suite.TASKS_BY_DOMAIN["qube"]:
    globals()[f"TestDmEnvConformance_{_task}"] = _dm_env_conformance_case(_task)


def test_every_task_has_a_gymnasium_id():
    pendulum = [task for env_id, task in GYMNASIUM_IDS.items()
                if gymnasium.spec(env_id).kwargs["domain"] == "qube"]
    assert sorted(pendulum) == sorted(suite.TASKS_BY_DOMAIN["qube"])
    assert GYMNASIUM_IDS["QubeSuite/Swingup-v0"] == "swingup"
    assert GYMNASIUM_IDS["QubeSuite/BalanceFollowSparse-v0"] == "balance_follow_sparse"


@pytest.mark.slow
@requires_offscreen_gl
def test_rendered_frame_shows_the_qube_and_its_led():
    env = gymnasium.make("QubeSuite/Swingup-v0", render_mode="rgb_array", width=320, height=240)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (240, 320, 3) and frame.dtype == np.uint8
    assert frame.std() > 20  # not blank
    pixels = frame.reshape(-1, 3).astype(int)
    greenish = (pixels[:, 1] > 150) & (pixels[:, 0] < 100)  # the LED: reward 0.2 hanging is mostly red
    reddish = (pixels[:, 0] > 150) & (pixels[:, 1] < 80)
    assert reddish.sum() > 20 and greenish.sum() < reddish.sum()
    env.unwrapped.physics.reset_to([0.0, 0.0, 0.0, 0.0])
    env.unwrapped.physics.set_led((0.0, 1.0, 0.0))
    upright = env.render()
    assert not np.array_equal(upright, frame)
    env.close()


@pytest.mark.slow
@requires_offscreen_gl
def test_dm_env_physics_renders_from_each_camera():
    env = suite.load("qube", "balance")
    env.reset()
    for camera in ("front_oblique", "front", "top"):
        frame = env.physics.render(120, 160, camera_id=camera)
        assert frame.shape == (120, 160, 3) and frame.std() > 10
    env.physics.free()
