"""A calibration's report: a PNG of recorded against simulated angles and an HTML page around it.

The figure shows held-out segments of the experiment (blocks the fit never saw), one
per phase: the encoders' angles and the 0.5 s-ahead predictions of the nominal and
of the calibrated simulation, each from the state estimated from the 0.1 s before
(`prediction`). The page adds the parameter table (nominal, estimate, 95 % interval),
what was fixed and why, the latency, the offsets and the experiment's metadata.
Needs matplotlib (the `media` extra).
"""

from __future__ import annotations

import base64
import html
import os

import numpy as np

from qube_suite import extras
from qube_suite.calibration import measurements, prediction
from qube_suite.calibration.calibration_file import Calibration
from qube_suite.calibration.experiment import Excitation
from qube_suite.calibration.identifiability import FIXED
from qube_suite.devices.qube import parameters as params


def write(calibration: Calibration, path: str | os.PathLike) -> tuple[str, str]:
    """Write the report to `path` (HTML) and its figure beside it (`.png`); return both paths.
    The experiment's recording (named in the calibration's metadata) must still be there."""
    path = os.fspath(path)
    figure_path = os.path.splitext(path)[0] + ".png"
    m = measurements.load(calibration.metadata["recording"])
    _figure(calibration, m).savefig(figure_path, dpi=110)
    with open(figure_path, "rb") as file:
        image = base64.b64encode(file.read()).decode("ascii")
    with open(path, "w", encoding="utf-8") as file:
        file.write(_page(calibration, image))
    return path, figure_path


def _figure(calibration: Calibration, m: measurements.Measurements):
    from qube_suite.calibration import held_out

    figure_module = extras.require("matplotlib.figure", "calibration report")
    figure = figure_module.Figure(figsize=(12, 6), layout="constrained")
    test = np.flatnonzero(held_out(m))
    offsets = (0.0, calibration.offsets.get("pendulum_encoder_offset", 0.0))
    nominal = prediction.predict(m, {}, test)
    calibrated = prediction.predict(m, calibration.parameters, test, calibration.latency_steps, offsets)
    excitation = Excitation(float(m.time[-1] - m.time[0]))
    phases = [excitation.phase(m.time[k]) for k in calibrated.starts]
    names = list(dict.fromkeys(phases))
    axes = figure.subplots(2, len(names), squeeze=False, sharex="col")
    for column, name in enumerate(names):
        rows = [i for i, phase in enumerate(phases) if phase == name]
        first = m.time[calibrated.starts[rows[len(rows) // 4]]]  # a few successive rollouts in one block
        chosen = [i for i in rows if 0.0 <= m.time[calibrated.starts[i]] - first < 0.5][::2]
        for row, label in enumerate(("arm angle theta (rad)", "pendulum angle alpha (rad)")):
            ax = axes[row, column]
            for i in chosen:
                time = m.time[calibrated.starts[i]] + calibrated.time
                ax.plot(time, calibrated.measured[i, :, row], color="black", lw=1.5,
                        label="recorded" if i == chosen[0] else None)
                ax.plot(time, nominal.predicted[i, :, row], color="tab:grey", ls="--",
                        label="nominal model" if i == chosen[0] else None)
                ax.plot(time, calibrated.predicted[i, :, row], color="tab:red",
                        label="calibrated model" if i == chosen[0] else None)
            if column == 0:
                ax.set_ylabel(label)
            if row == 0:
                ax.set_title(f"held out: {name}")
            else:
                ax.set_xlabel("time (s)")
    axes[0, 0].legend(loc="best", fontsize="small")
    figure.suptitle(f"0.5 s-ahead predictions on held-out segments: RMS {nominal.rms_at_horizon:.4f} rad "
                    f"(nominal) -> {calibrated.rms_at_horizon:.4f} rad (calibrated)")
    return figure


def _page(calibration: Calibration, image: str) -> str:
    rows = []
    for name, parameter in params.PARAMETERS.items():
        value = calibration.parameters[name]
        if name in calibration.intervals:
            low, high = calibration.intervals[name]
            interval = f"[{low:.4g}, {high:.4g}]"
        else:
            interval = "fixed at nominal" if name in FIXED else ""
        rows.append(f"<tr><td>{name}</td><td>{parameter.nominal:.4g}</td><td>{value:.4g}</td><td>{interval}</td>"
                    f"<td>{html.escape(parameter.unit)}</td></tr>")
    metadata = "".join(f"<li>{html.escape(str(key))}: {html.escape(str(value))}</li>"
                       for key, value in calibration.metadata.items())
    extra = {**calibration.combinations, **calibration.offsets, "latency_steps": calibration.latency_steps,
             **{f"prediction {key}": value for key, value in calibration.prediction.items()}}
    details = "".join(f"<li>{html.escape(key)}: {value if value is None else f'{value:.4g}'}</li>"
                      for key, value in extra.items())
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>Qube calibration</title>
<style>body {{ font-family: sans-serif; max-width: 1200px; margin: auto; }}
table {{ border-collapse: collapse; }} td, th {{ border: 1px solid #ccc; padding: 2px 8px; }}</style></head>
<body><h1>Qube calibration</h1>
<img src="data:image/png;base64,{image}" width="100%"
 alt="recorded and simulated angles on held-out segments">
<h2>Parameters</h2>
<table><tr><th>parameter</th><th>nominal</th><th>calibrated</th><th>95 % interval</th><th>unit</th></tr>
{''.join(rows)}</table>
<p>Fixed at nominal: the rotor's inertia cannot be told apart from the arm's; the arm's mass and length
set the torque scale (kt and every mass and inertia scale together), so the rotor's tolerance is part of
the intervals of the torque-scaled estimates.</p>
<h2>Identified combinations, offsets, latency, prediction</h2><ul>{details}</ul>
<h2>Experiment</h2><ul>{metadata}</ul>
</body></html>
"""
