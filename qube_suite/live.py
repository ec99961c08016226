"""Live scopes of a running Qube, in a process of their own, fed by the recorder's stream.

    qube-suite run --domain qube_hardware --task balance --controller balance --live
    qube-suite watch balance.jsonl --follow        # a recording another process is writing
    qube-suite watch balance.jsonl                 # replay a finished one

A run with `--live` records its episodes (`recording.Recorder`, a JSON line per
step, flushed as it is written) and starts `qube-suite watch RECORDING --follow`
as another process, which reads the lines as they appear and sends them to
Rerun's viewer (the `live` extra: `pip install "qube_suite[live]"`): scrolling
plots of the last `WINDOW` seconds of θ, α, voltage, motor current (on
hardware), reward and LED colour, and the digital twin — the simulated Qube put
in the measured angles and LED colour, drawn by MuJoCo's renderer — beside them.
The control loop does nothing more than it does with `--record`; whatever the
scope costs is spent in the other process. Rerun's viewer also replays a saved
scope (`--live FILE.rrd`, `rerun FILE.rrd`).
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any
from urllib.parse import quote

import numpy as np

from qube_suite import extras, recording
from qube_suite.files import MissingFileError

WINDOW = 10.0
"""Seconds of recorded time the scopes show, ending at the latest reading."""

TWIN_PERIOD = 0.1
"""Recorded time between two pictures of the digital twin in a replay (s)."""

LIVE_TWIN_PERIOD = 0.25
"""Wall-clock time between two pictures of the digital twin while following a recording (s): drawing
takes about 0.1 s with software OpenGL, and the scope must leave the computer to the control loop."""

NICENESS = 10
"""How much lower than the control loop's the following watcher's scheduling priority is (POSIX
nice increment): on a computer with few cores the loop gets the CPU first."""

TWIN_SIZE = (320, 240)
"""The twin's picture (pixels)."""

SCOPES = {"theta": "theta (rad)", "alpha": "alpha (rad)", "voltage": "voltage (V)",
          "raw_current": "current (A)", "reward": "reward"}
"""Recording columns plotted, and their plots' titles."""

POLL = 0.05
"""How often a followed recording is read for new lines (s)."""

SINKS = ("viewer", "web")
"""Where the scopes go besides a .rrd file: Rerun's native viewer, or its web viewer served locally."""
WEB_PORT, GRPC_PORT = 9090, 9876
"""Ports of the web viewer's page and of the stream it reads (Rerun's defaults)."""


def follow_lines(path: str | os.PathLike, follow: bool, done: threading.Event | None = None
                 ) -> Iterator[list[Any]]:
    """The JSON values of the recording at `path`, a batch of complete lines at a time.

    follow: go on reading lines as they are written, until `done` is set and every line is read
    (without `done`, until interrupted); else stop at the end of the file.
    """
    buffer = b""
    with open(path, "rb") as file:
        while True:
            chunk = file.read()
            buffer += chunk
            *lines, buffer = buffer.split(b"\n")
            if lines:
                yield [json.loads(line) for line in lines if line]
            if not chunk:
                if not follow:
                    return
                if done is not None and done.is_set():
                    follow = False  # one more read: what was written before `done` was set
                    continue
                time.sleep(POLL)


def stdin_closed() -> threading.Event:
    """An event set once standard input reaches its end: how `start_watcher`'s writer says it is done
    (closing the pipe; a writer that dies closes it too)."""
    event = threading.Event()

    def wait() -> None:
        while sys.stdin.buffer.read(4096):
            pass
        event.set()

    threading.Thread(target=wait, name="qube-suite watch stdin", daemon=True).start()
    return event


class Scope:
    """Sends a recording's rows to Rerun: `feed` each batch of JSON values as it is read.

    Args:
        stream: the `rerun` module (or a recording stream with its functions).
        twin: draws the digital twin: (theta, alpha, led rgb) -> image; None: no twin.
        live: the rows arrive as they are written: the twin is drawn for the latest reading, every
            `LIVE_TWIN_PERIOD` of wall-clock time at most, which keeps the scope up with the Qube
            even where drawing is slow; else every `TWIN_PERIOD` of recorded time.
    """

    def __init__(self, stream: Any, twin: Any = None, live: bool = False):
        self._rr = stream
        self._twin = twin
        self._live = live  # draw the twin at most once a batch, so that drawing never falls behind
        self._columns: list[str] = []
        self._offset = 0.0  # recorded time before this episode's start (s)
        self._last_time = 0.0
        self._next_twin = 0.0

    def feed(self, values: list[Any]) -> None:
        rows = []
        for value in values:
            if isinstance(value, list):
                rows.append(value)
                continue
            self._flush(rows)
            rows = []
            if isinstance(value, dict) and isinstance(value.get("episode"), dict):
                self._columns = value["episode"]["columns"]
                self._offset = self._last_time
            elif isinstance(value, dict) and value.get("format") is not None \
                    and value["format"] != recording.FORMAT:
                raise ValueError(f"not a qube_suite recording (format {value['format']!r})")
        self._flush(rows)

    def _flush(self, rows: list[list[Any]]) -> None:
        if not rows or not self._columns:
            return
        rr = self._rr
        data = np.array([[math.nan if x is None else x for x in row] for row in rows], dtype=float)
        column = {name: data[:, i] for i, name in enumerate(self._columns)}
        times = self._offset + column["time"]
        self._last_time = float(times[-1])
        index = [rr.TimeColumn("time", duration=times)]
        for name in SCOPES:
            if name in column:
                rr.send_columns(f"scope/{name}", indexes=index,
                                columns=rr.Scalars.columns(scalars=column[name]))
        led = np.stack([column["led_r"], column["led_g"], column["led_b"]], axis=1)
        rr.send_columns("scope/led", indexes=index, columns=rr.Scalars.columns(scalars=led))
        if self._twin is None:
            return
        if self._live:  # the latest reading, every LIVE_TWIN_PERIOD of wall-clock time at most
            if time.monotonic() >= self._next_twin:
                self._draw_twin(float(times[-1]), column["theta"][-1], column["alpha"][-1], led[-1])
                self._next_twin = time.monotonic() + LIVE_TWIN_PERIOD
            return
        for i, now in enumerate(times.tolist()):
            if now >= self._next_twin:
                self._draw_twin(now, column["theta"][i], column["alpha"][i], led[i])
                self._next_twin = now + TWIN_PERIOD

    def _draw_twin(self, now: float, theta: float, alpha: float, led: np.ndarray) -> None:
        self._rr.set_time("time", duration=now)
        self._rr.log("twin", self._rr.Image(self._twin(theta, alpha, led)))


class Twin:
    """The simulated Qube drawn in the measured angles and LED colour (MuJoCo's offscreen renderer)."""

    def __init__(self):
        from qube_suite.devices.qube import simulation as qube
        from qube_suite.media import FrameRenderer

        self._physics = qube.make_physics()
        self._frames = FrameRenderer(width=TWIN_SIZE[0], height=TWIN_SIZE[1])

    def __call__(self, theta: float, alpha: float, led: np.ndarray) -> np.ndarray:
        self._physics.reset_to([theta, alpha, 0.0, 0.0])
        self._physics.set_led(np.nan_to_num(led))
        return self._frames.render(self._physics)

    def close(self) -> None:
        self._frames.close()
        self._physics.close()


def blueprint() -> Any:
    """The scopes' layout: the plots stacked on the left, each showing the last `WINDOW` seconds,
    the twin on the right."""
    import rerun.blueprint as rrb

    last = rrb.VisibleTimeRange("time", start=rrb.TimeRangeBoundary.cursor_relative(seconds=-WINDOW),
                                end=rrb.TimeRangeBoundary.cursor_relative())
    plots = [rrb.TimeSeriesView(origin=f"scope/{name}", name=title, time_ranges=[last])
             for name, title in {**SCOPES, "led": "LED (r, g, b)"}.items()]
    twin = rrb.Spatial2DView(origin="twin", name="digital twin")
    return rrb.Blueprint(rrb.Horizontal(rrb.Vertical(*plots), twin, column_shares=[2, 1]),
                         collapse_panels=True)


def watch(path: str | os.PathLike, follow: bool = False, done: threading.Event | None = None,
          sink: str | None = "viewer", save: str | os.PathLike | None = None, twin: bool = True) -> int:
    """Show the recording at `path` in Rerun (see the module docstring); return the rows shown.

    Args:
        follow, done: as `follow_lines`.
        sink: "viewer" (Rerun's native viewer, spawned), "web" (its web viewer, served on this
            machine; the address is printed), or None with `save`.
        save: also (or only) write the scopes to this .rrd file, which `rerun FILE.rrd` replays.
        twin: draw the digital twin (needs OpenGL, offscreen or not).
    """
    extras.require("rerun", "the live scope", extra="live")
    import rerun as rr

    if sink is not None and sink not in SINKS:
        raise ValueError(f"sink must be one of {SINKS} or None, got {sink!r}")
    if sink is None and save is None:
        raise ValueError("give a sink, a file to save to, or both")
    if not os.path.exists(path):
        raise MissingFileError(path, "recording")
    if follow and hasattr(os, "nice"):
        os.nice(NICENESS)  # the Qube's control loop, on the same computer, comes first
    rr.init("qube_suite", recording_id=f"qube_suite:{os.path.abspath(path)}", spawn=False)
    layout = blueprint()
    sinks = []
    if save is not None:
        sinks.append(rr.FileSink(os.fspath(save)))
    if sink == "viewer":
        rr.spawn(connect=False)
        sinks.append(rr.GrpcSink())
    elif sink == "web":
        sinks.append(rr.GrpcServerSink(port=GRPC_PORT))  # a sink: set_sinks drops serve_grpc's server
        url = f"rerun+http://localhost:{GRPC_PORT}/proxy"
        rr.serve_web_viewer(web_port=WEB_PORT, open_browser=False, connect_to=url)
        print(f"scopes: open http://localhost:{WEB_PORT}/?url={quote(url, safe=':/')}", flush=True)
    rr.set_sinks(*sinks, default_blueprint=layout)
    drawer = Twin() if twin else None
    scope = Scope(rr, drawer, live=follow)
    rows = 0
    try:
        for values in follow_lines(path, follow, done):
            scope.feed(values)
            rows += sum(isinstance(value, list) for value in values)
    finally:
        if drawer is not None:
            drawer.close()
        rr.disconnect()
    return rows


def start_watcher(path: str | os.PathLike, target: str) -> subprocess.Popen:
    """Start `qube-suite watch path --follow --until-stdin-closes` in another process, showing the scopes
    on `target`: "viewer", "web" or a .rrd file to save them to. Close its standard input once the
    recording is complete (`finish_watcher`)."""
    destination = ["--sink", target] if target in SINKS else ["--sink", "none", "--save", target]
    command = [sys.executable, "-m", "qube_suite.cli", "watch", os.fspath(path), "--follow",
               "--until-stdin-closes", *destination]
    return subprocess.Popen(command, stdin=subprocess.PIPE)


def finish_watcher(watcher: subprocess.Popen, timeout: float = 120.0) -> None:
    """Tell the watcher the recording is complete and wait until it has shown all of it."""
    watcher.stdin.close()
    try:
        watcher.wait(timeout)
    except subprocess.TimeoutExpired:
        watcher.terminate()
