"""Frequency branches near an admissible interval's ends, refined and followed exactly.

An end of an admissible ``ky`` interval is the extremum over frequency of one
root of one constraint's quadratic (a :class:`~posicast.tune.hinf.Branch`).
Near the optimum several branches may be nearly active at once, so the optimum
search (:mod:`posicast.tune.optimum`) finds every candidate
(:func:`active_branches`), refines each exactly (:func:`exact_top`,
:func:`exact_bottom`) and follows them while ``kx`` moves (:class:`BranchTracker`).
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from .frequency import Columns
from .hinf import Branch, IntervalEnd, line_forbidden
from .refine import RootsOver, exact_end, exact_ends, parabola_vertex, root_values

__all__ = ["active_branches", "branch_value", "branch_values", "BranchTracker", "is_tracked", "exact_top",
           "exact_bottom"]

_INF = math.inf


def active_branches(cols: Columns, x: float, top: float, bottom: float, band: float = 0.25,
                    upper: bool = True) -> list[Branch]:
    """Frequency branches that may bound the admissible interval ``(bottom, top)``.

    ``upper``: local minima over the grid of the forbidden intervals' lower
    roots within ``band`` (relative) above ``top``; otherwise local maxima of
    their upper roots within ``band`` below ``bottom``.  The band is generous: a
    sharp dip of a root between grid points can sit a few per cent below its
    grid value (2.1 % was seen at a delay-induced branch), and a candidate that
    does not bind costs only its exact evaluation.
    """
    f = line_forbidden(cols, x)
    vals_all = f.lo[0] if upper else -f.hi[0]
    rid = f.lower_root if upper else f.upper_root
    col = f.col_lo[0]
    ref = top if upper else -bottom
    if not math.isfinite(ref):
        return []
    tol = band * max(abs(ref), 1e-12) + 1e-12
    limit = bottom if upper else -top
    ng = cols.n_grid
    out = []
    for ci in range(cols.n_constraints):
        for root in (0, 1, 2):
            sel = (f.constraint == ci) & (rid == root) & (col < ng)
            if not np.any(sel):
                continue
            val = np.full(ng, _INF)
            val[col[sel]] = vals_all[sel]
            val[~np.isfinite(val)] = _INF
            near = (val <= ref + tol) & (val >= limit)
            left = np.concatenate([[_INF], val[:-1]])
            right = np.concatenate([val[1:], [_INF]])
            out += [Branch(int(c), ci, root) for c in np.flatnonzero(near & (val <= left) & (val <= right))]
    return out


def branch_value(cols: Columns, x: float, branch: Branch, reach: int = 6,
                 rounds: int = 7) -> tuple[float, float, int]:
    """Exact minimum over frequency of one branch at ``x``, followed from its grid column.

    The grid minimum is searched within ``reach`` columns (the branch drifts
    as ``x`` moves), then refined by a 1-D search.  Returns ``(ky, omega, column)``.
    (:func:`branch_values` for several branches on one line.)
    """
    return branch_values(cols, x, [branch], reach, rounds)[0]


def branch_values(cols: Columns, x: float, branches: Sequence[Branch], reach: int = 6,
                  rounds: int = 7) -> list[tuple[float, float, int]]:
    """:func:`branch_value` of each branch on line ``x``: the grid columns of all in one evaluation and
    the exact minima zoomed in together (:func:`~posicast.tune.refine.exact_ends`; issue #15)."""
    if not branches:
        return []
    spans = [np.arange(max(col - reach, 1), min(col + reach, cols.n_grid - 2) + 1) for col, _, _ in branches]
    cc = np.concatenate(spans)
    ci = np.concatenate([np.full(sp.size, br[1]) for sp, br in zip(spans, branches)])
    rt = np.concatenate([np.full(sp.size, br[2]) for sp, br in zip(spans, branches)])
    vals = root_values(cols, np.full(cc.size, x), cc, ci, rt)  # elementwise: the numbers of each branch alone
    vals = np.where(np.isfinite(vals), vals, _INF)
    starts = np.cumsum([0] + [sp.size for sp in spans])
    cols_at = [int(sp[int(np.argmin(vals[a:b]))]) for sp, a, b in zip(spans, starts[:-1], starts[1:])]
    ends = exact_ends(cols, x, [Branch(j, br[1], br[2]) for j, br in zip(cols_at, branches)], upper=True,
                      rounds=rounds)
    return [(y, w, j) for (y, w), j in zip(ends, cols_at)]


class BranchTracker:
    """``x -> ky``: one branch's minimum (``upper``) or maximum over frequency, followed exactly.

    The frequency quantities do not depend on the gains, so a local grid
    (``n`` points over ``reach`` columns either side of the branch, about 1/30
    of the grid spacing) is evaluated once and each ``x`` costs array
    arithmetic only, with a parabola through the three best points.  When the
    extremum reaches the edge of the window (the branch drifts in frequency as
    ``x`` moves) the window is re-centred there.  ``inf`` (``-inf`` for a lower
    branch) when the branch's interval does not exist at ``x``.
    """

    def __init__(self, cols: Columns, branch: Branch, reach: int = 6, n: int = 401, upper: bool = True) -> None:
        self.cols = cols
        self.key = (branch[1], branch[2])  # (constraint, root)
        self.origin = branch[0]
        self.reach = reach
        self.n = n
        self.sign = 1.0 if upper else -1.0
        self._cache: dict[int, tuple[int, int, dict[str, np.ndarray], RootsOver]] = {}
        self._load(self.origin)

    def _load(self, col: int) -> None:
        """Centre the window on grid column ``col`` (its values evaluated once per column, and what of
        the branch's root does not depend on ``x``)."""
        if col not in self._cache:
            lo_c, hi_c = max(col - self.reach, 0), min(col + self.reach, self.cols.n_grid - 1)
            w = np.linspace(float(self.cols.omega[lo_c]), float(self.cols.omega[hi_c]), self.n)
            vals = self.cols.data.values(w)
            self._cache[col] = (lo_c, hi_c, vals, RootsOver(self.cols, vals, *self.key))
        self.col = col
        self.lo, self.hi, self.vals, self.roots = self._cache[col]

    def __call__(self, x: float) -> float:
        # every call starts at the branch's own window, and follows a drifting extremum at
        # most two windows away (a slope toward another branch is not followed for good)
        n, reach, ng = self.n, self.reach, self.cols.n_grid
        self._load(self.origin)
        for _ in range(3):
            f = self.sign * self.roots(x)  # = roots_at(self.cols, x, self.vals, *self.key)
            f = np.where(np.isfinite(f), f, _INF)
            k = int(np.argmin(f))
            if not np.isfinite(f[k]):
                return self.sign * _INF
            at_lo = k == 0 and self.lo > 0 and self.col - self.origin > -2 * reach
            at_hi = k == n - 1 and self.hi < ng - 1 and self.col - self.origin < 2 * reach
            if not (at_lo or at_hi):
                break
            self._load(self.lo if at_lo else self.hi)
        best = float(f[k])
        if 0 < k < n - 1 and np.all(np.isfinite(f[k - 1 : k + 2])):
            f0, f1, f2 = f[k - 1 : k + 2]
            corr = parabola_vertex(f0, f1, f2)
            if corr is not None:
                best = min(best, float(f1 - corr))
        return self.sign * best


def is_tracked(branch: Branch, trackers: Sequence[BranchTracker]) -> bool:
    """Does a tracker already follow ``branch``?  (Same constraint and root, and its column inside
    the tracker's window: the tracker follows the lowest minimum of its window anyway.)"""
    col, ci, root = branch
    return any(t.key == (ci, root) and (t.lo <= col <= t.hi or abs(col - t.origin) <= 6) for t in trackers)


def exact_bottom(cols: Columns, x: float, top: float, bottom: float) -> float:
    """Exact lower end of the admissible interval ``(bottom, top)`` on line ``x`` (mirror of :func:`exact_top`)."""
    if not math.isfinite(bottom):
        return bottom
    best = bottom
    for col, ci, root in active_branches(cols, x, top, bottom, upper=False):
        cc = np.arange(max(col - 1, 1), min(col + 1, cols.n_grid - 2) + 1)
        vals = root_values(cols, np.full(cc.size, x), cc, np.full(cc.size, ci), np.full(cc.size, root))
        vals = np.where(np.isfinite(vals), vals, -_INF)
        j = int(cc[int(np.argmax(vals))])
        yv, _ = exact_end(cols, x, Branch(j, ci, root), upper=False)
        if math.isfinite(yv) and best < yv < top:
            best = yv
        elif math.isfinite(yv) and yv >= top:
            return yv  # the interval is empty
    return best


def exact_top(cols: Columns, x: float, top: float, bottom: float) -> tuple[float, float, IntervalEnd]:
    """Exact upper end of the admissible interval ``(bottom, top)`` on line ``x``.

    Several frequency runs may be nearly active at once (the optimum often
    sits where two are equal), so every branch of :func:`active_branches` is
    refined exactly and the smallest is kept (at or below ``bottom`` it says
    the interval is empty exactly).  Returns ``(ky, omega, end)``.
    """
    # the exact top is the least exact branch minimum (it may lie a little above the polished grid
    # value as well as below it); the grid value stands only when no branch is found
    best, best_w, best_end = _INF, math.nan, None
    branches = active_branches(cols, x, top, bottom)
    for br, (yv, wv, j) in zip(branches, branch_values(cols, x, branches, reach=1)):
        if math.isfinite(yv) and yv < best:
            # below ``bottom``: this forbidden interval swallows the whole admissible interval
            best, best_w, best_end = yv, wv, Branch(j, br[1], br[2])
    if best_end is None:
        best = top
    # limit columns (omega -> infinity) are exact as they stand
    f = line_forbidden(cols, x)
    lo, col = f.lo[0], f.col_lo[0]
    lim = (col >= cols.n_grid) & np.isfinite(lo) & (lo >= bottom) & (lo < best)
    if np.any(lim):
        k = int(np.flatnonzero(lim)[np.argmin(lo[lim])])
        best, best_w, best_end = float(lo[k]), math.inf, Branch(int(col[k]), int(f.constraint[k]),
                                                               int(f.lower_root[k]))
    return best, best_w, best_end
