"""H-infinity regions and the stability region in a two-gain plane (seed 001 section 3, Algorithm 1).

The plane is scanned along lines ``kx = const``.  On each line:

1. **H-infinity regions, exactly in ky.**  At every frequency a constraint
   ``|u + kx a + ky b|^2 - w2 |nu + kx na + ky nb|^2 > 0`` is a quadratic in
   ``ky`` (Schlegel and Medvecova's "quadratic polynomial", seed 001 section 3):
   its forbidden set is an interval (or two rays).  Over a connected run of
   frequencies the union of these intervals is ``[min lo, max hi]``, so the
   admissible set on the line is the complement of a few intervals whose ends are
   extrema over frequency of the quadratic's roots.  The extrema come from the
   refined grid (:class:`~posicast.tune.frequency.FrequencyData`) with a parabolic
   correction; the chosen design point gets an exact 1-D refinement in frequency.
2. **D-decomposition.**  The closed-loop characteristic quasi-polynomial
   ``dC D_P + (n0 + kx nx + ky ny) N_P`` has a root on the imaginary axis where
   the line crosses a boundary:

   * complex-root boundary: ``1 + L(j omega) = 0`` for some ``omega > 0``, i.e.
     ``Im(U conj b) = 0`` with ``U = u + kx a``, at ``ky = -Re(U / b)``;
   * real-root boundary: the lowest Taylor coefficient at ``s = 0`` that is not
     identically zero (a distributed shaper's removable root at 0 is skipped);
   * infinite-root boundary: where the leading coefficients change the type
     (degree drop) or, for neutral loops, where the difference operator stops
     being strongly stable (``sum |d_k| = 1``, the test
     :func:`posicast.stability` applies).

   These break the line into segments, each inside one D-decomposition cell.
3. **Cells.**  Segments of adjacent lines are joined when the horizontal path
   between them crosses no boundary (checked with the same formulas); each joined
   component gets one certified spectrum check (:meth:`Loop.stability`, issue #3)
   at an interior point.  A segment that cannot be joined is simply checked on
   its own, so a missed join costs time, never correctness.

The admissible set is the intersection of the H-infinity regions with the
stable cells.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from .. import _validate as v
from ..core.quasipoly import QuasiPolynomial
from ..loops import Loop
from .family import ControllerFamily
from .frequency import FrequencyData

__all__ = ["Region", "LineData"]

_INF = math.inf


# ---------------------------------------------------------------------- per-line data
@dataclass
class LineData:
    """Everything known on one line ``kx = x``.

    Attributes
    ----------
    x : float
    hinf : ndarray, shape (k, 2)
        Intervals of ``ky`` meeting every H-infinity constraint (open; ends may be +/-inf).
    per_constraint : list of ndarray
        The same for each constraint alone.
    breaks : ndarray
        Sorted D-decomposition crossings; segment ``j`` is ``(breaks[j-1], breaks[j])``.
    break_kind : ndarray of str
        ``'c'`` complex-root, ``'r'`` real-root (s = 0), ``'i'`` infinite-root.
    break_err : ndarray
        Uncertainty of each break: complex-root crossings are interpolated between
        grid columns (the width of that bracket in ``ky``), unless refined exactly.
    comp : ndarray of int
        Component id of each segment (``len(breaks) + 1``), -1 if not assigned.
    ends : list of tuple
        Attribution of each ``hinf`` interval's ends: ``(column, constraint, root)``
        for the lower and upper end (None for an infinite end).
    """

    x: float
    hinf: np.ndarray
    per_constraint: list[np.ndarray]
    breaks: np.ndarray
    break_kind: np.ndarray
    ends: list[tuple[Any, Any]]
    comp: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    break_err: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def error_at(self, value: float) -> float:
        """Uncertainty of the break at ``value`` (0 for exact breaks and infinite ends)."""
        if not math.isfinite(value) or self.breaks.size == 0:
            return 0.0
        k = int(np.argmin(np.abs(self.breaks - value)))
        return float(self.break_err[k]) if self.breaks[k] == value and self.break_err.size else 0.0

    def segment_bounds(self, j: int) -> tuple[float, float]:
        lo = -_INF if j == 0 else float(self.breaks[j - 1])
        hi = _INF if j == self.breaks.size else float(self.breaks[j])
        return lo, hi

    @property
    def n_segments(self) -> int:
        return self.breaks.size + 1


def _interval_point(lo: float, hi: float) -> float:
    """A point inside ``(lo, hi)`` (either end may be infinite), of modest size.

    Stability is the same at every point of a D-decomposition segment; the
    spectrum check is cheapest where the gains are smallest.
    """
    if math.isfinite(lo) and math.isfinite(hi):
        if lo < 0.0 < hi:
            return 0.5 * lo if hi > -lo else 0.5 * hi  # nearer 0, still well inside
        # near the end closer to 0, but at least 2.5 % of the width inside (not on a boundary's roots)
        if lo >= 0.0:
            return lo + min(0.5 * (hi - lo), max(0.25 * lo, 0.025 * (hi - lo)))
        return hi - min(0.5 * (hi - lo), max(-0.25 * hi, 0.025 * (hi - lo)))
    if math.isfinite(lo):
        return 0.5 * lo if lo < 0 else lo + 0.25 * max(1e-3, abs(lo))
    if math.isfinite(hi):
        return 0.5 * hi if hi > 0 else hi - 0.25 * max(1e-3, abs(hi))
    return 0.0


# Budgets of the certified checks that label cells, counted in evaluations of the characteristic
# quasi-polynomial, never in seconds: a label must not depend on how busy the machine is.
_COUNT_EVALUATIONS = 2e6
_CHECK_EVALUATIONS = 2e7


def _certified_stability(loop: Loop) -> bool | str:
    """True/False from a certified spectrum check, or a message when it could not be certified.

    First the certified argument-principle count of the closed-loop roots with
    ``Re s >= 0`` (:func:`posicast.spectra.unstable_count`): its cost grows with
    the perimeter of the root-bound rectangle, so cells at huge gains (thousands
    of roots within the bound, all the islands a delay loop's H-infinity region
    has far out) are decided in milliseconds.  Where the count is not defined
    (a neutral loop whose difference operator is not strongly stable, a root
    within rounding of the imaginary axis, an ignored root not separated from
    others), the full certified search :meth:`Loop.stability` decides.
    """
    from ..spectra import unstable_count
    from ..spectra.rootfinder import RootFindingError

    try:
        return unstable_count(loop.characteristic, ignore=loop.cancelled, max_evaluations=_COUNT_EVALUATIONS) == 0
    except (RootFindingError, ValueError):
        pass
    try:
        return bool(loop.stability(max_evaluations=_CHECK_EVALUATIONS, timeout=1e9).stable)
    except (RootFindingError, ValueError) as exc:
        return f"spectrum check failed: {exc}"


def _subtract(iv: np.ndarray, ends: list, cuts: list[tuple[float, float, Any]]) -> tuple[np.ndarray, list]:
    """Remove the closed intervals ``cuts`` from the open intervals ``iv``.

    A new end is exact; it is attributed ``("cut", constraint, omega)``.
    """
    out, out_ends = [], []
    for (lo, hi), (e_lo, e_hi) in zip(iv, ends):
        pieces = [(lo, hi, e_lo, e_hi)]
        for c0, c1, tag in cuts:
            nxt = []
            for a, b, ea, eb in pieces:
                if c1 <= a or c0 >= b:
                    nxt.append((a, b, ea, eb))
                    continue
                if a < c0:
                    nxt.append((a, c0, ea, tag))
                if c1 < b:
                    nxt.append((c1, b, tag, eb))
            pieces = nxt
        for a, b, ea, eb in pieces:
            out.append((a, b))
            out_ends.append((ea, eb))
    return np.array(out, dtype=float).reshape(-1, 2), out_ends


def _intersect(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Intersection of two sorted lists of disjoint open intervals."""
    out = []
    i = j = 0
    while i < len(a) and j < len(b):
        lo = max(a[i][0], b[j][0])
        hi = min(a[i][1], b[j][1])
        if lo < hi:
            out.append((lo, hi))
        if a[i][1] < b[j][1]:
            i += 1
        else:
            j += 1
    return np.array(out, dtype=float).reshape(-1, 2)


def _quadratic_root(U: np.ndarray, N: np.ndarray, b: np.ndarray, nb: np.ndarray, w2: np.ndarray,
                    root: Any) -> np.ndarray:
    """Roots in ``ky`` of ``|U + ky b|^2 - w2 |N + ky nb|^2 = 0`` (the constraint's boundary at one frequency).

    ``root``: 0 the smaller, 1 the larger, 2 the single root of the linear case
    (``A = |b|^2 - w2 |nb|^2 = 0``, also used wherever ``A`` vanishes).  NaN where
    the root does not exist.  The stable form ``q = -(B + sign(B) sqrt(disc))``,
    roots ``D / q`` and ``q / A``, avoids cancellation.
    """
    A = np.abs(b) ** 2 - w2 * np.abs(nb) ** 2
    B = (U * np.conj(b)).real - w2 * (N * np.conj(nb)).real
    D = np.abs(U) ** 2 - w2 * np.abs(N) ** 2
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        disc = B * B - A * D
        sq = np.sqrt(np.where(disc >= 0, disc, np.nan))
        q = -(B + np.where(B >= 0, 1.0, -1.0) * sq)
        small, large = np.fmin(D / q, q / A), np.fmax(D / q, q / A)
        lin = -D / (2 * B)
    root = np.asarray(root)
    return np.where((root == 2) | (A == 0), lin, np.where(root == 0, small, large))


# ---------------------------------------------------------------------- the engine
class _Engine:
    """Line computations for one tuning problem."""

    def __init__(self, fd: FrequencyData, loop_factory: Callable[[float, float], Loop],
                 char_terms: tuple[QuasiPolynomial, QuasiPolynomial, QuasiPolynomial], zero_order: int) -> None:
        self.fd = fd
        self.loop_factory = loop_factory
        #: the ky window of interest (the tuning's ky_range or its automatic search window): H-infinity
        #: intervals are clipped to it, so that no work is spent beyond it
        self.y_window: tuple[float, float] = (-_INF, _INF)
        self.reload()
        self._real_boundary(char_terms, zero_order)
        self._infinite_boundary(char_terms)
        self.stability_calls = 0
        self.stability_failures: list[str] = []

    def reload(self) -> None:
        fd = self.fd
        cols = fd.columns()
        self.u, self.a, self.b = cols["u"], cols["a"], cols["b"]
        self.nc = len(fd.constraints)
        self.cons = [(cols[f"nu{i}"], cols[f"na{i}"], cols[f"nb{i}"], cols[f"w2{i}"]) for i in range(self.nc)]
        self.omega = fd.omega
        self.ng = fd.n_grid
        # columns usable for complex-root crossings: finite grid, omega > 0
        self.cross_ok = np.zeros(self.u.size, dtype=bool)
        self.cross_ok[: self.ng] = fd.omega > 0
        self.x_valid = self._valid_gain(self.a, fd.asymptote("a").m)
        self.y_valid = self._valid_gain(self.b, fd.asymptote("b").m)
        # the complex-root boundary as a curve: 1 + L(j omega) = 0 at (kx, ky) = (cx(omega), cy(omega))
        u, a, b = self.u[self.cross_ok], self.a[self.cross_ok], self.b[self.cross_ok]
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            det = a.real * b.imag - a.imag * b.real
            self.curve_x = (-u.real * b.imag + u.imag * b.real) / det
            self.curve_y = (-a.real * u.imag + a.imag * u.real) / det
        scale = np.abs(a) * np.abs(b)
        # a usable curve: no column where a and b are (nearly) real multiples of each other
        self.curve_ok = bool(np.all(np.abs(det) > 1e-12 * scale) and np.all(np.isfinite(self.curve_x))
                             and np.all(np.isfinite(self.curve_y)))

    def _valid_gain(self, term: np.ndarray, m: int) -> float:
        """Largest gain for which the grid covers every frequency where that term of ``L`` matters.

        The grid ends at least 30 times above every feature, where a decaying
        term (relative degree ``m < 0``) only decays further; for gains up to this
        bound it is below :meth:`_settled` past the grid's end, so ``1 + L`` and
        the channels are settled there.  A term with a nonzero limit (``m = 0``) is covered by
        the limit columns at every gain.  :meth:`FrequencyData.refine` extends
        the grid when larger gains are scanned.
        """
        if m >= 0:
            return _INF
        last = abs(term[self.ng - 1])
        return _INF if not last > 0 else self._settled() / last

    def _settled(self) -> float:
        """How small ``|L|`` must be past the grid's end for every constraint to hold there.

        1e-3 in general.  With unweighted ``||S||inf < Ms`` constraints only,
        ``|L| <= eps`` gives ``|S| <= 1 / (1 - eps)``, below ``Ms`` for
        ``eps < 1 - 1 / Ms``: half of that (at most 0.1) is used.  ``|L| < 1`` also
        rules out a root of ``1 + L`` there.
        """
        cons = self.fd.constraints
        if cons and all(c.kind == "S" and c.weight is None for c in cons):
            g = min(c.gamma for c in cons)
            if g > 1.0:
                return float(min(0.1, max(1e-3, 0.5 * (1.0 - 1.0 / g))))
        return 1e-3

    # ------------------------------------------------------------------ s = 0 and s = infinity
    def _real_boundary(self, terms: tuple[QuasiPolynomial, ...], m0: int) -> None:
        """``t(kx, ky) = T0 + kx Tx + ky Ty``: the Taylor coefficient of order ``m0`` at s = 0.

        ``m0`` is the multiplicity of the shaper's removable root at 0 (a root of the
        characteristic for every gain, cancelled from the poles).  If that
        coefficient vanishes for every gain, every controller of the family leaves
        a genuine closed-loop pole at s = 0 (``real_structural``).
        """
        cs = []
        for q in terms:
            if q.is_zero:
                cs.append((0.0, 0.0))
                continue
            c, sc = q.taylor(0.0, m0)
            cs.append((float(c[m0].real), float(sc[m0])))
        scale = max(sc for _, sc in cs)
        vals = tuple(val if abs(val) > 1e-10 * scale else 0.0 for val, _ in cs)
        self.real_structural = not any(vals)
        self.real_coeffs: tuple[float, float, float] | None = None if self.real_structural else vals  # type: ignore[assignment]

    def real_value(self, x: Any, y: Any) -> Any:
        T0, Tx, Ty = self.real_coeffs if self.real_coeffs is not None else (0.0, 0.0, 0.0)
        return T0 + np.asarray(x) * Tx + np.asarray(y) * Ty

    def _infinite_boundary(self, terms: tuple[QuasiPolynomial, ...]) -> None:
        """Leading coefficients of the characteristic, affine in the gains, per delay."""
        n = max(q.degree for q in terms if not q.is_zero)
        delays = np.unique(np.concatenate([q.delays for q in terms if not q.is_zero]))
        lead = np.zeros((3, delays.size))
        for k, q in enumerate(terms):
            if q.is_zero or q.degree < n:
                continue
            for row, tau in zip(q.coeffs, q.delays):
                j = int(np.argmin(np.abs(delays - tau)))
                lead[k, j] += row[n]
        keep = np.any(lead != 0, axis=0)
        self.lead = lead[:, keep]
        self.lead_delays = delays[keep]
        # row 0 of the characteristic: the smallest delay present for generic gains
        self.neutral_possible = self.lead.shape[1] > 1
        self.lead_varies = bool(np.any(self.lead[1:] != 0))

    def infinite_value(self, x: Any, y: Any) -> Any:
        """``sum_{k>0} |d_k| - |d_0|`` (neutral) or ``d_0`` (retarded): its sign flips at the boundary."""
        x, y = np.broadcast_arrays(np.atleast_1d(np.asarray(x, dtype=float)), np.atleast_1d(np.asarray(y, dtype=float)))
        L = self.lead[0][:, None] + self.lead[1][:, None] * x[None, :] + self.lead[2][:, None] * y[None, :]
        if not self.neutral_possible:
            return L[0]
        return np.sum(np.abs(L[1:]), axis=0) - np.abs(L[0])

    def _infinite_breaks(self, x: float) -> np.ndarray:
        if not self.lead_varies:
            return np.zeros(0)
        c0 = self.lead[0] + x * self.lead[1]
        c1 = self.lead[2]
        if not self.neutral_possible:
            return np.array([-c0[0] / c1[0]]) if c1[0] != 0 else np.zeros(0)
        sgn = np.ones(c0.size)
        sgn[0] = -1.0
        kinks = [-c0[i] / c1[i] for i in range(c0.size) if c1[i] != 0]
        pts = sorted(set(kinks))
        f = lambda yy: float(np.sum(sgn * np.abs(c0 + yy * c1)))  # noqa: E731
        probes = [pts[0] - 1e6 * (1 + abs(pts[0]))] + pts + [pts[-1] + 1e6 * (1 + abs(pts[-1]))] if pts else []
        out = []
        for ya, yb in zip(probes[:-1], probes[1:]):
            fa, fb = f(ya), f(yb)
            if fa == 0.0:
                out.append(ya)
            elif fa * fb < 0:
                out.append(ya - fa * (yb - ya) / (fb - fa))
        return np.array(sorted(set(out)))

    # ------------------------------------------------------------------ H-infinity intervals
    def _run_hull(self, L: np.ndarray, H: np.ndarray, V: np.ndarray, dU: np.ndarray) -> tuple[np.ndarray, ...]:
        """Replace each forbidden interval by the hull of its run of consecutive valid columns.

        Over a connected range of frequencies where the interval exists, the union
        of the intervals is the interval ``[min lo, max hi]`` (a continuous family
        of intervals with a connected parameter set), so the hull is the exact
        union, whatever the grid spacing; where the interval vanished between two
        grid points the hull forbids a little more, never less.  The grid and the
        limit columns are separate runs.  Returns ``L, H`` and the columns of the
        run's extremes (for the polish and the exact refinement).

        Two neighbouring columns belong to one run only where the grid resolves
        ``1 + L`` for the gains at the intervals' location: ``|dU| + |y| |db|``
        (``dU`` the change of ``u + kx a``, ``y`` the interval's finite end) must
        stay below a quarter of the constraint radius.  Elsewhere (e.g. far out,
        where a delay turns the phase quickly between coarse points) the
        intervals are kept as they are.
        """
        m, n = V.shape
        cols = np.broadcast_to(np.arange(n), (m, n))
        prev = np.zeros_like(V)
        prev[:, 1:] = V[:, :-1]
        if n > self.ng:
            prev[:, self.ng] = False
        with np.errstate(invalid="ignore"):
            y = np.abs(np.where(np.isfinite(L), L, H))
            y = np.where(np.isfinite(y), y, _INF)
            ymax = np.maximum(y[:, 1:], y[:, :-1])
            change = dU + ymax * np.abs(np.diff(self.b))[None, :]
        prev[:, 1:] &= change <= 0.25 * self.fd.r_min
        start = V & ~prev
        if not V.any():
            return L, H, cols.copy(), cols.copy()
        # runs are contiguous in the flattened valid entries: segment reductions with reduceat
        Vf = V.ravel()
        Lv, Hv, Cv = L.ravel()[Vf], H.ravel()[Vf], cols.ravel()[Vf]
        starts = np.flatnonzero(start.ravel()[Vf])
        lo = np.minimum.reduceat(Lv, starts)
        hi = np.maximum.reduceat(Hv, starts)
        seg = np.cumsum(start.ravel()[Vf]) - 1
        amin = np.minimum.reduceat(np.where(Lv == lo[seg], Cv, n), starts)
        amax = np.minimum.reduceat(np.where(Hv == hi[seg], Cv, n), starts)
        outL, outH = L.copy(), H.copy()
        cl, ch = cols.copy(), cols.copy()
        outL.ravel()[Vf] = lo[seg]
        outH.ravel()[Vf] = hi[seg]
        cl.ravel()[Vf] = amin[seg]
        ch.ravel()[Vf] = amax[seg]
        return outL, outH, cl, ch

    def _forbidden(self, x: np.ndarray, which: Sequence[int], hull: bool = True) -> tuple[np.ndarray, ...]:
        """Forbidden ky-intervals for lines ``x`` (m,), over every column and constraint in ``which``.

        Returns ``lo, hi`` (m, K), the columns ``col_lo, col_hi`` (m, K) each end
        is attributed to, and ``con, lroot, hroot`` (K,) with root ids 0 (smaller
        root), 1 (larger root), 2 (linear), -1 (infinite end).  With ``hull`` each
        interval is replaced by the hull of its frequency run (:meth:`_run_hull`).
        """
        m = x.size
        los, his, cl, ch, cons, lr, hr = [], [], [], [], [], [], []
        ncol = self.u.size
        colidx = np.broadcast_to(np.arange(ncol), (m, ncol))
        for ci in which:
            nu, na, nb, w2 = self.cons[ci]
            U = self.u[None, :] + x[:, None] * self.a[None, :]
            N = nu[None, :] + x[:, None] * na[None, :]
            b = self.b[None, :]
            A = (np.abs(self.b) ** 2 - w2 * np.abs(nb) ** 2)[None, :] * np.ones((m, 1))
            Ascale = (np.abs(self.b) ** 2 + w2 * np.abs(nb) ** 2)[None, :]
            B = (U * b.conj()).real - w2[None, :] * (N * nb[None, :].conj()).real
            D = np.abs(U) ** 2 - w2[None, :] * np.abs(N) ** 2
            with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
                A = np.where(np.abs(A) <= 1e-13 * Ascale, 0.0, A)
                disc = B * B - A * D
                sq = np.sqrt(np.maximum(disc, 0.0))
                q = -(B + np.where(B >= 0, 1.0, -1.0) * sq)
                r1 = np.where(q != 0, D / q, np.where(A != 0, 0.0, np.nan))
                r2 = np.where(A != 0, q / A, np.where(q > 0, _INF, -_INF))
            rlo = np.fmin(r1, r2)
            rhi = np.fmax(r1, r2)
            valid = np.isfinite(U) & np.isfinite(D) & np.isfinite(B) & np.isfinite(A)
            pos = valid & (A > 0) & (disc > 0)
            neg = valid & (A < 0)
            zer = valid & (A == 0)
            negd = neg & (disc > 0)
            negall = neg & ~(disc > 0)
            with np.errstate(invalid="ignore", divide="ignore"):
                root = -D / (2.0 * B)
            zpos = zer & (B > 0)
            zneg = zer & (B < 0)
            zall = zer & (B == 0) & (D <= 0)
            types = (
                # A > 0: [rlo, rhi]
                (pos, np.where(pos, rlo, _INF), np.where(pos, rhi, -_INF), 0, 1),
                # A < 0: (-inf, rlo] (everything when disc <= 0) and [rhi, inf)
                (negd | negall, np.where(negd | negall, -_INF, _INF),
                 np.where(negd, rlo, np.where(negall, _INF, -_INF)), -1, 0),
                (negd, np.where(negd, rhi, _INF), np.where(negd, _INF, -_INF), 1, -1),
                # A == 0: 2 B y + D > 0 (no hull: the side may change within a run)
                (None, np.where(zpos, -_INF, np.where(zneg, root, np.where(zall, -_INF, _INF))),
                 np.where(zpos, root, np.where(zneg, _INF, np.where(zall, _INF, -_INF))), 2, 2),
            )
            dU = np.abs(np.diff(U, axis=1)) if hull else None
            for V, lo_, hi_, lroot, hroot in types:
                if hull and V is not None:
                    lo_, hi_, c_lo, c_hi = self._run_hull(lo_, hi_, V, dU)
                else:
                    c_lo = c_hi = colidx
                los.append(lo_)
                his.append(hi_)
                cl.append(c_lo)
                ch.append(c_hi)
                cons.append(np.full(ncol, ci))
                lr.append(np.full(ncol, lroot))
                hr.append(np.full(ncol, hroot))
        return (np.concatenate(los, axis=1), np.concatenate(his, axis=1), np.concatenate(cl, axis=1),
                np.concatenate(ch, axis=1), np.concatenate(cons), np.concatenate(lr), np.concatenate(hr))

    def _complement(self, lo: np.ndarray, hi: np.ndarray, attr: tuple[np.ndarray, ...]) -> list[tuple[np.ndarray, list]]:
        """Per line: admissible open intervals (complement of the union) and their ends' attribution."""
        col_lo, col_hi, con, lr, hr = attr
        order = np.argsort(lo, axis=1, kind="stable")
        los = np.take_along_axis(lo, order, axis=1)
        his = np.take_along_axis(hi, order, axis=1)
        cm = np.maximum.accumulate(his, axis=1)
        out = []
        for i in range(lo.shape[0]):
            li, ci, oi, hi_ = los[i], cm[i], order[i], his[i]
            nvalid = int(np.searchsorted(li, _INF, side="left"))  # intervals with lo < inf
            iv, ends = [], []
            if nvalid == 0:
                out.append((np.array([[-_INF, _INF]]), [(None, None)]))
                continue
            li, ci, oi, hi_ = li[:nvalid], ci[:nvalid], oi[:nvalid], hi_[:nvalid]

            def attr_hi(j: int) -> Any:  # the interval whose hi is the running max at j
                k = int(np.argmax(hi_[: j + 1]))
                kk = oi[k]
                return (int(col_hi[i, kk]), int(con[kk]), int(hr[kk])) if math.isfinite(hi_[k]) else None

            def attr_lo(j: int) -> Any:
                kk = oi[j]
                return (int(col_lo[i, kk]), int(con[kk]), int(lr[kk])) if math.isfinite(li[j]) else None

            if li[0] > -_INF:
                iv.append((-_INF, li[0]))
                ends.append((None, attr_lo(0)))
            gaps = np.flatnonzero(li[1:] > ci[:-1])
            for j in gaps:
                iv.append((ci[j], li[j + 1]))
                ends.append((attr_hi(int(j)), attr_lo(int(j) + 1)))
            if ci[-1] < _INF:
                iv.append((ci[-1], _INF))
                ends.append((attr_hi(nvalid - 1), None))
            out.append((np.array(iv, dtype=float).reshape(-1, 2), ends))
        return out

    def _root_value(self, x: float, col: int, ci: int, root: int) -> float:
        """The quadratic's root ``root`` (0 smaller, 1 larger, 2 linear) at one column (NaN if none)."""
        return float(self._root_values(np.array([x]), np.array([col]), np.array([ci]), np.array([root]))[0])

    def _root_values(self, x: np.ndarray, col: np.ndarray, ci: np.ndarray, root: np.ndarray) -> np.ndarray:
        """The quadratic's roots at grid columns, vectorised (NaN where the root does not exist)."""
        out = np.full(x.shape, np.nan)
        for c in np.unique(ci):
            sel = ci == c
            nu, na, nb, w2 = (arr[col[sel]] for arr in self.cons[int(c)])
            u, a, b = self.u[col[sel]], self.a[col[sel]], self.b[col[sel]]
            out[sel] = _quadratic_root(u + x[sel] * a, nu + x[sel] * na, b, nb, w2, root[sel])
        return out

    def _polish_all(self, x: np.ndarray, ends: list[Any], values: np.ndarray, upper: np.ndarray,
                    rounds: int = 4) -> np.ndarray:
        """Exact interval ends: the extremum over frequency of each end's root, refined between its
        column's neighbours (vectorised over all ends).

        An upper end of an admissible interval is the minimum over frequency of a
        forbidden interval's lower root (``upper``); a lower end is a maximum.
        Each round evaluates the exact frequency response at 9 points per end (one
        call for all ends) and keeps the two intervals around the best point, so the
        bracket shrinks 4x per round; the grid value stands where nothing better is
        found.  (A parabola through three grid points, used before, can overshoot a
        sharp minimum and make the region smaller than it is.)
        """
        idx = [k for k, e in enumerate(ends) if e is not None and 0 < e[0] < self.ng - 1]
        if not idx:
            return values
        k = np.array(idx)
        col = np.array([ends[i][0] for i in idx])
        ci = np.array([ends[i][1] for i in idx])
        rt = np.array([ends[i][2] for i in idx])
        xs = x[k]
        sign = np.where(upper[k], 1.0, -1.0)
        lo = self.omega[col - 1].astype(float)
        hi = self.omega[col + 1].astype(float)
        best = sign * values[k]
        best = np.where(np.isfinite(best), best, _INF)
        t = np.linspace(0.0, 1.0, 9)
        for _ in range(rounds):
            w = lo[:, None] + (hi - lo)[:, None] * t[None, :]
            vals = self.fd.values(w.ravel())
            f = np.full(w.shape, _INF)
            for c in np.unique(ci):
                sel = np.flatnonzero(ci == c)
                rows = (sel[:, None] * 9 + np.arange(9)[None, :]).ravel()
                w2 = np.abs(vals[f"W{c}"][rows]) ** 2 / self.fd.constraints[int(c)].gamma ** 2
                r = _quadratic_root(vals["u"][rows] + np.repeat(xs[sel], 9) * vals["a"][rows],
                                    vals[f"nu{c}"][rows] + np.repeat(xs[sel], 9) * vals[f"na{c}"][rows],
                                    vals["b"][rows], vals[f"nb{c}"][rows], w2, np.repeat(rt[sel], 9))
                f[sel] = (np.repeat(sign[sel], 9) * r).reshape(-1, 9)
            f = np.where(np.isfinite(f), f, _INF)
            j = np.argmin(f, axis=1)
            fj = f[np.arange(f.shape[0]), j]
            best = np.minimum(best, fj)
            wj = w[np.arange(w.shape[0]), j]
            step = (hi - lo) / 8.0
            lo, hi = np.maximum(lo, wj - step), np.minimum(hi, wj + step)
        out = values.copy()
        out[k] = np.where(np.isfinite(best), sign * best, values[k])
        return out

    def _roots_at(self, x: float, vals: dict[str, np.ndarray], ci: int, root: int) -> np.ndarray:
        """The quadratic's root ``root`` at exact values (arrays over frequency)."""
        w2 = np.abs(vals[f"W{ci}"]) ** 2 / self.fd.constraints[ci].gamma ** 2
        return _quadratic_root(vals["u"] + x * vals["a"], vals[f"nu{ci}"] + x * vals[f"na{ci}"], vals["b"],
                               vals[f"nb{ci}"], w2, root)

    def exact_end(self, x: float, end: Any, upper: bool, rounds: int = 7) -> tuple[float, float]:
        """Exact extremum over frequency of one interval end: ``(ky, omega)``.

        Zooms in on the extremum between the column's neighbours: each round
        evaluates the exact frequency response at 9 points and keeps the two
        intervals around the best (the bracket shrinks 4x per round), then a
        parabola through the last three points.
        """
        col, ci, root = end
        if col >= self.ng:  # a limit column: no frequency to refine
            return self._root_value(x, col, ci, root), math.inf
        lo = float(self.omega[max(col - 1, 0)])
        hi = float(self.omega[min(col + 1, self.ng - 1)])
        sign = 1.0 if upper else -1.0
        base = self._root_value(x, col, ci, root)
        best_v, best_w = (sign * base if math.isfinite(base) else math.inf), float(self.omega[col])
        if not hi > lo:
            return base, best_w
        for _ in range(rounds):
            w = np.linspace(lo, hi, 9)
            f = sign * self._roots_at(x, self.fd.values(w), ci, root)
            f = np.where(np.isfinite(f), f, math.inf)
            k = int(np.argmin(f))
            if f[k] < best_v:
                best_v, best_w = float(f[k]), float(w[k])
            lo, hi = float(w[max(k - 1, 0)]), float(w[min(k + 1, 8)])
            if 0 < k < 8 and np.all(np.isfinite(f[k - 1 : k + 2])):
                f0, f1, f2 = f[k - 1 : k + 2]
                h = w[1] - w[0]
                curv = f0 - 2 * f1 + f2
                # the parabola's correction is trusted only above rounding, and never beyond the samples'
                # own spread (in a tiny bracket the curvature is rounding noise)
                if curv > 64 * np.finfo(float).eps * max(abs(f0), abs(f1), abs(f2), 1e-300):
                    corr = min((f2 - f0) ** 2 / (8 * curv), max(f0, f2) - f1)
                    vertex = f1 - corr
                    if vertex < best_v:
                        best_v, best_w = float(vertex), float(w[k] + h * (f0 - f2) / (2 * curv))
        return sign * best_v, best_w

    def active_branches(self, x: float, top: float, bottom: float, band: float = 0.25,
                        upper: bool = True) -> list[tuple[int, int, int]]:
        """Frequency branches that may bound the admissible interval ``(bottom, top)``.

        ``upper``: local minima over the grid of the forbidden intervals' lower
        roots within ``band`` (relative) above ``top``; otherwise local maxima of
        their upper roots within ``band`` below ``bottom``.  Each is
        ``(column, constraint, root)``.  The band is generous: a sharp dip of a
        root between grid points can sit a few per cent below its grid value
        (2.1 % was seen at a delay-induced branch), and a candidate that does
        not bind costs only its exact evaluation.
        """
        lo, hi, col, _, con, lr, hr = self._forbidden(np.array([x]), range(self.nc), hull=False)
        vals_all = lo[0] if upper else -hi[0]
        rid = lr if upper else hr
        col = col[0]
        ref = top if upper else -bottom
        if not math.isfinite(ref):
            return []
        tol = band * max(abs(ref), 1e-12) + 1e-12
        limit = bottom if upper else -top
        out = []
        for ci in range(self.nc):
            for root in (0, 1, 2):
                sel = (con == ci) & (rid == root) & (col < self.ng)
                if not np.any(sel):
                    continue
                val = np.full(self.ng, _INF)
                val[col[sel]] = vals_all[sel]
                val[~np.isfinite(val)] = _INF
                near = (val <= ref + tol) & (val >= limit)
                left = np.concatenate([[_INF], val[:-1]])
                right = np.concatenate([val[1:], [_INF]])
                out += [(int(c), ci, root) for c in np.flatnonzero(near & (val <= left) & (val <= right))]
        return out

    def branch_value(self, x: float, branch: tuple[int, int, int], reach: int = 6,
                     rounds: int = 7) -> tuple[float, float, int]:
        """Exact minimum over frequency of one branch at ``x``, followed from its grid column.

        The grid minimum is searched within ``reach`` columns (the branch drifts
        as ``x`` moves), then refined by a 1-D search.  Returns ``(ky, omega, column)``.
        """
        col, ci, root = branch
        lo_c, hi_c = max(col - reach, 1), min(col + reach, self.ng - 2)
        cols = np.arange(lo_c, hi_c + 1)
        vals = self._root_values(np.full(cols.size, x), cols, np.full(cols.size, ci), np.full(cols.size, root))
        vals = np.where(np.isfinite(vals), vals, _INF)
        j = int(cols[int(np.argmin(vals))])
        y, w = self.exact_end(x, (j, ci, root), upper=True, rounds=rounds)
        return y, w, j

    def branch_tracker(self, branch: tuple[int, int, int], reach: int = 6, n: int = 401,
                       upper: bool = True) -> Callable[[float], float]:
        """``x -> ky``: one branch's minimum (``upper``) or maximum over frequency, followed exactly.

        The frequency quantities do not depend on the gains, so a local grid
        (``n`` points over ``reach`` columns either side of the branch, about 1/30
        of the grid spacing) is evaluated once and each ``x`` costs array
        arithmetic only, with a parabola through the three best points.  When the
        extremum reaches the edge of the window (the branch drifts in frequency as
        ``x`` moves) the window is re-centred there.  ``inf`` (``-inf`` for a lower
        branch) when the branch's interval does not exist at ``x``.
        """
        _, ci, root = branch
        sign = 1.0 if upper else -1.0
        state: dict[str, Any] = {}

        origin = branch[0]
        cache: dict[int, tuple[int, int, dict[str, np.ndarray]]] = {}

        def load(col: int) -> None:
            if col not in cache:
                lo_c, hi_c = max(col - reach, 0), min(col + reach, self.ng - 1)
                w = np.linspace(float(self.omega[lo_c]), float(self.omega[hi_c]), n)
                cache[col] = (lo_c, hi_c, self.fd.values(w))
            lo_c, hi_c, vals = cache[col]
            state.update(col=col, lo=lo_c, hi=hi_c, vals=vals)

        load(origin)

        def value(x: float) -> float:
            # every call starts at the branch's own window, and follows a drifting extremum at
            # most two windows away (a slope toward another branch is not followed for good)
            load(origin)
            for _ in range(3):
                f = sign * self._roots_at(x, state["vals"], ci, root)
                f = np.where(np.isfinite(f), f, _INF)
                k = int(np.argmin(f))
                if not np.isfinite(f[k]):
                    return sign * _INF
                at_lo = k == 0 and state["lo"] > 0 and state["col"] - origin > -2 * reach
                at_hi = k == n - 1 and state["hi"] < self.ng - 1 and state["col"] - origin < 2 * reach
                if not (at_lo or at_hi):
                    break
                load(state["lo"] if at_lo else state["hi"])
            best = float(f[k])
            if 0 < k < n - 1 and np.all(np.isfinite(f[k - 1 : k + 2])):
                f0, f1, f2 = f[k - 1 : k + 2]
                curv = f0 - 2 * f1 + f2
                if curv > 64 * np.finfo(float).eps * max(abs(f0), abs(f1), abs(f2), 1e-300):
                    best = min(best, float(f1 - min((f2 - f0) ** 2 / (8 * curv), max(f0, f2) - f1)))
            return sign * best

        value.state = state  # type: ignore[attr-defined]
        value.key = (ci, root)  # type: ignore[attr-defined]
        value.origin = origin  # type: ignore[attr-defined]
        return value

    @staticmethod
    def tracked(branch: tuple[int, int, int], trackers: Sequence[Callable[[float], float]]) -> bool:
        """Does a tracker already follow ``branch``?  (Same constraint and root, and its column inside
        the tracker's window: the tracker follows the lowest minimum of its window anyway.)"""
        col, ci, root = branch
        return any(getattr(t, "key", None) == (ci, root)
                   and (t.state["lo"] <= col <= t.state["hi"] or abs(col - t.origin) <= 6)  # type: ignore[attr-defined]
                   for t in trackers)

    def exact_bottom(self, x: float, top: float, bottom: float) -> float:
        """Exact lower end of the admissible interval ``(bottom, top)`` on line ``x`` (mirror of :meth:`exact_top`)."""
        if not math.isfinite(bottom):
            return bottom
        best = bottom
        for br in self.active_branches(x, top, bottom, upper=False):
            col, ci, root = br
            cols = np.arange(max(col - 1, 1), min(col + 1, self.ng - 2) + 1)
            vals = self._root_values(np.full(cols.size, x), cols, np.full(cols.size, ci), np.full(cols.size, root))
            vals = np.where(np.isfinite(vals), vals, -_INF)
            j = int(cols[int(np.argmax(vals))])
            yv, _ = self.exact_end(x, (j, ci, root), upper=False)
            if math.isfinite(yv) and best < yv < top:
                best = yv
            elif math.isfinite(yv) and yv >= top:
                return yv  # the interval is empty
        return best

    def exact_top(self, x: float, top: float, bottom: float) -> tuple[float, float, Any]:
        """Exact upper end of the admissible interval ``(bottom, top)`` on line ``x``.

        Several frequency runs may be nearly active at once (the optimum often
        sits where two are equal), so every branch of :meth:`active_branches` is
        refined exactly and the smallest is kept (at or below ``bottom`` it says
        the interval is empty exactly).  Returns ``(ky, omega, end)``.
        """
        # the exact top is the least exact branch minimum (it may lie a little above the polished grid
        # value as well as below it); the grid value stands only when no branch is found
        best, best_w, best_end = _INF, math.nan, None
        for br in self.active_branches(x, top, bottom):
            yv, wv, j = self.branch_value(x, br, reach=1)
            if math.isfinite(yv) and yv < best:
                # below ``bottom``: this forbidden interval swallows the whole admissible interval
                best, best_w, best_end = yv, wv, (j, br[1], br[2])
        if best_end is None:
            best = top
        # limit columns (omega -> infinity) are exact as they stand
        lo, _, col, _, con, lr, _ = self._forbidden(np.array([x]), range(self.nc), hull=False)
        lo, col = lo[0], col[0]
        lim = (col >= self.ng) & np.isfinite(lo) & (lo >= bottom) & (lo < best)
        if np.any(lim):
            k = int(np.flatnonzero(lim)[np.argmin(lo[lim])])
            best, best_w, best_end = float(lo[k]), math.inf, (int(col[k]), int(con[k]), int(lr[k]))
        return best, best_w, best_end

    # ------------------------------------------------------------------ D-decomposition breaks
    @staticmethod
    def _curve_crossings(c_along: np.ndarray, c_across: np.ndarray, level: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Where the polyline ``(c_along, c_across)`` crosses ``c_along = level``: (row, value across)."""
        d = c_along[None, :] - level[:, None]
        sign = np.sign(d)
        ch = sign[:, :-1] * sign[:, 1:] <= 0
        with np.errstate(invalid="ignore", divide="ignore"):
            t = d[:, :-1] / (d[:, :-1] - d[:, 1:])
        t = np.where(np.isfinite(t), t, 0.0)
        val = c_across[None, :-1] + t * (c_across[None, 1:] - c_across[None, :-1])
        jump = np.abs(c_across[1:] - c_across[:-1]) > 1e3 * (1.0 + np.minimum(np.abs(c_across[:-1]), np.abs(c_across[1:])))
        jump |= np.abs(c_along[1:] - c_along[:-1]) > 1e3 * (1.0 + np.minimum(np.abs(c_along[:-1]), np.abs(c_along[1:])))
        rows, cols = np.nonzero(ch & ~jump[None, :])
        return rows, val[rows, cols], cols

    @staticmethod
    def _bracket_width(c_across: np.ndarray, cols: np.ndarray) -> np.ndarray:
        return np.abs(c_across[cols + 1] - c_across[cols])

    def _curve_at(self, w: float) -> tuple[float, float]:
        """The D-decomposition point ``(kx, ky)`` with ``1 + L(j w) = 0``, exactly."""
        v = self.fd.point(w)
        u, a, b = v["u"], v["a"], v["b"]
        det = a.real * b.imag - a.imag * b.real
        return ((-u.real * b.imag + u.imag * b.real) / det, (-a.real * u.imag + a.imag * u.real) / det)

    def crossing_frequency(self, x: float, col: int) -> tuple[float, float]:
        """Exact ``(omega, ky)`` where ``1 + L(j omega) = 0`` on the line ``kx = x``, between crossing
        columns ``col`` and ``col + 1`` (``Im((u + x a) conj(b)) = 0``, then ``ky = -Re((u + x a) / b)``)."""
        from scipy.optimize import brentq

        w_ok = self.omega[: self.ng][self.omega[: self.ng] > 0]
        if col < 0 or col + 1 >= w_ok.size:
            return math.nan, math.nan
        w0, w1 = float(w_ok[col]), float(w_ok[col + 1])

        def g(w: float) -> float:
            v = self.fd.point(w)
            return float(((v["u"] + x * v["a"]) * np.conj(v["b"])).imag)

        g0, g1 = g(w0), g(w1)
        if not (np.isfinite(g0) and np.isfinite(g1)) or g0 * g1 > 0:
            return math.nan, math.nan
        w = w0 if g0 == 0 else w1 if g1 == 0 else brentq(g, w0, w1, xtol=1e-14 * w1, rtol=1e-15)
        v = self.fd.point(w)
        return w, float(-((v["u"] + x * v["a"]) / v["b"]).real)

    def _forbidden_at(self, x: float, w: float) -> list[tuple[int, tuple[float, float]]]:
        """Exact union of each constraint's forbidden ``ky`` intervals over the frequency window around ``w``.

        At a crossing of the D-decomposition curve the forbidden interval exists in
        a window of frequencies (possibly far narrower than the grid), and its
        centre can sweep a long way across it (large gains).  The window's edges
        (where the quadratic's discriminant vanishes) are bracketed by a geometric
        walk outward from ``w`` and narrowed by vectorised subdivision; the window is
        then sampled densely, and the union is the hull ``[min lo, max hi]`` (a
        continuous family of intervals over a connected window).  Every stage
        evaluates the exact frequency response at many frequencies in one call.
        """
        out = []
        # offsets of the outward walk: (2^(k+1) - 1) 1e-6 w, k = 0..59, on both sides of w
        steps = (2.0 ** np.arange(1, 61) - 1.0) * 1e-6 * w
        for ci in range(self.nc):
            def width(ws: np.ndarray) -> np.ndarray:
                """``hi - lo`` of the forbidden interval at each frequency (-1 where it does not exist)."""
                ws = np.asarray(ws, dtype=float)
                ok = ws > 0
                res = np.full(ws.shape, -1.0)
                if np.any(ok):
                    vals = self.fd.values(ws[ok])
                    lo = self._roots_at(x, vals, ci, 0)
                    hi = self._roots_at(x, vals, ci, 1)
                    res[ok] = np.where(np.isfinite(lo) & np.isfinite(hi), hi - lo, -1.0)
                return res

            if not width(np.array([w]))[0] > 0:
                continue
            walk = width(np.concatenate([w - steps, w + steps])).reshape(2, -1)
            brackets = []
            for side, row in zip((-1.0, 1.0), walk):
                bad = np.flatnonzero(~(row > 0))
                if bad.size == 0:
                    brackets.append((w + side * steps[-1], None))
                    continue
                k = int(bad[0])
                brackets.append((w + side * steps[k - 1] if k > 0 else w, w + side * steps[k]))
            # narrow each open bracket (inside, outside) 32-fold per round: 4 rounds put the edge within
            # 1e-6 of the walk's last step, far below the 801-point sampling of the window below
            for _ in range(4):
                live = [k for k, (_, o) in enumerate(brackets) if o is not None]
                if not live:
                    break
                pts = np.concatenate([np.linspace(brackets[k][0], brackets[k][1], 33)[1:] for k in live])
                wd = width(pts).reshape(len(live), 32)
                for r, k in enumerate(live):
                    inside, outside = brackets[k]
                    grid = np.linspace(inside, outside, 33)
                    bad = np.flatnonzero(~(wd[r] > 0))
                    j = int(bad[0]) if bad.size else 31
                    brackets[k] = (float(grid[j]), float(grid[j + 1]))
            edges = [inside for inside, _ in brackets]
            ww = np.linspace(min(edges), max(edges), 801)
            vals = self.fd.values(ww)
            lo = self._roots_at(x, vals, ci, 0)
            hi = self._roots_at(x, vals, ci, 1)
            ok = np.isfinite(lo) & np.isfinite(hi)
            if np.any(ok):
                out.append((ci, (float(lo[ok].min()), float(hi[ok].max()))))
        return out

    def _complex_breaks(self, x: np.ndarray) -> list[np.ndarray]:
        return [ys for ys, _, _ in self._complex_breaks_cols(x)]

    def _complex_breaks_cols(self, x: np.ndarray) -> list[tuple[np.ndarray, np.ndarray | None, np.ndarray]]:
        """Per line: the complex-root crossings, (for the curve form) their columns, and their uncertainty."""
        if self.curve_ok:
            rows, ys, cols = self._curve_crossings(self.curve_x, self.curve_y, x)
            err = self._bracket_width(self.curve_y, cols)
            return [(ys[rows == i], cols[rows == i], err[rows == i]) for i in range(x.size)]
        return list(self._complex_breaks_general(x))

    def _complex_breaks_general(self, x: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        ok = self.cross_ok
        U = self.u[None, ok] + x[:, None] * self.a[None, ok]
        b = self.b[None, ok]
        g = (U * b.conj()).imag
        with np.errstate(divide="ignore", invalid="ignore"):
            y = -(U / b).real
        sign = np.sign(g)
        ch = (sign[:, :-1] * sign[:, 1:] < 0) & np.isfinite(y[:, :-1]) & np.isfinite(y[:, 1:])
        out = []
        for i in range(x.size):
            j = np.flatnonzero(ch[i])
            t = g[i, j] / (g[i, j] - g[i, j + 1])
            yy = y[i, j] + t * (y[i, j + 1] - y[i, j])
            # a sign change through a zero of b (y jumps to infinity) is not a crossing
            jump = np.abs(y[i, j + 1] - y[i, j]) > 1e3 * (1.0 + np.minimum(np.abs(y[i, j]), np.abs(y[i, j + 1])))
            keep = ~jump & np.isfinite(yy)
            out.append((yy[keep], j[keep], np.abs(y[i, j + 1] - y[i, j])[keep]))
        exact = np.flatnonzero(np.any(sign == 0, axis=0))  # g exactly zero on a grid point
        for jcol in exact:
            for i in range(x.size):
                if g[i, jcol] == 0 and np.isfinite(y[i, jcol]):
                    ys, c, e = out[i]
                    out[i] = (np.append(ys, y[i, jcol]), np.append(c, -1), np.append(e, 0.0))
        return out

    def lines(self, xs: np.ndarray) -> list[LineData]:
        """Compute :class:`LineData` for each ``x`` in ``xs`` (vectorised over frequency)."""
        xs = np.asarray(xs, dtype=float)
        out: list[LineData] = []
        block = max(1, int(2_000_000 // max(1, self.u.size * max(1, self.nc))))
        for k in range(0, xs.size, block):
            xb = xs[k : k + block]
            f = self._forbidden(xb, range(self.nc))
            total = self._complement(f[0], f[1], f[2:])
            per: list[list[np.ndarray]] = [[] for _ in xb]
            if self.nc > 1:
                for ci in range(self.nc):
                    fc = self._forbidden(xb, [ci])
                    for i, (iv, _) in enumerate(self._complement(fc[0], fc[1], fc[2:])):
                        per[i].append(iv)
            cbr_cols = self._complex_breaks_cols(xb)
            # polish every interval end of the block in one vectorised pass
            flat_ends = [e for _, ends in total for pair in ends for e in pair]
            flat_x = np.concatenate([np.full(2 * len(ends), x) for x, (_, ends) in zip(xb, total)])
            flat_v = np.concatenate([iv.reshape(-1) for iv, _ in total])
            upper = np.concatenate([np.tile([False, True], len(ends)) for _, ends in total])
            polished = self._polish_all(flat_x, flat_ends, flat_v, upper)
            offsets = np.cumsum([0] + [2 * len(ends) for _, ends in total])
            for i, x in enumerate(xb):
                iv, ends = total[i]
                iv = polished[offsets[i] : offsets[i + 1]].reshape(-1, 2).copy()
                # beyond y_valid the grid does not cover the loop's crossover: not verified, not admissible;
                # outside the search window (y_window) nothing is wanted
                y_lo = max(-self.y_valid, self.y_window[0])
                y_hi = min(self.y_valid, self.y_window[1])
                clipped_hi = iv[:, 1] > y_hi
                iv[:, 0] = np.maximum(iv[:, 0], y_lo)
                iv[:, 1] = np.minimum(iv[:, 1], y_hi)
                keep = iv[:, 0] < iv[:, 1]
                ends = [(e[0], None if c else e[1]) for e, c in zip(ends, clipped_hi)]
                iv = iv[keep]
                ends = [e for e, kk in zip(ends, keep) if kk]
                per[i] = [np.clip(p, y_lo, y_hi) for p in per[i]]
                cys, ccols, cerr = cbr_cols[i]
                cys, cerr = cys.copy(), cerr.copy()
                if ccols is not None and cys.size and iv.size:
                    # A crossing of the D-decomposition curve inside an H-infinity-admissible interval: |S| is
                    # infinite there, so (for a constraint that bounds S there) a forbidden interval must
                    # hold it.  The grid can miss that interval when it exists only in a frequency window
                    # narrower than its spacing (large gains move the ellipse fast).  The crossing is refined
                    # exactly, and the exact forbidden intervals at its frequency are cut from the line.
                    inside = np.any((cys[:, None] > iv[None, :, 0]) & (cys[:, None] < iv[None, :, 1]), axis=1)
                    cuts: list[tuple[float, float, Any]] = []
                    for k in np.flatnonzero(inside):
                        wk, yk = self.crossing_frequency(float(x), int(ccols[k]))
                        if math.isfinite(yk):
                            cys[k], cerr[k] = yk, 0.0
                            cuts += [(lo_, hi_, ("cut", ci_, wk)) for ci_, (lo_, hi_) in self._forbidden_at(float(x), wk)]
                    if cuts:
                        iv, ends = _subtract(iv, ends, cuts)
                br = [cys]
                errs = [cerr]
                kinds = [np.full(cys.size, "c")]
                if self.real_coeffs is not None and self.real_coeffs[2] != 0:
                    yr = -(self.real_coeffs[0] + x * self.real_coeffs[1]) / self.real_coeffs[2]
                    br.append(np.array([yr]))
                    errs.append(np.zeros(1))
                    kinds.append(np.array(["r"]))
                yi = self._infinite_breaks(float(x))
                br.append(yi)
                errs.append(np.zeros(yi.size))
                kinds.append(np.full(yi.size, "i"))
                allb = np.concatenate(br)
                alle = np.concatenate(errs)
                allk = np.concatenate(kinds)
                order = np.argsort(allb, kind="stable")
                allb, alle, allk = allb[order], alle[order], allk[order]
                keepb = np.concatenate([[True], np.diff(allb) > 1e-12 * (1 + np.abs(allb[1:]))]) if allb.size else np.zeros(0, bool)
                # Breaks outside the ky window are dropped but for the nearest one beyond each end, so that
                # the segments meeting the window are true D-decomposition cells (a delay loop's curve
                # spirals out and crosses a line thousands of times at gains nobody asked about).
                w_lo, w_hi = self.y_window
                below = np.flatnonzero(keepb & (allb < w_lo))
                above = np.flatnonzero(keepb & (allb > w_hi))
                keepb[below[:-1]] = False
                keepb[above[1:]] = False
                out.append(LineData(float(x), iv, per[i] if self.nc > 1 else [iv], allb[keepb], allk[keepb], ends,
                                    np.full(int(keepb.sum()) + 1, -1, dtype=int), alle[keepb]))
        return out

    # ------------------------------------------------------------------ joining lines
    def horizontal_crossing(self, x0: Any, x1: Any, ys: Any) -> np.ndarray:
        """For each ``y``: does the segment ``(x0, y) - (x1, y)`` cross a D-decomposition boundary?

        ``x0``, ``x1`` and ``ys`` broadcast together (one segment each).
        """
        x0, x1, ys = (np.asarray(v, dtype=float) for v in np.broadcast_arrays(x0, x1, ys))
        x0, x1, ys = x0.ravel(), x1.ravel(), ys.ravel()
        if ys.size == 0:
            return np.zeros(0, dtype=bool)
        lo, hi = np.minimum(x0, x1), np.maximum(x0, x1)
        ok = self.cross_ok
        u, a, b = self.u[ok], self.a[ok], self.b[ok]
        hit = np.zeros(ys.size, dtype=bool)
        block = max(1, int(2_000_000 // max(1, u.size)))
        if self.curve_ok:
            for k in range(0, ys.size, block):
                sl = slice(k, k + block)
                rows, xs, _ = self._curve_crossings(self.curve_y, self.curve_x, ys[sl])
                inside = (xs >= lo[sl][rows]) & (xs <= hi[sl][rows])
                hit[sl] = np.bincount(rows[inside], minlength=ys[sl].size) > 0
        for k in range(0, ys.size, block) if not self.curve_ok else ():
            sl = slice(k, k + block)
            U = u[None, :] + ys[sl, None] * b[None, :]
            g = (U * a.conj()[None, :]).imag
            with np.errstate(divide="ignore", invalid="ignore"):
                xx = -(U / a[None, :]).real
                t = g[:, :-1] / (g[:, :-1] - g[:, 1:])
            sign = np.sign(g)
            ch = (sign[:, :-1] * sign[:, 1:] <= 0) & np.isfinite(xx[:, :-1]) & np.isfinite(xx[:, 1:])
            t = np.where(np.isfinite(t), t, 0.0)
            xc = xx[:, :-1] + t * (xx[:, 1:] - xx[:, :-1])
            jump = np.abs(xx[:, 1:] - xx[:, :-1]) > 1e3 * (1.0 + np.minimum(np.abs(xx[:, :-1]), np.abs(xx[:, 1:])))
            hit[sl] = np.any(ch & ~jump & (xc >= lo[sl, None]) & (xc <= hi[sl, None]), axis=1)
        if self.real_coeffs is not None:
            r0 = self.real_value(x0, ys)
            r1 = self.real_value(x1, ys)
            hit |= (np.sign(r0) != np.sign(r1)) | (r0 == 0) | (r1 == 0)
        if self.lead_varies:
            f0 = self.infinite_value(x0, ys)
            f1 = self.infinite_value(x1, ys)
            hit |= (np.sign(f0) != np.sign(f1)) | (f0 == 0) | (f1 == 0)
        return hit


# ---------------------------------------------------------------------- union-find
class _Components:
    def __init__(self) -> None:
        self.parent: list[int] = []
        self.label: dict[int, bool | None] = {}
        self.point: dict[int, tuple[float, float]] = {}

    def new(self) -> int:
        self.parent.append(len(self.parent))
        return len(self.parent) - 1

    def find(self, i: int) -> int:
        while self.parent[i] != i:
            self.parent[i] = self.parent[self.parent[i]]
            i = self.parent[i]
        return i

    def union(self, i: int, j: int) -> None:
        ri, rj = self.find(i), self.find(j)
        if ri == rj:
            return
        li, lj = self.label.get(ri), self.label.get(rj)
        self.parent[rj] = ri
        if li is None and lj is not None:
            self.label[ri] = lj
            self.point[ri] = self.point[rj]


# ---------------------------------------------------------------------- the region
class Region:
    """Admissible controllers in a gain plane: H-infinity regions intersected with the stability region.

    Built by :func:`posicast.tune_pd` and friends (``result.region``).  The plane
    has the scanned gain :attr:`x_name` horizontally and the maximised gain
    :attr:`y_name` vertically; :attr:`x` are the scan lines (spacing
    :attr:`spacing`).  On each line the admissible ``ky`` set is exact up to the
    frequency grid (see the module docstring), so the region is resolved to the
    line spacing in ``kx``.

    Attributes
    ----------
    x_name, y_name : str
    x : ndarray
        The scan lines.
    spacing : float
    constraints : tuple of Constraint
    empty : bool
        No admissible stable controller on any line.
    """

    def __init__(self, engine: _Engine, family: ControllerFamily, lines: list[LineData],
                 comps: _Components, y_range: tuple[float, float]) -> None:
        self._engine = engine
        self.family = family
        self.x_name, self.y_name = family.x, family.y
        self._lines = lines
        self._comps = comps
        self.y_range = y_range
        self.constraints = engine.fd.constraints
        self.x = np.array([ln.x for ln in lines])
        self.spacing = float(np.median(np.diff(self.x))) if self.x.size > 1 else 0.0
        self._admissible: list[np.ndarray] | None = None

    # ------------------------------------------------------------------ labels
    def _label(self, cid: int, x: float, y: float) -> bool | None:
        root = self._comps.find(cid)
        if root in self._comps.label:
            return self._comps.label[root]
        eng = self._engine
        eng.stability_calls += 1
        lab = _certified_stability(eng.loop_factory(x, y))
        if isinstance(lab, str):
            eng.stability_failures.append(f"({self.x_name}={x:.6g}, {self.y_name}={y:.6g}): {lab}")
            lab = None
        self._comps.label[root] = lab
        self._comps.point[root] = (x, y)
        return lab

    def _segment_label(self, i: int, j: int, y: float) -> bool | None:
        ln = self._lines[i]
        return self._label(int(ln.comp[j]), ln.x, y)

    def _line(self, i: Any) -> int:
        """``i`` as a line index (TypeError/ValueError naming ``i``)."""
        if isinstance(i, (bool, np.bool_)) or not isinstance(i, (int, np.integer)):
            raise TypeError(f"i must be a line index (int), got {type(i).__name__}")
        if not 0 <= i < len(self._lines):
            raise ValueError(f"i must be a line index in [0, {len(self._lines) - 1}], got {i}")
        return int(i)

    def _constraint_index(self, constraint: Any) -> int | None:
        if constraint is None:
            return None
        if isinstance(constraint, (bool, np.bool_)) or not isinstance(constraint, (int, np.integer)):
            raise TypeError(f"constraint must be None or a constraint index (int), got {type(constraint).__name__}")
        if not 0 <= constraint < len(self.constraints):
            raise ValueError(f"constraint must be an index in [0, {len(self.constraints) - 1}], got {constraint}")
        return int(constraint)

    def admissible_intervals(self, i: int) -> np.ndarray:
        """Admissible ``ky`` intervals on line ``i`` (H-infinity and stable), clipped to ``y_range``."""
        i = self._line(i)
        if self._admissible is None:
            self._admissible = [None] * len(self._lines)  # type: ignore[list-item]
        cached = self._admissible[i]
        if cached is not None:
            return cached
        out = [(a, b) for a, b, j in self.pieces(i) if self._segment_label(i, j, _interval_point(a, b))]
        arr = np.array(out, dtype=float).reshape(-1, 2)
        self._admissible[i] = arr
        return arr

    def pieces(self, i: int) -> list[tuple[float, float, int]]:
        """H-infinity-admissible pieces of line ``i`` within ``y_range``, split at the breaks: ``(lo, hi, segment)``."""
        ln = self._lines[self._line(i)]
        out = []
        for lo, hi in _intersect(ln.hinf, np.array([self.y_range])):
            inner = ln.breaks[(ln.breaks > lo) & (ln.breaks < hi)]
            edges = np.concatenate([[lo], inner, [hi]])
            for a, b in zip(edges[:-1], edges[1:]):
                if a < b:
                    out.append((float(a), float(b), int(np.searchsorted(ln.breaks, _interval_point(a, b)))))
        return out

    def best(self) -> tuple[int, float, float] | None:
        """The admissible piece with the largest upper end: ``(line, lo, hi)``, or None.

        Pieces are checked best-first, so only the cells needed to decide the
        maximum get a spectrum check.
        """
        cand = [(hi, i, lo, j) for i in range(len(self._lines)) for lo, hi, j in self.pieces(i)]
        cand.sort(key=lambda t: -t[0])
        for hi, i, lo, j in cand:
            if self._segment_label(i, j, _interval_point(lo, hi)):
                return i, lo, hi
        return None

    def component_lines(self, i: int, y: float) -> np.ndarray:
        """Indices of the lines holding a segment of the same joined component as ``(x[i], y)``."""
        ln = self._lines[i]
        root = self._comps.find(int(ln.comp[int(np.searchsorted(ln.breaks, y))]))
        return np.array([k for k, other in enumerate(self._lines)
                         if any(self._comps.find(int(c)) == root for c in other.comp if c >= 0)], dtype=int)

    def hinf_intervals(self, i: int, constraint: int | None = None) -> np.ndarray:
        """H-infinity-admissible ``ky`` intervals on line ``i`` (all constraints, or one), stability ignored."""
        ln = self._lines[self._line(i)]
        constraint = self._constraint_index(constraint)
        return ln.hinf if constraint is None else ln.per_constraint[constraint]

    def default_window(self) -> tuple[float, float]:
        """The ``ky`` window shown and labelled by default: the admissible extent with half its height
        either side (or ``y_range``), within the verified gains ``|ky| <= y_valid``."""
        yv = self._engine.y_valid
        ext = self.extent()
        if ext is not None and math.isfinite(ext[2]) and math.isfinite(ext[3]):
            pad = 0.5 * max(ext[3] - ext[2], 1e-12)
            lo, hi = ext[2] - pad, ext[3] + pad
        else:
            lo, hi = self.y_range
        return max(lo, self.y_range[0], -yv), min(hi, self.y_range[1], yv)

    def stable_intervals(self, i: int, window: tuple[float, float] | None = None) -> np.ndarray:
        """Stable ``ky`` intervals on line ``i`` within ``window`` (default :meth:`default_window`).

        One certified spectrum check per D-decomposition cell not yet checked; the
        window keeps the checks to gains of interest (far out, a delay loop has
        thousands of roots in the search region).
        """
        ln = self._lines[self._line(i)]
        if window is not None:
            if isinstance(window, (str, bytes)) or not hasattr(window, "__len__") or len(window) != 2:
                raise TypeError(f"window must be a (low, high) pair or None, got {type(window).__name__}")
            window = (v.finite_real(window[0], "window[0]"), v.finite_real(window[1], "window[1]"))
        w_lo, w_hi = self.default_window() if window is None else window
        # beyond the engine's ky window the segments are not D-decomposition cells (breaks were dropped)
        w_lo, w_hi = max(w_lo, self._engine.y_window[0]), min(w_hi, self._engine.y_window[1])
        out = []
        for j in range(ln.n_segments):
            lo, hi = ln.segment_bounds(j)
            lo, hi = max(lo, w_lo), min(hi, w_hi)
            if lo < hi and self._segment_label(i, j, _interval_point(lo, hi)):
                out.append((lo, hi))
        return np.array(out, dtype=float).reshape(-1, 2)

    # ------------------------------------------------------------------ queries
    @property
    def empty(self) -> bool:
        return all(self.admissible_intervals(i).size == 0 for i in range(len(self._lines)))

    def top(self, i: int) -> float:
        """Largest admissible ``ky`` on line ``i`` (``-inf`` if none)."""
        i = self._line(i)
        iv = self.admissible_intervals(i)
        return float(iv[:, 1].max()) if iv.size else -_INF

    def contains(self, kx: Any, ky: Any) -> np.ndarray:
        """Admissible (H-infinity and stable)?  Nearest-line classification.

        A point between two lines is judged on the nearest line at the same
        ``ky``: a misclassified point is at most half a line spacing (in ``kx``)
        from the true boundary.
        """
        kx = v.strict_real_array(kx, "kx", allow_empty=True)
        ky = v.strict_real_array(ky, "ky", allow_empty=True)
        try:
            kx, ky = np.broadcast_arrays(kx, ky)
        except ValueError:
            raise ValueError(f"kx and ky must broadcast together, got shapes {kx.shape} and {ky.shape}") from None
        if self.x.size == 0:  # no line scanned (a loop refused before the scan): nothing is admissible
            return np.zeros(kx.shape, dtype=bool)
        idx = np.clip(np.searchsorted(self.x, kx), 1, max(self.x.size - 1, 1))
        if self.x.size > 1:
            left = self.x[idx - 1]
            idx = np.where(np.abs(kx - left) <= np.abs(self.x[np.minimum(idx, self.x.size - 1)] - kx), idx - 1, idx)
        else:
            idx = np.zeros(kx.shape, dtype=int)
        out = np.zeros(kx.shape, dtype=bool)
        inside_x = (kx >= self.x[0] - 0.5 * self.spacing) & (kx <= self.x[-1] + 0.5 * self.spacing)
        for i in np.unique(idx):
            sel = (idx == i) & inside_x
            iv = self.admissible_intervals(int(i))
            if iv.size:
                yy = ky[sel]
                out[sel] = np.any((yy[:, None] > iv[None, :, 0]) & (yy[:, None] < iv[None, :, 1]), axis=1)
        return out

    def extent(self) -> tuple[float, float, float, float] | None:
        """``(x_min, x_max, y_min, y_max)`` of the admissible set, or None if empty."""
        xs, ylo, yhi = [], [], []
        for i, ln in enumerate(self._lines):
            iv = self.admissible_intervals(i)
            if iv.size:
                xs.append(ln.x)
                ylo.append(iv[:, 0].min())
                yhi.append(iv[:, 1].max())
        if not xs:
            return None
        return min(xs), max(xs), min(ylo), max(yhi)

    def area(self) -> float:
        """Area of the admissible set (line sum; ``inf`` if unbounded)."""
        tot = 0.0
        for i in range(len(self._lines)):
            iv = self.admissible_intervals(i)
            tot += float(np.sum(iv[:, 1] - iv[:, 0])) if iv.size else 0.0
        return tot * self.spacing

    @property
    def stability_checks(self) -> int:
        """Certified spectrum checks made so far (one per D-decomposition component)."""
        return self._engine.stability_calls

    def _intervals(self, i: int, what: str, constraint: int | None, y: np.ndarray) -> np.ndarray:
        """Line ``i``'s ``'admissible'``, ``'hinf'`` or ``'stable'`` intervals (stable: within ``y``'s span)."""
        v.choice(what, "what", ("admissible", "hinf", "stable"))
        if what == "admissible":
            return self.admissible_intervals(i)
        if what == "hinf":
            return self.hinf_intervals(i, constraint)
        if what == "stable":
            return self.stable_intervals(i, (float(y.min()), float(y.max())) if y.size else None)
        raise ValueError(f"what must be 'admissible', 'hinf' or 'stable', got {what!r}")

    def _grid_args(self, y: Any, what: Any, constraint: Any) -> tuple[np.ndarray, int | None]:
        y = v.strict_real_array(y, "y", allow_empty=True)
        if y.ndim != 1:
            raise ValueError(f"y must be a 1-D array of gains, got shape {y.shape}")
        v.choice(what, "what", ("admissible", "hinf", "stable"))
        return y, self._constraint_index(constraint)

    def mask(self, y: np.ndarray, what: str = "admissible", constraint: int | None = None) -> np.ndarray:
        """Membership on the grid ``lines x y``: ``'admissible'``, ``'hinf'`` or ``'stable'``."""
        y, constraint = self._grid_args(y, what, constraint)
        out = np.zeros((self.x.size, y.size), dtype=bool)
        for i in range(self.x.size):
            iv = self._intervals(i, what, constraint, y)
            if iv.size:
                out[i] = np.any((y[:, None] > iv[None, :, 0]) & (y[:, None] < iv[None, :, 1]), axis=1)
        return out

    def field(self, y: np.ndarray, what: str = "admissible", constraint: int | None = None) -> np.ndarray:
        """Signed distance in ``ky`` to the set's boundary on each line (positive inside), on ``lines x y``.

        Its zero contour joins the exact interval ends of neighbouring lines by
        straight segments: a smooth drawing of the region instead of the
        staircase of :meth:`mask`.
        """
        y, constraint = self._grid_args(y, what, constraint)
        span = float(np.ptp(y)) if y.size > 1 else 1.0
        out = np.full((self.x.size, y.size), -span)
        for i in range(self.x.size):
            iv = self._intervals(i, what, constraint, y)
            if iv.size:
                lo = np.where(np.isfinite(iv[:, 0]), iv[:, 0], -1e300)
                hi = np.where(np.isfinite(iv[:, 1]), iv[:, 1], 1e300)
                d = np.minimum(y[:, None] - lo[None, :], hi[None, :] - y[:, None]).max(axis=1)
                out[i] = np.clip(d, -span, span)
        return out

    def plot(self, ax: Any = None, **kwargs: Any) -> tuple[Any, Any]:
        """Draw the region (see :func:`posicast.tune.region_plot`)."""
        from .plots import region_plot

        return region_plot(self, ax=ax, **kwargs)

    def __repr__(self) -> str:
        ext = self.extent()
        where = "empty" if ext is None else (
            f"{self.x_name} in [{ext[0]:.4g}, {ext[1]:.4g}], {self.y_name} in [{ext[2]:.4g}, {ext[3]:.4g}]")
        return f"Region({self.x.size} lines, spacing {self.spacing:.3g}; admissible: {where})"


def join_lines(engine: _Engine, lines: list[LineData], comps: _Components,
               wanted: Callable[[int], np.ndarray] | None = None) -> None:
    """Assign component ids to the segments of ``lines`` and join adjacent ones without a crossing.

    ``wanted(i)`` is a boolean mask over line ``i``'s segments limiting the joins
    to segments of interest (default: all).  All the crossing checks go to one
    vectorised call.
    """
    for ln in lines:
        for j in range(ln.n_segments):
            if ln.comp[j] < 0:
                ln.comp[j] = comps.new()
    masks = [wanted(i) if wanted is not None else np.ones(ln.n_segments, dtype=bool) for i, ln in enumerate(lines)]
    pairs: list[tuple[int, int, int]] = []
    x0s, x1s, ys = [], [], []
    for i in range(len(lines) - 1):
        A, B = lines[i], lines[i + 1]
        ma, mb = masks[i], masks[i + 1]
        if not (ma.any() and mb.any()):
            continue
        ja = jb = 0
        while ja < A.n_segments and jb < B.n_segments:
            alo, ahi = A.segment_bounds(ja)
            blo, bhi = B.segment_bounds(jb)
            lo, hi = max(alo, blo), min(ahi, bhi)
            if lo < hi and ma[ja] and mb[jb]:
                # the overlap's ends are breaks known to within their uncertainty: join only through
                # its certain part (a skipped join costs one more spectrum check, never a wrong label)
                e_lo = max(A.error_at(lo), B.error_at(lo))
                e_hi = max(A.error_at(hi), B.error_at(hi))
                if lo + e_lo < hi - e_hi:
                    pairs.append((i, ja, jb))
                    x0s.append(A.x)
                    x1s.append(B.x)
                    ys.append(_interval_point(lo + e_lo, hi - e_hi))
            if ahi <= bhi:
                ja += 1
            else:
                jb += 1
    if not pairs:
        return
    hit = engine.horizontal_crossing(np.array(x0s), np.array(x1s), np.array(ys))
    for (i, ja, jb), h in zip(pairs, hit):
        if not h:
            comps.union(int(lines[i].comp[ja]), int(lines[i + 1].comp[jb]))
