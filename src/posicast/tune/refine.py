"""Interval ends refined between grid columns (seed 001 section 3): the exact extremum over frequency.

An admissible interval's end on a scan line is the extremum over frequency of
one root of one constraint's quadratic (a :class:`~posicast.tune.hinf.Branch`,
named by the grid column where it was found).  :func:`polish_ends` refines
every end of a block of lines between its column's neighbours (vectorised),
:func:`exact_end` one end to rounding, and :func:`forbidden_window` finds the
exact forbidden set at a D-decomposition crossing whose frequency window is
narrower than the grid.  Every stage evaluates the exact frequency response
(:meth:`~posicast.tune.frequency.FrequencyData.values`).
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from .frequency import Columns
from .hinf import Branch, IntervalEnd, quadratic_root, quadratic_root_of

__all__ = ["root_value", "root_values", "roots_at", "RootsOver", "polish_ends", "parabola_vertex", "exact_end", "exact_ends",
           "forbidden_window"]

_INF = math.inf


# ---------------------------------------------------------------------- one root between columns
def root_values(cols: Columns, x: np.ndarray, col: np.ndarray, ci: np.ndarray, root: np.ndarray) -> np.ndarray:
    """The quadratic's roots at grid columns, vectorised (NaN where the root does not exist)."""
    out = np.full(x.shape, np.nan)
    for c in np.unique(ci):
        sel = ci == c
        nu, na, nb, w2 = (arr[col[sel]] for arr in cols.constraints[int(c)])
        u, a, b = cols.u[col[sel]], cols.a[col[sel]], cols.b[col[sel]]
        out[sel] = quadratic_root(u + x[sel] * a, nu + x[sel] * na, b, nb, w2, root[sel])
    return out


def root_value(cols: Columns, x: float, col: int, ci: int, root: int) -> float:
    """The quadratic's root ``root`` (0 smaller, 1 larger, 2 linear) at one column (NaN if none)."""
    return float(root_values(cols, np.array([x]), np.array([col]), np.array([ci]), np.array([root]))[0])


def roots_at(cols: Columns, x: float, vals: dict[str, np.ndarray], ci: int, root: int) -> np.ndarray:
    """The quadratic's root ``root`` at exact values ``vals`` (arrays over frequency)."""
    w2 = np.abs(vals[f"W{ci}"]) ** 2 / cols.data.constraints[ci].gamma ** 2
    return quadratic_root(vals["u"] + x * vals["a"], vals[f"nu{ci}"] + x * vals[f"na{ci}"], vals["b"],
                          vals[f"nb{ci}"], w2, root)


class RootsOver:
    """``x -> roots_at(cols, x, vals, ci, root)`` on fixed frequencies ``vals``: what does not depend on
    ``x`` (the weight, the quadratic's leading coefficient, the conjugates) is computed once.

    Issue #15: a :class:`~posicast.tune.branches.BranchTracker` asks for hundreds of ``x`` on the same
    window.  ``B`` and ``D`` are formed as :func:`~posicast.tune.hinf.quadratic_root` forms them and the
    root comes from the same :func:`~posicast.tune.hinf.quadratic_root_of`, so the numbers are the same.
    """

    def __init__(self, cols: Columns, vals: dict[str, np.ndarray], ci: int, root: int) -> None:
        self.u, self.a = vals["u"], vals["a"]
        self.nu, self.na = vals[f"nu{ci}"], vals[f"na{ci}"]
        b, nb = vals["b"], vals[f"nb{ci}"]
        self.w2 = np.abs(vals[f"W{ci}"]) ** 2 / cols.data.constraints[ci].gamma ** 2
        self.A = np.abs(b) ** 2 - self.w2 * np.abs(nb) ** 2
        self.conj_b, self.conj_nb = np.conj(b), np.conj(nb)
        self.root = int(root)

    def __call__(self, x: float) -> np.ndarray:
        U = self.u + x * self.a
        N = self.nu + x * self.na
        w2 = self.w2
        B = (U * self.conj_b).real - w2 * (N * self.conj_nb).real
        D = np.abs(U) ** 2 - w2 * np.abs(N) ** 2
        return quadratic_root_of(self.A, B, D, self.root)


def polish_ends(cols: Columns, x: np.ndarray, ends: Sequence[IntervalEnd], values: np.ndarray,
                upper: np.ndarray, rounds: int = 4, where: bool = False) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Exact interval ends: the extremum over frequency of each end's root, refined between its
    column's neighbours (vectorised over all ends).

    An upper end of an admissible interval is the minimum over frequency of a
    forbidden interval's lower root (``upper``); a lower end is a maximum.
    Each round evaluates the exact frequency response at 9 points per end (one
    call for all ends) and keeps the two intervals around the best point, so the
    bracket shrinks 4x per round; the grid value stands where nothing better is
    found.  (A parabola through three grid points, used before, can overshoot a
    sharp minimum and make the region smaller than it is.)  The first round's points depend on the
    column alone: each distinct column is evaluated once (:func:`_first_round`).  With ``where``, also
    the frequency of each end's extremum (NaN for the ends not polished).
    """
    idx = [k for k, e in enumerate(ends) if e is not None and 0 < e[0] < cols.n_grid - 1]
    omega = np.full(values.shape, np.nan)
    if not idx:
        return (values, omega) if where else values
    k = np.array(idx)
    col = np.array([ends[i][0] for i in idx])
    ci = np.array([ends[i][1] for i in idx])
    rt = np.array([ends[i][2] for i in idx])
    xs = x[k]
    sign = np.where(upper[k], 1.0, -1.0)
    lo = cols.omega[col - 1].astype(float)
    hi = cols.omega[col + 1].astype(float)
    best = sign * values[k]
    best = np.where(np.isfinite(best), best, _INF)
    best_w = cols.omega[col].astype(float)
    t = np.linspace(0.0, 1.0, 9)
    for r in range(rounds):
        w = lo[:, None] + (hi - lo)[:, None] * t[None, :]
        vals = _first_round(cols, col, w) if r == 0 else cols.data.values(w.ravel())
        f = np.full(w.shape, _INF)
        for c in np.unique(ci):
            sel = np.flatnonzero(ci == c)
            rows = (sel[:, None] * 9 + np.arange(9)[None, :]).ravel()
            w2 = np.abs(vals[f"W{c}"][rows]) ** 2 / cols.data.constraints[int(c)].gamma ** 2
            r = quadratic_root(vals["u"][rows] + np.repeat(xs[sel], 9) * vals["a"][rows],
                               vals[f"nu{c}"][rows] + np.repeat(xs[sel], 9) * vals[f"na{c}"][rows],
                               vals["b"][rows], vals[f"nb{c}"][rows], w2, np.repeat(rt[sel], 9))
            f[sel] = (np.repeat(sign[sel], 9) * r).reshape(-1, 9)
        f = np.where(np.isfinite(f), f, _INF)
        j = np.argmin(f, axis=1)
        fj = f[np.arange(f.shape[0]), j]
        wj = w[np.arange(w.shape[0]), j]
        best_w = np.where(fj < best, wj, best_w)
        best = np.minimum(best, fj)
        step = (hi - lo) / 8.0
        lo, hi = np.maximum(lo, wj - step), np.minimum(hi, wj + step)
    out = values.copy()
    out[k] = np.where(np.isfinite(best), sign * best, values[k])
    if where:
        omega[k] = best_w
        return out, omega
    return out


def _first_round(cols: Columns, col: np.ndarray, w: np.ndarray) -> dict[str, np.ndarray]:
    """``cols.data.values(w.ravel())`` for :func:`polish_ends`' first round, whose 9 points per end depend
    on the end's column alone: each distinct column is evaluated once (issue #15: the ends of a block of
    neighbouring lines share a few columns, ~4 ends a column on the demo's designs).  The response is
    evaluated point by point, so the numbers are the same."""
    _, first, inv = np.unique(col, return_index=True, return_inverse=True)
    if first.size == col.size:
        return cols.data.values(w.ravel())
    vals = cols.data.values(w[first].ravel())
    rows = (inv.reshape(-1)[:, None] * w.shape[1] + np.arange(w.shape[1])[None, :]).ravel()
    return {k: v[rows] for k, v in vals.items()}


def parabola_vertex(f0: float, f1: float, f2: float) -> float | None:
    """The correction ``f1 - vertex`` of the parabola through three equally spaced samples around a
    minimum ``f1``, or None where the curvature is rounding noise.

    The correction is trusted only above rounding, and never beyond the samples'
    own spread (in a tiny bracket the curvature is rounding noise).
    """
    curv = f0 - 2 * f1 + f2
    if curv > 64 * np.finfo(float).eps * max(abs(f0), abs(f1), abs(f2), 1e-300):
        return min((f2 - f0) ** 2 / (8 * curv), max(f0, f2) - f1)
    return None


def exact_end(cols: Columns, x: float, end: Branch, upper: bool, rounds: int = 7) -> tuple[float, float]:
    """Exact extremum over frequency of one interval end: ``(ky, omega)``.

    Zooms in on the extremum between the column's neighbours: each round
    evaluates the exact frequency response at 9 points and keeps the two
    intervals around the best (the bracket shrinks 4x per round), then a
    parabola through the last three points.  (:func:`exact_ends` for several.)
    """
    return exact_ends(cols, x, [end], upper, rounds)[0]


def exact_ends(cols: Columns, x: float, ends: Sequence[Branch], upper: bool,
               rounds: int = 7) -> list[tuple[float, float]]:
    """:func:`exact_end` of several ends on one line ``x``, in lockstep: each round evaluates the exact
    frequency response once for every end's 9 points (issue #15: the response's per-call cost dominated
    when each branch zoomed in alone).  Each end's numbers are those :func:`exact_end` gives it alone
    (the response is evaluated point by point)."""
    sign = 1.0 if upper else -1.0
    out: list[tuple[float, float]] = [(math.nan, math.nan)] * len(ends)
    live: list[_Zoom] = []
    memo = cols.cache.setdefault("exact_ends", {})  # the final design's end was found by the search
    for k, (col, ci, root) in enumerate(ends):
        key = (float(x), col, ci, root, upper, rounds)
        if key in memo:
            out[k] = memo[key]
            continue
        if col >= cols.n_grid:  # a limit column: no frequency to refine
            out[k] = (root_value(cols, x, col, ci, root), math.inf)
            continue
        lo = float(cols.omega[max(col - 1, 0)])
        hi = float(cols.omega[min(col + 1, cols.n_grid - 1)])
        base = root_value(cols, x, col, ci, root)
        best_w = float(cols.omega[col])
        if not hi > lo:
            out[k] = (base, best_w)
            continue
        live.append(_Zoom(k, ci, root, lo, hi, sign * base if math.isfinite(base) else math.inf, best_w))
    for _ in range(rounds if live else 0):
        ws = [np.linspace(z.lo, z.hi, 9) for z in live]
        vals = cols.data.values(np.concatenate(ws))
        for r, (z, w) in enumerate(zip(live, ws)):
            f = sign * roots_at(cols, x, _rows(vals, z.ci, slice(9 * r, 9 * r + 9)), z.ci, z.root)
            z.step(w, f)
    for z in live:
        out[z.k] = (sign * z.best_v, z.best_w)
        if len(memo) >= 64:
            memo.pop(next(iter(memo)))
        memo[(float(x), *ends[z.k], upper, rounds)] = out[z.k]
    return out


def _rows(vals: dict[str, np.ndarray], ci: int, rows: slice) -> dict[str, np.ndarray]:
    """The arrays :func:`roots_at` reads for constraint ``ci``, at ``rows``."""
    keys = ("u", "a", "b", f"W{ci}", f"nu{ci}", f"na{ci}", f"nb{ci}")
    return {k: vals[k][rows] for k in keys}


class _Zoom:
    """One end's bracket ``[lo, hi]`` and best value so far in :func:`exact_ends`."""

    def __init__(self, k: int, ci: int, root: int, lo: float, hi: float, best_v: float, best_w: float) -> None:
        self.k, self.ci, self.root = k, ci, root
        self.lo, self.hi = lo, hi
        self.best_v, self.best_w = best_v, best_w

    def step(self, w: np.ndarray, f: np.ndarray) -> None:
        """One round: ``f`` (sign-adjusted roots at the 9 points ``w``) narrows the bracket."""
        f = np.where(np.isfinite(f), f, math.inf)
        k = int(np.argmin(f))
        if f[k] < self.best_v:
            self.best_v, self.best_w = float(f[k]), float(w[k])
        self.lo, self.hi = float(w[max(k - 1, 0)]), float(w[min(k + 1, 8)])
        if 0 < k < 8 and np.all(np.isfinite(f[k - 1 : k + 2])):
            f0, f1, f2 = f[k - 1 : k + 2]
            corr = parabola_vertex(f0, f1, f2)
            if corr is not None:
                vertex = f1 - corr
                if vertex < self.best_v:
                    h = w[1] - w[0]
                    self.best_v = float(vertex)
                    self.best_w = float(w[k] + h * (f0 - f2) / (2 * (f0 - 2 * f1 + f2)))


# ---------------------------------------------------------------------- a window narrower than the grid
def _interval_width(cols: Columns, x: float, ci: int, ws: np.ndarray) -> np.ndarray:
    """``hi - lo`` of constraint ``ci``'s forbidden interval at each frequency (-1 where it does not exist)."""
    ws = np.asarray(ws, dtype=float)
    ok = ws > 0
    res = np.full(ws.shape, -1.0)
    if np.any(ok):
        vals = cols.data.values(ws[ok])
        lo = roots_at(cols, x, vals, ci, 0)
        hi = roots_at(cols, x, vals, ci, 1)
        res[ok] = np.where(np.isfinite(lo) & np.isfinite(hi), hi - lo, -1.0)
    return res


def _window_edges(cols: Columns, x: float, ci: int, w: float, steps: np.ndarray) -> list[float]:
    """The frequencies just inside both edges of the window around ``w`` where the interval exists.

    A geometric walk outward from ``w`` brackets each edge; each open bracket
    (inside, outside) is then narrowed 32-fold per round: 4 rounds put the edge
    within 1e-6 of the walk's last step, far below the 801-point sampling of the
    window in :func:`forbidden_window`.
    """
    walk = _interval_width(cols, x, ci, np.concatenate([w - steps, w + steps])).reshape(2, -1)
    brackets: list[tuple[float, float | None]] = []
    for side, row in zip((-1.0, 1.0), walk):
        bad = np.flatnonzero(~(row > 0))
        if bad.size == 0:
            brackets.append((w + side * steps[-1], None))
            continue
        k = int(bad[0])
        brackets.append((w + side * steps[k - 1] if k > 0 else w, w + side * steps[k]))
    for _ in range(4):
        live = [k for k, (_, o) in enumerate(brackets) if o is not None]
        if not live:
            break
        pts = np.concatenate([np.linspace(brackets[k][0], brackets[k][1], 33)[1:] for k in live])
        wd = _interval_width(cols, x, ci, pts).reshape(len(live), 32)
        for r, k in enumerate(live):
            inside, outside = brackets[k]
            grid = np.linspace(inside, outside, 33)
            bad = np.flatnonzero(~(wd[r] > 0))
            j = int(bad[0]) if bad.size else 31
            brackets[k] = (float(grid[j]), float(grid[j + 1]))
    return [inside for inside, _ in brackets]


def forbidden_window(cols: Columns, x: float, w: float) -> list[tuple[int, tuple[float, float]]]:
    """Exact union of each constraint's forbidden ``ky`` intervals over the frequency window around ``w``.

    At a crossing of the D-decomposition curve the forbidden interval exists in
    a window of frequencies (possibly far narrower than the grid), and its
    centre can sweep a long way across it (large gains).  The window's edges
    (where the quadratic's discriminant vanishes) are bracketed by a geometric
    walk outward from ``w`` and narrowed by vectorised subdivision; the window is
    then sampled densely, and the union is the hull ``[min lo, max hi]`` (a
    continuous family of intervals over a connected window).  Every stage
    evaluates the exact frequency response at many frequencies in one call.
    Returns ``(constraint, (lo, hi))`` for each constraint forbidding anything at ``w``.
    """
    out = []
    # offsets of the outward walk: (2^(k+1) - 1) 1e-6 w, k = 0..59, on both sides of w
    steps = (2.0 ** np.arange(1, 61) - 1.0) * 1e-6 * w
    for ci in range(cols.n_constraints):
        if not _interval_width(cols, x, ci, np.array([w]))[0] > 0:
            continue
        edges = _window_edges(cols, x, ci, w, steps)
        ww = np.linspace(min(edges), max(edges), 801)
        vals = cols.data.values(ww)
        lo = roots_at(cols, x, vals, ci, 0)
        hi = roots_at(cols, x, vals, ci, 1)
        ok = np.isfinite(lo) & np.isfinite(hi)
        if np.any(ok):
            out.append((ci, (float(lo[ok].min()), float(hi[ok].max()))))
    return out
