"""D-decomposition boundaries in the gain plane (seed 001 section 3, step 5 of Algorithm 1).

The closed-loop characteristic quasi-polynomial ``dC D_P + (n0 + kx nx + ky ny) N_P``
has a root on the imaginary axis where the gains cross a boundary:

* complex-root boundary (:class:`ComplexCurve`): ``1 + L(j omega) = 0`` for some
  ``omega > 0``, i.e. ``Im(U conj b) = 0`` with ``U = u + kx a``, at
  ``ky = -Re(U / b)``;
* real-root boundary (:class:`RealBoundary`): the lowest Taylor coefficient at
  ``s = 0`` that is not identically zero (a distributed shaper's removable root at
  0 is skipped);
* infinite-root boundary (:class:`InfiniteBoundary`): where the leading
  coefficients change the type (degree drop) or, for neutral loops, where the
  difference operator stops being strongly stable (``sum |d_k| = 1``, the test
  :func:`posicast.stability` applies).

On a scan line these are the *breaks* (:class:`BreakKind`); between two lines,
:func:`horizontal_crossing` says whether a horizontal path crosses any of them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum
from typing import Any, NamedTuple

import numpy as np
from scipy.optimize import brentq

from ..core.quasipoly import QuasiPolynomial
from .frequency import Columns

__all__ = ["BreakKind", "RealBoundary", "InfiniteBoundary", "ComplexCurve", "ComplexBreaks", "real_boundary",
           "infinite_boundary", "complex_curve", "complex_breaks", "crossing_frequency", "horizontal_crossing"]


class BreakKind(str, Enum):
    """Which boundary a scan line crosses at a break (stored as its one-letter value)."""

    COMPLEX = "c"  #: a pair of roots crosses the imaginary axis at +-j omega, omega > 0
    REAL = "r"  #: a real root crosses at s = 0
    INFINITE = "i"  #: roots come from or go to infinity (degree drop, strong stability lost)


# ---------------------------------------------------------------------- s = 0
@dataclass(frozen=True)
class RealBoundary:
    """``t(kx, ky) = T0 + kx Tx + ky Ty``: the Taylor coefficient of the characteristic at s = 0.

    ``coeffs`` is None when it vanishes for every gain (``structural``): every
    controller of the family then leaves a genuine closed-loop pole at s = 0.
    """

    coeffs: tuple[float, float, float] | None

    @property
    def structural(self) -> bool:
        return self.coeffs is None

    def value(self, x: Any, y: Any) -> Any:
        T0, Tx, Ty = self.coeffs if self.coeffs is not None else (0.0, 0.0, 0.0)
        return T0 + np.asarray(x) * Tx + np.asarray(y) * Ty

    def break_at(self, x: float) -> float | None:
        """The line ``kx = x``'s crossing ``ky``, or None (no boundary, or parallel to the line)."""
        if self.coeffs is None or self.coeffs[2] == 0:
            return None
        return -(self.coeffs[0] + x * self.coeffs[1]) / self.coeffs[2]


def real_boundary(terms: tuple[QuasiPolynomial, ...], m0: int) -> RealBoundary:
    """The coefficient of order ``m0`` at s = 0 of ``terms`` (the characteristic's parts ``1, kx, ky``).

    ``m0`` is the multiplicity of the shaper's removable root at 0 (a root of the
    characteristic for every gain, cancelled from the poles).
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
    return RealBoundary(None if not any(vals) else vals)  # type: ignore[arg-type]


# ---------------------------------------------------------------------- s = infinity
@dataclass(frozen=True)
class InfiniteBoundary:
    """Leading coefficients of the characteristic, affine in the gains, per delay.

    ``lead`` is (3, k): the parts ``1, kx, ky`` of the coefficient of ``s^n`` at
    each of the ``k`` delays ``lead_delays`` (row 0 of the characteristic: the
    smallest delay present for generic gains).
    """

    lead: np.ndarray
    lead_delays: np.ndarray

    @property
    def neutral_possible(self) -> bool:
        return self.lead.shape[1] > 1

    @property
    def lead_varies(self) -> bool:
        return bool(np.any(self.lead[1:] != 0))

    def value(self, x: Any, y: Any) -> Any:
        """``sum_{k>0} |d_k| - |d_0|`` (neutral) or ``d_0`` (retarded): its sign flips at the boundary."""
        x, y = np.broadcast_arrays(np.atleast_1d(np.asarray(x, dtype=float)), np.atleast_1d(np.asarray(y, dtype=float)))
        L = self.lead[0][:, None] + self.lead[1][:, None] * x[None, :] + self.lead[2][:, None] * y[None, :]
        if not self.neutral_possible:
            return L[0]
        return np.sum(np.abs(L[1:]), axis=0) - np.abs(L[0])

    def breaks(self, x: float) -> np.ndarray:
        """The ``ky`` where the line ``kx = x`` crosses the boundary, sorted."""
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


def infinite_boundary(terms: tuple[QuasiPolynomial, ...]) -> InfiniteBoundary:
    """The leading coefficients of ``terms`` (the characteristic's parts ``1, kx, ky``) per delay."""
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
    return InfiniteBoundary(lead[:, keep], delays[keep])


# ---------------------------------------------------------------------- 1 + L(j omega) = 0
@dataclass(frozen=True)
class ComplexCurve:
    """The complex-root boundary as a curve: ``1 + L(j omega) = 0`` at ``(kx, ky) = (x(omega), y(omega))``.

    ``cross_ok`` marks the columns usable for crossings (finite grid, ``omega > 0``);
    ``ok`` says the curve form is usable (no column where ``a`` and ``b`` are
    (nearly) real multiples of each other), else crossings are found line by line.
    """

    cross_ok: np.ndarray
    x: np.ndarray
    y: np.ndarray
    ok: bool
    _lines: dict[str, _Polyline] = field(default_factory=dict, repr=False, compare=False)

    def polyline(self, along: str) -> _Polyline:
        """The curve's segments for crossings of ``along = level`` (``'x'`` or ``'y'``), made once."""
        if along not in self._lines:
            self._lines[along] = _polyline(self.x, self.y) if along == "x" else _polyline(self.y, self.x)
        return self._lines[along]


def complex_curve(cols: Columns) -> ComplexCurve:
    """Cramer's rule on ``u + kx a + ky b = 0`` (real and imaginary parts) at every usable column."""
    cross_ok = np.zeros(cols.u.size, dtype=bool)
    cross_ok[: cols.n_grid] = cols.omega > 0
    u, a, b = cols.u[cross_ok], cols.a[cross_ok], cols.b[cross_ok]
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        det = a.real * b.imag - a.imag * b.real
        curve_x = (-u.real * b.imag + u.imag * b.real) / det
        curve_y = (-a.real * u.imag + a.imag * u.real) / det
    scale = np.abs(a) * np.abs(b)
    ok = bool(np.all(np.abs(det) > 1e-12 * scale) and np.all(np.isfinite(curve_x)) and np.all(np.isfinite(curve_y)))
    return ComplexCurve(cross_ok, curve_x, curve_y, ok)


class _Polyline(NamedTuple):
    """The curve's usable segments in one orientation, for :func:`_curve_crossings`: the coordinate
    crossed (``along``) and the other one (``across``), the segments not across a jump (a pole of the
    curve), the closed span of ``along`` over each, and a span of ``across`` that holds every crossing
    value :func:`_curve_crossings` can compute on the segment (the closed span, widened by 1e-14 of the
    segment's size for the interpolation's rounding)."""

    along: np.ndarray
    across: np.ndarray
    seg: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    across_lo: np.ndarray
    across_hi: np.ndarray


def _polyline(c_along: np.ndarray, c_across: np.ndarray) -> _Polyline:
    p, q = c_along[:-1], c_along[1:]
    jump = np.abs(c_across[1:] - c_across[:-1]) > 1e3 * (1.0 + np.minimum(np.abs(c_across[:-1]), np.abs(c_across[1:])))
    jump |= np.abs(q - p) > 1e3 * (1.0 + np.minimum(np.abs(p), np.abs(q)))
    seg = np.flatnonzero(~jump & ~np.isnan(p) & ~np.isnan(q))
    c0, c1 = c_across[seg], c_across[seg + 1]
    pad = 1e-14 * np.maximum(np.abs(c0), np.abs(c1))
    return _Polyline(c_along, c_across, seg, np.minimum(p[seg], q[seg]), np.maximum(p[seg], q[seg]),
                     np.minimum(c0, c1) - pad, np.maximum(c0, c1) + pad)


def _curve_crossings(line: _Polyline, level: np.ndarray, ordered: bool = True,
                     across: tuple[float, float] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where the polyline ``(line.along, line.across)`` crosses ``along = level``: (row, value across, column).

    A segment ``j`` crosses level ``i`` when ``(along[j] - level[i])`` and ``(along[j + 1] - level[i])``
    do not have the same strict sign, i.e. the level lies in the segment's closed span; segments across
    a jump (a pole of the curve) are skipped.  The levels are sorted once and each segment's span is
    located among them by binary search, so the cost grows with the number of segments and of
    crossings, not with their product.  Sorted by row, then column (``ordered``; else in no particular
    order).  With ``across = (lo, hi)``, only the segments that can give a value in ``[lo, hi]``: every
    crossing with its value there, and perhaps others.
    """
    level = np.asarray(level, dtype=float)
    c_along, c_across, seg = line.along, line.across, line.seg
    order = np.argsort(level, kind="stable")
    order = order[~np.isnan(level[order])]
    sl = level[order]
    seg_lo, seg_hi = line.lo, line.hi
    if sl.size:  # only the segments whose span meets the levels' range (issue #15: a lumped shaper's curve
        # has ~10^5 segments, most of them far out, and the binary searches cost more than this test)
        near = (seg_hi >= sl[0]) & (seg_lo <= sl[-1])
        if across is not None:
            near &= (line.across_hi >= across[0]) & (line.across_lo <= across[1])
        near = np.flatnonzero(near)
        seg, seg_lo, seg_hi = seg[near], seg_lo[near], seg_hi[near]
    start = np.searchsorted(sl, seg_lo, side="left")
    count = np.searchsorted(sl, seg_hi, side="right") - start
    count = np.maximum(count, 0)
    cols = np.repeat(seg, count)
    first = np.repeat(np.cumsum(count) - count, count)
    rank = np.repeat(start, count) + (np.arange(cols.size) - first)
    rows = order[rank]
    d0 = c_along[cols] - level[rows]
    d1 = c_along[cols + 1] - level[rows]
    with np.errstate(invalid="ignore", divide="ignore"):
        t = d0 / (d0 - d1)
    t = np.where(np.isfinite(t), t, 0.0)
    val = c_across[cols] + t * (c_across[cols + 1] - c_across[cols])
    if not ordered:
        return rows, val, cols
    # the columns are already ascending (segment by segment): a stable sort by row keeps them so
    srt = np.argsort(rows, kind="stable")
    return rows[srt], val[srt], cols[srt]


def _split_rows(rows: np.ndarray, m: int) -> list[slice]:
    """For row indices sorted ascending, the slice of each row ``0 .. m - 1``."""
    edges = np.searchsorted(rows, np.arange(m + 1))
    return [slice(int(edges[i]), int(edges[i + 1])) for i in range(m)]


class ComplexBreaks(NamedTuple):
    """One line's complex-root crossings ``ky``, the crossing columns (-1: exactly on a column; None
    when not known) and the uncertainty of each (the bracket's width in ``ky``)."""

    ky: np.ndarray
    columns: np.ndarray | None
    error: np.ndarray


def complex_breaks(cols: Columns, curve: ComplexCurve, x: np.ndarray,
                   window: tuple[float, float] | None = None) -> list[ComplexBreaks]:
    """Per line ``kx = x[i]``: the complex-root crossings, interpolated between grid columns.

    With ``window = (lo, hi)`` (and the curve form usable), a line's crossings are those from ``lo`` down
    to the nearest one below it and from ``hi`` up to the nearest one above it (each, if there is one), and
    perhaps others: what :func:`~posicast.tune.scan.scan_lines` keeps of a line's crossings (issue #15: with a lumped
    shaper the curve crosses each line ~2000 times, nearly all of them at gains far outside the window).
    """
    if not curve.ok:
        return _complex_breaks_general(cols, curve, x)
    if window is None or not (np.isfinite(window[0]) and np.isfinite(window[1])):
        return _breaks_of(curve, *_curve_crossings(curve.polyline("x"), x), x.size)
    return _windowed_breaks(curve, x, float(window[0]), float(window[1]))


def _breaks_of(curve: ComplexCurve, rows: np.ndarray, ys: np.ndarray, cc: np.ndarray, m: int) -> list[ComplexBreaks]:
    err = np.abs(curve.y[cc + 1] - curve.y[cc])
    return [ComplexBreaks(ys[k], cc[k], err[k]) for k in _split_rows(rows, m)]


#: a curve with fewer segments than this is crossed whole (windowing would cost more than it saves)
_WINDOWED_ABOVE = 8000


def _windowed_breaks(curve: ComplexCurve, x: np.ndarray, lo: float, hi: float) -> list[ComplexBreaks]:
    """:func:`complex_breaks` with a window: the crossings within a band ``[lo - M, hi + M]``, ``M`` the
    window's width, then ten times wider for the lines whose nearest crossing below ``lo`` or above ``hi``
    is not inside the band clear of its edge (1e-9 relative: the scan's duplicate test must see the same
    neighbours), while the band holds at most a quarter of the curve's segments; then, for the lines still
    pending, all of their crossings.  A small curve is crossed whole at once."""
    line = curve.polyline("x")
    out: list[ComplexBreaks | None] = [None] * x.size
    pending = np.arange(x.size)
    width = max(hi - lo, 1e-300)
    while pending.size and line.seg.size >= _WINDOWED_ABOVE:
        b_lo, b_hi = lo - width, hi + width
        if np.count_nonzero((line.across_hi >= b_lo) & (line.across_lo <= b_hi)) > 0.25 * line.seg.size:
            break
        rows, ys, cc = _curve_crossings(line, x[pending], across=(b_lo, b_hi))
        # per line, the nearest crossing below lo and above hi, and whether each is clear of the band's edge
        nearest_below = np.full(pending.size, -np.inf)
        np.maximum.at(nearest_below, rows[ys < lo], ys[ys < lo])
        nearest_above = np.full(pending.size, np.inf)
        np.minimum.at(nearest_above, rows[ys > hi], ys[ys > hi])
        with np.errstate(invalid="ignore"):
            done = ((nearest_below - b_lo > 1e-9 * (1.0 + np.abs(nearest_below)))
                    & (b_hi - nearest_above > 1e-9 * (1.0 + np.abs(nearest_above))))
        for i, b, ok in zip(pending, _breaks_of(curve, rows, ys, cc, pending.size), done):
            if ok:
                out[i] = b
        pending = pending[~done]
        width *= 10.0
    if pending.size:
        for i, b in zip(pending, _breaks_of(curve, *_curve_crossings(line, x[pending]), pending.size)):
            out[i] = b
    return out  # type: ignore[return-value]


def _complex_breaks_general(cols: Columns, curve: ComplexCurve, x: np.ndarray) -> list[ComplexBreaks]:
    """Sign changes of ``Im(U conj b)`` along each line (the curve form is not usable)."""
    ok = curve.cross_ok
    U = cols.u[None, ok] + x[:, None] * cols.a[None, ok]
    b = cols.b[None, ok]
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
        out.append(ComplexBreaks(yy[keep], j[keep], np.abs(y[i, j + 1] - y[i, j])[keep]))
    exact = np.flatnonzero(np.any(sign == 0, axis=0))  # g exactly zero on a grid point
    for jcol in exact:
        for i in range(x.size):
            if g[i, jcol] == 0 and np.isfinite(y[i, jcol]):
                ys, c, e = out[i]
                out[i] = ComplexBreaks(np.append(ys, y[i, jcol]), np.append(c, -1), np.append(e, 0.0))
    return out


def crossing_frequency(cols: Columns, x: float, col: int) -> tuple[float, float]:
    """Exact ``(omega, ky)`` where ``1 + L(j omega) = 0`` on the line ``kx = x``, between crossing
    columns ``col`` and ``col + 1`` (``Im((u + x a) conj(b)) = 0``, then ``ky = -Re((u + x a) / b)``)."""
    w_ok = cols.omega[: cols.n_grid][cols.omega[: cols.n_grid] > 0]
    if col < 0 or col + 1 >= w_ok.size:
        return math.nan, math.nan
    w0, w1 = float(w_ok[col]), float(w_ok[col + 1])

    def g(w: float) -> float:
        v = cols.data.point(w)
        return float(((v["u"] + x * v["a"]) * np.conj(v["b"])).imag)

    g0, g1 = g(w0), g(w1)
    if not (np.isfinite(g0) and np.isfinite(g1)) or g0 * g1 > 0:
        return math.nan, math.nan
    w = w0 if g0 == 0 else w1 if g1 == 0 else brentq(g, w0, w1, xtol=1e-14 * w1, rtol=1e-15)
    v = cols.data.point(w)
    return w, float(-((v["u"] + x * v["a"]) / v["b"]).real)


# ---------------------------------------------------------------------- between two lines
def _curve_hits(cols: Columns, curve: ComplexCurve, lo: np.ndarray, hi: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Does the horizontal segment ``[lo, hi] x {y}`` cross the complex-root boundary?"""
    ok = curve.cross_ok
    hit = np.zeros(ys.size, dtype=bool)
    block = max(1, int(2_000_000 // max(1, int(np.count_nonzero(ok)))))
    if curve.ok:
        for k in range(0, ys.size, block):
            sl = slice(k, k + block)
            if not ys[sl].size:
                continue
            # only the segments that can cross inside some [lo, hi] (issue #15; NaN ends are never inside)
            a, b = float(np.fmin.reduce(lo[sl])), float(np.fmax.reduce(hi[sl]))
            rows, xs, _ = _curve_crossings(curve.polyline("y"), ys[sl], ordered=False,
                                           across=(a, b) if a == a and b == b else None)
            inside = (xs >= lo[sl][rows]) & (xs <= hi[sl][rows])
            hit[sl] = np.bincount(rows[inside], minlength=ys[sl].size) > 0
        return hit
    u, a, b = cols.u[ok], cols.a[ok], cols.b[ok]
    for k in range(0, ys.size, block):
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
    return hit


def horizontal_crossing(cols: Columns, curve: ComplexCurve, real: RealBoundary, infinite: InfiniteBoundary,
                        x0: Any, x1: Any, ys: Any) -> np.ndarray:
    """For each ``y``: does the segment ``(x0, y) - (x1, y)`` cross a D-decomposition boundary?

    ``x0``, ``x1`` and ``ys`` broadcast together (one segment each).
    """
    x0, x1, ys = (np.asarray(v, dtype=float) for v in np.broadcast_arrays(x0, x1, ys))
    x0, x1, ys = x0.ravel(), x1.ravel(), ys.ravel()
    if ys.size == 0:
        return np.zeros(0, dtype=bool)
    hit = _curve_hits(cols, curve, np.minimum(x0, x1), np.maximum(x0, x1), ys)
    if real.coeffs is not None:
        r0 = real.value(x0, ys)
        r1 = real.value(x1, ys)
        hit |= (np.sign(r0) != np.sign(r1)) | (r0 == 0) | (r1 == 0)
    if infinite.lead_varies:
        f0 = infinite.value(x0, ys)
        f1 = infinite.value(x1, ys)
        hit |= (np.sign(f0) != np.sign(f1)) | (f0 == 0) | (f1 == 0)
    return hit
