"""Benchmark: the demo report's CPU time (issue #15: ``make demo`` in <= 20 s of CPU).

Runs ``python -m posicast_reports.demo`` (``make demo``'s job) into a temporary folder in
a fresh process, several times, and prints the CPU of the whole process (user + system,
children included; BLAS on one thread, as the demo sets it), the median, its ratio to the
comparator and the goal.  Each run also runs ``python -m posicast_reports.reproduce``
(``make reproduce``, the seed reproductions split off the demo in wave 7): an information
row with no goal, so that the total of both stays visible.

The comparator is the figure recorded before this work (:data:`PREVIOUS`, the all-in-one
demo of a fresh clone of main after the wave-3 merges, benchmarks/RESULTS.md) or, with
``--before SRC``, another checkout's ``src`` run in the same session, alternating with this
one (``PYTHONPATH=SRC`` shadows the installed posicast).  A checkout without
``posicast_reports/reproduce.py`` has the all-in-one demo (seed reproductions included): the
printed rows say so.  The load average is printed with each run: the CPU time of a run grows
with the machine's load.

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
from pathlib import Path

from _harness import machine_info, md_table, print_machine_info
from bench_startup import _PROGRESS

#: CPU seconds of ``make demo`` on a fresh clone of main before the wave-4 speed work (stop 23 note):
#: the all-in-one demo, seed reproductions included.
PREVIOUS = 42.0
GOAL = 20.0
#: the sections whose computation issue #15's wave 4 changed (the others are shown too)
OWNED = ("seed 001 tuning", "identification", "printer calibration")


def has_reproduce(src: str | None) -> bool:
    """Whether the checkout (``src``, or this one) has ``make reproduce`` (else its demo is all-in-one)."""
    root = Path(src) if src is not None else Path(__file__).resolve().parents[1] / "src"
    return (root / "posicast_reports" / "reproduce.py").is_file()


def report_cpu(module: str = "demo", src: str | None = None) -> tuple[float, float, dict[str, float]]:
    """``(CPU seconds, wall seconds, {section: CPU seconds})`` of one ``python -m posicast_reports.<module>``
    run (``demo`` or ``reproduce``) in a fresh process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    env = dict(os.environ, MPLBACKEND="Agg")
    if src is not None:
        env["PYTHONPATH"] = src + os.pathsep + env.get("PYTHONPATH", "")
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        run = subprocess.run([sys.executable, "-m", f"posicast_reports.{module}", "--out", out], check=True, env=env,
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    sections = {("write index.html" if m["what"].startswith("wrote ") else m["what"]): float(m["cpu"])
                for m in map(_PROGRESS.match, run.stderr.splitlines()) if m}
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), wall, sections


def _load() -> str:
    return "/".join(f"{x:.2f}" for x in os.getloadavg())


def _section_table(secs: dict[str, list[dict[str, float]]], labels: list[str]) -> str:
    """Median CPU per section (rows: every section any label ran, in order of appearance)."""
    names = list(dict.fromkeys(name for label in labels for s in secs[label] for name in s))
    rows = []
    for name in names:
        row = [name + (" *" if name.startswith(OWNED) else "")]
        for label in labels:
            vals = [s[name] for s in secs[label] if name in s]
            row.append(f"{statistics.median(vals):.1f}" if vals else "–")
        rows.append(row)
    return md_table(["section"] + labels, rows)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="one run")
    ap.add_argument("--runs", type=int, default=None)
    ap.add_argument("--before", default=None, help="another checkout's src directory, run alternately")
    args = ap.parse_args()
    runs = args.runs or (1 if args.quick else 3)
    print_machine_info(machine_info())
    split_before = args.before is not None and has_reproduce(args.before)
    # (label, module, src): this checkout's demo and reproduce, then the comparator's
    jobs = [("demo", "demo", None), ("reproduce", "reproduce", None)]
    if args.before:
        jobs.append(("before demo" if split_before else "before (all-in-one demo)", "demo", args.before))
        if split_before:
            jobs.append(("before reproduce", "reproduce", args.before))
    cpu: dict[str, list[float]] = {label: [] for label, _, _ in jobs}
    secs: dict[str, list[dict[str, float]]] = {label: [] for label, _, _ in jobs}
    for i in range(runs):
        for label, module, src in jobs:
            load = _load()
            c, w, s = report_cpu(module, src)
            cpu[label].append(c)
            secs[label].append(s)
            print(f"run {i + 1} {label}: {c:.1f} s CPU, {w:.1f} s wall (load average before {load}, after {_load()})")
    demo_labels = [label for label, module, _ in jobs if module == "demo"]
    print("\nmake demo: CPU per section, median of the runs [s] (* = computation changed in wave 4)\n")
    print(_section_table(secs, demo_labels))
    rep_labels = [label for label, module, _ in jobs if module == "reproduce"]
    print("\nmake reproduce (information): CPU per section, median of the runs [s]\n")
    print(_section_table(secs, rep_labels))

    med = {label: statistics.median(v) for label, v in cpu.items()}
    if args.before:
        base = med[demo_labels[1]]
        what = ("before's demo (same session)" if split_before else
                "before's all-in-one demo, seed reproductions included (same session; it has no make reproduce)")
    else:
        base, what = PREVIOUS, f"the previous figure ({PREVIOUS:g} s, the all-in-one demo)"
    met = med["demo"] <= GOAL
    print(f"\ndemo report (make demo): median {med['demo']:.1f} s CPU of {runs} run(s); {med['demo'] / base:.2f}x "
          f"{what}; goal <= {GOAL:g} s CPU: {'met' if met else 'MISSED'}")
    total = med["demo"] + med["reproduce"]
    line = (f"seed reproductions (make reproduce), information, no goal: median {med['reproduce']:.1f} s CPU; "
            f"demo + reproduce {total:.1f} s")
    if args.before:
        before_total = med[demo_labels[1]] + (med["before reproduce"] if split_before else 0.0)
        line += f" (before: {before_total:.1f} s{'' if split_before else ', its all-in-one demo'})"
    print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
