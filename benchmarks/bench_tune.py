"""Benchmark: posicast.tune_pd on seed 001 Table 1 against a brute-force check of the same regions.

The twelve designs of seed 001 Table 1 (gantry crane, PD, control-action
structure with Ms = 1.2 and inverse-shaper structure with Ms = 2; shapers DeZV,
DtZV, DcZV, DtaZV, notch and none) are timed together, median of several runs
in this process.  Next to each design: the brute-force check of its region
(`posicast.testing.sample_check`: random gains in the region's box, ||S||inf on a
dense uniform frequency grid with refinement near the bound, and a certified
spectrum check per controller that meets the bound), its time, the points
misclassified and how many of those are not explained by a boundary within
half a line spacing, and the best Kp the brute-force samples found (ours must
be at least as large: it is the exact supremum).

Targets (issue #6): all 12 designs in < 5 s; every misclassified point
explained.

Usage: python benchmarks/bench_tune.py [--quick]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

from _harness import machine_info, md_table, print_machine_info, timed
from posicast.testing import sample_check
from posicast_reports.seed001 import table1


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    runs = 2 if args.quick else 5
    n_points = 500 if args.quick else 2000
    print_machine_info(machine_info())
    print(f"\n12 designs of seed 001 Table 1, {runs} runs; brute force: {n_points} random gains per design\n")
    timing = timed(lambda: table1(0.0), runs)
    if timing.error:
        print("FAILED:", timing.error)
        return 1
    rows = timing.result
    print(f"all 12 designs: median {timing.median:.2f} s over {timing.runs} runs "
          f"(min {min(timing.times):.2f}, max {max(timing.times):.2f}); target < 5 s: "
          f"{'met' if timing.median < 5.0 else 'MISSED'}\n")
    table = []
    failures = 0
    brute_total = 0.0
    for k, row in enumerate(rows):
        r = row.result
        t0 = time.perf_counter()
        chk = sample_check(r, n=n_points, seed=k)
        dt = time.perf_counter() - t0
        brute_total += dt
        adm = chk.points[chk.brute]
        best_brute = float(adm[:, 1].max()) if adm.size else float("nan")
        bad = chk.unexplained + chk.failures + (best_brute > r.kp * (1 + 1e-9))
        failures += bool(bad)
        table.append([row.label, row.structure.replace("_", " "), f"{r.kp:.4f}", f"{r.kd:.4f}", f"{r.ms:.7f}",
                      f"{r.timings['total']:.2f}", f"{dt:.1f}", f"{dt / r.timings['total']:.0f}",
                      str(int(chk.brute.sum())), str(chk.misclassified.size), str(chk.unexplained),
                      f"{best_brute:.4f}"])
        print(" | ".join(table[-1]), flush=True)
    print()
    print(md_table(["shaper", "structure", "Kp", "Kd", "Ms", "design [s]", "brute force [s]", "ratio",
                    "admissible samples", "misclassified", "unexplained", "best brute Kp"], table))
    per_design = statistics.median(float(t[5]) for t in table)
    print(f"\nbrute-force checks: {brute_total:.0f} s in all ({n_points} points each); "
          f"designs: {timing.median:.2f} s in all (median per design {per_design:.2f} s)")
    if failures:
        print(f"{failures} designs FAILED the brute-force check")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
