"""H-infinity constraints on a scan line ``kx = x``: forbidden intervals of ``ky`` (seed 001 section 3).

With ``1 + L = u + kx a + ky b`` and a constraint channel's numerator
``nu + kx na + ky nb`` (:mod:`posicast.tune.frequency`), the constraint
``|W X| < gamma`` at one frequency is a quadratic inequality in ``ky``
(:func:`forbidden_interval`).  On a line, each constraint forbids at every
column an interval (or two rays); the admissible set is the complement of their
union (:func:`forbidden`, :func:`complement`).  The ends of the admissible
intervals are extrema over frequency of one root of one quadratic: a
:class:`Branch`, refined between grid columns in :mod:`~posicast.tune.refine`.
"""

from __future__ import annotations

import math
from enum import IntEnum
from typing import NamedTuple, Sequence, Union

import numpy as np

from ._kernels import kernel
from .frequency import Columns

__all__ = ["Root", "Branch", "Cut", "IntervalEnd", "Ends", "ForbiddenPiece", "Forbidden", "forbidden_interval",
           "quadratic_root", "quadratic_root_of", "forbidden", "complement", "line_forbidden", "meets_window"]

_INF = math.inf


# ---------------------------------------------------------------------- named concepts
class Root(IntEnum):
    """Which root of the constraint's quadratic in ``ky`` an interval end is."""

    INFINITE = -1  #: no root: the end is at -inf or +inf
    SMALLER = 0
    LARGER = 1
    LINEAR = 2  #: the single root where the quadratic's leading coefficient vanishes


class Branch(NamedTuple):
    """A frequency branch: one root of one constraint's quadratic, followed over frequency.

    It is named by the grid column where it was found.  An interval end computed
    on the grid is attributed to the branch that makes it.
    """

    column: int
    constraint: int
    root: int


class Cut(NamedTuple):
    """An interval end computed exactly at a refined D-decomposition crossing frequency ``omega``
    (see :func:`posicast.tune.scan.scan_lines`)."""

    constraint: int
    omega: float


#: What bounds an admissible interval at one end: a branch, an exact cut, or nothing (an infinite
#: end, a stability break or the range).
IntervalEnd = Union[Branch, Cut, None]


class ForbiddenPiece(NamedTuple):
    """One piece ``[lo, hi]`` of a constraint's forbidden set (empty where ``lo > hi``).

    ``lower`` and ``upper`` say which roots the ends are; ``run`` marks where the
    piece exists, for the union over a run of frequencies (None: never joined over
    frequency, the side may change within a run).
    """

    lo: np.ndarray
    hi: np.ndarray
    lower: Root
    upper: Root
    run: np.ndarray | None


class Forbidden(NamedTuple):
    """Forbidden intervals of ``ky`` on ``m`` lines, ``K`` entries each ((column, constraint, piece) triples,
    or runs of them: :func:`forbidden`).

    ``lo, hi, col_lo, col_hi`` are (m, K): the ends and the columns they are
    attributed to; ``constraint, lower_root, upper_root`` are (K,) (the same on every line) or (m, K).
    """

    lo: np.ndarray
    hi: np.ndarray
    col_lo: np.ndarray
    col_hi: np.ndarray
    constraint: np.ndarray
    lower_root: np.ndarray
    upper_root: np.ndarray


# ---------------------------------------------------------------------- one constraint at one frequency
def forbidden_interval(U: np.ndarray, N: np.ndarray, b: np.ndarray, nb: np.ndarray,
                       w2: np.ndarray) -> tuple[ForbiddenPiece, ...]:
    """The forbidden ``ky`` of one constraint at one frequency (arrays: any number of lines and frequencies).

    Seed 001 eq. 6-7 (``||W X||_inf < gamma``), transformed to the gain plane as
    in seed 001 section 3 (Schlegel and Medvecova's "quadratic polynomial"): at
    one frequency, with ``U = u + kx a`` and ``N = nu + kx na``, the constraint
    ``|U + ky b|^2 - w2 |N + ky nb|^2 > 0`` (``w2 = |W|^2 / gamma^2``) reads

        A ky^2 + 2 B ky + D > 0,   A = |b|^2 - w2 |nb|^2,
                                   B = Re(U conj b) - w2 Re(N conj nb),
                                   D = |U|^2 - w2 |N|^2,

    so the forbidden set ``A ky^2 + 2 B ky + D <= 0`` is, with the roots
    ``rlo <= rhi`` (stable form ``q = -(B + sign(B) sqrt(B^2 - A D))``, roots
    ``D / q`` and ``q / A``):

    * ``A > 0``: ``[rlo, rhi]`` (nothing without real roots);
    * ``A < 0``: ``(-inf, rlo]`` and ``[rhi, inf)`` (everything without real roots);
    * ``A = 0`` (to 1e-13 of ``|b|^2 + w2 |nb|^2``): ``2 B ky + D <= 0``, a ray
      from ``-D / (2 B)`` (everything if ``B = 0`` and ``D <= 0``).

    Returns the four pieces in that order (empty ones have ``lo = inf``, ``hi = -inf``); where ``A > 0``
    at every column given (an unweighted bound on ``S``, whose numerator does not depend on ``ky``),
    only the first: the others are empty.
    """
    A = np.abs(b) ** 2 - w2 * np.abs(nb) ** 2
    Ascale = np.abs(b) ** 2 + w2 * np.abs(nb) ** 2
    B = (U * b.conj()).real - w2 * (N * nb.conj()).real
    D = np.abs(U) ** 2 - w2 * np.abs(N) ** 2
    with np.errstate(invalid="ignore"):
        A = np.where(np.abs(A) <= 1e-13 * Ascale, 0.0, A)
        positive = bool(np.all((A > 0) | np.isnan(A)))
    if positive:  # the same numbers as below, without the pieces that cannot exist
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            disc = B * B - A * D
            q = -(B + np.where(B >= 0, 1.0, -1.0) * np.sqrt(np.maximum(disc, 0.0)))
            r1 = np.where(q != 0, D / q, 0.0)
            r2 = q / A
            pos = np.isfinite(D) & np.isfinite(B) & (A > 0) & (disc > 0)  # D finite: U finite; A > 0: A finite
            return (ForbiddenPiece(np.where(pos, np.fmin(r1, r2), _INF), np.where(pos, np.fmax(r1, r2), -_INF),
                                   Root.SMALLER, Root.LARGER, pos),)
    A = A * np.ones((U.shape[0], 1))
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
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
    return (
        ForbiddenPiece(np.where(pos, rlo, _INF), np.where(pos, rhi, -_INF), Root.SMALLER, Root.LARGER, pos),
        ForbiddenPiece(np.where(negd | negall, -_INF, _INF), np.where(negd, rlo, np.where(negall, _INF, -_INF)),
                       Root.INFINITE, Root.SMALLER, negd | negall),
        ForbiddenPiece(np.where(negd, rhi, _INF), np.where(negd, _INF, -_INF), Root.LARGER, Root.INFINITE, negd),
        ForbiddenPiece(np.where(zpos, -_INF, np.where(zneg, root, np.where(zall, -_INF, _INF))),
                       np.where(zpos, root, np.where(zneg, _INF, np.where(zall, _INF, -_INF))),
                       Root.LINEAR, Root.LINEAR, None),
    )


def quadratic_root(U: np.ndarray, N: np.ndarray, b: np.ndarray, nb: np.ndarray, w2: np.ndarray,
                   root: np.ndarray | int) -> np.ndarray:
    """Roots in ``ky`` of ``|U + ky b|^2 - w2 |N + ky nb|^2 = 0`` (the constraint's boundary at one frequency).

    ``root``: 0 the smaller, 1 the larger, 2 the single root of the linear case
    (``A = |b|^2 - w2 |nb|^2 = 0``, also used wherever ``A`` vanishes); see
    :func:`forbidden_interval`.  NaN where the root does not exist.  The stable
    form ``q = -(B + sign(B) sqrt(disc))``, roots ``D / q`` and ``q / A``, avoids
    cancellation.
    """
    A = np.abs(b) ** 2 - w2 * np.abs(nb) ** 2
    B = (U * np.conj(b)).real - w2 * (N * np.conj(nb)).real
    D = np.abs(U) ** 2 - w2 * np.abs(N) ** 2
    return quadratic_root_of(A, B, D, root)


def quadratic_root_of(A: np.ndarray, B: np.ndarray, D: np.ndarray, root: np.ndarray | int) -> np.ndarray:
    """:func:`quadratic_root` from the coefficients of ``A ky^2 + 2 B ky + D`` (for callers that keep the
    parts of ``A`` and ``B`` that do not change, e.g. :class:`~posicast.tune.refine.RootsOver`)."""
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        disc = B * B - A * D
        sq = np.sqrt(np.where(disc >= 0, disc, np.nan))
        q = -(B + np.where(B >= 0, 1.0, -1.0) * sq)
        small, large = np.fmin(D / q, q / A), np.fmax(D / q, q / A)
        lin = -D / (2 * B)
    root = np.asarray(root)
    return np.where((root == 2) | (A == 0), lin, np.where(root == 0, small, large))


# ---------------------------------------------------------------------- over frequency, on lines
class _Runs(NamedTuple):
    """One entry per frequency run of a piece: its line, first column, hull ``[lo, hi]`` and the columns
    of the hull's extremes (row-major: by line, then column)."""

    row: np.ndarray
    first: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    col_lo: np.ndarray
    col_hi: np.ndarray


def _run_hull(cols: Columns, L: np.ndarray, H: np.ndarray, V: np.ndarray, dU: np.ndarray) -> _Runs:
    """The hull of each forbidden interval's run of consecutive valid columns, one entry per run.

    Over a connected range of frequencies where the interval exists, the union
    of the intervals is the interval ``[min lo, max hi]`` (a continuous family
    of intervals with a connected parameter set), so the hull is the exact
    union, whatever the grid spacing; where the interval vanished between two
    grid points the hull forbids a little more, never less.  The grid and the
    limit columns are separate runs.  Each run is named by the columns of its
    extremes (for the polish and the exact refinement).

    Two neighbouring columns belong to one run only where the grid resolves
    ``1 + L`` for the gains at the intervals' location: ``|dU| + |y| |db|``
    (``dU`` the change of ``u + kx a``, ``y`` the interval's finite end) must
    stay below a quarter of the constraint radius.  Elsewhere (e.g. far out,
    where a delay turns the phase quickly between coarse points) the
    intervals are kept as they are.

    Every column of a run would carry the same hull, so one entry stands for the run: the union, and
    which interval bounds it, do not change, and with a lumped shaper's tens of thousands of columns
    the complement's sort stays small (issue #15).
    """
    m, n = V.shape
    prev = np.zeros_like(V)
    prev[:, 1:] = V[:, :-1]
    if n > cols.n_grid:
        prev[:, cols.n_grid] = False
    with np.errstate(invalid="ignore"):
        y = np.where(np.isfinite(L), L, H)
        np.abs(y, out=y)
        y[~np.isfinite(y)] = _INF
        change = np.maximum(y[:, 1:], y[:, :-1])
        change *= _db(cols)[None, :]
        np.add(dU, change, out=change)
    prev[:, 1:] &= change <= 0.25 * cols.data.r_min
    where = np.flatnonzero(V.ravel())
    if not where.size:
        e = np.zeros(0, dtype=int)
        return _Runs(e, e, np.zeros(0), np.zeros(0), e, e)
    # runs are contiguous in the flattened valid entries: segment reductions with reduceat
    Lv, Hv, Cv = L.ravel()[where], H.ravel()[where], where % n
    sv = ~prev.ravel()[where]
    starts = np.flatnonzero(sv)
    lo = np.minimum.reduceat(Lv, starts)
    hi = np.maximum.reduceat(Hv, starts)
    seg = np.cumsum(sv) - 1
    amin = np.minimum.reduceat(np.where(Lv == lo[seg], Cv, n), starts)
    amax = np.minimum.reduceat(np.where(Hv == hi[seg], Cv, n), starts)
    return _Runs(where[starts] // n, Cv[starts], lo, hi, amin, amax)


def _b_parts(cols: Columns) -> tuple[np.ndarray, np.ndarray]:
    """``Re b, Im b`` as contiguous arrays, made once per columns."""
    if "b parts" not in cols.cache:
        cols.cache["b parts"] = (np.ascontiguousarray(cols.b.real), np.ascontiguousarray(cols.b.imag))
    return cols.cache["b parts"]


def _db(cols: Columns) -> np.ndarray:
    """``|b|``'s change between neighbouring columns, ``|diff(b)|``, made once per columns."""
    if "db" not in cols.cache:
        cols.cache["db"] = np.abs(np.diff(cols.b))
    return cols.cache["db"]


def _parts(cols: Columns) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``Re u, Im u, Re a, Im a`` as contiguous arrays, made once per columns."""
    if "parts" not in cols.cache:
        cols.cache["parts"] = tuple(np.ascontiguousarray(p) for p in (cols.u.real, cols.u.imag, cols.a.real,
                                                                      cols.a.imag))
    return cols.cache["parts"]


def _entries(lo: np.ndarray, hi: np.ndarray, col: np.ndarray) -> _Runs:
    """Each non-empty entry (``lo < inf``) of a piece not joined over frequency, as a run of its own."""
    row, j = np.nonzero(lo < _INF)
    return _Runs(row, j, lo[row, j], hi[row, j], col[row, j], col[row, j])


def _compact(m: int, parts: list[tuple[_Runs, int, int, int, int]]) -> Forbidden:
    """The runs of every piece ``(runs, first column's index, constraint, lower root, upper root)`` as one
    :class:`Forbidden` with a row per line, in the order of the pieces and columns, padded with empty
    entries ``[inf, -inf]``."""
    row = np.concatenate([r.row for r, *_ in parts])
    order = np.lexsort((np.concatenate([r.first + off for r, off, *_ in parts]), row))
    row = row[order]
    count = np.bincount(row, minlength=m)
    k = max(1, int(count.max()))
    pos = np.arange(row.size) - np.repeat(np.cumsum(count) - count, count)

    def fill(values: list[np.ndarray], pad: float) -> np.ndarray:
        flat = np.concatenate(values)
        out = np.full((m, k), pad, dtype=flat.dtype)
        out[row, pos] = flat[order]
        return out

    def each(i: int) -> list[np.ndarray]:
        return [np.full(r.row.size, p[i]) for r, *p in parts]

    none = int(Root.INFINITE)
    return Forbidden(fill([r.lo for r, *_ in parts], _INF), fill([r.hi for r, *_ in parts], -_INF),
                     fill([r.col_lo for r, *_ in parts], 0), fill([r.col_hi for r, *_ in parts], 0),
                     fill(each(1), 0), fill(each(2), none), fill(each(3), none))


def forbidden(cols: Columns, x: np.ndarray, which: Sequence[int], hull: bool = True) -> Forbidden:
    """Forbidden ky-intervals for lines ``x`` (m,), over every column and constraint in ``which``.

    Each (column, constraint) gives the pieces of :func:`forbidden_interval`.  With ``hull`` each piece
    is replaced by the hull of its frequency runs (:func:`_run_hull`), one entry per run, and the
    entries differ from line to line (``constraint`` and the roots too have shape (m, K)); without, there
    is one entry per column and piece, the same on every line (``constraint`` and the roots: (K,)).
    """
    m = x.size
    los, his, cl, cons, lr, hr = [], [], [], [], [], []
    runs: list[tuple[_Runs, int, int, int, int]] = []
    offset = 0
    ncol = cols.u.size
    colidx = np.broadcast_to(np.arange(ncol), (m, ncol))
    ur, ui, ar, ai = _parts(cols)
    compiled = kernel() if hull else None
    Ur = Ui = dU = None
    U: np.ndarray | None = None
    for ci in which:
        nu, na, nb, w2 = cols.constraints[ci]
        fixed = _fixed_numerator(cols, ci)
        if fixed is not None and compiled is not None:  # the pieces and their runs' hull in one compiled pass
            *hull_runs, lrow, lpos, llo, lhi, lcol, nz = compiled(
                np.ascontiguousarray(x, dtype=float), ur, ui, ar, ai, *_b_parts(cols), fixed[0], fixed[1], _db(cols), 0.25 * cols.data.r_min,
                cols.n_grid)
            first, offset = offset, offset + ncol
            if hull_runs[0].size:
                runs.append((_Runs(*hull_runs), first, ci, int(Root.SMALLER), int(Root.LARGER)))
            if nz:  # the linear case's entries, on the columns where A = 0 (as _fixed_numerator_pieces gives them)
                first, offset = offset, offset + nz
                if lrow.size:
                    runs.append((_Runs(lrow, lpos, llo, lhi, lcol, lcol), first, ci, int(Root.LINEAR),
                                 int(Root.LINEAR)))
            continue
        if Ur is None:  # 1 + L without ky, in real and imaginary parts (the same numbers as u + x a in complex)
            Ur = np.multiply(x[:, None], ar[None, :])
            np.add(ur[None, :], Ur, out=Ur)
            Ui = np.multiply(x[:, None], ai[None, :])
            np.add(ui[None, :], Ui, out=Ui)
            if hull:  # |change of u + x a| between neighbouring columns
                dU = np.subtract(Ur[:, 1:], Ur[:, :-1])
                dUi = np.subtract(Ui[:, 1:], Ui[:, :-1])
                np.hypot(dU, dUi, out=dU)
                del dUi
        if fixed is not None:  # ||S||inf-like: N = nu, A = |b|^2 >= 0 at every column
            pieces: list[tuple[ForbiddenPiece, np.ndarray | None]] = _fixed_numerator_pieces(Ur, Ui, cols.b, *fixed)
        else:
            if U is None:
                U = cols.u[None, :] + x[:, None] * cols.a[None, :]
            N = nu[None, :] + x[:, None] * na[None, :]
            pieces = [(pc, None) for pc in forbidden_interval(U, N, cols.b[None, :], nb[None, :], w2[None, :])]
        for (lo_, hi_, lroot, hroot, V), on in pieces:
            first, offset = offset, offset + lo_.shape[1]
            if (V is not None and not V.any()) or (V is None and not np.any(lo_ <= hi_)):
                continue  # empty everywhere on these lines (e.g. no A < 0 for an unweighted Ms bound)
            c_at = colidx if on is None else colidx[:, on]
            if hull:
                r = _run_hull(cols, lo_, hi_, V, dU) if V is not None else _entries(lo_, hi_, c_at)
                runs.append((r, first, ci, int(lroot), int(hroot)))
                continue
            los.append(lo_)
            his.append(hi_)
            cl.append(c_at)
            cons.append(np.full(lo_.shape[1], ci))
            lr.append(np.full(lo_.shape[1], int(lroot)))
            hr.append(np.full(lo_.shape[1], int(hroot)))
    if runs:
        return _compact(m, runs)
    if not los:  # nothing forbidden anywhere: one empty piece keeps the shapes
        los, his, cl = [np.full((m, 1), _INF)], [np.full((m, 1), -_INF)], [np.zeros((m, 1), int)]
        cons, lr, hr = [np.zeros(1, int)], [np.full(1, int(Root.INFINITE))], [np.full(1, int(Root.INFINITE))]
    col = np.concatenate(cl, axis=1)
    return Forbidden(np.concatenate(los, axis=1), np.concatenate(his, axis=1), col, col, np.concatenate(cons),
                     np.concatenate(lr), np.concatenate(hr))


def _fixed_numerator(cols: Columns, ci: int) -> tuple[np.ndarray, np.ndarray] | None:
    """``(A, w2 |nu|^2)`` per column when constraint ``ci``'s numerator does not depend on the gains
    (``na = nb = 0``: a bound on ``S``, weighted or not), so that ``A = |b|^2 >= 0`` at every column
    (0 where ``b`` vanishes, e.g. the limit columns of a decaying ``b``); else None."""
    key = ("fixed numerator", ci)
    if key not in cols.cache:
        cols.cache[key] = _fixed_numerator_of(cols, ci)
    return cols.cache[key]


def _fixed_numerator_of(cols: Columns, ci: int) -> tuple[np.ndarray, np.ndarray] | None:
    nu, na, nb, w2 = cols.constraints[ci]
    if np.any(na != 0) or np.any(nb != 0):
        return None
    A = np.abs(cols.b) ** 2 - w2 * np.abs(nb) ** 2
    Ascale = np.abs(cols.b) ** 2 + w2 * np.abs(nb) ** 2
    with np.errstate(invalid="ignore"):
        A = np.where(np.abs(A) <= 1e-13 * Ascale, 0.0, A)
        if np.any(A < 0):
            return None
    return A, w2 * np.abs(nu) ** 2


def _fixed_numerator_pieces(Ur: np.ndarray, Ui: np.ndarray, b: np.ndarray, A: np.ndarray,
                            c: np.ndarray) -> list[tuple[ForbiddenPiece, np.ndarray | None]]:
    """:func:`forbidden_interval`'s pieces for a numerator free of the gains, in real arithmetic
    (``B = Re(U conj b)``, ``D = |U|^2 - w2 |nu|^2``; the same stable roots ``D / q`` and ``q / A``): the
    interval where ``A > 0`` (every column), and where ``A = 0`` the ray or everything (on those columns
    only, given as the second item; no ``A < 0`` here)."""
    # the same operations as in complex arithmetic, on as few fresh (m, columns) arrays as possible:
    # with a lumped shaper's tens of thousands of columns, allocating them costs more than the arithmetic
    br, bi = np.ascontiguousarray(b.real)[None, :], np.ascontiguousarray(b.imag)[None, :]
    A2, c2 = A[None, :], c[None, :]
    B = np.multiply(Ur, br)
    tmp = np.multiply(Ui, bi)
    B += tmp
    D = np.multiply(Ur, Ur)
    np.multiply(Ui, Ui, out=tmp)
    D += tmp
    D -= c2
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        disc = np.multiply(B, B)
        np.multiply(A2, D, out=tmp)
        disc -= tmp
        s = np.maximum(disc, 0.0)
        np.sqrt(s, out=s)
        # q = -(B + sign(B) s) = (s if B < 0 else -s) - B, the same number (rounding is symmetric);
        # NaN B: NaN, not an interval below.  (A masked negation was the slowest line here.)
        q = np.negative(s)
        np.copyto(q, s, where=B < 0)
        q -= B
        r1 = np.divide(D, q, out=tmp)
        r1[q == 0] = 0.0
        pos = np.isfinite(D)
        pos &= np.isfinite(B)
        pos &= A2 > 0
        pos &= disc > 0
        r2 = np.divide(q, A2, out=q)
        lo = np.fmin(r1, r2, out=disc)
        hi = np.fmax(r1, r2, out=r2)
    notpos = ~pos
    np.copyto(lo, _INF, where=notpos)
    np.copyto(hi, -_INF, where=notpos)
    out: list[tuple[ForbiddenPiece, np.ndarray | None]] = [(ForbiddenPiece(lo, hi, Root.SMALLER, Root.LARGER, pos),
                                                            None)]
    z = np.flatnonzero(A == 0)
    if z.size:  # the linear case, on those columns only: 2 B ky + D <= 0
        Bz, Dz = B[:, z], D[:, z]
        ok = np.isfinite(Ur[:, z]) & np.isfinite(Ui[:, z]) & np.isfinite(Dz) & np.isfinite(Bz)
        with np.errstate(invalid="ignore", divide="ignore"):
            root = -Dz / (2.0 * Bz)
        zpos, zneg, zall = ok & (Bz > 0), ok & (Bz < 0), ok & (Bz == 0) & (Dz <= 0)
        lo4 = np.where(zpos, -_INF, np.where(zneg, root, np.where(zall, -_INF, _INF)))
        hi4 = np.where(zpos, root, np.where(zneg, _INF, np.where(zall, _INF, -_INF)))
        out.append((ForbiddenPiece(lo4, hi4, Root.LINEAR, Root.LINEAR, None), z))
    return out


def line_forbidden(cols: Columns, x: float) -> Forbidden:
    """:func:`forbidden` on the line ``x`` over every column and constraint, without the hull: the few
    lines the exact optimum visits are asked for again and again (the branches above and below, the
    limit columns), so the last ones are kept with the columns."""
    memo = cols.cache.setdefault("lines", {})
    key = float(x)
    if key not in memo:
        if len(memo) >= 8:
            memo.pop(next(iter(memo)))
        memo[key] = forbidden(cols, np.array([key]), range(cols.n_constraints), hull=False)
    return memo[key]


#: What bounds each admissible interval of a line, below and above.
Ends = list[tuple[IntervalEnd, IntervalEnd]]


def complement(f: Forbidden) -> list[tuple[np.ndarray, Ends]]:
    """Per line: admissible open intervals (complement of the union of ``f``) and their ends' branches."""
    order = np.argsort(f.lo, axis=1, kind="stable")
    los = np.take_along_axis(f.lo, order, axis=1)
    his = np.take_along_axis(f.hi, order, axis=1)
    cm = np.maximum.accumulate(his, axis=1)
    if f.constraint.ndim == 1:  # one entry per column, the same on every line
        shape = f.lo.shape
        f = f._replace(constraint=np.broadcast_to(f.constraint, shape), lower_root=np.broadcast_to(f.lower_root, shape),
                       upper_root=np.broadcast_to(f.upper_root, shape))
    return [_line_complement(f, i, los[i], cm[i], order[i], his[i]) for i in range(f.lo.shape[0])]


def meets(f: Forbidden, lo: float, hi: float) -> np.ndarray:
    """Per line: does an admissible interval of :func:`complement` (``f``'s open gaps) meet ``(lo, hi)``?

    The same gaps as :func:`complement` (sorted lower ends, running maximum of the upper ends), found for
    every line at once and without naming their ends (issue #15: the probe of
    :func:`~posicast.tune.scan._forbidden_on_probe` has an entry per column, thousands per line)."""
    order = np.argsort(f.lo, axis=1, kind="stable")
    los = np.take_along_axis(f.lo, order, axis=1)
    his = np.take_along_axis(f.hi, order, axis=1)
    valid = los < _INF
    cm = np.maximum.accumulate(np.where(valid, his, -_INF), axis=1)
    m = los.shape[0]
    # gap j runs from the running maximum before entry j (-inf for j = 0) to entry j's lower end (inf past the
    # valid entries): (-inf, lo_0), the gaps between entries, (max hi, inf); the repeats of the last are harmless
    starts = np.concatenate([np.full((m, 1), -_INF), cm], axis=1)
    ends = np.concatenate([np.where(valid, los, _INF), np.full((m, 1), _INF)], axis=1)
    return np.any(np.maximum(starts, lo) < np.minimum(ends, hi), axis=1)


def meets_window(cols: Columns, x: np.ndarray, which: Sequence[int], lo: float, hi: float) -> np.ndarray:
    """``meets(forbidden(cols, x, which, hull=False), lo, hi)``: per line, is some ``ky`` in ``(lo, hi)`` admissible
    at every column?  Compiled (:func:`~posicast.tune._kernels.fixed_numerator_meets`) where every constraint
    of ``which`` has a fixed numerator: the same answer, from the intervals that reach into the window."""
    compiled = kernel("meets")
    fixed = [_fixed_numerator(cols, ci) for ci in which]
    if compiled is None or not fixed or any(f is None for f in fixed):
        return meets(forbidden(cols, x, which, hull=False), lo, hi)
    A = np.stack([f[0] for f in fixed])
    c = np.stack([f[1] for f in fixed])
    return compiled(np.ascontiguousarray(x, dtype=float), *_parts(cols), *_b_parts(cols), A, c, float(lo), float(hi))


def _line_complement(f: Forbidden, i: int, li: np.ndarray, ci: np.ndarray, oi: np.ndarray,
                     hi_: np.ndarray) -> tuple[np.ndarray, Ends]:
    """The gaps of one line's sorted forbidden intervals (``li`` sorted lower ends, ``ci`` the running
    maximum of the upper ends ``hi_``, ``oi`` the sort order)."""
    nvalid = int(np.searchsorted(li, _INF, side="left"))  # intervals with lo < inf
    if nvalid == 0:
        return np.array([[-_INF, _INF]]), [(None, None)]
    li, ci, oi, hi_ = li[:nvalid], ci[:nvalid], oi[:nvalid], hi_[:nvalid]
    gaps = np.flatnonzero(li[1:] > ci[:-1])
    # where the running maximum first takes its value: argmax(hi_[:j + 1]) for every j at once (a line of a
    # lumped shaper's loop has thousands of entries: one argmax per gap was a tenth of pass 2 on the crane)
    first_max = None
    if (gaps.size or ci[-1] < _INF) and not np.isnan(hi_).any():
        rising = np.empty(nvalid, dtype=bool)
        rising[0] = True
        np.greater(hi_[1:], ci[:-1], out=rising[1:])
        first_max = np.maximum.accumulate(np.where(rising, np.arange(nvalid), 0))

    def attr_hi(j: int) -> Branch | None:  # the interval whose hi is the running max at j
        k = int(np.argmax(hi_[: j + 1])) if first_max is None else int(first_max[j])
        kk = oi[k]
        return Branch(int(f.col_hi[i, kk]), int(f.constraint[i, kk]), int(f.upper_root[i, kk])) \
            if math.isfinite(hi_[k]) else None

    def attr_lo(j: int) -> Branch | None:
        kk = oi[j]
        return Branch(int(f.col_lo[i, kk]), int(f.constraint[i, kk]), int(f.lower_root[i, kk])) \
            if math.isfinite(li[j]) else None

    iv: list[tuple[float, float]] = []
    ends: Ends = []
    if li[0] > -_INF:
        iv.append((-_INF, li[0]))
        ends.append((None, attr_lo(0)))
    for j in gaps:
        iv.append((ci[j], li[j + 1]))
        ends.append((attr_hi(int(j)), attr_lo(int(j) + 1)))
    if ci[-1] < _INF:
        iv.append((ci[-1], _INF))
        ends.append((attr_hi(nvalid - 1), None))
    return np.array(iv, dtype=float).reshape(-1, 2), ends
