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

Issue #15 (part A): the same crane with a **lumped** shaper in the loop (ZV, ZVD,
EI in the control-action and the inverse-shaper structure), each design timed
alone (median of several runs, CPU time) next to the DeZV design of the same
structure; goals: every design (the 12 above and these 6) <= 2 s, and each
lumped design <= 2x its DeZV design.  (The inverse ZVD and EI loops are neutral
for every PD and are refused at once, without a scan.)

Issue #15 (wave 5): the demo report designs seed 001's Table 1 three times (as printed, with the fitted
loop delay and 41 lines, with a derivative filter and 41 lines): 36 designs, CPU median next to the
figure before wave 5 (12.9 s, idle machine); goal <= 5 s.

Usage: python benchmarks/bench_tune.py [--quick]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

from _harness import machine_info, md_table, print_machine_info, timed
from posicast.cases import ALL
from posicast.shapers import design
from posicast.testing import sample_check
from posicast.tune import tune_pd
from posicast_reports.seed001 import PAPER_DELAY, STRUCTURES, table1
from posicast_reports.seed001_report import GAINS_ONLY_LINES, TF

#: CPU of the demo's 36 designs before wave 5 of issue #15 (idle machine, one BLAS thread)
DEMO_DESIGNS_BEFORE = 12.9
DEMO_DESIGNS_GOAL = 5.0

LUMPED = ("zv", "zvd", "ei")


def _cpu_median(fn, runs: int) -> tuple[float, object]:
    times, out = [], None
    for _ in range(runs):
        t0 = time.process_time()
        out = fn()
        times.append(time.process_time() - t0)
    return statistics.median(times), out


def lumped_rows(runs: int) -> tuple[list[list[str]], bool]:
    """Each lumped-shaper design and the DeZV design of its structure: CPU medians, ratio and goals."""
    crane = ALL["gantry_crane"]
    rows, ok = [], True
    for structure, ms, _ in STRUCTURES:
        base, _r = _cpu_median(lambda: tune_pd(crane.G, design("dezv", crane.mode), structure, ms=ms, F=crane.F),
                               runs)
        rows.append([structure.replace("_", " "), "DeZV", f"{base:.2f}", "1.00", f"{_r.kp:.6g}", "-"])
        for kind in LUMPED:
            S = design(kind, crane.mode)
            t, r = _cpu_median(lambda: tune_pd(crane.G, S, structure, ms=ms, F=crane.F), runs)
            met = t <= 2.0 and t <= 2.0 * base
            ok &= met
            kp = "refused (neutral)" if r.kp is None else f"{r.kp:.6g}"
            rows.append([structure.replace("_", " "), kind.upper(), f"{t:.2f}", f"{t / base:.2f}", kp,
                         "met" if met else "MISSED"])
    return rows, ok


def demo_designs() -> None:
    """The 36 designs of the demo report's seed 001 section, one CPU figure."""
    table1(0.0)
    table1(PAPER_DELAY, n_lines=GAINS_ONLY_LINES)
    table1(0.0, derivative_filter=TF, n_lines=GAINS_ONLY_LINES)


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
    slow = [t[0] + ", " + t[1] for t in table if float(t[5]) > 2.0]
    print(f"issue #15: every Table 1 design <= 2 s: {'met' if not slow else 'MISSED: ' + '; '.join(slow)}")
    if failures:
        print(f"{failures} designs FAILED the brute-force check")

    lruns = 2 if args.quick else 5
    print(f"\nissue #15: lumped shapers in the loop, each design alone, median CPU time of {lruns} runs\n")
    lrows, lok = lumped_rows(lruns)
    print(md_table(["structure", "shaper", "design CPU [s]", "ratio to DeZV", "Kp", "goal (<= 2 s and <= 2x DeZV)"],
                   lrows))
    n_met = sum(r[-1] == "met" for r in lrows)
    n_goal = sum(r[-1] != "-" for r in lrows)
    print(f"\nlumped designs: {'every goal met' if lok else f'goals met for {n_met} of {n_goal} designs: MISSED'}")

    druns = 1 if args.quick else 3
    t_demo, _ = _cpu_median(demo_designs, druns)
    print(f"\nissue #15: the demo's 36 seed 001 designs (Table 1 three times), median CPU of {druns} runs: "
          f"{t_demo:.2f} s; before wave 5 {DEMO_DESIGNS_BEFORE:.1f} s (ratio {t_demo / DEMO_DESIGNS_BEFORE:.2f}); "
          f"goal <= {DEMO_DESIGNS_GOAL:.0f} s: {'met' if t_demo <= DEMO_DESIGNS_GOAL else 'MISSED'}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
