"""Progress of long commands (`run`, `demo`, `eval`, `train`), by one rule.

On a terminal, a tqdm bar on stderr; otherwise (a log file, a pipe, a CI job) one
line on stderr each time another `every` percent is done, so that logs hold a few
lines rather than bar frames, once the work has taken `delay` seconds (work done
sooner leaves no lines); `quiet`: nothing.

    with Progress(total=2048, unit="step", description="swing-up") as progress:
        for _ in range(2048):
            progress.update()
"""

from __future__ import annotations

import sys
import time
from typing import IO, Any

from tqdm import tqdm

DEFAULT_EVERY = 10
"""Percent of the work between two progress lines when stderr is not a terminal."""

DEFAULT_DELAY = 1.0
"""Seconds of work before the first progress line: short work leaves none."""


class Progress:
    """Progress towards `total` `unit`s of work, described by `description`.

    Args:
        total: the amount of work (steps, episodes).
        unit: what is counted, e.g. "step".
        description: what is being done, e.g. "mpc on qube/swingup".
        quiet: show nothing.
        every: percent between lines when `stream` is not a terminal.
        delay: seconds before the first line (default DEFAULT_DELAY).
        stream: where progress goes (default: stderr).
    """

    def __init__(self, total: int, unit: str, description: str, quiet: bool = False,
                 every: float = DEFAULT_EVERY, delay: float | None = None, stream: IO[str] | None = None):
        self.total, self.unit, self.description = int(total), unit, description
        self.n = 0
        self._stream = sys.stderr if stream is None else stream
        self._every = every
        self._first_line_time = time.monotonic() + (DEFAULT_DELAY if delay is None else delay)
        self._next_line = every
        self._postfix = ""
        self._bar = None
        self._lines = False
        if not quiet:
            if _is_terminal(self._stream):
                self._bar = tqdm(total=self.total, unit=unit, desc=description, file=self._stream,
                                 dynamic_ncols=True, unit_scale=self.total >= 100_000)
            else:
                self._lines = True

    def update(self, amount: int = 1) -> None:
        """`amount` more units are done."""
        self.advance_to(self.n + amount)

    def advance_to(self, done: int) -> None:
        """`done` units are done in all (an episode that ended early skips ahead)."""
        done = min(int(done), self.total)
        if done <= self.n:
            return
        if self._bar is not None:
            self._bar.update(done - self.n)
        self.n = done
        if self._lines and self.total > 0:
            percent = 100.0 * done / self.total
            if percent >= self._next_line:
                while self._next_line <= percent:
                    self._next_line += self._every
                if time.monotonic() >= self._first_line_time:
                    print(f"{self.description}: {percent:.0f} % ({done}/{self.total} {self.unit}s)"
                          f"{self._postfix}", file=self._stream, flush=True)

    def set_postfix(self, **values: Any) -> None:
        """Values shown beside the bar, or at the end of the next lines, e.g. mean_return=1820."""
        text = ", ".join(f"{key} {value}" for key, value in values.items())
        self._postfix = f", {text}" if text else ""
        if self._bar is not None:
            self._bar.set_postfix(values, refresh=False)

    def write(self, message: str) -> None:
        """Print `message` on stdout without breaking the bar."""
        if self._bar is not None:
            tqdm.write(message, file=sys.stdout)
        else:
            print(message, flush=True)

    def close(self) -> None:
        """Finish the bar."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()


def _is_terminal(stream: IO[str]) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):  # no isatty, or a closed stream
        return False
