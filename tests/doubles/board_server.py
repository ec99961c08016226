"""The board behind the wall-clock `quanser.hardware` double: a process of its own.

A real Qube's board keeps running when the program that drives it dies: its
watchdog expires on the board's own clock and puts the outputs into their
expiration states. To test that, the double's board must outlive the process
that drives it, so it lives here, in a separate process started by the test
(`BoardServer`), and the double's `HIL` in any process talks to it over a Unix
socket (`multiprocessing.connection`, one thread per connection).

Each card identifier is one board: the substitute board of `qube_suite` in its
wall-clock mode (`_hil_sim.HIL(realtime=True)`: the plant integrates up to the
present at every call, and `task_read` sleeps until the next sample is due, so
samples pile up in the task buffer while the driving process is busy). A ticker
thread brings every board up to the present every millisecond, so a watchdog
expires when it is due even when nobody calls. A board's plant, encoder counts
and watchdog state persist from one open to the next, as a physical Qube's do.
Where the system allows it the process runs with real-time scheduling, since a
real board's clock does not wait for the host's scheduler; the process driving
it (the code under test) runs at normal priority and bears all the host's delays.

When a driving process disappears without closing its board (killed), its tasks
are deleted, as the driver does when a handle is released, and the board is left
exactly as it was: outputs as last written until the watchdog expires. The next
process to open the card gets the same board, watchdog expiry included.

`state(identifier)` (not part of Quanser's API) reports what a test checks on the
board: the voltage the amplifier applies, whether it is enabled, whether the
watchdog has expired, whether the last owner closed it, the card options set,
and the longest time since the last open between two watchdog reloads while it ran (`worst_period`:
the control loop's worst sample period, as the board saw it).
`set_true_state(state, identifier)` (not part of Quanser's API either) is a hand on
the Qube: it puts the plant at [theta, alpha, dtheta, dalpha], whoever holds the
board, and the encoders count the move.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import threading
import time
from multiprocessing.connection import Client, Listener

AUTHKEY = b"qube-suite-wall-clock-board"
ADDRESS_VARIABLE = "QUBE_SUITE_BOARD_SERVER"
"""Environment variable holding the server's socket path; the double connects to it."""

TICK = 0.001
"""The ticker's period (s): how late a watchdog expiry can be applied at worst."""


class _Board:
    def __init__(self, card_type: str):
        from qube_suite.hardware import _hil_sim

        self.hil = _hil_sim.HIL(realtime=True)
        self.card_type = card_type
        self.owner: int | None = None        # connection id holding it open
        self.closed_cleanly = False
        self.options = ""
        self.tasks: dict[int, object] = {}
        self.last_reload: float | None = None
        self.worst_period = 0.0      # longest time between two watchdog reloads while it ran (s)


class _Server:
    def __init__(self):
        from qube_suite.hardware import _hil_sim

        self.sim = _hil_sim
        self.boards: dict[str, _Board] = {}
        self.lock = threading.Lock()
        self.next_id = 1

    # -- the ticker ------------------------------------------------------------------------

    def tick_forever(self) -> None:
        while True:
            with self.lock:
                boards = [b for b in self.boards.values() if b.hil.is_valid()]
            for board in boards:
                board.hil.time  # noqa: B018  (catches the plant up with the wall clock)
            time.sleep(TICK)

    # -- connections -----------------------------------------------------------------------

    def serve(self, connection, connection_id: int) -> None:
        try:
            while True:
                try:
                    request = connection.recv()
                except (EOFError, OSError):
                    break
                try:
                    reply = ("ok", self.handle(connection_id, *request))
                except self.sim.HILError as error:
                    reply = ("hil", error.error_code, error.get_error_message())
                except Exception as error:  # a bug of the double: let the client see it
                    reply = ("bug", f"{type(error).__name__}: {error}")
                try:
                    connection.send(reply)
                except (OSError, BrokenPipeError):
                    break
        finally:
            self.abandon(connection_id)

    def abandon(self, connection_id: int) -> None:
        """The process holding a board went away without closing it: release its tasks only."""
        with self.lock:
            for board in self.boards.values():
                if board.owner == connection_id:
                    for task in board.tasks.values():
                        with contextlib.suppress(self.sim.HILError):
                            board.hil.task_delete(task)
                    board.tasks.clear()
                    board.owner = None

    def handle(self, connection_id: int, method: str, identifier: str, *args):
        if method == "state":
            return self.state(identifier)
        if method == "set_true_state":
            return self.set_true_state(identifier, *args)
        if method == "open":
            return self.open(connection_id, identifier, *args)
        board = self.boards.get(identifier)
        if board is None or board.owner != connection_id:
            raise self.sim.HILError(-1, "the board is not open")
        hil = board.hil
        if method == "close":
            for task in board.tasks.values():
                hil.task_delete(task)
            board.tasks.clear()
            hil.close()
            board.owner, board.closed_cleanly = None, True
            return None
        if method in ("watchdog_start", "watchdog_reload"):
            now = time.perf_counter()
            if method == "watchdog_reload" and board.last_reload is not None:
                board.worst_period = max(board.worst_period, now - board.last_reload)
            board.last_reload = now
        elif method in ("watchdog_stop", "watchdog_clear"):
            board.last_reload = None
        if method == "set_card_specific_options":
            board.options = args[0]
            return None
        if method == "task_read_values":
            task_id, count, *buffers = args
            task = board.tasks.get(task_id)
            if task is None:
                raise self.sim.HILError(-5, "invalid task handle (deleted or of another board)")
            return (hil.task_read(task, count, *buffers), *buffers)
        if method.endswith("_values"):                     # immediate reads: fill and send back
            channels, count, buffer = args
            getattr(hil, method[:-len("_values")])(channels, count, buffer)
            return buffer
        if method.startswith("task_create"):
            task = getattr(hil, method)(*args)
            task_id = self.next_id
            self.next_id += 1
            board.tasks[task_id] = task
            return task_id
        if method.startswith("task_"):
            task_id, *rest = args
            task = board.tasks.get(task_id)
            if task is None:
                raise self.sim.HILError(-5, "invalid task handle (deleted or of another board)")
            result = getattr(hil, method)(task, *rest)
            if method == "task_delete":
                del board.tasks[task_id]
            return result
        return getattr(hil, method)(*args)

    def open(self, connection_id: int, identifier: str, card_type: str):
        with self.lock:
            board = self.boards.get(identifier)
            if board is not None and board.owner is not None:
                raise self.sim.HILError(-11, f"board {identifier} is in use by another process")
            if board is None:
                board = self.boards[identifier] = _Board(card_type)
            elif board.card_type != card_type:
                raise self.sim.HILError(-2, f"board {identifier} is a {board.card_type}, not a {card_type}")
            if not board.hil.is_valid():
                board.hil.open(card_type, identifier)
            board.owner, board.closed_cleanly = connection_id, False
            board.worst_period, board.last_reload = 0.0, None
        return None

    def set_true_state(self, identifier: str, state) -> None:
        board = self.boards.get(identifier)
        if board is None:
            raise self.sim.HILError(-11, f"board {identifier} was never opened")
        board.hil.set_true_state(state)

    def state(self, identifier: str) -> dict | None:
        board = self.boards.get(identifier)
        if board is None:
            return None
        hil = board.hil
        open_ = hil.is_valid()
        return {
            "applied_voltage": hil.applied_voltage, "written_voltage": hil.written_voltage,
            "amplifier_enabled": hil.amplifier_enabled,
            "watchdog_expired": hil.watchdog_is_expired() if open_ else None,
            "held": board.owner is not None, "closed_cleanly": board.closed_cleanly,
            "card_options": board.options, "true_state": hil.true_state().tolist(), "time": hil.time,
            "led": hil.led, "worst_period": board.worst_period,
        }


def _run_like_hardware() -> str:
    """A board's clock and watchdog are hardware: the host's scheduler never delays them. The
    nearest a process gets is real-time scheduling (SCHED_FIFO, where allowed), else a raised
    priority, else none; returns which."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(20))
        return "SCHED_FIFO"
    except (AttributeError, PermissionError, OSError):
        pass
    try:
        os.nice(-10)
        return "nice -10"
    except (PermissionError, OSError):
        return "normal"


def serve(address: str) -> None:
    """Run a board server on the Unix socket `address` until killed."""
    _run_like_hardware()
    server = _Server()
    threading.Thread(target=server.tick_forever, daemon=True).start()
    listener = Listener(address, "AF_UNIX", authkey=AUTHKEY)
    print("ready", flush=True)
    while True:
        connection = listener.accept()
        connection_id = server.next_id
        server.next_id += 1
        threading.Thread(target=server.serve, args=(connection, connection_id), daemon=True).start()


class BoardServer:
    """Start a board server process for a test; `environment()` gives the variables its children need."""

    def __init__(self, directory: str):
        self.address = os.path.join(directory, "board.sock")
        self.process = subprocess.Popen([sys.executable, __file__, self.address], stdout=subprocess.PIPE,
                                        text=True)
        if self.process.stdout.readline().strip() != "ready":
            raise RuntimeError("the board server did not start")
        self._client = Client(self.address, "AF_UNIX", authkey=AUTHKEY)

    def state(self, identifier: str = "0") -> dict | None:
        """The board's state (see the module docstring); None if it was never opened."""
        self._client.send(("state", identifier))
        return self._client.recv()[1]

    def set_true_state(self, state, identifier: str = "0") -> None:
        """Move the Qube by hand: its plant to [theta, alpha, dtheta, dalpha] (rad, rad/s)."""
        self._client.send(("set_true_state", identifier, [float(v) for v in state]))
        reply = self._client.recv()
        if reply[0] != "ok":
            raise RuntimeError(f"wall-clock board: {reply[1:]}")

    def environment(self) -> dict[str, str]:
        return {ADDRESS_VARIABLE: self.address}

    def stop(self) -> None:
        self._client.close()
        self.process.kill()
        self.process.wait()


if __name__ == "__main__":
    serve(sys.argv[1])
