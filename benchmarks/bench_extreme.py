"""Benchmark: the spectral tools on extreme gains and scales (reliability issue, wave 4).

Each row times posicast's certified answer beside an independent, uncertified computation of the same
roots (numpy's eigenvalue roots of the characteristic polynomial; the Lambert W branches of
``s + a e^{-s}``, ``s = W_k(-a)``), checks that they agree, and prints the ratio.  The refusal rows
time how long posicast takes to refuse work it cannot do (no comparator: the point is "at once").

Usage: python benchmarks/bench_extreme.py [--quick]
"""

from __future__ import annotations

import argparse
import statistics
import time
import warnings

import numpy as np
from scipy.special import lambertw

import posicast as pc
from _harness import machine_info, md_table, print_machine_info


def _median(f, runs: int) -> tuple[float, object]:
    out, times = None, []
    for _ in range(runs):
        t0 = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def _crane_pd(kd: float, S=None):
    crane = pc.cases.ALL["gantry_crane"]
    C = pc.TransferFunction.from_poly(np.polyadd([0.01, 1.0], [kd, 0.0]), [0.01, 1.0])
    return pc.control_action(G=crane.G, F=crane.F, C=C, S=S)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    runs = 1 if ap.parse_args().quick else 3
    print_machine_info(machine_info())
    rows = []

    q = pc.QuasiPolynomial.from_poly(np.polymul([1.0, 1.0], [1.0, 1e100]))
    t_pc, r = _median(lambda: (pc.stability(q).stable, pc.rightmost(q, 2)), runs)
    t_np, ref = _median(lambda: np.roots(np.polymul([1.0, 1.0], [1.0, 1e100])), runs)
    ok = np.allclose(np.sort(r[1].real), np.sort(ref.real), rtol=1e-12)
    rows.append(["(s+1)(s+1e100): stability + rightmost(2) vs np.roots", f"{t_pc * 1e3:.1f} ms",
                 f"{t_np * 1e3:.3f} ms", f"{t_pc / t_np:.0f}x", "yes" if ok else "NO"])

    L = _crane_pd(4.6e16)
    c = L.characteristic.coeffs[0]
    t_pc, r = _median(lambda: pc.rightmost(L, 10), runs)
    t_np, ref = _median(lambda: np.roots(c[::-1]), runs)
    ok = r.size == 10 and all(np.min(np.abs(r - z)) <= 1e-8 * max(1.0, abs(z)) for z in ref)
    rows.append(["crane, PD kd = 4.6e16: rightmost(10) vs np.roots", f"{t_pc * 1e3:.1f} ms",
                 f"{t_np * 1e3:.3f} ms", f"{t_pc / t_np:.0f}x", "yes" if ok else "NO"])

    a = 1e3
    qa = pc.QuasiPolynomial([[0.0, 1.0], [a, 0.0]], [0.0, 1.0])
    t_pc, st = _median(lambda: pc.stability(qa), runs)

    def branches():
        w = np.array([complex(lambertw(-a, k)) for k in range(-400, 401)])
        return w[w.real >= 0]

    t_w, ref = _median(branches, runs)
    ok = st.unstable_roots.size == ref.size and all(np.min(np.abs(st.unstable_roots - z)) <= 1e-12 * abs(z)
                                                    for z in ref)
    rows.append([f"s + 1e3 e^-s: stability ({ref.size} roots in Re s >= 0) vs Lambert W", f"{t_pc * 1e3:.1f} ms",
                 f"{t_w * 1e3:.1f} ms", f"{t_pc / t_w:.1f}x", "yes" if ok else "NO"])

    S = pc.design("zv", pc.Mode(10.0, 0.03))
    refusals = [
        ("ZV loop, PD kp = 1e12: stability refused (BudgetExceeded)",
         lambda: pc.stability(pc.control_action(G=([1.0], [1.0, 1.0, 0.0]), C=([1e12, 1e12], [0.01, 1.0]), S=S))),
        ("crane + DeZV, kd = 4.6e16: rightmost(2) refused (BudgetExceeded)",
         lambda: pc.rightmost(_crane_pd(4.6e16, pc.design("dezv", pc.cases.ALL["gantry_crane"].mode)), 2)),
        ("PD loop kp = 1e300: stability refused (ValueError, the range)",
         lambda: pc.stability((pc.as_transfer(([1e300, 1e300], [0.01, 1.0]))
                               * pc.as_transfer(([1.0], [1.0, 1.0, 0.0]))).feedback())),
    ]
    for name, f in refusals:
        def attempt(f=f):
            try:
                f()
            except (ValueError, pc.spectra.RootFindingError) as exc:
                return type(exc).__name__
            return "answered"

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t, what = _median(attempt, runs)
        rows.append([name, f"{t * 1e3:.1f} ms", "-", "-", what])

    print()
    print(md_table(["case", "posicast (certified)", "comparator", "ratio", "agree"], rows))


if __name__ == "__main__":
    main()
