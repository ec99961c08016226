"""A strict, wall-clock test double of Quanser's `quanser.hardware` (HIL, HILError, Clock).

Put `tests/doubles` on `sys.path` (only the tests and benchmarks that use it do),
start a board process (`board_server.BoardServer`, whose socket path the
environment variable `QUBE_SUITE_BOARD_SERVER` names) and `from quanser.hardware
import HIL` drives its board as the real module drives a Qube. The board lives in
that other process (see `board_server.py`), so it outlives the process driving it.

The contract, from Quanser's Python HIL API documentation
(docs.quanser.com/quarc/documentation/python/hardware/, sections "Task I/O",
"Watchdog", "Immediate I/O") and Quanser's own Qube-Servo code
(Quanser_Academic_Resources, 0_libraries/python/pal/products/qube.py), and held
strictly here:

* channel arrays are numpy arrays of dtype uint32 with at least `num_channels`
  entries; analog and other buffers float64, encoder buffers int32, digital
  buffers int8 (`t_boolean`), watchdog digital states int32 (`t_digital_state`);
  a wrong dtype, a short or read-only buffer raises TypeError or ValueError, as
  the real module's buffer checks do; every method has the real argument list;
* `HIL()` makes an unopened card, `HIL(card_type, card_identifier)` opens one;
  every call on a closed card, on a deleted task or on a task of another card
  raises `HILError`; tasks are created, optionally given a buffer-overflow mode,
  started, read, stopped and deleted; `task_read` blocks until the next sample
  (the board's clock, not the caller's), samples that fall due while the caller
  is busy wait in the task's buffer (`samples_in_buffer`), and a full buffer
  behaves by the task's `BufferOverflowMode` (by default the next read raises);
* the watchdog runs on the wall clock in the board process: `watchdog_start(t)`
  arms it, `watchdog_reload()` returns False once it has expired, expiry puts the
  outputs into the expiration states and makes every write raise `HILError` until
  `watchdog_clear()`;
* `HILError` has `error_code` and `get_error_message()`; `str()` of it gives only
  the code, as the real class does, so callers must ask for the message;
* a call is atomic, as a call into Quanser's C library is: a signal handler
  (Ctrl-C) runs only after the board has answered. Each call's request and reply
  travel on a thread of the card's own, where no signal handler can cut into
  them; the caller waits for the reply, and an interrupt that arrives meanwhile
  is raised once the call is over, so no reply is ever left for the next call.
"""

from __future__ import annotations

import enum
import itertools
import os
import queue
import threading
import time

import numpy as np

from quanser.hardware.enumerations import BufferOverflowMode, DigitalState  # noqa: F401

MAX_STRING_LENGTH = 2048


class Clock(enum.IntEnum):
    HARDWARE_CLOCK_0 = 0


class HILError(Exception):
    """An error of the HIL API: a negative `error_code`; the text comes from `get_error_message()`."""

    def __init__(self, error_code: int, message: str = ""):
        super().__init__(error_code)
        self.error_code = error_code
        self._message = message

    def get_error_message(self) -> str:
        return self._message

    def __str__(self) -> str:
        return str(self.error_code)


def _channels(channels, num_channels, kind: str) -> np.ndarray:
    if not isinstance(channels, np.ndarray) or channels.dtype != np.uint32 or channels.ndim != 1:
        raise TypeError(f"{kind} channels must be a 1-d numpy array of dtype uint32, got "
                        f"{type(channels).__name__} {getattr(channels, 'dtype', '')}")
    if not isinstance(num_channels, (int, np.integer)) or isinstance(num_channels, bool):
        raise TypeError(f"num_channels must be an int, got {num_channels!r}")
    if not 0 <= num_channels <= len(channels):
        raise ValueError(f"num_channels {num_channels} does not fit the {len(channels)} {kind} channels")
    return np.array(channels[:num_channels])


def _buffer(buffer, dtype, needed: int, kind: str, writable: bool) -> np.ndarray | None:
    if needed == 0 and buffer is None:
        return None
    if not isinstance(buffer, np.ndarray) or buffer.dtype != dtype or not buffer.flags.c_contiguous:
        raise TypeError(f"{kind} buffer must be a contiguous numpy array of dtype {np.dtype(dtype).name}, "
                        f"got {type(buffer).__name__} {getattr(buffer, 'dtype', '')}")
    if buffer.size < needed:
        raise ValueError(f"{kind} buffer holds {buffer.size} values, {needed} needed")
    if writable and not buffer.flags.writeable:
        raise ValueError(f"{kind} buffer is read-only")
    return buffer


class _Carrier:
    """A thread that carries a card's calls to the board and back: signal handlers run only in the
    main thread, so none can cut a call in two. Each reply is filed under its call's number, so an
    interrupted caller leaves nothing behind that a later call could take for its own."""

    def __init__(self, connection):
        self._connection = connection
        self._calls = itertools.count()
        self._requests: queue.SimpleQueue = queue.SimpleQueue()
        self._replies: dict[int, tuple] = {}
        self._bell: queue.SimpleQueue = queue.SimpleQueue()  # rung once a reply is filed
        self._thread = threading.Thread(target=self._serve, name="hil-carrier", daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        while True:
            number, request = self._requests.get()
            if request is None:
                return
            try:
                self._connection.send(request)
                reply = self._connection.recv()
            except BaseException as error:  # the board process is gone: the caller sees why
                reply = ("bug", f"{type(error).__name__}: {error}")
            self._replies[number] = reply
            self._bell.put(number)

    def call(self, request: tuple) -> tuple:
        """The board's reply to `request`; an interrupt while waiting is raised after the reply came."""
        number = next(self._calls)
        self._requests.put((number, request))
        try:
            while number not in self._replies:
                self._bell.get()
            return self._replies.pop(number)
        except BaseException:
            while number not in self._replies:  # the call completes first, as a C call would
                time.sleep(0.0001)
            self._replies.pop(number)
            raise

    def stop(self) -> None:
        self._requests.put((None, None))
        self._thread.join()


class _Task:
    """A task handle: valid only with the card that created it."""

    def __init__(self, card: HIL, task_id: int, counts: tuple[int, int, int, int]):
        self.card, self.task_id, self.counts = card, task_id, counts


class HIL:
    """A card of the wall-clock board process; see the module docstring."""

    INFINITE = -1

    def __init__(self, card_type: str | None = None, card_identifier: str = "0"):
        self._connection = None
        self._identifier = None
        self._carrier: _Carrier | None = None
        if card_type is not None:
            self.open(card_type, card_identifier)

    # -- transport -------------------------------------------------------------------------

    def _call(self, method: str, *args):
        if self._connection is None:
            raise HILError(-1, "the card is not open")
        reply = self._carrier.call((method, self._identifier, *args))
        if reply[0] == "hil":
            raise HILError(reply[1], reply[2])
        if reply[0] == "bug":
            raise RuntimeError(f"wall-clock board: {reply[1]}")
        return reply[1]

    # -- opening ---------------------------------------------------------------------------

    def open(self, card_type: str, card_identifier: str) -> None:
        from multiprocessing.connection import Client

        if self._connection is not None:
            raise HILError(-6, "this HIL object already has an open card")
        if not isinstance(card_type, str) or not isinstance(card_identifier, str):
            raise TypeError("card_type and card_identifier must be strings")
        address = os.environ.get("QUBE_SUITE_BOARD_SERVER")
        if address is None:
            raise HILError(-11, "no board is connected (start a wall-clock board server)")
        from board_server import AUTHKEY

        self._connection = Client(address, "AF_UNIX", authkey=AUTHKEY)
        self._identifier = card_identifier
        self._carrier = _Carrier(self._connection)
        try:
            self._call("open", card_type)
        except BaseException:
            self._hang_up()
            raise

    def is_valid(self) -> bool:
        return self._connection is not None

    def close(self) -> None:
        if self._connection is None:
            return
        try:
            self._call("close")
        finally:
            self._hang_up()

    def _hang_up(self) -> None:
        self._carrier.stop()
        self._connection.close()
        self._connection, self._carrier = None, None

    def set_card_specific_options(self, options: str, max_length: int) -> None:
        if not isinstance(options, str) or not isinstance(max_length, int):
            raise TypeError("options must be a string and max_length an int")
        if len(options) >= max_length:
            raise HILError(-6, "the options string is longer than max_length")
        self._call("set_card_specific_options", options)

    # -- immediate I/O ---------------------------------------------------------------------

    def _read(self, method, channels, num_channels, buffer, dtype, kind):
        chans = _channels(channels, num_channels, kind)
        buffer = _buffer(buffer, dtype, len(chans), kind, writable=True)
        values = self._call(method, chans, len(chans), np.zeros(len(chans), dtype=dtype))
        buffer[:len(chans)] = values

    def _write(self, method, channels, num_channels, buffer, dtype, kind):
        chans = _channels(channels, num_channels, kind)
        buffer = _buffer(buffer, dtype, len(chans), kind, writable=False)
        self._call(method, chans, len(chans), np.array(buffer[:len(chans)]))

    def read_analog(self, channels, num_channels, buffer) -> None:
        self._read("read_analog_values", channels, num_channels, buffer, np.float64, "analog input")

    def read_encoder(self, channels, num_channels, buffer) -> None:
        self._read("read_encoder_values", channels, num_channels, buffer, np.int32, "encoder")

    def read_digital(self, channels, num_channels, buffer) -> None:
        self._read("read_digital_values", channels, num_channels, buffer, np.int8, "digital input")

    def read_other(self, channels, num_channels, buffer) -> None:
        self._read("read_other_values", channels, num_channels, buffer, np.float64, "other input")

    def write_analog(self, channels, num_channels, buffer) -> None:
        self._write("write_analog", channels, num_channels, buffer, np.float64, "analog output")

    def write_digital(self, channels, num_channels, buffer) -> None:
        self._write("write_digital", channels, num_channels, buffer, np.int8, "digital output")

    def write_other(self, channels, num_channels, buffer) -> None:
        self._write("write_other", channels, num_channels, buffer, np.float64, "other output")

    def set_encoder_counts(self, channels, num_channels, buffer) -> None:
        self._write("set_encoder_counts", channels, num_channels, buffer, np.int32, "encoder")

    # -- tasks -----------------------------------------------------------------------------

    def task_create_reader(self, samples_in_buffer, analog_channels, num_analog_channels, encoder_channels,
                           num_encoder_channels, digital_channels, num_digital_channels, other_channels,
                           num_other_channels) -> _Task:
        if not isinstance(samples_in_buffer, (int, np.integer)) or samples_in_buffer <= 0:
            raise HILError(-6, f"samples_in_buffer must be a positive int, got {samples_in_buffer!r}")
        groups = [_channels(c, n, kind) if n else None for c, n, kind in (
            (analog_channels, num_analog_channels, "analog input"),
            (encoder_channels, num_encoder_channels, "encoder"),
            (digital_channels, num_digital_channels, "digital input"),
            (other_channels, num_other_channels, "other input"))]
        args = []
        for chans in groups:
            args += [chans, 0 if chans is None else len(chans)]
        task_id = self._call("task_create_reader", int(samples_in_buffer), *args)
        return _Task(self, task_id, tuple(0 if g is None else len(g) for g in groups))

    def task_create_encoder_reader(self, samples_in_buffer, channels, num_channels) -> _Task:
        return self.task_create_reader(samples_in_buffer, None, 0, channels, num_channels, None, 0, None, 0)

    def _task(self, task) -> int:
        if not isinstance(task, _Task) or task.card is not self:
            raise HILError(-5, "not a task handle of this card")
        return task.task_id

    def task_set_buffer_overflow_mode(self, task, mode) -> None:
        self._call("task_set_buffer_overflow_mode", self._task(task), int(BufferOverflowMode(mode)))

    def task_start(self, task, clock, frequency, num_samples) -> None:
        if not isinstance(num_samples, (int, np.integer)):
            raise TypeError(f"num_samples must be an int, got {num_samples!r}")
        self._call("task_start", self._task(task), int(Clock(clock)), float(frequency), int(num_samples))

    def task_read(self, task, num_samples, analog_buffer, encoder_buffer, digital_buffer,
                  other_buffer) -> int:
        task_id = self._task(task)
        if not isinstance(num_samples, (int, np.integer)) or num_samples <= 0:
            raise HILError(-6, f"num_samples must be a positive int, got {num_samples!r}")
        n_analog, n_encoder, n_digital, n_other = task.counts
        buffers = [_buffer(b, dtype, num_samples * n, kind, writable=True) for b, dtype, n, kind in (
            (analog_buffer, np.float64, n_analog, "analog"), (encoder_buffer, np.int32, n_encoder, "encoder"),
            (digital_buffer, np.int8, n_digital, "digital"), (other_buffer, np.float64, n_other, "other"))]
        fresh = [None if b is None else np.zeros(b.size, dtype=b.dtype) for b in buffers]
        count, *values = self._call("task_read_values", task_id, int(num_samples), *fresh)
        for buffer, value in zip(buffers, values, strict=True):
            if buffer is not None:
                buffer[:] = value
        return count

    def task_read_encoder(self, task, num_samples, buffer) -> int:
        return self.task_read(task, num_samples, None, buffer, None, None)

    def task_get_buffer_overflows(self, task) -> int:
        return self._call("task_get_buffer_overflows", self._task(task))

    def task_stop(self, task) -> None:
        self._call("task_stop", self._task(task))

    def task_delete(self, task) -> None:
        self._call("task_delete", self._task(task))
        task.card = None

    # -- watchdog --------------------------------------------------------------------------

    def watchdog_set_analog_expiration_state(self, channels, num_channels, voltages) -> None:
        self._write("watchdog_set_analog_expiration_state", channels, num_channels, voltages, np.float64,
                    "analog output")

    def watchdog_set_digital_expiration_state(self, channels, num_channels, states) -> None:
        chans = _channels(channels, num_channels, "digital output")
        states = _buffer(states, np.int32, len(chans), "digital state", writable=False)
        values = [int(DigitalState(s)) for s in states[:len(chans)]]
        self._call("watchdog_set_digital_expiration_state", chans, len(chans), values)

    def watchdog_start(self, timeout) -> None:
        self._call("watchdog_start", float(timeout))

    def watchdog_reload(self) -> bool:
        return self._call("watchdog_reload")

    def watchdog_is_expired(self) -> bool:
        return self._call("watchdog_is_expired")

    def watchdog_clear(self) -> None:
        self._call("watchdog_clear")

    def watchdog_stop(self) -> None:
        self._call("watchdog_stop")
