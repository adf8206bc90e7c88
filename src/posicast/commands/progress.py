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

The library's loops are not touched: the callback is called at a coarse level (a file,
a firmware), and the thread only reads the clock.
"""

from __future__ import annotations

import sys
import threading
import time
from contextlib import contextmanager
from typing import Callable, Iterator

__all__ = ["working", "steps", "DELAY"]

#: Seconds of silence before any progress is shown.
DELAY = 1.0


def _line(start: float, msg: str) -> None:
    print(f"[{time.monotonic() - start:5.1f} s] {msg}", file=sys.stderr, flush=True)


@contextmanager
def working(what: str, quiet: bool = False, delay: float | None = None) -> Iterator[None]:
    """Say on stderr that ``what`` goes on, after ``delay`` (default :data:`DELAY`) seconds and then at
    doubling intervals, while the block runs; and when it ends, if anything was said."""
    wait = DELAY if delay is None else delay
    if quiet:
        yield
        return
    start = time.monotonic()
    done = threading.Event()
    said = threading.Event()

    def tick() -> None:
        gap = wait
        while not done.wait(max(0.0, start + gap - time.monotonic())):
            _line(start, f"{what} ...")
            said.set()
            gap = 2.0 * max(gap, 0.5)

    thread = threading.Thread(target=tick, name="posicast-progress", daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()
        if said.is_set():
            _line(start, f"{what}: done")


def steps(quiet: bool = False, delay: float | None = None) -> Callable[[str], None]:
    """A ``progress(message)`` callback printing ``[elapsed] message`` on stderr once ``delay`` (default
    :data:`DELAY`) has passed."""
    start = time.monotonic()
    wait = DELAY if delay is None else delay

    def say(msg: str) -> None:
        if not quiet and time.monotonic() - start >= wait:
            _line(start, msg)

    return say
