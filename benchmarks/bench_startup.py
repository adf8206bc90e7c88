"""Benchmark: start-up and the demo report (issue #15 part A).

* ``import posicast`` against ``import numpy``, each in a fresh interpreter
  (``python -c ...``, wall time of the whole process, median of several runs);
  goal: ratio <= 2.
* ``posicast --help`` (``python -m posicast --help``, fresh process); goal <= 0.5 s.
* ``import posicast`` followed by the first use of a public name
  (``posicast.design``): what a user pays for the first design (no goal; for the record).
* the demo report (``python -m posicast_reports.demo``, into a temporary folder: ``make demo``'s
  job, without the seed reproductions of ``make reproduce``): CPU time of the whole process
  (user + system, children included); goal <= 20 s.
  One run (``--quick``: skipped), with the CPU of each section read from the
  report's progress lines and the load average before and after (the CPU time of
  a run grows with the machine's load: record it with the figure).

Usage: python benchmarks/bench_startup.py [--quick] [--runs N] [--no-demo | --demo-only]
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time

from _harness import machine_info, md_table, print_machine_info


def _wall(cmd: list[str], runs: int) -> list[float]:
    out = []
    for _ in range(runs):
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        out.append(time.perf_counter() - t0)
    return out


#: a progress line of the demo (``[demo ...]``) or of the seed reproductions (``[reproduce ...]``)
_PROGRESS = re.compile(r"^\[(?:demo|reproduce) +[0-9.]+ s\] (?P<what>.*): [0-9.]+ s \(CPU (?P<cpu>[0-9.]+) s, total")


def _demo_cpu() -> tuple[float, float, list[tuple[str, float]]]:
    """``(CPU seconds, wall seconds, [(section, CPU seconds)])`` of one demo run in a fresh process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    with tempfile.TemporaryDirectory() as out:
        env = dict(os.environ, MPLBACKEND="Agg")
        t0 = time.perf_counter()
        run = subprocess.run([sys.executable, "-m", "posicast_reports.demo", "--out", out], check=True, env=env,
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    sections = [("write index.html" if m["what"].startswith("wrote ") else m["what"], float(m["cpu"]))
                for m in map(_PROGRESS.match, run.stderr.splitlines()) if m]
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), wall, sections


def _load() -> str:
    return "/".join(f"{x:.2f}" for x in os.getloadavg())


def demo_row() -> bool:
    """Run the demo once, print its sections and the total against the goal; True if met."""
    load0 = _load()
    cpu, wall, sections = _demo_cpu()
    print(f"\ndemo report, one run (load average 1/5/15 min before {load0}, after {_load()})\n")
    print(md_table(["section", "CPU [s]"], [[what, f"{t:.1f}"] for what, t in sections]))
    met = cpu <= 20.0
    print(f"\ndemo report: {cpu:.1f} s CPU of the whole process ({wall:.1f} s wall); goal <= 20 s CPU: "
          f"{'met' if met else 'MISSED'}")
    return met


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--runs", type=int, default=None)
    ap.add_argument("--no-demo", action="store_true")
    ap.add_argument("--demo-only", action="store_true", help="only the demo row")
    args = ap.parse_args()
    if args.demo_only:
        print_machine_info(machine_info())
        return 0 if demo_row() else 1
    runs = args.runs or (3 if args.quick else 9)
    print_machine_info(machine_info())
    py = sys.executable
    cases = [
        ("python -c 'import numpy'", [py, "-c", "import numpy"]),
        ("python -c 'import posicast'", [py, "-c", "import posicast"]),
        ("posicast --help", [py, "-m", "posicast", "--help"]),
        ("import posicast; posicast.design", [py, "-c", "import posicast; posicast.design"]),
    ]
    _wall([py, "-c", "pass"], 1)  # warm the file cache
    med = {}
    rows = []
    for name, cmd in cases:
        t = _wall(cmd, runs)
        med[name] = statistics.median(t)
        rows.append([name, f"{med[name]:.3f}", f"{min(t):.3f}", f"{max(t):.3f}"])
    print(f"\nfresh processes, {runs} runs each (wall time of the whole process)\n")
    print(md_table(["command", "median [s]", "min [s]", "max [s]"], rows))
    ratio = med["python -c 'import posicast'"] / med["python -c 'import numpy'"]
    help_t = med["posicast --help"]
    ok = ratio <= 2.0 and help_t <= 0.5
    print(f"\nimport posicast / import numpy: {ratio:.2f} (goal <= 2: {'met' if ratio <= 2 else 'MISSED'})")
    print(f"posicast --help: {help_t:.3f} s (goal <= 0.5 s: {'met' if help_t <= 0.5 else 'MISSED'})")
    if not (args.quick or args.no_demo):
        demo_row()
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
