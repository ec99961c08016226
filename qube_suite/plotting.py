"""Plots of episodes and comparisons (matplotlib, the `media` extra, imported on use).

    from qube_suite import baselines, episodes, plotting, suite
    env = suite.load("qube", "balance", task_kwargs={"random": 0})
    trace = episodes.run_episode(env, baselines.make("balance"))
    plotting.plot_episode(trace, "balance.png")                  # the states, voltage, reward, LED
    plotting.plot_returns({"balance": [2040.1, 2039.5]}, "returns.png")

Every function returns the matplotlib `Figure` and, given a path, also saves it
there. Figures are made without pyplot, so they work without a display and leave
pyplot's state alone.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from qube_suite import extras
from qube_suite.episodes import EpisodeTrace

DPI = 110
"""Resolution of saved figures (dots per inch)."""


def _figure(width: float, height: float) -> Any:
    figure_module = extras.require("matplotlib.figure", "plotting")
    return figure_module.Figure(figsize=(width, height), layout="constrained")


def _finish(figure: Any, path: str | os.PathLike | None) -> Any:
    if path is not None:
        figure.savefig(path, dpi=DPI)
    return figure


def _break_at_wraps(time: np.ndarray, degrees: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(time, angle in degrees) with a NaN point wherever the angle wraps past +-180, so that
    the plotted line breaks there instead of crossing the axis."""
    jumps = np.flatnonzero(np.abs(np.diff(degrees)) > 180.0) + 1
    return np.insert(time.astype(float), jumps, np.nan), np.insert(degrees.astype(float), jumps, np.nan)


def plot_episode(trace: EpisodeTrace, path: str | os.PathLike | None = None, title: str | None = None) -> Any:
    """One episode over time: theta (with the follow target), alpha, their velocities, the
    voltage, the reward and the LED's colour. Angles in degrees.

    Args:
        trace: from `qube_suite.episodes.run_episode`.
        path: save the figure here (PNG, PDF, SVG: by the suffix); None: don't save.
        title: the figure's title; default: the trace's label and return.
    """
    figure = _figure(8.0, 9.0)
    axes = figure.subplots(7, 1, sharex=True, height_ratios=[1, 1, 1, 1, 1, 1, 0.35])
    time, state = trace.time, trace.state
    theta, alpha = np.degrees(state[:, 0]), np.degrees(state[:, 1])
    rows = [
        ("θ (deg)", *_break_at_wraps(time, theta)), ("α (deg)", *_break_at_wraps(time, alpha)),
        ("θ̇ (rad/s)", time, state[:, 2]), ("α̇ (rad/s)", time, state[:, 3]),
        ("voltage (V)", time, trace.voltage), ("reward", time, trace.reward),
    ]
    for axis, (label, times, values) in zip(axes, rows, strict=False):
        axis.plot(times, values, linewidth=1.0, color="C0")
        axis.set_ylabel(label)
        axis.grid(alpha=0.3)
    if trace.target is not None:
        axes[0].plot(time, np.degrees(trace.target), linestyle="--", linewidth=1.0, color="C1",
                     label="target")
        axes[0].legend(loc="upper right", fontsize=8)
    axes[1].set_yticks([-180, -90, 0, 90, 180])
    led = axes[-1]
    edges = np.append(time, time[-1] + (time[-1] - time[-2] if len(time) > 1 else 1.0))
    led.pcolormesh(edges, [0.0, 1.0], np.clip(trace.led, 0.0, 1.0)[np.newaxis, :, :])
    led.set_yticks([])
    led.set_ylabel("LED")
    led.set_xlabel("time (s)")
    outcome = "terminated" if trace.terminated else f"{trace.steps} steps"
    figure.suptitle(title or f"{trace.label or 'episode'}: return {trace.episode_return:.1f} ({outcome})")
    return _finish(figure, path)


def plot_returns(returns: Mapping[str, Sequence[float]], path: str | os.PathLike | None = None,
                 title: str = "", ylabel: str = "return") -> Any:
    """Returns of several policies side by side: a bar at each one's mean, its standard
    deviation as an error bar, and each episode's return as a dot.

    Args:
        returns: policy name -> the return of each of its episodes.
        path: save the figure here; None: don't save.
        title, ylabel: labels.
    """
    if not returns or any(len(values) == 0 for values in returns.values()):
        raise ValueError("plot_returns needs at least one return for every policy")
    names = list(returns)
    figure = _figure(max(3.0, 1.2 * len(names) + 1.5), 3.5)
    axis = figure.subplots()
    for i, name in enumerate(names):
        values = np.asarray(returns[name], dtype=float)
        axis.bar(i, values.mean(), yerr=values.std(), capsize=4, color=f"C{i % 10}", alpha=0.6)
        spread = np.linspace(-0.15, 0.15, len(values)) if len(values) > 1 else np.zeros(1)
        axis.plot(i + spread, values, "o", markersize=3, color="black")
    axis.set_xticks(range(len(names)), names)
    axis.set_ylabel(ylabel)
    axis.grid(axis="y", alpha=0.3)
    if title:
        axis.set_title(title)
    return _finish(figure, path)


def plot_curves(x: Sequence[Any], curves: Mapping[str, Sequence[float]],
                path: str | os.PathLike | None = None, xlabel: str = "", ylabel: str = "return",
                title: str = "") -> Any:
    """One line per policy over a common x, e.g. mean return against a parameter's strength.

    Args:
        x: the x values (numbers, or labels placed evenly).
        curves: policy name -> one y value per x (NaN leaves a gap).
        path: save the figure here; None: don't save.
        xlabel, ylabel, title: labels.
    """
    numeric = all(isinstance(value, (int, float)) and math.isfinite(value) for value in x)
    positions = list(x) if numeric else list(range(len(x)))
    figure = _figure(5.0, 3.5)
    axis = figure.subplots()
    for name, values in curves.items():
        if len(values) != len(positions):
            raise ValueError(f"curve {name!r} has {len(values)} values for {len(positions)} x values")
        axis.plot(positions, values, marker="o", label=name)
    if not numeric:
        axis.set_xticks(positions, [str(value) for value in x])
    axis.set_xlabel(xlabel)
    axis.set_ylabel(ylabel)
    axis.grid(alpha=0.3)
    axis.legend(fontsize=8)
    if title:
        axis.set_title(title)
    return _finish(figure, path)
