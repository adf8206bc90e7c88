"""Benchmark: posicast.roots against the comparators qpmr and cxroots.

For every test quasi-polynomial h (shaper numerators and closed-loop
characteristic quasi-polynomials of the seed 000 example) this script

* times ``posicast.roots(h, region=R)`` and ``qpmr.qpmr(coefs, delays, region=R)``
  on R = [-20, 5] x [0, 500] (median of several runs in this process);
* times ``cxroots.Rectangle(...).roots(h, h')`` on the smaller region
  R_cx = [-20, 5] x [-0.1, 100] (cxroots is slow; fewer runs), and posicast on
  R_cx as well for a like-for-like ratio;
* compares the root sets (each root matched to the nearest root of the other
  set), and checks every tool against a 40-digit mpmath Newton polish of the
  roots (the referee).

qpmr (GPL-3.0) and cxroots are benchmark comparators only: they come from the
``bench`` extra and are imported here, never by the library.

Usage: python benchmarks/bench_roots.py [--quick] [--cases zv,dzv] [--no-cxroots]
"""

from __future__ import annotations

import argparse
import logging
import sys
import warnings
from dataclasses import dataclass
from typing import Callable

import numpy as np

import _harness as H

REGION = (-20.0, 5.0, 0.0, 500.0)
# cxroots: smaller, and Im starts just below the real axis: cxroots needs a contour
# free of roots, and these quasi-polynomials have real roots (s = 0 for the
# distributed shapers, s = -1 and others for the closed loops).
CX_REGION = (-20.0, 5.0, -0.1, 100.0)
# qpmr again with the bottom edge moved off the real axis: qpmr is slow, and may
# drop roots, when a root lies on the region boundary (shown in the details table).
QPMR_NUDGED = (-20.0, 5.0, -0.1, 500.0)
AGREE_TOL = 1e-8
BOUNDARY_TOL = 1e-6


# ----------------------------------------------------------------------------- cases


@dataclass
class Case:
    name: str
    what: str
    build: Callable[[], object]  # -> posicast.QuasiPolynomial


def _cases() -> list[Case]:
    import posicast
    from posicast import QuasiPolynomial as QP

    m1 = posicast.Mode(10.0, 0.03)  # seed 000: F(s) = s / (s^2 + 0.6 s + 100)
    m2 = posicast.Mode(27.0, 0.05)

    def num(kind, **kw):
        return lambda: posicast.design(kind, m1, **kw).num

    def loop(kind):
        # seed 000: G = M/N = 1/(s^2+s), C = P/Q = (10s+10)/(0.01s+1), inverse-shaper
        # loop: CE = S.num Q N + P M S.den
        def build():
            S = posicast.design(kind, m1)
            N, M = QP.from_poly([1.0, 1.0, 0.0]), QP.from_poly([1.0])
            P, Q = QP.from_poly([10.0, 10.0]), QP.from_poly([0.01, 1.0])
            return S.num * Q * N + P * M * S.den

        return build

    def two_mode():
        return posicast.design("zv", m1).num * posicast.design("zv", m2).num

    return [
        Case("zv", "ZV numerator, Mode(10, 0.03)", num("zv")),
        Case("zvd3", "ZVD^3 numerator (zvdk, k=3): quadruple roots", num("zvdk", k=3)),
        Case("dzv", "DZV numerator", num("dzv")),
        Case("dezv", "DEZV numerator", num("dezv")),
        Case("dtzv", "DTZV numerator (double root at s=0)", num("dtzv")),
        Case("dczv", "DCZV numerator", num("dczv")),
        Case("dtazv", "DTAZV numerator (double root at s=0)", num("dtazv")),
        Case("loop-zv", "closed loop, inverse ZV shaper", loop("zv")),
        Case("loop-dzv", "closed loop, inverse DZV shaper", loop("dzv")),
        Case("two-mode", "ZV(10, 0.03).num * ZV(27, 0.05).num", two_mode),
    ]


# ----------------------------------------------------------------------------- tools


def numpy_qp(coeffs, delays) -> Callable:
    """Vectorised evaluator of sum_i sum_k coeffs[i, k] s**k exp(-s delays[i])."""
    rows = [(np.asarray(c, float)[::-1].copy(), -float(t)) for c, t in zip(coeffs, delays)]

    def f(s):
        s = np.asarray(s, dtype=complex)
        out = np.zeros_like(s)
        for desc, mt in rows:
            out = out + np.polyval(desc, s) * np.exp(mt * s)
        return out if out.ndim else complex(out)

    return f


class _Counter(logging.Handler):
    def __init__(self):
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record):
        self.messages.append(record.getMessage())


def import_tools():
    """Return (posicast_roots or None, why, qpmr or None, cxroots or None)."""
    try:
        from posicast import roots as proots

        why = ""
    except ImportError as exc:
        proots, why = None, f"{type(exc).__name__}: {exc}"
    try:
        import qpmr
    except ImportError:
        qpmr = None
    try:
        import cxroots
    except ImportError:
        cxroots = None
    return proots, why, qpmr, cxroots


def _time_qpmr(qpmr, C, D, region, args):
    """Time qpmr.qpmr(C, D, region=region) with its defaults; also collect its log warnings."""
    counter = _Counter()
    qlog = logging.getLogger("qpmr")
    qlog.addHandler(counter)
    try:
        with warnings.catch_warnings():
            # qpmr hands the complex grid values to contourpy, which keeps the
            # real part (as the algorithm intends) and warns about the cast.
            warnings.simplefilter("ignore", getattr(np, "exceptions", np).ComplexWarning)
            t = H.timed(lambda: qpmr.qpmr(C, D, region=region)[0], args.repeats, args.budget, args.run_limit)
    finally:
        qlog.removeHandler(counter)
    return t, [m.split(",")[0][:70] for m in counter.messages]


# ----------------------------------------------------------------------------- main


def run(args) -> int:
    proots, why, qpmr, cxroots = import_tools()
    print("# Benchmark: quasi-polynomial roots (posicast.roots vs qpmr vs cxroots)")
    H.print_machine_info(H.machine_info(("numpy", "scipy", "posicast", "qpmr", "cxroots", "mpmath")))
    if proots is None:
        print(f"\n!! posicast.roots is not importable yet ({why}).")
        print("!! Running the comparator side only (qpmr vs cxroots).")
    if qpmr is None or cxroots is None:
        missing = [n for n, m in (("qpmr", qpmr), ("cxroots", cxroots)) if m is None]
        print(f"\n!! comparator(s) not installed: {', '.join(missing)} (pip install -e '.[bench]').")
    if args.no_cxroots:
        cxroots = None
    print(
        f"\nregion {REGION} for posicast and qpmr: up to {args.repeats} runs each, median"
        f" (qpmr stops repeating after {args.budget:g} s of runs)."
    )
    if cxroots is not None:
        print(
            f"cxroots is slow: region {CX_REGION} only, up to {args.cx_repeats} runs"
            f" (stops after {args.cx_budget:g} s); posicast is timed on that region too."
        )
    print(f"one run is abandoned after {args.run_limit:g} s. Agreement: max distance <= {AGREE_TOL:g}.")
    print("qpmr: defaults (its grid-step heuristic, e=1e-6, Newton); cxroots: defaults, exact derivative.\n")

    cases = _cases()
    if args.cases:
        wanted = set(args.cases.split(","))
        cases = [c for c in cases if c.name in wanted]

    rows, details, notes = [], [], []
    for case in cases:
        h = case.build()
        C = np.asarray(h.coeffs, dtype=float)
        D = np.asarray(h.delays, dtype=float)
        print(f"- {case.name}: {case.what}; {C.shape[0]} delays, degree {C.shape[1] - 1} ...", flush=True)
        case_notes = []

        # --- posicast
        tp = tpc = None
        if proots is not None:
            tp = H.timed(lambda: proots(h, region=REGION), args.repeats, args.budget, args.run_limit)
            if cxroots is not None:
                tpc = H.timed(lambda: proots(h, region=CX_REGION), args.repeats, args.budget, args.run_limit)
            for lab, t in (("posicast", tp), ("posicast (cx region)", tpc)):
                if t is not None and t.error:
                    case_notes.append(f"{lab} failed: {t.error}")

        # --- qpmr
        tq = tqn = None
        if qpmr is not None:
            tq, msgs = _time_qpmr(qpmr, C, D, REGION, args)
            if tq.error:
                case_notes.append(f"qpmr failed: {tq.error}")
            if msgs:
                case_notes.append(f"qpmr logged {len(msgs)} warning(s): {'; '.join(sorted(set(msgs)))}")
            tqn, msgs = _time_qpmr(qpmr, C, D, QPMR_NUDGED, args)
            if tqn.error:
                case_notes.append(f"qpmr (Im from {QPMR_NUDGED[2]}) failed: {tqn.error}")

        # --- cxroots
        tc = None
        if cxroots is not None:
            f = numpy_qp(C, D)
            dh = h.derivative()
            df = numpy_qp(dh.coeffs, dh.delays)
            rect = cxroots.Rectangle([CX_REGION[0], CX_REGION[1]], [CX_REGION[2], CX_REGION[3]])
            with warnings.catch_warnings(record=True) as wlist:
                warnings.simplefilter("always")
                tc = H.timed(lambda: rect.roots(f, df), args.cx_repeats, args.cx_budget, args.run_limit)
            if tc.error:
                case_notes.append(f"cxroots failed: {tc.error}")
            if wlist:
                kinds = sorted({w.category.__name__ for w in wlist})
                case_notes.append(f"cxroots raised {len(wlist)} warning(s) ({', '.join(kinds)})")

        # --- root lists (repeated by multiplicity)
        P = tp.result.roots if tp is not None and tp.result is not None else None
        Pc = tpc.result.roots if tpc is not None and tpc.result is not None else None
        Q = np.asarray(tq.result, dtype=complex) if tq is not None and tq.result is not None else None
        Qn = np.asarray(tqn.result, dtype=complex) if tqn is not None and tqn.result is not None else None
        X = None
        if tc is not None and tc.result is not None:
            X = np.repeat(np.asarray(tc.result.roots, dtype=complex), tc.result.multiplicities)

        # --- referee: posicast's distinct roots (or qpmr's clusters) polished in 40 digits
        if tp is not None and tp.result is not None:
            starts = list(tp.result.distinct)
            mults = list(tp.result.multiplicities)
            if tpc is not None and tpc.result is not None:
                for z, m in zip(tpc.result.distinct, tpc.result.multiplicities):
                    if not starts or np.min(np.abs(np.asarray(starts) - z)) > 1e-6:
                        starts.append(z)
                        mults.append(m)
        else:  # no posicast: qpmr's roots (clusters of copies = multiple roots), then cxroots'
            starts, mults = [], []
            if Q is not None and Q.size:
                c, m = H.cluster(Q, 0.25)
                starts, mults = list(c), list(m)
            if tc is not None and tc.result is not None:
                for z, m in zip(tc.result.roots, tc.result.multiplicities):
                    if not starts or np.min(np.abs(np.asarray(starts) - z)) > 0.25:
                        starts.append(z)
                        mults.append(m)
        ref = H.mp_refine(C, D, starts, mults) if len(starts) else np.zeros(0, complex)
        if np.isnan(ref).any():
            case_notes.append(f"referee: {int(np.isnan(ref).sum())} start(s) did not converge")

        # --- comparisons
        cmp_pq = H.compare_roots(P, Q, REGION, boundary_tol=BOUNDARY_TOL) if P is not None and Q is not None else None
        if X is not None and Pc is not None:
            cmp_x = H.compare_roots(Pc, X, CX_REGION, boundary_tol=BOUNDARY_TOL)
            xlab = "posicast-cxroots"
        elif X is not None and Q is not None:
            cmp_x = H.compare_roots(Q, X, CX_REGION, boundary_tol=BOUNDARY_TOL)
            xlab = "qpmr-cxroots"
        else:
            cmp_x, xlab = None, ""
        if cmp_pq is not None and cmp_pq.summary() != "-":
            case_notes.append(f"posicast(A) vs qpmr(B): {cmp_pq.summary()}")
        if cmp_x is not None and cmp_x.summary() != "-":
            case_notes.append(f"{xlab.replace('-', '(A) vs ')}(B): {cmp_x.summary()}")

        def n(res_list, tm, cnt=None):
            if tm is None:
                return "n/a"
            if res_list is None:
                return "fail"
            return str(cnt if cnt is not None else len(res_list))

        n_p = n(P, tp, tp.result.count if tp is not None and tp.result is not None else None)
        n_q = n(Q, tq)
        n_x = n(X, tc)
        n_pc = n(Pc, tpc, tpc.result.count if tpc is not None and tpc.result is not None else None)
        t_p = tp.median if tp else float("nan")
        t_q = tq.median if tq else float("nan")
        t_x = tc.median if tc else float("nan")
        t_pc = tpc.median if tpc else float("nan")
        ratio = t_p / t_q if np.isfinite(t_p) and np.isfinite(t_q) else float("nan")
        ratio_x = t_pc / t_x if np.isfinite(t_pc) and np.isfinite(t_x) else float("nan")

        def agree(c):
            if c is None:
                return "-"
            if not c.agree:
                return "NO"
            return "yes*" if c.boundary_ignored or c.n_a != c.n_b else "yes"

        rows.append(
            [
                case.name,
                f"{n_p} / {n_q}",
                H.fmt_time(t_p),
                H.fmt_time(t_q),
                "-" if not np.isfinite(ratio) else f"{ratio:.3g}",
                H.fmt_sci(cmp_pq.max_dist) if cmp_pq else "-",
                agree(cmp_pq),
                f"{n_pc} / {n_x}" if cxroots is not None else "-",
                H.fmt_time(t_pc),
                H.fmt_time(t_x),
                "-" if not np.isfinite(ratio_x) else f"{ratio_x:.2g}",
                H.fmt_sci(cmp_x.max_dist) if cmp_x else "-",
                agree(cmp_x),
            ]
        )

        def err(z, region):
            if z is None or ref.size == 0:
                return float("nan")
            return H.centroid_error(z[H.in_region(z, region, BOUNDARY_TOL)], ref)

        details.append(
            [
                case.name,
                f"{tp.runs if tp else 0}/{tq.runs if tq else 0}/{tc.runs if tc else 0}",
                H.fmt_sci(err(P, REGION)),
                H.fmt_sci(err(Q, REGION)),
                f"{n(Qn, tqn)}, {H.fmt_time(tqn.median if tqn else float('nan'))}, {H.fmt_sci(err(Qn, QPMR_NUDGED))}",
                H.fmt_sci(err(Pc, CX_REGION)),
                H.fmt_sci(err(X, CX_REGION)),
            ]
        )
        notes.extend(f"{case.name}: {m}" for m in case_notes)

    print("\n## Results (medians; n = roots counted with multiplicity)\n")
    print(
        H.md_table(
            [
                "case",
                "n posicast / qpmr",
                "posicast",
                "qpmr",
                "posicast/qpmr",
                "max dist P-Q",
                "agree",
                "n posicast / cxroots (cx region)",
                "posicast (cx region)",
                "cxroots",
                "posicast/cxroots",
                f"max dist {'P' if proots else 'Q'}-X",
                "agree",
            ],
            rows,
        )
    )
    print(
        "\n## Accuracy: max distance to the 40-digit referee (mpmath Newton polish of the roots)\n"
    )
    print(
        H.md_table(
            [
                "case",
                "runs P/Q/X",
                "posicast",
                "qpmr",
                f"qpmr on Im >= {QPMR_NUDGED[2]:g}: n, time, error",
                "posicast (cx region)",
                "cxroots",
            ],
            details,
        )
    )
    print("\n## Notes\n")
    if not notes:
        print("- none")
    for m in notes:
        print(f"- {m}")
    print(
        "\n'agree' = every root matched (nearest root of the other set within 0.25) and max distance <= "
        f"{AGREE_TOL:g}; unmatched roots within {BOUNDARY_TOL:g} of the region boundary are ignored;\n"
        "'yes*' = agree, but boundary roots were ignored or the counts with multiplicity differ (see Notes)."
    )
    if proots is None:
        print("\n!! posicast.roots was not importable: only the comparators were run.")
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=5, help="runs of posicast and qpmr per case (median)")
    ap.add_argument("--budget", type=float, default=30.0, help="stop repeating a tool after this many seconds")
    ap.add_argument("--cx-repeats", type=int, default=2, help="runs of cxroots per case")
    ap.add_argument("--cx-budget", type=float, default=20.0, help="stop repeating cxroots after this many seconds")
    ap.add_argument("--run-limit", type=float, default=300.0, help="abandon one run after this many seconds")
    ap.add_argument("--cases", default="", help="comma-separated case names (default: all)")
    ap.add_argument("--no-cxroots", action="store_true", help="skip cxroots")
    ap.add_argument("--quick", action="store_true", help="1 run per tool, no cxroots")
    args = ap.parse_args(argv)
    if args.quick:
        args.repeats = args.cx_repeats = 1
        args.no_cxroots = True
    return run(args)


if __name__ == "__main__":
    sys.exit(main())
