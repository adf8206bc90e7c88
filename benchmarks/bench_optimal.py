"""Benchmark: optimal shapers (issue #17) against the closed forms they replace.

Each case designs an optimal shaper (``design("si")``, ``shortest_shaper``, ``design("um_zv")``...) and,
side by side, the closed-form shaper (or convolution of single-mode ones) a user would otherwise take
for the same bands: design time (median), duration, impulse count and the worst residual vibration
over the bands (posicast.residual_vibration on 4001 points per band).  Target (issue #17 acceptance 4):
every design under 1 s for up to 3 modes.

Usage: python benchmarks/bench_optimal.py [--quick]
"""

from __future__ import annotations

import argparse
import sys
from functools import reduce

import numpy as np
from _harness import fmt_time, machine_info, md_table, print_machine_info, timed

from posicast import Mode, design, residual_vibration, shortest_shaper

M42, M63 = Mode.from_hz(42.0, 0.05), Mode.from_hz(63.0, 0.05)
THREE = [Mode.from_hz(f, 0.03) for f in (30.0, 47.0, 71.0)]
ONE = Mode.from_hz(40.0, 0.05)


def worst(S, modes, band):
    r = np.linspace(band[0], band[1], 4001)
    return max(float(np.max(residual_vibration(S, r * m.omega, m.zeta))) for m in modes)


def conv(kind, modes, **kw):
    return reduce(lambda a, b: a * b, [design(kind, m, **kw) for m in modes])


# (label, modes, band, optimal design, comparator label, comparator design)
CASES = [
    ("SI, 1 mode, +-5 %", [ONE], (0.95, 1.05), lambda: design("si", ONE, vtol=0.05, band=(0.95, 1.05)),
     "ZVD", lambda: design("zvd", ONE)),
    ("SI, 1 mode, +-10 %", [ONE], (0.9, 1.1), lambda: design("si", ONE, vtol=0.05, band=(0.9, 1.1)),
     "ZVD", lambda: design("zvd", ONE)),
    ("SI, 1 mode, +-20 %", [ONE], (0.8, 1.2), lambda: design("si", ONE, vtol=0.05, band=(0.8, 1.2)),
     "ZVDD", lambda: design("zvdd", ONE)),
    ("SI, 1 mode, +-30 %", [ONE], (0.7, 1.3), lambda: design("si", ONE, vtol=0.05, band=(0.7, 1.3)),
     "2-hump EI", lambda: design("ei2", ONE, vtol=0.05)),
    ("SI, 1 mode, +-10 %, zeta 0-0.15", [ONE], (0.9, 1.1),
     lambda: design("si", ONE, vtol=0.05, band=(0.9, 1.1), damping=(0.0, 0.15)), "ZVD", lambda: design("zvd", ONE)),
    ("2 modes 42/63 Hz, +-10 %", [M42, M63], (0.9, 1.1),
     lambda: shortest_shaper([M42, M63], vtol=0.05, band=(0.9, 1.1)), "ZV(42) * ZVD(63)",
     lambda: design("zv", M42) * design("zvd", M63)),
    ("2 modes, <= 5 impulses, 0.1 ms grid", [M42, M63], (0.9, 1.1),
     lambda: shortest_shaper([M42, M63], vtol=0.05, band=(0.9, 1.1), max_impulses=5, sample_period=1e-4),
     "ZV(42) * ZVD(63)", lambda: design("zv", M42) * design("zvd", M63)),
    ("2 modes, <= 3 impulses (infeasible)", [M42, M63], (0.9, 1.1),
     lambda: shortest_shaper([M42, M63], vtol=0.05, band=(0.9, 1.1), max_impulses=3),
     "ZV * ZV", lambda: conv("zv", [M42, M63])),
    ("3 modes 30/47/71 Hz, +-7 %", THREE, (0.93, 1.07),
     lambda: shortest_shaper(THREE, vtol=0.05, band=(0.93, 1.07)), "ZVD * ZVD * ZVD", lambda: conv("zvd", THREE)),
    ("3 modes, <= 5 impulses", THREE, (0.93, 1.07),
     lambda: shortest_shaper(THREE, vtol=0.05, band=(0.93, 1.07), max_impulses=5), "ZV * ZV * ZV",
     lambda: conv("zv", THREE)),
    ("UM-ZV (zeta 0.05)", [ONE], (1.0, 1.0), lambda: design("um_zv", ONE), "ZV", lambda: design("zv", ONE)),
    ("UM-ZVD (zeta 0.05)", [ONE], (1.0, 1.0), lambda: design("um_zvd", ONE), "ZVD", lambda: design("zvd", ONE)),
]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 repeats instead of 7")
    args = ap.parse_args(argv)
    repeats = 3 if args.quick else 7
    print_machine_info(machine_info())
    rows, slow = [], []
    for label, modes, band, opt, clabel, closed in CASES:
        t_opt = timed(opt, repeats, budget=10.0)
        t_cf = timed(closed, repeats, budget=2.0)
        S, C = t_opt.result, t_cf.result
        if S is None or C is None:
            print(f"{label}: failed: {t_opt.error or t_cf.error}", file=sys.stderr)
            return 1
        o = S.optimality
        if t_opt.median >= 1.0:
            slow.append(label)
        rows.append([label, fmt_time(t_opt.median), f"{S.duration * 1e3:.3f} ms", str(S.n_impulses),
                     f"{worst(S, modes, band):.4f}", o.status, clabel, fmt_time(t_cf.median),
                     f"{C.duration * 1e3:.3f} ms", str(C.n_impulses), f"{worst(C, modes, band):.4f}",
                     f"{S.duration / C.duration:.3f}"])
        print(f"{label}: {fmt_time(t_opt.median)}  {o.summary()}", flush=True)
    print()
    print(md_table(["case", "optimal: time", "duration", "impulses", "max V on bands", "status", "closed form",
                    "time", "duration", "impulses", "max V on bands", "duration ratio"], rows))
    print()
    if slow:
        print(f"FAIL: {len(slow)} designs took 1 s or more: {', '.join(slow)}")
        return 1
    print(f"PASS: all {len(rows)} designs under 1 s (median of up to {repeats} runs)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
