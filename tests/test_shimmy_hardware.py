"""shimmy's dm_control compatibility env on the hardware domain: it draws the digital twin, passes
Gymnasium's checker, and a seed puts the substitute board's Qube back the same way every time."""

import warnings

import numpy as np
import pytest
from conftest import requires_offscreen_gl

from qube_suite import suite
from qube_suite.hardware.plant import ESTIMATED
from qube_suite.tasks import SUITE

pytestmark = pytest.mark.hardware


@requires_offscreen_gl
def test_shimmy_renders_the_digital_twin():
    from shimmy import DmControlCompatibilityV0

    env = DmControlCompatibilityV0(suite.load("qube_hardware", "balance"), render_mode="rgb_array",
                                   render_kwargs={"width": 64, "height": 48})
    env.reset(seed=0)
    image = env.render()
    env.close()
    assert image.shape == (48, 64, 3) and image.std() > 10


def test_shimmy_check_env_passes_on_the_substitute_board():
    from gymnasium.utils.env_checker import check_env
    from shimmy import DmControlCompatibilityV0

    # On the estimated plant: check_env's determinism check wants a seeded reset's first step to repeat
    # exactly. On the real Qube's plant (the default) it fails (measured 2026-11-28): a reset brings the
    # Qube to rest within its tolerances, not to one state, and the two first observations differ.
    env = DmControlCompatibilityV0(suite.load("qube_hardware", "balance", domain_kwargs={"plant": ESTIMATED}))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # shimmy's dict observation and float64 are by design
        check_env(env, skip_render_check=True)
    env.close()


@pytest.mark.parametrize("task", list(SUITE))
def test_seeds_give_different_repeatable_starts_on_the_substitute(task):
    from shimmy import DmControlCompatibilityV0

    env = DmControlCompatibilityV0(suite.load("qube_hardware", task))
    first = [env.reset(seed=seed)[0]["state"] for seed in (0, 1, 0)]
    env.close()
    assert not np.array_equal(first[0], first[1])
    np.testing.assert_array_equal(first[2], env_start(task, seed=0, after_seed=1))


def env_start(task, seed, after_seed):
    """The first observation of a seeded episode on a fresh substitute, after one of `after_seed`."""
    env = suite.load("qube_hardware", task)
    env.reset(seed=after_seed)
    start = env.reset(seed=seed).observation["state"]
    env.close()
    return start
