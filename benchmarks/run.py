"""Run every benchmark script ``benchmarks/bench_*.py`` (each in its own process).

Usage::

    python benchmarks/run.py                 # all of them
    python benchmarks/run.py roots           # only bench_roots.py (names or substrings)
    python benchmarks/run.py --quick         # passes --quick to every script

Every bench script must run standalone (``python benchmarks/bench_X.py``) and
accept ``--quick``.  The exit status is non-zero if any script failed.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    flags = [a for a in argv if a.startswith("-")]
    names = [a for a in argv if not a.startswith("-")]
    scripts = sorted(HERE.glob("bench_*.py"))
    if names:
        scripts = [s for s in scripts if any(n in s.stem for n in names)]
    if not scripts:
        print(f"no benchmark matches {names} in {HERE}", file=sys.stderr)
        return 2
    env = dict(os.environ)
    env.setdefault("MPLBACKEND", "Agg")
    summary = []
    for script in scripts:
        print(f"\n===== {script.name} =====", flush=True)
        t0 = time.perf_counter()
        rc = subprocess.call([sys.executable, str(script), *flags], cwd=HERE.parent, env=env)
        summary.append((script.name, rc, time.perf_counter() - t0))
    print("\n===== summary =====")
    for name, rc, dt in summary:
        print(f"{name}: {'ok' if rc == 0 else f'FAILED (exit {rc})'} in {dt:.0f} s")
    return 0 if all(rc == 0 for _, rc, _ in summary) else 1


if __name__ == "__main__":
    sys.exit(main())
