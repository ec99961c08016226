"""The model files: the Qube alone in model.xml, the scene in scene.xml, keyframes the domains agree with."""

import math

import mujoco
import numpy as np
import pytest

from qube_suite import suite
from qube_suite.devices.qube import simulation as qube
from qube_suite.devices.qube.batch import QubeBatch, physics_model

DYNAMICS = ["body_mass", "body_inertia", "body_pos", "body_ipos", "dof_damping", "dof_armature",
            "dof_frictionloss", "jnt_stiffness", "actuator_gainprm", "actuator_biasprm", "qpos0"]


def test_the_qube_file_holds_no_scene_and_the_scene_includes_it():
    alone = mujoco.MjModel.from_xml_path(str(qube.MODEL_PATH))
    scene = mujoco.MjModel.from_xml_path(str(qube.SCENE_PATH))
    assert (alone.ntex, alone.nlight, alone.ncam) == (0, 0, 0)
    assert mujoco.mj_name2id(alone, mujoco.mjtObj.mjOBJ_GEOM, "bench") == -1
    assert mujoco.mj_name2id(alone, mujoco.mjtObj.mjOBJ_GEOM, "led") >= 0
    assert (scene.ntex, scene.nlight) == (2, 2)
    assert [scene.camera(i).name for i in range(scene.ncam)] == ["front_oblique", "front", "top"]
    for field in DYNAMICS:
        np.testing.assert_array_equal(getattr(scene, field), getattr(alone, field), err_msg=field)
    assert mujoco.mj_sizeModel(alone) < 20_000 < 5_000_000 < mujoco.mj_sizeModel(scene)


@pytest.mark.parametrize(("key", "alpha"), [("hanging", math.pi), ("upright", 0.0)])
def test_keyframes_are_the_states_the_domains_report(key, alpha):
    physics = qube.make_physics()
    physics.reset(keyframe_id=physics.model.name2id(key, "key"))
    np.testing.assert_array_equal(physics.qube_state(), [0.0, alpha, 0.0, 0.0])

    model = physics_model(250.0)
    keyframe = model.key(key)
    np.testing.assert_array_equal(keyframe.qpos[[qube.ElementIds(model).arm_qpos,
                                                 qube.ElementIds(model).pendulum_qpos]], [0.0, alpha])
    batch = QubeBatch(1)
    batch.reset_world(0, [*keyframe.qpos.tolist(), *keyframe.qvel.tolist()])
    np.testing.assert_array_equal(batch.qube_state(), [[0.0, alpha, 0.0, 0.0]])
    batch.close()


def test_the_tasks_score_the_keyframes_as_hanging_and_upright():
    physics = qube.make_physics()
    balance, dampen = suite.make_task("qube", "balance", {}), suite.make_task("qube", "dampen", {})
    physics.reset(keyframe_id=physics.model.name2id("upright", "key"))
    assert balance.get_reward(physics) == 1.0  # the goal of the swing-up and balance tasks
    physics.reset(keyframe_id=physics.model.name2id("hanging", "key"))
    assert dampen.get_reward(physics) == 1.0  # the goal of dampen
    assert balance.get_reward(physics) == pytest.approx(0.2)  # 1 - 0.8 pi / pi
