"""Progress of long work on stderr, shared by the subcommands (issue #20).

stdout carries the result (text or ``--json``); progress goes to stderr only, and
``--quiet`` silences it.  Two forms, both silent during the first second so that
quick runs print nothing:

* :func:`working` wraps one long library call that reports nothing itself (a tuning,
  a QFT design, a certified spectrum, a simulation): a tqdm bar with the elapsed time,
  refreshed by a background thread, closed when the call returns;
* :func:`steps` is a callback for library code that reports its steps as lines of text
  (``calibrate(progress=...)``): each line after the first second is shown with the
  elapsed time.

The library's loops are not touched: the callback is called at a coarse level (a file,
a firmware), and the bar's thread only reads the clock.
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


@contextmanager
def working(what: str, quiet: bool = False, delay: float | None = None) -> Iterator[None]:
    """Show ``what`` with a running clock on stderr while the block runs (after ``delay`` seconds, default
    :data:`DELAY`)."""
    wait = DELAY if delay is None else delay
    if quiet:
        yield
        return
    from tqdm import tqdm  # a core dependency; imported only by subcommands that may run long

    done = threading.Event()

    def tick() -> None:
        if done.wait(wait):
            return
        bar = tqdm(desc=what, total=None, file=sys.stderr, leave=False, bar_format="{desc}: {elapsed}",
                   initial=0, mininterval=0.0)
        try:
            while not done.wait(0.5):
                bar.refresh()
        finally:
            bar.close()

    thread = threading.Thread(target=tick, name="posicast-progress", daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()


def steps(quiet: bool = False, delay: float | None = None) -> Callable[[str], None]:
    """A ``progress(message)`` callback printing ``[elapsed] message`` on stderr once ``delay`` (default
    :data:`DELAY`) has passed."""
    start = time.monotonic()
    wait = DELAY if delay is None else delay

    def say(msg: str) -> None:
        elapsed = time.monotonic() - start
        if not quiet and elapsed >= wait:
            print(f"[{elapsed:5.1f} s] {msg}", file=sys.stderr, flush=True)

    return say
