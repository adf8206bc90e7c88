"""Benchmark: sparse shaper filters against the dense convolution they replace (issue #16 acceptance 2).

* Batch: 2e5 samples at 10 kHz shaped by a ZVD for a 0.05 Hz mode (200,042 dense taps, 5 nonzero):
  ``posicast.shape_signal`` (sparse taps) against ``scipy.signal.lfilter`` with every dense tap (the
  filter ShaperFilter ran before issue #16, kept as ``streaming._dense_shape``).  Both outputs are
  compared (must agree to 1e-12) and the ratio printed (target >= 100).
* The kinds the issue measured at over a minute (zvdk k=20, ei3, dtazv at 0.05 Hz / 10 kHz): sparse only,
  and dtazv also dense.
* Streaming: ``ShaperFilter.push`` per sample for ZVD, DZV and the inverse DZV, modes from 5 Hz to
  0.05 Hz (shaper duration 0.2 s .. 20 s, 2,000 .. 200,000 taps): the cost per sample must not grow.

Usage: python benchmarks/bench_shaping.py [--quick]
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy import signal
from _harness import fmt_time, machine_info, md_table, print_machine_info, timed

import posicast as pc
from posicast.simulation.streaming import ShaperFilter, _dense_shape, discretize, shape_signal

FS = 10000.0


def batch(n: int, repeats: int) -> list[list[str]]:
    rows = []
    x = np.cumsum(np.random.default_rng(0).standard_normal(n)) / 100.0
    for kind, kw in (("zvd", {}), ("zvdk", {"k": 20}), ("ei3", {}), ("dtazv", {})):
        S = pc.design(kind, pc.Mode.from_hz(0.05, 0.02), **kw)
        D = discretize(S, FS)
        sp = timed(lambda: shape_signal(D, x, FS), repeats)
        fft = timed(lambda: signal.fftconvolve(x, D.taps)[: x.size], repeats)
        dense = ratio = err = "-"
        if kind in ("zvd", "dtazv"):
            de = timed(lambda: _dense_shape(D, x), 1)
            diff = float(np.max(np.abs(sp.result - de.result)))
            if diff > 1e-12 * max(1.0, float(np.max(np.abs(x)))):
                raise SystemExit(f"{kind}: sparse and dense differ by {diff:.3g}")
            dense, ratio, err = fmt_time(de.median), f"{de.median / sp.median:.0f}", f"{diff:.1e}"
        rows.append([f"{kind}{kw.get('k', '')}", f"{D.n_taps:,}", str(D.sparse.n_terms), fmt_time(sp.median), dense,
                     ratio, err, fmt_time(fft.median)])
    return rows


def streaming(n: int) -> list[list[str]]:
    rows = []
    for kind, inverse in (("zvd", False), ("dzv", False), ("dzv", True)):
        row = [kind + (" inverse" if inverse else "")]
        for f_hz in (5.0, 0.5, 0.05):
            # the inverse of a 0.05 Hz mode's shaper at 10 kHz forgets at 1e-6 per sample: "marginal"
            f = ShaperFilter(pc.design(kind, pc.Mode.from_hz(f_hz, 0.02)), FS, inverse=inverse, allow_marginal=True)
            f.process(np.zeros(10))
            x = np.sin(np.arange(n) * 1e-3).tolist()

            def run() -> None:
                for v in x:
                    f.push(v)

            t = timed(run, 5)
            row.append(f"{t.median / n * 1e6:.1f} us ({f.discrete.n_taps:,} taps)")
        rows.append(row)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    print_machine_info(machine_info())
    n = 20_000 if args.quick else 200_000
    print(f"\n## Batch: {n:,} samples at {FS:g} Hz, modes at 0.05 Hz (zeta 0.02)\n")
    print(md_table(["shaper", "dense taps", "sparse terms/sample", "sparse (posicast)", "dense lfilter (before)",
                    "ratio", "max |diff|", "dense FFT convolution (batch only)"], batch(n, 3 if args.quick else 5)))
    m = 500 if args.quick else 3000
    print(f"\n## Streaming: ShaperFilter.push, {m:,} samples, per-sample time against the shaper's length\n")
    print(md_table(["filter", "5 Hz mode", "0.5 Hz", "0.05 Hz"], streaming(m)))


if __name__ == "__main__":
    main()
