"""What the two report jobs (``make demo``, ``make reproduce``) share.

One BLAS thread, a progress line per section, the report's closing line and the command line
(``--out DIR``).  This module imports neither numpy nor posicast, so a job can call
:func:`one_blas_thread` before numpy loads its BLAS.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import Any, Callable, TextIO

__all__ = ["Progress", "one_blas_thread", "finish", "command_line"]


def one_blas_thread() -> None:
    """Ask numpy's BLAS for one thread; call it before numpy is imported.  A value already set wins.

    The reports' linear algebra is on small matrices (at most 23 x 10^4), which BLAS worker threads do
    not speed up; on a busy 2-core machine their spin-waiting cost 35-40 % of the demo's CPU (issue #15,
    benchmarks/RESULTS.md).
    """
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")


class Progress:
    """One line on stderr per finished section: its wall and CPU time, and the running totals.

    ``name`` starts each line (``[demo  12.3 s] ...``, ``[reproduce  4.5 s] ...``).
    """

    def __init__(self, stream: TextIO | None = None, name: str = "demo") -> None:
        self.stream = sys.stderr if stream is None else stream
        self.name = name
        self.start_wall, self.start_cpu = time.perf_counter(), time.process_time()
        self.wall, self.cpu = self.start_wall, self.start_cpu

    def done(self, what: str) -> None:
        """Print the line for ``what``, which has just finished."""
        wall, cpu = time.perf_counter(), time.process_time()
        print(f"[{self.name} {wall - self.start_wall:6.1f} s] {what}: {wall - self.wall:.1f} s "
              f"(CPU {cpu - self.cpu:.1f} s, total CPU {cpu - self.start_cpu:.1f} s)", file=self.stream, flush=True)
        self.wall, self.cpu = wall, cpu


def finish(report: Any, started: float, say: Callable[[str], None]) -> Path:
    """Close ``report`` with its generation time (since ``started``, a ``time.perf_counter()`` reading),
    write it into its folder, say so, and return the path of ``index.html``."""
    report.paragraph(f"<small>Generated in {time.perf_counter() - started:.1f} s.</small>")
    path = report.write()
    say(f"wrote {path}")
    return path


def command_line(build: Callable[[str], Path], default_out: str, description: str | None,
                 argv: list[str] | None = None) -> int:
    """A report job's command line: ``--out DIR`` (default ``default_out``), ``build(DIR)``, ``wrote PATH``."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--out", default=default_out, help=f"output folder (default: {default_out})")
    args = parser.parse_args(argv)
    print(f"wrote {build(args.out)}")
    return 0
