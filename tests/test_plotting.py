"""Episode and comparison plots are written and show something."""

import imageio.v3 as iio
import numpy as np
import pytest

from qube_suite import baselines, episodes, extras, plotting, suite


def image(path):
    picture = iio.imread(path)
    assert picture.ndim == 3 and picture.shape[0] > 200 and picture.shape[1] > 200
    return picture[..., :3].astype(int)


def test_episode_plot_is_written_with_every_signal(tmp_path):
    env = suite.load("qube", "balance_follow", task_kwargs={"random": 0},
                     environment_kwargs={"time_limit": 1.0})
    trace = episodes.run_episode(env, baselines.make("balance"), label="lqr")
    figure = plotting.plot_episode(trace, tmp_path / "episode.png")
    axes = figure.get_axes()
    assert [axis.get_ylabel() for axis in axes] == [
        "θ (deg)", "α (deg)", "θ̇ (rad/s)", "α̇ (rad/s)", "voltage (V)", "reward", "LED"]
    assert len(axes[0].get_lines()) == 2  # theta and its target
    np.testing.assert_allclose(axes[4].get_lines()[0].get_ydata(), trace.voltage)
    assert "lqr: return" in figure._suptitle.get_text()
    picture = image(tmp_path / "episode.png")
    assert picture.std() > 20  # not blank
    greenish = (picture[..., 1] > 200) & (picture[..., 0] < 80) & (picture[..., 2] < 80)
    assert greenish.sum() > 1000  # the LED strip of a balanced episode


def test_comparison_plots(tmp_path):
    figure = plotting.plot_returns({"mpc": [1850.0, 1790.0, 1820.0], "balance": [410.0]},
                                   tmp_path / "returns.png", title="swingup")
    assert [tick.get_text() for tick in figure.get_axes()[0].get_xticklabels()] == ["mpc", "balance"]
    assert image(tmp_path / "returns.png").std() > 20
    curves = {"balance": [1.0, 1.0, 0.4], "mpc": [1.0, 0.9, 0.1]}
    figure = plotting.plot_curves(["nominal", "2048", "64"], curves, tmp_path / "curves.png",
                                  xlabel="encoder counts", ylabel="success rate")
    assert len(figure.get_axes()[0].get_lines()) == 2
    assert image(tmp_path / "curves.png").std() > 20
    with pytest.raises(ValueError, match="at least one return"):
        plotting.plot_returns({"mpc": []})
    with pytest.raises(ValueError, match="3 x values"):
        plotting.plot_curves([1, 2, 3], {"mpc": [1.0]})


def test_missing_matplotlib_says_how_to_install(monkeypatch):
    trace = episodes.run_episode(suite.load("qube", "balance", environment_kwargs={"time_limit": 0.1}),
                                 baselines.make("balance"))
    monkeypatch.setattr(extras, "available", lambda module: False)
    with pytest.raises(ImportError, match=r"plotting needs matplotlib: pip install 'qube_suite\[media\]'"):
        plotting.plot_episode(trace)
