"""Third-party checks on every QubeSuite id: Gymnasium's own environment tests (API, passive checker,
determinism rollout, render modes, out-of-bound actions, pickle), stable-baselines3's `check_env`, and
shimmy's dm_control round trip including `close()` on both domains.

The Gymnasium functions re-create the logic of Gymnasium's tests/envs/test_envs.py and
test_action_dim_check.py (not shipped with the package) with its public helpers.
"""

import contextlib
import pickle
import warnings

import gymnasium
import numpy as np
import pytest
from conftest import requires_offscreen_gl
from gymnasium.utils.env_checker import check_env, data_equivalence

import qube_suite  # noqa: F401  (registers the Gymnasium ids)
from qube_suite import suite
from qube_suite.wrappers import GYMNASIUM_IDS, HARDWARE_GYMNASIUM_IDS

SIM_IDS = sorted(GYMNASIUM_IDS)
ALL_IDS = SIM_IDS + sorted(HARDWARE_GYMNASIUM_IDS)
SEED, NUM_STEPS = 0, 50

BY_DESIGN = (".*symmetric and normalized .*space.*",  # the action is in volts (docs/conventions.md)
             ".*Box observation space m.*infinity.*")  # velocities are unbounded
"""Warnings of Gymnasium's and SB3's checkers that are about deliberate choices."""


@contextlib.contextmanager
def ignoring_by_design():
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # anything else the checkers say fails the test
        for message in BY_DESIGN:
            warnings.filterwarnings("ignore", message=message)
        yield


@pytest.mark.slow
@pytest.mark.parametrize("env_id", ALL_IDS)
def test_env_api(env_id):
    env = gymnasium.make(env_id)
    with ignoring_by_design():
        check_env(env.unwrapped, skip_render_check=True)
    env.close()


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_passive_env_checker_has_nothing_to_say(env_id):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        env = gymnasium.make(env_id, disable_env_checker=False)
        env.reset(seed=SEED)
        env.step(env.action_space.sample())
        env.close()
    assert [str(warning.message) for warning in caught] == []


@pytest.mark.parametrize("env_id", SIM_IDS)  # the hardware ids are registered nondeterministic
def test_env_determinism_rollout(env_id):
    env_1, env_2 = gymnasium.make(env_id), gymnasium.make(env_id)
    data_equivalence(env_1.reset(seed=SEED), env_2.reset(seed=SEED))
    env_1.action_space.seed(SEED)
    for _ in range(NUM_STEPS):
        action = env_1.action_space.sample()
        step_1, step_2 = env_1.step(action), env_2.step(action)
        assert data_equivalence(step_1, step_2), (step_1, step_2)
        assert env_1.observation_space.contains(step_1[0])
        if step_1[2] or step_1[3]:
            data_equivalence(env_1.reset(seed=SEED), env_2.reset(seed=SEED))
    env_1.close()
    env_2.close()


@pytest.mark.slow
@requires_offscreen_gl
@pytest.mark.parametrize("env_id", ["QubeSuite/Swingup-v0", "QubeSuite/BalanceFollowHardware-v0"])
def test_render_modes(env_id):
    for mode in gymnasium.spec(env_id).make().metadata["render_modes"]:  # "human" only with a display
        env = gymnasium.make(env_id, render_mode=mode, width=64, height=48)
        env.reset(seed=SEED)
        frames = [env.render(), env.step(env.action_space.sample()) and env.render()]
        if mode == "rgb_array":
            assert all(frame.shape == (48, 64, 3) and frame.dtype == np.uint8 for frame in frames)
        env.close()


@pytest.mark.parametrize("env_id", SIM_IDS)
def test_box_actions_out_of_bound_act_as_the_bound(env_id):
    env, out_of_bound = gymnasium.make(env_id), gymnasium.make(env_id)
    env.reset(seed=42)
    out_of_bound.reset(seed=42)
    space = env.action_space
    for bound, offset in ((space.high, 100.0), (space.low, -100.0)):
        observation = env.step(bound)[0]
        action = bound + np.float32(offset)
        assert not space.contains(action)
        np.testing.assert_array_equal(out_of_bound.step(action)[0], observation)
    env.close()
    out_of_bound.close()


@pytest.mark.parametrize("env_id", SIM_IDS)
def test_pickle_env(env_id):
    env = gymnasium.make(env_id)
    pickled = pickle.loads(pickle.dumps(env))
    data_equivalence(env.reset(), pickled.reset())
    action = env.action_space.sample()
    assert data_equivalence(env.step(action), pickled.step(action))
    env.close()
    pickled.close()


def test_pickling_a_hardware_env_is_refused_clearly():
    env = gymnasium.make("QubeSuite/BalanceHardware-v0")
    env.reset(seed=0)
    try:
        with pytest.raises(TypeError, match="board"):
            pickle.dumps(env)
    finally:
        env.close()


@pytest.mark.parametrize("env_id", SIM_IDS + ["QubeSuite/SwingupHardware-v0"])
def test_stable_baselines3_check_env(env_id):
    env_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = gymnasium.make(env_id)
    with ignoring_by_design():
        env_checker.check_env(env, warn=True)
    env.close()


@pytest.mark.parametrize("domain", ["qube", "qube_hardware"])
def test_shimmy_round_trip_including_close(domain):
    import shimmy  # noqa: F401  (registers dm_control/compatibility-env-v0)

    native = suite.load(domain, "balance", task_kwargs={"random": 11})
    env = gymnasium.make("dm_control/compatibility-env-v0", env=native)
    reference = suite.load(domain, "balance", task_kwargs={"random": 11})
    observation, _ = env.reset(seed=11)  # a seeded reset, also for the substitute board
    np.testing.assert_array_equal(observation["state"], reference.reset(seed=11).observation["state"])
    for _ in range(20):
        observation, reward, terminated, truncated, _ = env.step(np.array([0.4]))
        expected = reference.step(np.array([0.4]))
        np.testing.assert_array_equal(observation["state"], expected.observation["state"])
        assert reward == expected.reward and not terminated and not truncated
    reference.close()
    env.close()
    if domain == "qube_hardware":
        board = native.physics.qube.board
        assert board.applied_voltage == 0.0 and not board.amplifier_enabled


@pytest.mark.slow
@requires_offscreen_gl
def test_gymnasium_record_video_writes_an_episode(tmp_path):
    pytest.importorskip("moviepy")  # in the media extra
    env = gymnasium.make("QubeSuite/Swingup-v0", render_mode="rgb_array", width=64, height=48,
                         time_limit=0.012)  # 3 steps: software rendering is slow
    env = gymnasium.wrappers.RecordVideo(env, str(tmp_path / "videos"), episode_trigger=lambda episode: True,
                                         disable_logger=True)
    env.reset(seed=0)
    truncated = False
    while not truncated:
        truncated = env.step(np.array([1.0], np.float32))[3]
    env.close()
    videos = list((tmp_path / "videos").glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 500
