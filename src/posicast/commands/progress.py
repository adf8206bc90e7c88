"""Progress of long work on stderr, shared by the subcommands (issue #20).

stdout carries the result (text or ``--json``); progress goes to stderr only, one line
at a time, each ``[elapsed s] message`` (the form ``calibrate`` has always printed, easy to
read in a log or a CI job), and ``--quiet`` silences it.  Quick runs print nothing: the
first line comes after :data:`DELAY` seconds.

* :func:`working` wraps one long library call that reports nothing itself (a tuning, a
  QFT design, a certified spectrum, a simulation): a background thread prints that the
  work goes on after 1, 2, 4, 8, ... seconds, and how long it took once it is done (if it
  printed anything);
* :func:`steps` is a callback for library code that reports its steps as lines of text
  (``calibrate(progress=...)``): each line after the first second is shown.

On a terminal (stderr is a TTY) the same messages are one live status line drawn by tqdm
(a core dependency, imported only then): ``message: 00:12`` redrawn in place, left on
screen when the work ends.  Anywhere else (a pipe, a log file, CI) they are the plain lines
above, so a log holds no carriage returns.

The library's loops are not touched: the callback is called at a coarse level (a file,
a firmware), and the thread only reads the clock.
"""

from __future__ import annotations

import sys
import threading
import time
from contextlib import contextmanager
from typing import Any, Iterator

__all__ = ["working", "steps", "Steps", "DELAY"]

#: Seconds of silence before any progress is shown.
DELAY = 1.0


def _line(start: float, msg: str) -> None:
    print(f"[{time.monotonic() - start:5.1f} s] {msg}", file=sys.stderr, flush=True)


def _on_terminal() -> bool:
    isatty = getattr(sys.stderr, "isatty", None)
    return bool(isatty and isatty())


def _status_line(what: str) -> Any:
    """A tqdm status line on stderr, drawn at once (no bar: the work's length is unknown)."""
    from tqdm import tqdm

    return tqdm(total=None, desc=what, file=sys.stderr, mininterval=0.2, leave=True, bar_format="{desc}: {elapsed}")


@contextmanager
def working(what: str, quiet: bool = False, delay: float | None = None) -> Iterator[None]:
    """Say on stderr that ``what`` goes on, after ``delay`` (default :data:`DELAY`) seconds and then at
    doubling intervals, while the block runs; and when it ends, if anything was said.  On a
    terminal: one live tqdm status line instead."""
    wait = DELAY if delay is None else delay
    if quiet:
        yield
        return
    start = time.monotonic()
    done = threading.Event()
    bar: list[Any] = []  # the terminal's status line, made by the thread once ``wait`` has passed (tqdm's
    #                      own delay would end a line it only refreshed without its newline)
    said = threading.Event()

    def on_terminal() -> None:
        if done.wait(wait):
            return
        bar.append(_status_line(what))
        bar[0].start_t -= time.monotonic() - start  # elapsed from the start of the work
        bar[0].refresh()
        while not done.wait(0.5):
            bar[0].refresh()

    def in_a_log() -> None:
        gap = wait
        while not done.wait(max(0.0, start + gap - time.monotonic())):
            _line(start, f"{what} ...")
            said.set()
            gap = 2.0 * max(gap, 0.5)

    thread = threading.Thread(target=on_terminal if _on_terminal() else in_a_log, name="posicast-progress",
                              daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()
        if bar:
            bar[0].close()
        if said.is_set():
            _line(start, f"{what}: done")


class Steps:
    """A ``progress(message)`` callback printing ``[elapsed] message`` on stderr once ``delay`` (default
    :data:`DELAY`) has passed; on a terminal, the messages replace each other on one tqdm status line.

    Use it as a context manager, so that a terminal's status line is closed before the result is
    printed (or the error line)::

        with steps(args.quiet) as say:
            cal = calibrate(files, progress=say)
    """

    def __init__(self, quiet: bool = False, delay: float | None = None) -> None:
        self._start = time.monotonic()
        self._wait = DELAY if delay is None else delay
        self._quiet = quiet
        self._bar: Any = None  # the terminal's status line, made at the first message shown

    def __call__(self, msg: str) -> None:
        if self._quiet or time.monotonic() - self._start < self._wait:
            return
        if not _on_terminal():
            _line(self._start, msg)
            return
        if self._bar is None:
            self._bar = _status_line(msg)
            # elapsed from the start of the work, as in the plain lines (tqdm's own clock)
            self._bar.start_t -= time.monotonic() - self._start
            self._bar.refresh()
        self._bar.set_description_str(msg, refresh=True)

    def close(self) -> None:
        """End the terminal's status line (nothing to do for plain lines)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> "Steps":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def steps(quiet: bool = False, delay: float | None = None) -> Steps:
    """The :class:`Steps` callback (``with steps(quiet) as say: ...``)."""
    return Steps(quiet, delay)
