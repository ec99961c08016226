"""Fidelity on a real Qube: calibrate on recordings of a physical Qube-Servo 2, predict others.

Reads TU Darmstadt's 40 recordings of a Qube-Servo 2 (`../shared/real_qube/`, see its README;
or `--data DIR`): 10 open-loop voltage chirps and 30 closed-loop swing-ups (25 at 250 Hz, 5 at
500 Hz). Calibrates on chirps only (`calibration.calibrate_recordings`: encoders and voltage, no
current) and reports, for the nominal and the calibrated model, the RMS angle error of
predictions 0.1, 0.5 and 1 s ahead (`calibration.prediction`: MuJoCo rollouts from states
estimated on the 0.1 s before each start, recorded voltages replayed; both angles, wrapped):

* held-out chirps: leave one recording out, calibrate on the other nine, predict it;
* every swing-up, from a calibration on all ten chirps, also split into starts where the pendulum
  is balancing (within 0.4 rad of upright: a +-4 V limit cycle, the arm reversing every 0.1 s) and
  where it swings; and two floors there: the calibrated model's error 0.1 s ahead from the start
  that suits it best (fitted through the horizon too: its own error, not the start's), and how far
  its own prediction moves when the start's pendulum angle moves one encoder count (chaos: upright,
  the replayed voltages do not stabilise the model, and an error grows about 10-fold per 0.2 s);
* what each part of the model buys: calibrations on eight chirps (held out: neg_4, pos_4) with
  the unknowns added one group at a time, each row also predicting every swing-up 0.1 s ahead, and
  a last row whose fit also takes the windows where the arm reverses without sticking;
* the parameters with their 95 % intervals against nominal, and the spread (min, max) of the
  ten single-chirp calibrations: honest intervals contain most of that spread;
* a figure of recorded against predicted angles (`--figure`), and the wall time.

    python benchmarks/real_qube.py [--data DIR] [--out FILE.json] [--figure FILE.png] [--smoothed-start]
    python benchmarks/real_qube.py --save qube_suite/devices/qube/real_qube_servo2.yaml   # only that
    python benchmarks/real_qube.py --frequency-response   # only that (or --residual-structure)

`--residual-structure` instead fits all ten chirps (latency 1.5 samples) and reports how much of
the arm's momentum-balance residual candidate terms explain (least squares on their weak-form
projections): a hardening cable (theta^3), Stribeck friction, a per-recording torque offset and
a per-recording cable stiffness. `--frequency-response` instead calibrates on all ten chirps and
compares the arm's response to the chirp at each frequency (the recorded arm angle's component at
the voltage's frequency, relative to the voltage's, in windows of two periods) with the calibrated
model's, simulated over the whole chirp from its first 0.1 s: a compliant coupling between the
motor and the arm or backlash in it would bend the ratio at the chirp's high frequencies.
`--smoothed-start` starts each prediction from the zero-phase
filter's state at its start (the metric of the data's README, which peeks 5 samples ahead)
instead of a state fitted to the 0.1 s before it. `--save` writes the calibration on all ten
chirps, as shipped in the package (`qube_suite.devices.qube.parameters.REAL_QUBE_SERVO2`), and stops.
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import time

import numpy as np

from qube_suite import calibration
from qube_suite.calibration import calibration_file, prediction, recordings
from qube_suite.devices.qube import parameters

HORIZONS = (0.1, 0.5, 1.0)
SMOOTHED_START = False
"""Whether predictions start from the filter's state (`--smoothed-start`)."""
DEFAULT_DATA = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "real_qube")
ABLATION = (
    ("viscous only, whole-sample latency",
     ("motor_torque_constant", "rotor_inertia", "pendulum_length", "arm_damping", "pendulum_damping",
      "pendulum_encoder_offset")),
    ("+ Coulomb friction on both joints", ("arm_friction", "pendulum_friction")),
    ("+ cable spring and its rest angle", ("cable_stiffness", "arm_torque_offset")),
    ("+ voltage dead zone", ("voltage_deadzone",)),
    ("+ fractional-sample latency", ()),
    ("+ slack band of the cable", ("cable_slack",)),
)
REVERSALS_ROW = "+ the arm's windows with reversals (not sticking) in the fit"
"""The ablation's last row: every unknown, the fit also taking the windows where the arm reverses without
sticking (`calibration.calibrate_recordings(reversals=True)`), which the shipped calibration does not."""
BALANCING_ANGLE = 0.4
"""A swing-up's start counts as balancing where the pendulum is within this of upright (rad)."""
ENCODER_COUNT = 2.0 * np.pi / 2048
"""One count of the Qube-Servo 2's encoders (rad)."""
FRACTIONAL_LATENCY_ROW = 4
"""The ablation's rows before this one take the latency rounded to whole samples."""


def predictions(calibration_: calibration.Calibration | None, m, horizon: float, **options
                ) -> prediction.Predictions:
    """Predictions `horizon` ahead on `m` of the nominal model (None) or a calibration; `options` as
    `prediction.predict`'s."""
    samples = np.arange(len(m))
    if calibration_ is None:
        return prediction.predict(m, {}, samples, horizon=horizon, smoothed_start=SMOOTHED_START, **options)
    c = calibration_
    rest = c.offsets.get("arm_encoder_offset")
    return prediction.predict(
        m, c.parameters, samples, c.actuation["latency_seconds"] / m.sample_time,
        (0.0, c.offsets["pendulum_encoder_offset"]), horizon=horizon,
        voltage_deadzone=c.actuation["voltage_deadzone"],
        cable_rest_angle=0.0 if rest is None else -rest, cable_slack=c.offsets.get("cable_slack", 0.0),
        smoothed_start=SMOOTHED_START, **options)


def predict(calibration_: calibration.Calibration | None, m, horizon: float) -> np.ndarray:
    """Errors at `horizon` (starts, 2) of the nominal model (None) or a calibration on `m`."""
    return predictions(calibration_, m, horizon).error_at_horizon


def balancing(p: prediction.Predictions, m) -> np.ndarray:
    """Which of the starts of `p` find the pendulum balancing (within `BALANCING_ANGLE` of upright)."""
    return np.abs(m.alpha[p.starts]) < BALANCING_ANGLE


def wrapped(angle: np.ndarray) -> np.ndarray:
    return np.mod(angle + np.pi, 2.0 * np.pi) - np.pi


def swingup_table(calibration_: calibration.Calibration | None, ms: list) -> dict[str, dict[str, float]]:
    """RMS errors (rad) at each horizon on the swing-ups `ms`: all starts, balancing, swinging."""
    out = {}
    for h in HORIZONS:
        runs = [(predictions(calibration_, m, h), m) for m in ms]
        out[f"{h:g}"] = split([p.error_at_horizon for p, _ in runs], [balancing(p, m) for p, m in runs])
    return out


def floors(c: calibration.Calibration, ms: list) -> dict[str, dict[str, float]]:
    """What limits the calibrated model on the swing-ups `ms`, balancing and swinging starts apart (rad):
    its error 0.1 s ahead from the start fitted through the horizon too (the model's own error), and
    how far its own prediction moves, 0.1 and 0.5 s ahead, when the start's pendulum angle moves one
    encoder count (the chaos no model can beat)."""
    out = {}
    runs = [(predictions(c, m, 0.1, fit_through_horizon=True), m) for m in ms]
    out["best_start_0.1"] = split([p.error_at_horizon for p, _ in runs], [balancing(p, m) for p, m in runs])
    for h in (0.1, 0.5):
        moved, upright = [], []
        for m in ms:
            base = predictions(c, m, h, start_perturbation=np.zeros(4))
            other = predictions(c, m, h, start_perturbation=np.array([0.0, ENCODER_COUNT, 0.0, 0.0]))
            moved.append(wrapped(other.predicted[:, -1] - base.predicted[:, -1]))
            upright.append(balancing(base, m))
        out[f"one_count_{h:g}"] = split(moved, upright)
    return out


def split(errors: list[np.ndarray], upright: list[np.ndarray]) -> dict[str, float]:
    return {"all": rms(errors), "balancing": rms([e[b] for e, b in zip(errors, upright, strict=True)]),
            "swinging": rms([e[~b] for e, b in zip(errors, upright, strict=True)])}


def rms(errors: list[np.ndarray]) -> float:
    return float(np.sqrt(np.mean(np.concatenate(errors) ** 2)))


def table(calibration_: calibration.Calibration | None, ms: list) -> dict[str, float]:
    return {f"{h:g}": rms([predict(calibration_, m, h) for m in ms]) for h in HORIZONS}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=DEFAULT_DATA)
    parser.add_argument("--out", default=None, help="write the results as JSON here")
    parser.add_argument("--figure", default=None, help="write recorded against predicted angles here")
    parser.add_argument("--save", default=None, help="write the calibration on all chirps here and stop")
    parser.add_argument("--smoothed-start", action="store_true")
    parser.add_argument("--residual-structure", action="store_true")
    parser.add_argument("--frequency-response", action="store_true")
    args = parser.parse_args()
    global SMOOTHED_START
    SMOOTHED_START = args.smoothed_start
    if args.residual_structure:
        residual_structure(sorted(glob.glob(os.path.join(args.data, "qs2_chirp_*.csv"))))
        return
    if args.frequency_response:
        frequency_response(sorted(glob.glob(os.path.join(args.data, "qs2_chirp_*.csv"))))
        return
    if args.save:
        save(sorted(glob.glob(os.path.join(args.data, "qs2_chirp_*.csv"))), args.save)
        return
    started = time.perf_counter()
    chirps = sorted(glob.glob(os.path.join(args.data, "qs2_chirp_*.csv")))
    swings = {hz: sorted(glob.glob(os.path.join(args.data, f"qs2_swingup_{hz}hz_*.csv")))
              for hz in (250, 500)}
    if len(chirps) != 10:
        raise SystemExit(f"expected 10 chirps in {args.data}, found {len(chirps)}")
    read = {path: recordings.read(path) for path in chirps + swings[250] + swings[500]}
    results: dict = {"machine": "see docs/calibration.md"}

    held_out = {"nominal": table(None, [read[p] for p in chirps]), "calibrated": {}}
    errors = {h: [] for h in HORIZONS}
    for path in chirps:
        c = calibration.calibrate_recordings([p for p in chirps if p != path])
        for h in HORIZONS:
            errors[h].append(predict(c, read[path], h))
    held_out["calibrated"] = {f"{h:g}": rms(errors[h]) for h in HORIZONS}
    results["held_out_chirps"] = held_out
    print("held-out chirps", held_out, flush=True)

    full = calibration.calibrate_recordings(chirps)
    results["swingups"] = {}
    for hz, paths in swings.items():
        ms = [read[p] for p in paths]
        results["swingups"][f"{hz}Hz"] = {"nominal": swingup_table(None, ms),
                                          "calibrated": swingup_table(full, ms), "floors": floors(full, ms)}
        print(f"swing-ups {hz} Hz", results["swingups"][f"{hz}Hz"], flush=True)

    train = [p for p in chirps if not p.endswith("_4.csv")]
    test = [read[p] for p in chirps if p.endswith("_4.csv")]
    free: tuple[str, ...] = ()
    results["ablation"] = []
    for index, (name, added) in enumerate((*ABLATION, (REVERSALS_ROW, ()))):
        free = free + added
        c = calibration.calibrate_recordings(train, free=free, reversals=name == REVERSALS_ROW)
        if index < FRACTIONAL_LATENCY_ROW:  # until then, the latency rounded to whole samples
            c.actuation["latency_seconds"] = round(c.latency_steps) * read[train[0]].sample_time
        row = {"model": name, "chirps": table(c, test), "latency_ms": 1e3 * c.actuation["latency_seconds"],
               "swingups_0.1s": {f"{hz}Hz": rms([predict(c, read[p], 0.1) for p in paths])
                                 for hz, paths in swings.items()}}
        results["ablation"].append(row)
        print("ablation", row, flush=True)

    singles = [calibration.calibrate_recordings([p]) for p in chirps]
    rows = {}
    for name, (low, high) in full.intervals.items():
        value = full.parameters.get(name, full.actuation.get(name))
        spread = [s.parameters.get(name, s.actuation.get(name)) for s in singles]
        inside = sum(1 for s, v in zip(singles, spread, strict=True)
                     if s.intervals[name][0] <= value <= s.intervals[name][1])
        rows[name] = {"nominal": parameters.NOMINAL.get(name, 0.0), "calibrated": value,
                      "interval": [low, high],
                      "single_chirp_min": min(spread), "single_chirp_max": max(spread),
                      "single_intervals_containing_all_chirp_estimate": inside}
        print(f"{name:24s} nominal {rows[name]['nominal']:.4g} calibrated {value:.4g} "
              f"[{low:.4g}, {high:.4g}] "
              f"single-chirp {min(spread):.4g}..{max(spread):.4g}; {inside}/10 single intervals contain it")
    results["parameters"] = rows
    results["latency_ms"] = 1e3 * full.actuation["latency_seconds"]
    results["combinations"] = full.combinations
    results["wall_seconds"] = time.perf_counter() - started
    print(f"wall time {results['wall_seconds']:.0f} s")
    if args.out:
        with open(args.out, "w", encoding="utf-8") as file:
            json.dump(results, file, indent=1)
    if args.figure:
        figure(full, read[chirps[-1]], read[swings[250][0]], args.figure)


def residual_structure(chirps: list[str]) -> None:
    """Print the share of the arm equation's residual that candidate terms explain (see the module)."""
    from qube_suite.calibration import fit

    read = [recordings.read(path) for path in chirps]
    result = fit.fit_voltage(read, latency=1.5)
    residuals, terms = [], []
    for s, voltage in zip(result.signals, result.voltages, strict=True):
        arm, _ = fit.voltage_equations(result.x, s, fit.delayed_voltage(voltage, result.latency))
        starts, zero = s.starts[s.arm_sliding], np.zeros_like(s.theta)
        residuals.append(arm)
        terms.append({name: fit._balance(zero, torque, 0.0, starts, s.sample_time) for name, torque in (
            ("one", np.ones_like(s.theta)), ("theta", s.theta), ("theta^3", s.theta**3),
            ("stribeck", np.exp(-(s.dtheta / 0.3) ** 2) * np.sign(s.dtheta)))})
    y = np.concatenate(residuals)

    def explained(columns: list[np.ndarray]) -> float:
        design = np.column_stack(columns)
        coefficients, *_ = np.linalg.lstsq(design, -y, rcond=None)
        return 1.0 - float(np.sqrt(np.mean((y + design @ coefficients) ** 2) / np.mean(y**2)))

    def per_recording(name: str) -> list[np.ndarray]:
        columns, start = [], 0
        for part, term in zip(residuals, terms, strict=True):
            column = np.zeros(len(y))
            column[start:start + len(part)] = term[name]
            columns.append(column)
            start += len(part)
        return columns

    def shared(name: str) -> np.ndarray:
        return np.concatenate([term[name] for term in terms])

    print(f"arm residual RMS {np.sqrt(np.mean(y**2)):.3g} N m s; share of its RMS explained by")
    for label, columns in (("a hardening cable, theta^3", [shared("theta^3")]),
                           ("Stribeck friction, exp(-(v / 0.3 rad/s)^2) sign(v)", [shared("stribeck")]),
                           ("a torque offset per recording", per_recording("one")),
                           ("a torque offset and a cable stiffness per recording",
                            per_recording("one") + per_recording("theta"))):
        print(f"  {label}: {100 * explained(columns):.0f} %")


FREQUENCY_WINDOWS = np.arange(0.5, 9.01, 0.5)
"""Centres (s into each chirp) of the windows `frequency_response` compares, 9.6 down to 1.4 Hz."""


def frequency_response(chirps: list[str]) -> None:
    """Print the arm's response to each chirp's voltage (rad/V, phase in degrees) against the model's
    calibrated on all `chirps`, averaged over them, at the frequencies of `FREQUENCY_WINDOWS`."""
    c = calibration.calibrate_recordings(chirps)
    recorded, simulated, frequencies = [], [], []
    for path in chirps:
        m = recordings.read(path)
        whole = predictions(c, m, m.time[-1] - 0.35)  # one start, 0.2 s in
        start = whole.starts[0]
        span = slice(start, start + len(whole.time))
        local = chirp_frequency(m.time, m.voltage)
        frequencies.append(local(FREQUENCY_WINDOWS))
        recorded.append(response(m.time[span], m.theta[span], m.voltage[span], frequencies[-1]))
        simulated.append(response(m.time[span], whole.predicted[0, :, 0], m.voltage[span], frequencies[-1]))
    real, model = np.mean(recorded, axis=0), np.mean(simulated, axis=0)
    print("frequency (Hz) | recorded gain (rad/V), phase (deg) | model's | recorded / model")

    def gain_phase(z: complex, digits: int) -> str:
        return f"{abs(z):.{digits}f} {np.degrees(np.angle(z)):+7.1f}"

    for f, a, b in zip(np.mean(frequencies, axis=0), real, model, strict=True):
        print(f"{f:5.2f} | {gain_phase(a, 4)} | {gain_phase(b, 4)} | {gain_phase(a / b, 3)}")


def chirp_frequency(time: np.ndarray, voltage: np.ndarray):
    """The chirp's frequency (Hz) as a function of time (s): a cubic fitted to the half-periods between
    its voltage's zero crossings (each quantised to a sample)."""
    crossings = time[1:][np.diff(np.sign(voltage)) != 0]
    middles, frequency = 0.5 * (crossings[1:] + crossings[:-1]), 0.5 / np.diff(crossings)
    return np.polynomial.Polynomial.fit(middles, frequency, 3)


def response(time: np.ndarray, angle: np.ndarray, voltage: np.ndarray, frequencies: np.ndarray) -> np.ndarray:
    """The complex ratio of `angle`'s (rad) to `voltage`'s (V) component at each of `frequencies` (Hz),
    over two periods around each of `FREQUENCY_WINDOWS` (s of `time`; a drift quadratic in time removed)."""
    out = []
    for centre, f in zip(FREQUENCY_WINDOWS, frequencies, strict=True):
        inside = np.abs(time - centre) < 1.0 / f
        t = time[inside] - centre
        phase = 2.0 * np.pi * f * t
        basis = np.column_stack([np.cos(phase), np.sin(phase), np.ones_like(t), t, t**2])
        a = np.linalg.lstsq(basis, angle[inside], rcond=None)[0]
        v = np.linalg.lstsq(basis, voltage[inside], rcond=None)[0]
        out.append(complex(a[0], -a[1]) / complex(v[0], -v[1]))
    return np.array(out)


def save(chirps: list[str], path: str) -> None:
    """Calibrate on `chirps` and save the result at `path`, its source named rather than its paths."""
    c = calibration.calibrate_recordings(chirps)
    c.metadata.update(identifier="TU Darmstadt, 2021", date="2021-04-14", recording=(
        "10 voltage chirps qs2_chirp_{pos,neg}_{0..4}.csv, converted from SimuRLacra "
        "(famura/SimuRLacra, Pyrado/data/perma/evaluation, BSD-3-Clause)"))
    c.save(path)
    os.remove(calibration_file.randomization_path(path))  # the package ships the calibration alone
    print(f"calibration on {len(chirps)} chirps written to {path}")


def figure(c: calibration.Calibration, chirp, swing, path: str) -> None:
    """Recorded angles against 0.5 s predictions of both models, on a chirp and a swing-up."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(11, 6), sharex="col")
    for column, (m, title) in enumerate(((chirp, "chirp (in the calibration)"), (swing, "swing-up, 250 Hz"))):
        samples = np.arange(len(m))
        rest = c.offsets.get("arm_encoder_offset")
        runs = {
            "nominal": prediction.predict(m, {}, samples, horizon=0.5),
            "calibrated": prediction.predict(
                m, c.parameters, samples, c.actuation["latency_seconds"] / m.sample_time,
                (0.0, c.offsets["pendulum_encoder_offset"]), horizon=0.5,
                voltage_deadzone=c.actuation["voltage_deadzone"],
                cable_rest_angle=0.0 if rest is None else -rest,
                cable_slack=c.offsets.get("cable_slack", 0.0))}
        for row, label in enumerate(("arm angle (rad)", "pendulum angle (rad)")):
            ax = axes[row, column]
            ax.plot(m.time, m.theta if row == 0 else m.alpha, "k", lw=1, label="recorded")
            for (name, p), colour in zip(runs.items(), ("tab:red", "tab:blue"), strict=True):
                for i, start in enumerate(p.starts[::5]):
                    j = 5 * i
                    ax.plot(m.time[start] + p.time, p.predicted[j, :, row], colour, lw=1,
                            label=f"{name}, 0.5 s ahead" if i == 0 else None)
            ax.set_ylabel(label)
        axes[0, column].set_title(title)
        axes[1, column].set_xlabel("time (s)")
    axes[0, 0].legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=80)


if __name__ == "__main__":
    main()
