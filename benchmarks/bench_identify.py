"""Benchmark: posicast.identify (OE) against sdypy-EMA's LSCF and seed 002's ARX.

Scenario: seed 002's mode (28 Hz, zeta 0.05) sampled at 400 Hz, 2000 samples,
12-bit, 5 % output noise; random binary and chirp inputs; seeded trials.

* posicast OE: ``posicast.identify(t, u, y)`` (time per fit, median).
* sdypy-EMA (bench extra only): H1 FRF estimate (scipy csd / welch, 512-sample
  segments) then ``EMA.Model(...).get_poles("lscf")`` and
  ``select_closest_poles([28])``; the timing includes the FRF estimate.
* ARX: ``posicast.identify(..., method="arx")`` (seed 002 eq. 19-25).

Errors are relative (mean +- sd) in percent; target: OE fit <= 50 ms.

Usage: python benchmarks/bench_identify.py [--quick]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import statistics
import time
import warnings

import numpy as np
from scipy import signal

import posicast
from posicast.testing import synthetic

TRUE = posicast.Mode.from_hz(28.0, 0.05)


def _ema(d):
    from sdypy import EMA

    f, Puy = signal.csd(d.u, d.y, fs=d.sample_rate, nperseg=512)
    _, Puu = signal.welch(d.u, fs=d.sample_rate, nperseg=512)
    with warnings.catch_warnings(), contextlib.redirect_stderr(io.StringIO()):
        warnings.simplefilter("ignore")
        a = EMA.Model(frf=(Puy / Puu)[None, :], freq=f, lower=5, upper=100, pol_order_high=30,
                      frf_type="receptance")
        a.get_poles(method="lscf", show_progress=False)
        a.select_closest_poles([TRUE.freq_hz])
    return float(a.nat_freq[0]) * 2 * np.pi, float(a.nat_xi[0])


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    trials = 15 if args.quick else 100
    try:
        import sdypy.EMA  # noqa: F401
        have_ema = True
    except ImportError:
        have_ema = False
        print("sdypy-EMA not installed (pip install -e '.[bench]'): comparator skipped")
    print(f"{trials} trials, 2000 samples at 400 Hz, 5 % output noise, truth 28 Hz / zeta 0.05\n")
    print("| input | tool | median time [ms] | omega err % | zeta err % | 95 % coverage omega / zeta |")
    print("|---|---|---|---|---|---|")
    for inp in ("random_binary", "chirp"):
        res = {"posicast OE": [], "seed ARX": [], "sdypy-EMA LSCF": []}
        times = {k: [] for k in res}
        for s in range(trials):
            d = synthetic(TRUE, inp, n=2000, noise=0.05, seed=s)
            t0 = time.perf_counter()
            r = posicast.identify(d.t, d.u, d.y)
            times["posicast OE"].append(time.perf_counter() - t0)
            iv = r.intervals[0]
            res["posicast OE"].append((r.modes[0].omega, r.modes[0].zeta, iv.omega[0] <= TRUE.omega <= iv.omega[1],
                                       iv.zeta[0] <= TRUE.zeta <= iv.zeta[1]))
            t0 = time.perf_counter()
            try:
                r = posicast.identify(d.t, d.u, d.y, method="arx")
                res["seed ARX"].append((r.modes[0].omega, r.modes[0].zeta, None, None))
            except ValueError:
                pass
            times["seed ARX"].append(time.perf_counter() - t0)
            if have_ema:
                t0 = time.perf_counter()
                w, z = _ema(d)
                times["sdypy-EMA LSCF"].append(time.perf_counter() - t0)
                res["sdypy-EMA LSCF"].append((w, z, None, None))
        for tool, rows in res.items():
            if not rows:
                if tool != "sdypy-EMA LSCF" or have_ema:
                    print(f"| {inp} | {tool} | {1000 * statistics.median(times[tool]):.1f} | failed (no oscillatory "
                          f"pole) in all {trials} | – | – |")
                continue
            a = np.array([(w / TRUE.omega - 1, z / TRUE.zeta - 1) for w, z, _, _ in rows])
            cov = (f"{np.mean([c[2] for c in rows]):.2f} / {np.mean([c[3] for c in rows]):.2f}"
                   if rows[0][2] is not None else "–")
            print(f"| {inp} | {tool} | {1000 * statistics.median(times[tool]):.1f} | "
                  f"{100 * a[:, 0].mean():+.3f} ± {100 * a[:, 0].std():.3f} | "
                  f"{100 * a[:, 1].mean():+.2f} ± {100 * a[:, 1].std():.2f} | {cov} |"
                  + (f" ({len(rows)}/{trials} succeeded)" if len(rows) < trials else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
