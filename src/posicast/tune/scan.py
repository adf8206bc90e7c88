"""The line scan: the gain plane along lines ``kx = const`` (seed 001 section 3, steps 4-5 of Algorithm 1).

On each line:

1. **H-infinity regions, exactly in ky** (:mod:`posicast.tune.hinf`).  At every
   frequency a constraint is a quadratic in ``ky``: its forbidden set is an
   interval (or two rays).  Over a connected run of frequencies the union of
   these intervals is ``[min lo, max hi]``, so the admissible set on the line is
   the complement of a few intervals whose ends are extrema over frequency of
   the quadratic's roots.  The extrema come from the refined grid
   (:class:`~posicast.tune.frequency.FrequencyData`), polished between columns;
   the chosen design point gets an exact 1-D refinement in frequency.
2. **D-decomposition** (:mod:`posicast.tune.boundaries`): the complex-, real- and
   infinite-root boundaries break the line into segments, each inside one
   D-decomposition cell.

:class:`Problem` holds what the scan needs for one tuning problem;
:func:`scan_lines` returns one :class:`LineData` per line.  The cells are
joined and labelled in :mod:`posicast.tune.cells`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from ..core.quasipoly import QuasiPolynomial
from ..loops import Loop
from .boundaries import (BreakKind, ComplexBreaks, ComplexCurve, InfiniteBoundary, RealBoundary, complex_breaks,
                         complex_curve, crossing_frequency, horizontal_crossing, infinite_boundary, real_boundary)
from .cells import StabilityLedger
from .frequency import (Asymptote, Columns, FrequencyData, columns_of, grid_subset, thin_columns, thinnable,
                        with_frequencies)
from .hinf import Branch, Cut, Ends, IntervalEnd, complement, forbidden, meets_window
from .refine import forbidden_window, polish_ends

__all__ = ["Problem", "LineData", "make_problem", "regrid", "scan_lines", "forbidden_above", "intersect", "subtract"]

_INF = math.inf


# ---------------------------------------------------------------------- the problem
@dataclass(frozen=True)
class Problem:
    """Everything the line scan of one tuning problem needs.

    Attributes
    ----------
    columns : Columns
        The frequency data on the current grid.
    curve : ComplexCurve
        The complex-root boundary on that grid.
    real, infinite : RealBoundary, InfiniteBoundary
        The boundaries at s = 0 and s = infinity (independent of the grid).
    loop_factory : callable
        ``(kx, ky) -> Loop``, for the certified spectrum checks.
    y_window : (float, float)
        The ``ky`` window of interest (the tuning's ``ky_range`` or its automatic
        search window): H-infinity intervals are clipped to it, so that no work is
        spent beyond it.
    x_valid, y_valid : float
        The largest ``|kx|``, ``|ky|`` for which the grid covers every frequency
        where that term of ``L`` matters (:func:`_valid_gain`).
    ledger : StabilityLedger
        The certified spectrum checks made so far.
    """

    columns: Columns
    curve: ComplexCurve
    real: RealBoundary
    infinite: InfiniteBoundary
    loop_factory: Callable[[float, float], Loop]
    y_window: tuple[float, float]
    x_valid: float
    y_valid: float
    ledger: StabilityLedger = field(default_factory=StabilityLedger)

    @property
    def fd(self) -> FrequencyData:
        """The frequency data (exact evaluation off the grid)."""
        return self.columns.data

    def crossing(self, x0: Any, x1: Any, ys: Any) -> np.ndarray:
        """:func:`~posicast.tune.boundaries.horizontal_crossing` for this problem."""
        return horizontal_crossing(self.columns, self.curve, self.real, self.infinite, x0, x1, ys)


def _settled(fd: FrequencyData) -> float:
    """How small ``|L|`` must be past the grid's end for every constraint to hold there.

    1e-3 in general.  With unweighted ``||S||inf < Ms`` constraints only,
    ``|L| <= eps`` gives ``|S| <= 1 / (1 - eps)``, below ``Ms`` for
    ``eps < 1 - 1 / Ms``: half of that (at most 0.1) is used.  ``|L| < 1`` also
    rules out a root of ``1 + L`` there.
    """
    cons = fd.constraints
    if cons and all(c.kind == "S" and c.weight is None for c in cons):
        g = min(c.gamma for c in cons)
        if g > 1.0:
            return float(min(0.1, max(1e-3, 0.5 * (1.0 - 1.0 / g))))
    return 1e-3


def _valid_gain(cols: Columns, term: np.ndarray, asym: Asymptote) -> float:
    """Largest gain for which the grid covers every frequency where that term of ``L`` matters.

    The grid ends at least 30 times above every feature, where a decaying
    term (relative degree ``m < 0``) only decays further; for gains up to this
    bound it is below :func:`_settled` past the grid's end, so ``1 + L`` and
    the channels are settled there.  A term whose high-frequency form
    ``(j omega)^m h(omega)`` oscillates in magnitude (a lumped shaper in the loop: ``S`` has zeros near
    the axis every period) is bounded past the end by its envelope ``omega^m sup |h|``, not by its value at
    the last column, which may sit near one of those zeros.  A term with a nonzero limit (``m = 0``) is
    covered by the limit columns at every gain.  :meth:`FrequencyData.refine` extends
    the grid when larger gains are scanned.
    """
    if asym.m >= 0:
        return _INF
    last = abs(term[cols.n_grid - 1])
    peak = asym.peak
    if peak is not None and math.isfinite(peak):  # (an infinite peak: h has poles on the axis, a neutral loop)
        last = max(last, float(cols.omega[cols.n_grid - 1]) ** asym.m * peak)
    return _INF if not last > 0 else _settled(cols.data) / last


def make_problem(fd: FrequencyData, loop_factory: Callable[[float, float], Loop],
                 char_terms: tuple[QuasiPolynomial, QuasiPolynomial, QuasiPolynomial], zero_order: int,
                 y_window: tuple[float, float]) -> Problem:
    """The scan's problem on ``fd``'s current grid (``char_terms``: the characteristic's parts ``1, kx, ky``;
    ``zero_order``: the multiplicity of the shaper's removable root at 0)."""
    return _on_grid(fd, loop_factory, real_boundary(char_terms, zero_order), infinite_boundary(char_terms),
                    y_window, StabilityLedger())


def regrid(problem: Problem, fd: FrequencyData | None = None) -> Problem:
    """The same problem on its frequency data's new grid (after :meth:`FrequencyData.refine`), or on ``fd``'s
    (a refined copy of it), with the same stability ledger."""
    return _on_grid(problem.fd if fd is None else fd, problem.loop_factory, problem.real, problem.infinite,
                    problem.y_window, problem.ledger)


def _on_grid(fd: FrequencyData, loop_factory: Callable[[float, float], Loop], real: RealBoundary,
             infinite: InfiniteBoundary, y_window: tuple[float, float], ledger: StabilityLedger) -> Problem:
    cols = columns_of(fd)
    return Problem(cols, complex_curve(cols), real, infinite, loop_factory, y_window,
                   _valid_gain(cols, cols.a, fd.asymptote("a")), _valid_gain(cols, cols.b, fd.asymptote("b")),
                   ledger)


# ---------------------------------------------------------------------- per-line data
@dataclass(frozen=True)
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
        :class:`~posicast.tune.boundaries.BreakKind` values: ``'c'`` complex-root,
        ``'r'`` real-root (s = 0), ``'i'`` infinite-root.
    ends : list of (IntervalEnd, IntervalEnd)
        What bounds each ``hinf`` interval below and above (None for an infinite end).
    comp : ndarray of int
        Component id of each segment (``len(breaks) + 1``), -1 if not assigned.
    break_err : ndarray
        Uncertainty of each break: complex-root crossings are interpolated between
        grid columns (the width of that bracket in ``ky``), unless refined exactly.
    """

    x: float
    hinf: np.ndarray
    per_constraint: list[np.ndarray]
    breaks: np.ndarray
    break_kind: np.ndarray
    ends: Ends
    comp: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    break_err: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def error_at(self, value: float) -> float:
        """Uncertainty of the break at ``value`` (0 for exact breaks and infinite ends)."""
        if not math.isfinite(value) or self.breaks.size == 0:
            return 0.0
        k = int(np.searchsorted(self.breaks, value))  # the breaks are sorted: the first equal one, if any
        return float(self.break_err[k]) if k < self.breaks.size and self.breaks[k] == value and \
            self.break_err.size else 0.0

    def segment_bounds(self, j: int) -> tuple[float, float]:
        lo = -_INF if j == 0 else float(self.breaks[j - 1])
        hi = _INF if j == self.breaks.size else float(self.breaks[j])
        return lo, hi

    @property
    def n_segments(self) -> int:
        return self.breaks.size + 1


def subtract(iv: np.ndarray, ends: Ends, cuts: list[tuple[float, float, Cut]]) -> tuple[np.ndarray, Ends]:
    """Remove the closed intervals ``cuts`` from the open intervals ``iv``; a new end is its :class:`Cut`."""
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


def intersect(a: np.ndarray, b: np.ndarray) -> np.ndarray:
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


# ---------------------------------------------------------------------- the scan
def scan_lines(problem: Problem, xs: np.ndarray) -> list[LineData]:
    """Compute :class:`LineData` for each ``x`` in ``xs`` (vectorised over frequency, in blocks of lines).

    On a grid that can be thinned, the lines are taken in groups of similar ``|x|``
    (a decade each).  A group's H-infinity intervals are computed on the grid
    columns its gains need over the whole ``ky`` window
    (:func:`~posicast.tune.frequency.thin_columns`: with a lumped shaper the grid is
    dense only where ``|L|`` is large for those gains); its D-decomposition
    crossings on the whole grid.  Otherwise every line needs every column: one group.
    """
    cols = problem.columns
    xs = np.asarray(xs, dtype=float)
    out: list[LineData | None] = [None] * xs.size
    y_top = min(max(abs(problem.y_window[0]), abs(problem.y_window[1])), problem.y_valid)
    mag = np.abs(xs)
    with np.errstate(divide="ignore"):
        decade = np.floor(np.log10(mag))  # -inf at x = 0: those lines join the lowest decade
    finite = np.isfinite(decade)
    decade = np.where(finite, decade, float(decade[finite].min()) if finite.any() else 0.0)
    if not thinnable(cols):  # every line needs every column: one group (the same numbers, fewer calls)
        decade = np.zeros_like(decade)
    crossings = _crossings(problem, xs)
    def thinned(d: float) -> tuple[Columns, np.ndarray | None]:
        """The columns decade ``d`` needs, blocked lines included (the same thinning with or without them)."""
        return thin_columns(cols, float(mag[decade == d].max()), y_top)

    blocked = np.zeros(xs.size, dtype=bool)
    if cols.n_constraints == 1 and thinnable(cols):
        # from the largest gains down, while the probe still finds forbidden lines (small gains rarely are)
        # and costs a fraction of the scan (a narrow window's thinned columns are about as many as its own)
        for d in np.unique(decade)[::-1]:
            if _PROBE_SHARE * _probe(cols).u.size > thinned(d)[0].u.size:
                break
            group = np.flatnonzero(decade == d)
            blocked[group] = _forbidden_on_probe(problem, xs[group])
            if not blocked[group].any():
                break
    for i in np.flatnonzero(blocked):
        out[i] = _blocked_line(problem, xs[i], crossings[i])
    for d in np.unique(decade):
        group = np.flatnonzero((decade == d) & ~blocked)
        if not group.size:
            continue
        sub, sel = thinned(d)
        block = max(1, int(2_000_000 // max(1, sub.u.size * max(1, sub.n_constraints))))
        for k in range(0, group.size, block):
            idx = group[k : k + block]
            for i, line in zip(idx, _scan_block(problem, sub, sel, xs[idx], [crossings[j] for j in idx])):
                out[i] = line
    return [ln for ln in out if ln is not None]


#: the probe of :func:`_forbidden_on_probe`: about this many evenly spaced grid columns
_PROBE_COLUMNS = 1024
#: the probe runs only on lines whose thinned columns are at least this many times its own (issue #15: pass 2's
#: window around the inverse ZV loop's optimum needs 2 300-3 100 columns, the probe has 2 100, limit columns
#: included; it left 7 of 161 lines out there, at a sixth of the whole scan's time)
_PROBE_SHARE = 4
#: the probe of :func:`forbidden_above`: every grid column up to this many (the inner lines' grid has 12 000 to
#: 25 000 on the seed 001 crane: every 18th column left 9 outer lines of the inverse ZV loop unshown, every
#: column 4), and this many frequencies from the grid's end to the top
_ABOVE_GRID_COLUMNS = 32768
_ABOVE_TOP_COLUMNS = 1024


def _forbidden_on_probe(problem: Problem, xs: np.ndarray) -> np.ndarray:
    """Which lines ``xs`` the (single) H-infinity constraint forbids over the whole verified window, shown on
    a probe of every k-th grid column and the limit columns.

    Each probe column's forbidden interval is exact (the bound fails there at that frequency), so a line
    the probe's union covers from ``max(-y_valid, y_window[0])`` to ``min(y_valid, y_window[1])`` has no
    admissible gain at all: :func:`_blocked_line` gives it the :class:`LineData` of a line without admissible
    intervals.  The scan would give it the same wherever its columns include the probe's (on the whole grid a
    probe column is its own entry or inside a run's hull); a thinned scan that missed a probe column's
    violation would be the less exact of the two.  Issue #15: with a lumped shaper, most of the sweep's lines
    at large ``|kx|`` are forbidden throughout, and a probe of ~1000 of the ~85 000 columns shows it for
    nearly all of them.
    """
    y_lo = max(-problem.y_valid, problem.y_window[0])
    y_hi = min(problem.y_valid, problem.y_window[1])
    return ~meets_window(_probe(problem.columns), xs, [0], y_lo, y_hi)


def _probe(cols: Columns) -> Columns:
    """The columns of :func:`_forbidden_on_probe`: about :data:`_PROBE_COLUMNS` of the grid's, and the limit columns."""
    if "probe" not in cols.cache:
        cols.cache["probe"] = grid_subset(cols, np.arange(0, cols.n_grid, max(1, cols.n_grid // _PROBE_COLUMNS)))
    return cols.cache["probe"]


def forbidden_above(problem: Problem, xs: np.ndarray, floor: float, top: float) -> tuple[np.ndarray, int]:
    """Which lines ``xs`` have no H-infinity-admissible ``ky`` in ``[floor, y_window[1]]``, shown on a probe;
    and how many frequency columns the probe has.

    The probe: the grid's columns (about :data:`_ABOVE_GRID_COLUMNS` evenly spaced ones on a larger grid),
    :data:`_ABOVE_TOP_COLUMNS` frequencies evenly spaced from the grid's end up to ``top`` [rad/s] (exact
    values), and the limit columns.  Each column's forbidden intervals are exact (every constraint fails
    there, at that frequency), whatever the gains: the grid need not be valid for ``xs``.  So a line shown
    here has no admissible gain at or above ``floor``; a line not shown may still have none (the probe is a
    sample).  Issue #15: with a lumped shaper in the loop, the sweep's lines at large ``|kx|`` need a grid up
    to the delay ceiling; where they are shown to hold nothing above the best point of the inner lines, the
    design does without them.
    """
    cols = problem.columns
    key = ("probe above", float(top))
    if key not in cols.cache:
        probe = grid_subset(cols, np.arange(0, cols.n_grid, max(1, cols.n_grid // _ABOVE_GRID_COLUMNS)))
        end = float(cols.omega[cols.n_grid - 1])
        if top > end:
            probe = with_frequencies(probe, np.linspace(end, top, _ABOVE_TOP_COLUMNS + 1)[1:])
        cols.cache[key] = probe
    probe = cols.cache[key]
    shown = ~meets_window(probe, xs, range(cols.n_constraints), floor, problem.y_window[1])
    return shown, int(probe.u.size)


def _blocked_line(problem: Problem, x: Any, cbr: ComplexBreaks) -> LineData:
    """The :class:`LineData` of a line with no admissible interval (what :func:`_scan_block` gives it)."""
    iv = np.zeros((0, 2))
    iv, ends, cx = _cut_missed_intervals(problem, float(x), iv, [], cbr)
    breaks, kinds, errs = _line_breaks(problem, x, cx)
    return LineData(float(x), iv, [iv], breaks, kinds, ends, np.full(breaks.size + 1, -1, dtype=int), errs)


def _crossings(problem: Problem, xs: np.ndarray) -> list[ComplexBreaks]:
    """The complex-root crossings of every line ``xs`` on the whole grid: in one call where the curve form
    is used (each line's crossings are the same as alone; issue #15: one pass over the curve's segments
    instead of one per group of lines), else in blocks of lines that keep the (lines x columns) arrays small."""
    cols = problem.columns
    if problem.curve.ok:  # _line_breaks keeps the window's crossings and the nearest beyond each end
        return complex_breaks(cols, problem.curve, xs, window=problem.y_window)
    step = max(1, int(2_000_000 // max(1, cols.u.size)))
    return [c for k in range(0, xs.size, step) for c in complex_breaks(cols, problem.curve, xs[k: k + step])]


def _scan_block(problem: Problem, sub: Columns, sel: np.ndarray | None, xb: np.ndarray,
                cbr: list[ComplexBreaks]) -> list[LineData]:
    """The lines ``xb``: H-infinity intervals on the columns ``sub`` (the grid's columns ``sel``; None: all)."""
    cols = problem.columns
    nc = cols.n_constraints
    total = complement(forbidden(sub, xb, range(nc)))
    per: list[list[np.ndarray]] = [[] for _ in xb]
    if nc > 1:
        for ci in range(nc):
            for i, (iv, _) in enumerate(complement(forbidden(sub, xb, [ci]))):
                per[i].append(iv)
    polished, total = _polish_block(sub, sel, cols, xb, total)
    out = []
    for i, x in enumerate(xb):
        iv, ends, per_i = _clip_to_window(problem, polished[i], total[i][1], per[i])
        iv, ends, cx = _cut_missed_intervals(problem, float(x), iv, ends, cbr[i])
        breaks, kinds, errs = _line_breaks(problem, x, cx)
        out.append(LineData(float(x), iv, per_i if nc > 1 else [iv], breaks, kinds, ends,
                            np.full(breaks.size + 1, -1, dtype=int), errs))
    return out


def _polish_block(sub: Columns, sel: np.ndarray | None, cols: Columns, xb: np.ndarray,
                  total: list[tuple[np.ndarray, Ends]]) -> tuple[list[np.ndarray], list[tuple[np.ndarray, Ends]]]:
    """Every interval end of a block of lines polished in one vectorised pass (:func:`polish_ends`).

    On thinned columns (``sel`` not None) each end is then named by the whole grid's column
    nearest to its extremum and polished again between that grid's neighbours (as on the whole
    grid), so that later refinements (:func:`~posicast.tune.refine.exact_end`) bracket it there too.
    """
    flat_ends = [e for _, ends in total for pair in ends for e in pair]
    flat_x = np.concatenate([np.full(2 * len(ends), x) for x, (_, ends) in zip(xb, total)])
    flat_v = np.concatenate([iv.reshape(-1) for iv, _ in total])
    upper = np.concatenate([np.tile([False, True], len(ends)) for _, ends in total])
    polished, where = polish_ends(sub, flat_x, flat_ends, flat_v, upper, where=True)
    offsets = np.cumsum([0] + [2 * len(ends) for _, ends in total])
    if sel is not None:
        named = _grid_branches(flat_ends, where, sub, sel, cols)
        # polished again between the whole grid's neighbours of the extremum: as exact as without thinning
        polished = polish_ends(cols, flat_x, named, polished, upper)
        total = [(iv, [(named[offsets[i] + 2 * j], named[offsets[i] + 2 * j + 1]) for j in range(len(ends))])
                 for i, (iv, ends) in enumerate(total)]
    return [polished[offsets[i] : offsets[i + 1]].reshape(-1, 2).copy() for i in range(len(total))], total


def _grid_branches(ends: list[IntervalEnd], where: np.ndarray, sub: Columns, sel: np.ndarray,
                   cols: Columns) -> list[IntervalEnd]:
    """Branches found on the thinned columns ``sub``, each named by the whole grid's column nearest to its
    polished extremum ``where`` (the column it was found at where that is not finite); a limit column keeps
    its place among the limit columns; other ends as they are.  (One binary search for all of them.)"""
    out = list(ends)
    k = [i for i, e in enumerate(ends) if isinstance(e, Branch)]
    if not k:
        return out
    column = np.array([ends[i].column for i in k])
    grid = column < sub.n_grid
    named = np.where(grid, 0, cols.n_grid + column - sub.n_grid)
    named[grid] = sel[column[grid]]
    w = where[k]
    near = grid & np.isfinite(w)
    if near.any():
        j = np.clip(np.searchsorted(cols.omega, w[near]), 1, cols.n_grid - 1)
        named[near] = np.where(np.abs(cols.omega[j] - w[near]) < np.abs(cols.omega[j - 1] - w[near]), j, j - 1)
    for i, c in zip(k, named.tolist()):
        out[i] = Branch(c, ends[i].constraint, ends[i].root)
    return out


def _clip_to_window(problem: Problem, iv: np.ndarray, ends: Ends,
                    per: list[np.ndarray]) -> tuple[np.ndarray, Ends, list[np.ndarray]]:
    """Clip a line's intervals to the verified gains and the search window.

    Beyond ``y_valid`` the grid does not cover the loop's crossover: not
    verified, not admissible; outside the search window (``y_window``) nothing
    is wanted.  An upper end moved by the clip is no longer a branch's.
    """
    y_lo = max(-problem.y_valid, problem.y_window[0])
    y_hi = min(problem.y_valid, problem.y_window[1])
    clipped_hi = iv[:, 1] > y_hi
    iv[:, 0] = np.maximum(iv[:, 0], y_lo)
    iv[:, 1] = np.minimum(iv[:, 1], y_hi)
    keep = iv[:, 0] < iv[:, 1]
    ends = [(e[0], None if c else e[1]) for e, c in zip(ends, clipped_hi)]
    iv = iv[keep]
    ends = [e for e, kk in zip(ends, keep) if kk]
    return iv, ends, [np.clip(p, y_lo, y_hi) for p in per]


def _cut_missed_intervals(problem: Problem, x: float, iv: np.ndarray, ends: Ends,
                          cbr: ComplexBreaks) -> tuple[np.ndarray, Ends, ComplexBreaks]:
    """Refine the complex-root crossings inside admissible intervals, and cut what the grid missed.

    A crossing of the D-decomposition curve inside an H-infinity-admissible
    interval: ``|S|`` is infinite there, so (for a constraint that bounds ``S``
    there) a forbidden interval must hold it.  The grid can miss that interval
    when it exists only in a frequency window narrower than its spacing (large
    gains move the ellipse fast).  The crossing is refined exactly, and the
    exact forbidden intervals at its frequency are cut from the line.
    """
    cys, ccols, cerr = cbr
    cys, cerr = cys.copy(), cerr.copy()
    if ccols is not None and cys.size and iv.size:
        inside = np.any((cys[:, None] > iv[None, :, 0]) & (cys[:, None] < iv[None, :, 1]), axis=1)
        cuts: list[tuple[float, float, Cut]] = []
        for k in np.flatnonzero(inside):
            wk, yk = crossing_frequency(problem.columns, x, int(ccols[k]))
            if math.isfinite(yk):
                cys[k], cerr[k] = yk, 0.0
                cuts += [(lo_, hi_, Cut(ci_, wk)) for ci_, (lo_, hi_) in forbidden_window(problem.columns, x, wk)]
        if cuts:
            iv, ends = subtract(iv, ends, cuts)
    return iv, ends, ComplexBreaks(cys, ccols, cerr)


def _line_breaks(problem: Problem, x: Any, cbr: ComplexBreaks) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The line's D-decomposition breaks, sorted and deduplicated: ``(ky, kind, uncertainty)``.

    Breaks outside the ky window are dropped but for the nearest one beyond each
    end, so that the segments meeting the window are true D-decomposition cells
    (a delay loop's curve spirals out and crosses a line thousands of times at
    gains nobody asked about).
    """
    br = [cbr.ky]
    errs = [cbr.error]
    kinds = [np.full(cbr.ky.size, BreakKind.COMPLEX.value)]
    yr = problem.real.break_at(x)
    if yr is not None:
        br.append(np.array([yr]))
        errs.append(np.zeros(1))
        kinds.append(np.array([BreakKind.REAL.value]))
    yi = problem.infinite.breaks(float(x))
    br.append(yi)
    errs.append(np.zeros(yi.size))
    kinds.append(np.full(yi.size, BreakKind.INFINITE.value))
    allb = np.concatenate(br)
    alle = np.concatenate(errs)
    allk = np.concatenate(kinds)
    order = np.argsort(allb, kind="stable")
    allb, alle, allk = allb[order], alle[order], allk[order]
    keepb = np.concatenate([[True], np.diff(allb) > 1e-12 * (1 + np.abs(allb[1:]))]) if allb.size else np.zeros(0, bool)
    w_lo, w_hi = problem.y_window
    below = np.flatnonzero(keepb & (allb < w_lo))
    above = np.flatnonzero(keepb & (allb > w_hi))
    keepb[below[:-1]] = False
    keepb[above[1:]] = False
    return allb[keepb], allk[keepb], alle[keepb]
