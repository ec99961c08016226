"""The live scope's web page seen the way a person sees it: `qube-suite watch REC --follow --sink web`
follows a recording as it is written, and headless Chromium (software WebGL) loads the printed address;
its screenshots must show the traces, and the traces must move as the recording grows. Skipped, saying
why, where Chromium or Rerun is missing (`apt-get install chromium`, the `live` extra)."""

import base64
import json
import os
import re
import shutil
import socket
import subprocess
import sys
import threading
import time
import urllib.request

import imageio.v3 as iio
import numpy as np
import pytest

from qube_suite import baselines, episodes, live, recording, suite

pytest.importorskip("rerun", reason="the live scope needs the live extra (rerun-sdk)")
websockets_client = pytest.importorskip("websockets.sync.client", reason="needs websockets (mujoco's)")

CHROMIUM = next((shutil.which(name) for name in ("chromium", "chromium-browser", "google-chrome")
                 if shutil.which(name)), None)
pytestmark = [pytest.mark.render, pytest.mark.slow,
              pytest.mark.skipif(CHROMIUM is None, reason="needs Chromium (apt-get install chromium)")]

FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader", "--disable-quic",
         "--no-first-run", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", "--remote-debugging-port=0", "--window-size=1280,800"]
FIRST_ROWS = 500  # written before the first screenshot; the rest only after it
WAIT = 90.0  # seconds, at most, for the page to show what is expected (software rendering is slow)


def port_in_use(port):
    with socket.socket() as probe:
        return probe.connect_ex(("127.0.0.1", port)) == 0


class Page:
    """A headless Chromium tab driven over the DevTools protocol."""

    def __init__(self, profile, address):
        self.browser = subprocess.Popen([CHROMIUM, *FLAGS, f"--user-data-dir={profile}", address],
                                        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        active_port = profile / "DevToolsActivePort"
        deadline = time.monotonic() + 60
        while not (active_port.exists() and active_port.read_text().strip()):
            if time.monotonic() > deadline or self.browser.poll() is not None:
                self.close()
                pytest.fail("Chromium did not open its DevTools port")
            time.sleep(0.1)
        port = active_port.read_text().split()[0]
        targets = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json", timeout=30))
        tab = next(target["webSocketDebuggerUrl"] for target in targets if target["type"] == "page")
        self.socket = websockets_client.connect(tab, max_size=None, open_timeout=30, legacy=True)
        self.calls = 0

    def call(self, method, **params):
        self.calls += 1
        self.socket.send(json.dumps({"id": self.calls, "method": method, "params": params}))
        while True:
            message = json.loads(self.socket.recv(timeout=60))
            if message.get("id") == self.calls:
                if "error" in message:
                    raise RuntimeError(f"{method}: {message['error']}")
                return message["result"]

    def screenshot(self):
        return iio.imread(base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"]))

    def close(self):
        if hasattr(self, "socket"):
            self.socket.close()
        self.browser.terminate()
        self.browser.wait(timeout=30)


def traces(image):
    """Mask of the coloured pixels in the plots (the left 60 % of the page below its top bar): the
    traces and their legend dots; Rerun draws everything else there in greys (bar a selected item)."""
    height, width = image.shape[:2]
    plots = image[int(0.08 * height):int(0.95 * height), :int(0.6 * width), :3].astype(int)
    return plots.max(axis=2) - plots.min(axis=2) > 60


def plotted(image):
    """Whether colour runs across more than half the plots' width, as traces do (not a blank page, nor
    the welcome page with its one coloured item)."""
    columns = np.flatnonzero(traces(image).any(axis=0))
    return columns.size > 0 and columns.max() - columns.min() > 0.5 * traces(image).shape[1]


def wait_for(page, condition, what):
    deadline = time.monotonic() + WAIT
    while time.monotonic() < deadline:
        image = page.screenshot()
        if condition(image):
            return image
        time.sleep(1.0)
    pytest.fail(f"the page did not show {what} within {WAIT:.0f} s")


@pytest.fixture
def rows(tmp_path):
    path = tmp_path / "whole.jsonl"
    environment = suite.load("qube", "swingup", task_kwargs={"random": 0})
    with recording.Recorder(path, environment):
        episodes.run_episode(environment, baselines.for_environment("swingup", environment), seed=0)
    environment.close()
    return path.read_text().splitlines(keepends=True)


def test_the_web_scope_shows_the_traces_moving_as_the_recording_grows(rows, tmp_path):
    if port_in_use(live.WEB_PORT) or port_in_use(live.GRPC_PORT):
        pytest.skip(f"ports {live.WEB_PORT}/{live.GRPC_PORT} are taken (another scope is open)")
    followed = tmp_path / "followed.jsonl"
    header = next(i for i, line in enumerate(rows) if line.startswith("["))
    followed.write_text("".join(rows[:header + FIRST_ROWS]))
    first_seen = threading.Event()

    def write_the_rest():
        if first_seen.wait(timeout=3 * WAIT):
            with open(followed, "a") as out:
                for line in rows[header + FIRST_ROWS:]:
                    out.write(line)
                    out.flush()
                    time.sleep(0.002)

    environment = dict(os.environ, PYTHONUNBUFFERED="1")
    watcher = subprocess.Popen([sys.executable, "-m", "qube_suite.cli", "watch", str(followed), "--follow",
                                "--until-stdin-closes", "--sink", "web"], stdin=subprocess.PIPE,
                               stdout=subprocess.PIPE, text=True, env=environment)
    writer = threading.Thread(target=write_the_rest, daemon=True)
    writer.start()
    page = None
    try:
        printed = watcher.stdout.readline()
        address = re.search(r"open (http://\S+)", printed)
        assert address, f"watch printed no address: {printed!r}"
        profile = tmp_path / "profile"
        profile.mkdir()
        page = Page(profile, address.group(1))
        early = wait_for(page, plotted, "the traces")
        first_seen.set()
        writer.join(timeout=2 * WAIT)
        late = wait_for(page, lambda image: plotted(image) and (traces(image) != traces(early)).sum() > 2000,
                        "the traces moving")
    finally:
        first_seen.set()
        if page is not None:
            page.close()
        live.finish_watcher(watcher)
    iio.imwrite(tmp_path / "early.png", early)  # kept beside the test's files for a person to look at
    iio.imwrite(tmp_path / "late.png", late)
