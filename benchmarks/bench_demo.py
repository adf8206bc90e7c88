"""Benchmark: the demo report's CPU time (issue #15: ``make demo`` in <= 20 s of CPU).

Runs ``python -m posicast_reports.demo`` into a temporary folder in a fresh process,
several times, and prints the CPU of the whole process (user + system, children
included; BLAS on one thread, as the demo sets it), the median, its ratio to the
previous posicast figure and the goal.  The comparator is the figure recorded
before this work (:data:`PREVIOUS`, a fresh clone of main after the wave-3 merges,
benchmarks/RESULTS.md) or, with ``--before SRC``, another checkout's ``src`` run in
the same session, alternating with this one (``PYTHONPATH=SRC`` shadows the
installed posicast).  The load average is printed with each run: the CPU time of a
run grows with the machine's load.

Usage: python benchmarks/bench_demo.py [--quick] [--runs N] [--before /work/main/src]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

from _harness import machine_info, md_table, print_machine_info
from bench_startup import _PROGRESS

#: CPU seconds of ``make demo`` on a fresh clone of main before the wave-4 speed work (stop 23 note).
PREVIOUS = 42.0
GOAL = 20.0
#: the sections whose computation issue #15's wave 4 changed (the others are shown too)
OWNED = ("seed 001 tuning", "identification and calibration")


def demo_cpu(src: str | None = None) -> tuple[float, float, dict[str, float]]:
    """``(CPU seconds, wall seconds, {section: CPU seconds})`` of one demo run in a fresh process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    env = dict(os.environ, MPLBACKEND="Agg")
    if src is not None:
        env["PYTHONPATH"] = src + os.pathsep + env.get("PYTHONPATH", "")
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        run = subprocess.run([sys.executable, "-m", "posicast_reports.demo", "--out", out], check=True, env=env,
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    sections = {("write index.html" if m["what"].startswith("wrote ") else m["what"]): float(m["cpu"])
                for m in map(_PROGRESS.match, run.stderr.splitlines()) if m}
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), wall, sections


def _load() -> str:
    return "/".join(f"{x:.2f}" for x in os.getloadavg())


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="one run")
    ap.add_argument("--runs", type=int, default=None)
    ap.add_argument("--before", default=None, help="another checkout's src directory, run alternately")
    args = ap.parse_args()
    runs = args.runs or (1 if args.quick else 3)
    print_machine_info(machine_info())
    labels = ["after"] + (["before"] if args.before else [])
    cpu: dict[str, list[float]] = {k: [] for k in labels}
    secs: dict[str, list[dict[str, float]]] = {k: [] for k in labels}
    for i in range(runs):
        for label in labels:
            load = _load()
            c, w, s = demo_cpu(args.before if label == "before" else None)
            cpu[label].append(c)
            secs[label].append(s)
            print(f"run {i + 1} {label}: {c:.1f} s CPU, {w:.1f} s wall (load average before {load}, after {_load()})")
    names = list(secs["after"][0])
    rows = []
    for name in names:
        row = [name + (" *" if name.startswith(OWNED) else "")]
        for label in labels:
            row.append(f"{statistics.median(s.get(name, float('nan')) for s in secs[label]):.1f}")
        rows.append(row)
    print("\nCPU per section, median of the runs [s] (* = computation changed in wave 4)\n")
    print(md_table(["section"] + labels, rows))
    med = statistics.median(cpu["after"])
    base = statistics.median(cpu["before"]) if args.before else PREVIOUS
    what = "before (same session)" if args.before else f"the previous figure ({PREVIOUS:g} s)"
    met = med <= GOAL
    print(f"\ndemo report: median {med:.1f} s CPU of {runs} run(s); {med / base:.2f}x {what}; "
          f"goal <= {GOAL:g} s CPU: {'met' if met else 'MISSED'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
