"""Compiled kernels of the H-infinity scan (issue #15): the forbidden intervals of an ``||S||``-like bound over
every (line, column), and the hull of their frequency runs, in one pass without temporaries; and the probes'
test whether those intervals cover a window.

:func:`fixed_numerator_runs` computes, number for number, what :func:`~posicast.tune.hinf._fixed_numerator_pieces`
and :func:`~posicast.tune.hinf._run_hull` compute with numpy (the same operations in the same order; no
fused multiply-add: numba keeps IEEE arithmetic unless asked for fast-math), on arrays that never leave the
cache.  With a lumped shaper's tens of thousands of columns those two were 40-60 % of a design's scan.
:func:`fixed_numerator_meets` answers :func:`~posicast.tune.hinf.meets` for the probes from the same intervals.

numba is imported on the first call (:func:`kernel`), not with posicast; where it cannot be imported, the numpy
path is used and gives the same numbers.
"""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

__all__ = ["kernel", "fixed_numerator_runs", "fixed_numerator_meets"]

_KERNELS: dict[str, Any] = {}  # name -> compiled function, once tried; empty values where numba is missing


def kernel(name: str = "runs") -> Callable[..., Any] | None:
    """The compiled :func:`fixed_numerator_runs` (``"runs"``) or :func:`fixed_numerator_meets` (``"meets"``),
    or None where numba cannot be imported.

    Both call :func:`_column_interval`, compiled first: the module's name for it is rebound to the compiled
    function, which numba then calls from the kernels (and Python too, with the same numbers)."""
    global _column_interval
    if not _KERNELS:
        try:
            import numba
        except ImportError:  # pragma: no cover - numba is a dependency; the numpy path stays correct
            _KERNELS.update(runs=None, meets=None)
            return None
        python = _COLUMN_INTERVAL
        for options in ({"cache": True}, {}):  # cached next to this module, or (no writable place) per process
            try:
                jit = numba.njit(error_model="numpy", nogil=True, **options)
                _column_interval = jit(python)
                _KERNELS.update(runs=jit(fixed_numerator_runs), meets=jit(fixed_numerator_meets))
                break
            except RuntimeError:
                _column_interval = python
    return _KERNELS[name]


def _column_interval(Ur: float, Ui: float, br: float, bi: float, A: float, c: float) -> tuple[int, float, float]:
    """What a fixed-numerator constraint forbids at one column and line, ``U = Ur + j Ui``: ``(kind, lo, hi)``,
    kind 0 nothing, 1 the interval ``[lo, hi]`` where ``A > 0`` (``pos`` of ``_fixed_numerator_pieces``), 2
    the linear case's entry where ``A = 0`` (a ray, or everything; only where ``lo < inf``, as ``_entries``
    keeps it).  The same operations in the same order as the numpy path."""
    B = Ur * br + Ui * bi
    D = Ur * Ur + Ui * Ui
    D = D - c
    if A == 0.0:  # 2 B ky + D <= 0
        if not (abs(Ur) < math.inf and abs(Ui) < math.inf and abs(D) < math.inf and abs(B) < math.inf):
            return 0, math.inf, -math.inf
        root = -D / (2.0 * B)
        if B > 0.0:
            return 2, -math.inf, root
        if B < 0.0:
            return (2, root, math.inf) if root < math.inf else (0, math.inf, -math.inf)
        if D <= 0.0:
            return 2, -math.inf, math.inf
        return 0, math.inf, -math.inf
    disc = B * B - A * D
    if not ((abs(D) < math.inf) and (abs(B) < math.inf) and A > 0.0 and disc > 0.0):
        return 0, math.inf, -math.inf
    s = math.sqrt(disc)
    q = (s if B < 0.0 else -s) - B
    r1 = 0.0 if q == 0.0 else D / q
    r2 = q / A
    if r1 != r1:  # numpy's fmin / fmax: a NaN loses
        return 1, r2, r2
    if r2 != r2:
        return 1, r1, r1
    return 1, (r1 if r1 <= r2 else r2), (r1 if r1 >= r2 else r2)


_COLUMN_INTERVAL = _column_interval  # the Python function, whatever the module's name is bound to


def fixed_numerator_runs(x: np.ndarray, ur: np.ndarray, ui: np.ndarray, ar: np.ndarray, ai: np.ndarray,
                         br: np.ndarray, bi: np.ndarray, A: np.ndarray, c: np.ndarray, db: np.ndarray,
                         limit: float, n_grid: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                                             np.ndarray, np.ndarray]:
    """The runs of the ``A > 0`` piece of a fixed-numerator constraint on the lines ``x``: ``(row, first column,
    lo, hi, column of lo, column of hi)``, one entry per run, row-major (see ``_run_hull``); then the entries
    of the ``A = 0`` piece (the linear case, each column alone: ``(row, its place among the A = 0 columns, lo,
    hi, column)``, those with ``lo < inf``, row-major) and the number of those columns.

    ``U = u + x a`` in parts ``ur, ui, ar, ai``; ``b`` in parts ``br, bi``; ``A = |b|^2`` and ``c = w2 |nu|^2``
    per column; ``db = |diff(b)|``; two neighbouring columns join where ``|dU| + max|y| |db| <= limit``
    (``limit`` a quarter of the constraint radius), never across column ``n_grid`` (the limit columns)."""
    m = x.size
    n = ur.size
    cap = m * n  # at most one run per entry (np.empty reserves; only the pages written are touched)
    row = np.empty(cap, np.int64)
    first = np.empty(cap, np.int64)
    lo = np.empty(cap, np.float64)
    hi = np.empty(cap, np.float64)
    clo = np.empty(cap, np.int64)
    chi = np.empty(cap, np.int64)
    nz = 0
    for j in range(n):
        if A[j] == 0.0:
            nz += 1
    lrow = np.empty(m * nz, np.int64)
    lpos = np.empty(m * nz, np.int64)
    llo = np.empty(m * nz, np.float64)
    lhi = np.empty(m * nz, np.float64)
    lcol = np.empty(m * nz, np.int64)
    kl = 0
    k = -1
    for i in range(m):
        xi = x[i]
        prev_valid = False
        prev_ur = 0.0
        prev_ui = 0.0
        prev_y = 0.0
        p = 0
        for j in range(n):
            Ur = ur[j] + xi * ar[j]
            Ui = ui[j] + xi * ai[j]
            kind, lo_j, hi_j = _column_interval(Ur, Ui, br[j], bi[j], A[j], c[j])
            if A[j] == 0.0:  # the linear case: an entry of its own where it forbids anything
                if kind == 2:
                    lrow[kl] = i
                    lpos[kl] = p
                    llo[kl] = lo_j
                    lhi[kl] = hi_j
                    lcol[kl] = j
                    kl += 1
                p += 1
            pos = kind == 1
            y = 0.0
            if pos:
                y = lo_j if abs(lo_j) < math.inf else hi_j
                y = abs(y)
                if not abs(y) < math.inf:
                    y = math.inf
            joined = False
            if pos and prev_valid and j != n_grid and j > 0:
                dU = math.hypot(Ur - prev_ur, Ui - prev_ui)
                yy = y if y >= prev_y else prev_y
                if y != y or prev_y != prev_y:
                    yy = math.nan
                change = dU + yy * db[j - 1]
                joined = change <= limit
            if pos:
                if joined:
                    if lo_j < lo[k]:
                        lo[k] = lo_j
                        clo[k] = j
                    if hi_j > hi[k]:
                        hi[k] = hi_j
                        chi[k] = j
                else:
                    k += 1
                    row[k] = i
                    first[k] = j
                    lo[k] = lo_j
                    hi[k] = hi_j
                    clo[k] = j
                    chi[k] = j
            prev_valid = pos
            prev_ur = Ur
            prev_ui = Ui
            prev_y = y
    k += 1
    return (row[:k].copy(), first[:k].copy(), lo[:k].copy(), hi[:k].copy(), clo[:k].copy(), chi[:k].copy(),
            lrow[:kl].copy(), lpos[:kl].copy(), llo[:kl].copy(), lhi[:kl].copy(), lcol[:kl].copy(), nz)



def fixed_numerator_meets(x: np.ndarray, ur: np.ndarray, ui: np.ndarray, ar: np.ndarray, ai: np.ndarray,
                          br: np.ndarray, bi: np.ndarray, A: np.ndarray, c: np.ndarray, y_lo: float,
                          y_hi: float) -> np.ndarray:
    """Per line ``x``: does a gap of the union of the forbidden intervals of fixed-numerator constraints (rows of
    ``A``, ``c``), one per column each, meet the open interval ``(y_lo, y_hi)``?  What
    :func:`~posicast.tune.hinf.meets` says of :func:`~posicast.tune.hinf.forbidden` without the hull, from the
    intervals that reach into ``(y_lo, y_hi)`` only (sorted, not all of them)."""
    m = x.size
    n = ur.size
    out = np.zeros(m, np.bool_)
    lo = np.empty(n * A.shape[0], np.float64)
    hi = np.empty(n * A.shape[0], np.float64)
    for i in range(m):
        xi = x[i]
        cnt = 0
        for ci in range(A.shape[0]):
            for j in range(n):
                Ur = ur[j] + xi * ar[j]
                Ui = ui[j] + xi * ai[j]
                kind, a, b = _column_interval(Ur, Ui, br[j], bi[j], A[ci, j], c[ci, j])
                if kind == 0:
                    continue
                if a < math.inf and b > y_lo and a < y_hi:  # the entries that reach into (y_lo, y_hi)
                    lo[cnt] = a
                    hi[cnt] = b
                    cnt += 1
        order = np.argsort(lo[:cnt], kind="mergesort")
        covered = y_lo
        gap = False
        for t in range(cnt):
            e = order[t]
            if lo[e] > covered:
                gap = True
                break
            if hi[e] > covered:
                covered = hi[e]
        out[i] = gap or covered < y_hi
    return out
