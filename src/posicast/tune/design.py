"""One-call robust fixed-structure controller design for loops with shapers (seed 001, Algorithm 1).

``tune_pd``, ``tune_pi`` and ``tune_pid`` follow seed 001 section 3:

1. the shaper ``S`` is given (step 1 of Algorithm 1);
2. the loop of the chosen architecture is formed, ``L = C P`` with ``P = G``,
   ``S G`` or ``G / S`` (eq. 5; step 2);
3. the requirements are H-infinity constraints ``||W X||_inf < gamma``
   (eq. 6-7), by default ``||S||_inf < Ms`` (eq. 14-15; step 3);
4. their regions in the gain plane are computed exactly per scan line and
   intersected with the stability region of the infinite-dimensional loop
   (D-decomposition plus one certified spectrum check per component; steps 4-5);
5. the point with the largest integral gain is chosen (eq. 8: minimum integral
   error; for a PD, maximum ``Kp`` through eq. 16; step 6) and verified
   independently: spectrum (:meth:`Loop.stability`) and peak sensitivity from
   the loop's own channels.

The stages live in their own modules: :mod:`~posicast.tune.frequency` (the
frequency data; :mod:`~posicast.tune.axis` evaluates it), :mod:`~posicast.tune.hinf` (H-infinity
constraints on a line; :mod:`~posicast.tune.refine` refines their ends),
:mod:`~posicast.tune.boundaries` (D-decomposition), :mod:`~posicast.tune.scan`
(the line scan), :mod:`~posicast.tune.cells` (stability cells),
:mod:`~posicast.tune.regions` (the region), :mod:`~posicast.tune.branches` and
:mod:`~posicast.tune.optimum` (the exact optimum and its verification).
"""

from __future__ import annotations

import copy
import math
import time
from dataclasses import replace
from typing import Any, Callable, Iterator, Mapping, Sequence

import numpy as np

from .. import _validate as v
from ..core.quasipoly import QuasiPolynomial
from ..core.transfer import TransferFunction, as_transfer
from ..loops import Loop, feature_frequencies
from .cells import Cells, StabilityLedger, interval_point, join_lines
from .constraints import Constraint
from .family import ControllerFamily, pd_family, pi_family, pid_family
from .frequency import _MAX_POINTS as _MAX_GRID
from .frequency import Asymptote, FrequencyData, _poly_tf
from .inputs import (architecture_argument, check_architecture, check_blocks, check_range, constraint_tuple,
                     constraints_with_ms)
from .optimum import SWEEP_DECADES, empty_result, optimum, weakly_neutral
from .regions import (Region, SkippedLines, best_piece, component_extent, component_lines, make_region, pieces,
                      segment_stable)
from .result import TuningResult
from .scan import LineData, Problem, forbidden_above, make_problem, regrid, scan_lines

__all__ = ["TuningResult", "tune", "tune_pd", "tune_pi", "tune_pid"]

_PASS1_LINES = 41
# Scan lines: at most MAX_LINES (memory), and pass 2 is refused when its time, estimated from the measured
# cost of a pass-1 line (5 ms to 100 ms a line, depending on the frequency grid the loop's delays need),
# would exceed MAX_SECONDS.
MAX_LINES = 100_001
MAX_SECONDS = 60.0
#: pass 2 scans a window around the best component when the frequency grid has this many columns or more
WINDOW_ABOVE = 8000


def _architecture(architecture: Any, structure: Any) -> str:
    """The architecture asked for (``structure=`` warns: its old name), checked under the keyword used."""
    value, name = architecture_argument(architecture, structure)
    return check_architecture(value, name)


def _scale_estimate(loop0: Loop, family: ControllerFamily) -> tuple[float, float]:
    """Gain magnitudes at which ``|kx a| ~ 1`` and ``|ky b| ~ 1`` near the plant's phase crossover."""
    P = loop0.plant_gain
    feats = [f for f in feature_frequencies([P]) if 1e-8 < f < 1e9] or [1.0]
    w = np.geomspace(min(feats) / 30, max(feats) * 30, 600)
    p = np.asarray(P.freqresp(w))
    cx = np.asarray(_poly_tf(family.nx, family.dC).freqresp(w))
    cy = np.asarray(_poly_tf(family.ny, family.dC).freqresp(w))
    a, b = np.abs(cx * p), np.abs(cy * p)
    ph = np.unwrap(np.angle(cy * p))
    ok = np.isfinite(ph) & np.isfinite(a) & np.isfinite(b) & (a > 0) & (b > 0)
    if not np.any(ok):
        return 1.0, 1.0
    w, a, b, ph = w[ok], a[ok], b[ok], ph[ok]
    target = ph[0] - math.pi
    k = np.flatnonzero(ph <= target)
    i = int(k[0]) if k.size else int(np.argmin(np.abs(np.log(b))))
    return 1.0 / a[i], 1.0 / b[i]


class _Tuner:
    """The plant, shaper, controller family and constraints of one tuning, and its loops."""

    def __init__(self, G: TransferFunction, S: Any, architecture: str, family: ControllerFamily,
                 constraints: tuple[Constraint, ...], F: Any) -> None:
        self.G, self.S, self.architecture, self.family, self.F = G, S, architecture, family, F
        self.constraints = constraints
        self.loop0 = Loop(architecture, G=G, C=1.0, F=F, S=S)
        P = self.loop0.plant_gain
        dC = QuasiPolynomial.from_poly(np.trim_zeros(family.dC, "f"))

        def qp(desc: np.ndarray) -> QuasiPolynomial:
            t = np.trim_zeros(desc, "f")
            return QuasiPolynomial.from_poly(t) if t.size else QuasiPolynomial.zero()

        self.char_terms = (dC * P.den + qp(family.n0) * P.num, qp(family.nx) * P.num, qp(family.ny) * P.num)
        self.m0 = int(np.count_nonzero(self.loop0.cancelled == 0))

    def loop(self, kx: float, ky: float) -> Loop:
        return Loop(self.architecture, G=self.G, C=self.family.controller(kx, ky), F=self.F, S=self.S)


def _hinf_wanted(lines: list[LineData]) -> Callable[[int], np.ndarray]:
    """Mask of the segments of line ``i`` that meet an H-infinity-admissible interval."""

    def wanted(i: int) -> np.ndarray:
        ln = lines[i]
        iv = ln.hinf
        if not iv.size:
            return np.zeros(ln.n_segments, dtype=bool)
        edges = np.concatenate([[-math.inf], ln.breaks, [math.inf]])
        return np.any((iv[None, :, 0] < edges[1:, None]) & (iv[None, :, 1] > edges[:-1, None]), axis=1)

    return wanted


def _build_region(problem: Problem, family: ControllerFamily, xs: np.ndarray,
                  y_range: tuple[float, float], previous: Region | None = None,
                  search_range: tuple[float, float] | None = None,
                  whole_sweep: Callable[[], Region] | None = None, skipped: SkippedLines | None = None) -> Region:
    """Scan ``xs``; the cells of ``previous`` whose checked point connects to a new segment
    without crossing a boundary pass their stability label on (no second spectrum check).
    With ``search_range`` wider than ``y_range`` the region is windowed and keeps ``previous`` as its sweep
    (``whole_sweep``: what scans the whole sweep instead, when pass 1 left lines out: ``skipped``)."""
    lines = scan_lines(problem, xs)
    cells = Cells(problem.loop_factory, problem.ledger, (family.x, family.y))
    join_lines(problem, lines, cells, _hinf_wanted(lines))
    if previous is not None and lines:
        _inherit_labels(problem, previous.cells, lines, cells, xs)
    windowed = search_range is not None and tuple(search_range) != tuple(y_range)
    if not windowed:  # the whole range on these lines: no sweep kept, but the lines pass 1 left out are named
        return make_region(problem, family, lines, cells, y_range, search_range, skipped=skipped)
    return make_region(problem, family, lines, cells, y_range, search_range,
                       previous if whole_sweep is None else whole_sweep, skipped)


# ---------------------------------------------------------------------- pass 1
#: with a lumped shaper in the loop, pass 1 first scans the lines within 10^INNER_DECADES natural scales
INNER_DECADES = 2


def _inner_lines(tuner: _Tuner, xs: np.ndarray, sx: float) -> np.ndarray | None:
    """Mask of the sweep's inner lines (``|kx| <= 10^INNER_DECADES sx``) when a lumped shaper is in the loop,
    else None (one pass over every line).

    A lumped shaper (a sum of delayed impulses) keeps ``|S(j omega)|`` oscillating without decay, so the grid
    for the sweep's largest gains is uniform up to the delay ceiling (issue #15: 47 000-92 000 columns on the
    seed 001 crane, against 12 000-25 000 for the inner lines)."""
    if tuner.S is None or tuner.architecture == "feedforward":
        return None
    asym = Asymptote.of(as_transfer(tuner.S, "S"))
    if asym.m != 0 or asym.peak is None:
        return None
    inner = np.abs(xs) <= 10.0**INNER_DECADES * sx * (1.0 + 1e-9)
    return inner if not inner.all() else None


def _sweep_problem(tuner: _Tuner, family: ControllerFamily, cons: tuple[Constraint, ...], xs: np.ndarray,
                   sx: float, sy: float, yr: tuple[float, float]) -> Problem:
    """The frequency data and scan problem of pass 1 on the lines ``xs``: a grid valid for the largest of them
    (and, at low frequency, for the smallest), stopped at the delay ceiling."""
    fd = FrequencyData(tuner.loop0, family, cons, scale=(float(np.max(np.abs(xs))), 4 * sy), limit_for_delays=True)
    nonzero = np.abs(xs[xs != 0])
    fd.refine(fd._scale, small=(float(nonzero.min()) if nonzero.size else sx, sy * 10.0 ** -SWEEP_DECADES),
              ceiling=fd.delay_ceiling)
    return make_problem(fd, tuner.loop, tuner.char_terms, tuner.m0, yr)


def _sweep_region(problem: Problem, family: ControllerFamily, xs: np.ndarray,
                  yr: tuple[float, float]) -> tuple[Region, np.ndarray]:
    """Pass 1's region on the lines ``xs`` the grid verifies, and those lines.

    A delay loop's pass-1 grid stops at ``fd.delay_ceiling`` (else ``e^{-s} / (s + 1)`` would stretch it to
    1e9 rad/s for hopeless huge gains): the sweep keeps the lines the grid verifies."""
    xs = xs[np.abs(xs) <= problem.x_valid]
    return _build_region(problem, family, xs, yr), xs


def _inner_decides(region: Region, best: tuple[int, float, float] | None) -> bool:
    """Is the inner lines' pass 1 the whole sweep's, given that the outer lines hold no admissible ``ky >= 0``?

    Yes when its best piece reaches above 0 (no outer piece can top it) and that piece's component ends
    inside the inner lines (joins run between neighbouring lines only: it cannot reach the outer ones)."""
    if best is None or not best[2] > 0.0:
        return False
    comp = component_lines(region, best[0], interval_point(best[1], best[2]))
    return bool(comp.min() > 0 and comp.max() < region.x.size - 1)


#: :func:`_unstable_above` scans at most this many outer lines and checks at most this many cells (each check
#: of a cell at such gains costs about 45 ms on the crane): beyond, the whole sweep is the cheaper way
_UNSTABLE_LINES = 8
_UNSTABLE_CELLS = 4


def _unstable_above(problem: Problem, family: ControllerFamily, runs: list[np.ndarray], sy: float,
                    yr: tuple[float, float], floor: float) -> int | None:
    """How many cells a certified spectrum check showed unstable to show that the lines of ``runs`` hold no
    *stable* H-infinity-admissible ``ky`` in ``[floor, yr[1]]``; None when that is not shown (the whole sweep is
    scanned then).

    Lines the probe of :func:`~posicast.tune.scan.forbidden_above` does not show forbidden may hold admissible
    gains in unstable cells only (issue #15: the inverse-shaper loop with a ZV shaper on the seed 001 crane is
    H-infinity-admissible up to ``ky`` 6.5e4-8.2e4 at ``kx`` 689-2178, in one cell with unstable roots). These
    few lines are scanned exactly over ``yr`` (within the gains the grid verifies, as in the whole sweep) on a
    copy of the grid extended to their gains (the inner lines keep their own, smaller grid). Each run of lines
    neighbouring in the sweep is joined into cells; a cell's roots cross the imaginary axis only on its
    boundary, so one check per cell holding an admissible piece at or above ``floor`` decides them all. A copy
    stopped at its size cap, or a check that fails, shows nothing (the checks are counted in the design's ledger,
    their failures are not: the whole sweep decides then)."""
    xs = np.concatenate(runs)
    if xs.size > _UNSTABLE_LINES:
        return None
    fd = copy.copy(problem.fd)  # refine() replaces the grid's arrays: the copy leaves the inner grid as it is
    fd.refine((float(np.max(np.abs(xs))), 4 * sy), ceiling=fd.delay_ceiling)
    outer = replace(regrid(problem, fd), y_window=yr, ledger=StabilityLedger())
    if fd.capped or np.any(np.abs(xs) > outer.x_valid):
        return None
    cells: list[tuple[Region, int, int, float]] = []
    for run in runs:
        region = _build_region(outer, family, run, yr)
        first: dict[int, tuple[Region, int, int, float]] = {}
        for i, ln in enumerate(region.lines):
            for lo, hi, j in pieces(region, i):
                if hi > floor:
                    root = region.cells.find(int(ln.comp[j]))
                    first.setdefault(root, (region, i, j, interval_point(max(lo, floor), hi)))
        cells += first.values()
    if len(cells) > _UNSTABLE_CELLS:
        return None
    unstable = all(segment_stable(region, i, j, y) is False for region, i, j, y in cells)
    problem.ledger.calls += outer.ledger.calls
    return len(cells) if unstable else None


def _sweep_runs(xs: np.ndarray, mask: np.ndarray) -> list[np.ndarray]:
    """The lines ``xs[mask]`` in runs of neighbours in ``xs`` (joins are made between neighbouring lines only)."""
    idx = np.flatnonzero(mask)
    return [xs[r] for r in np.split(idx, np.flatnonzero(np.diff(idx) != 1) + 1) if r.size]


def _whole_sweep(tuner: _Tuner, family: ControllerFamily, cons: tuple[Constraint, ...], xs: np.ndarray, sx: float,
                 sy: float, yr: tuple[float, float]) -> Callable[[], Region]:
    """What scans pass 1 on every sweep line (as a design without the inner pass does), when first asked for."""

    def scan() -> Region:
        return _sweep_region(_sweep_problem(tuner, family, cons, xs, sx, sy, yr), family, xs, yr)[0]

    return scan


def _snap_up(value: float) -> float:
    """The smallest of 1, 2, 5 times a power of ten that is ``>= value`` (a window that reads well and does
    not move with rounding-level changes of the first pass)."""
    k = math.floor(math.log10(value))
    for f in (1.0, 2.0, 5.0, 10.0):
        if value <= f * 10.0**k * (1 + 1e-12):
            return f * 10.0**k
    return 10.0 ** (k + 1)


def _windows(problem: Problem, sweep: Region, comp: np.ndarray, best: tuple[int, float, float],
             yr: tuple[float, float]) -> Iterator[tuple[float, float]]:
    """The ``ky`` windows pass 2 tries, narrowest first; the last is the whole range ``yr``.

    Only a large frequency grid (``WINDOW_ABOVE`` columns or more: a lumped shaper or a delay in the loop,
    whose ``|L|`` does not decay) is worth a window: the columns a line needs
    (:func:`~posicast.tune.frequency.thin_columns`) grow with the ``ky`` it must resolve.
    The first window is ``+/- R``, ``R`` twice the largest ``|ky|`` of the best component on the sweep
    lines rounded up to 1, 2 or 5 times a power of ten; each next one is ten times wider.
    """
    if problem.columns.n_grid >= WINDOW_ABOVE and math.isfinite(best[2]):
        lo, hi = component_extent(sweep, comp, best[0], interval_point(best[1], best[2]))
        base = max(abs(lo), abs(hi))
        if math.isfinite(base) and base > 0:
            R = _snap_up(2.0 * base)
            while R < max(abs(yr[0]), abs(yr[1])):
                yield max(yr[0], -R), min(yr[1], R)
                R = _snap_up(10.0 * R)
    yield yr


def _reaches_edge(region: Region, yr: tuple[float, float]) -> bool:
    """Does an admissible piece of a windowed region reach the window's top, or the best component reach
    its bottom (the component continues beyond: a wider window is needed)?"""
    w_lo, w_hi = region.y_range
    best = best_piece(region)
    root = None
    if best is not None:
        ln = region.lines[best[0]]
        root = region.cells.find(int(ln.comp[int(np.searchsorted(ln.breaks, interval_point(best[1], best[2])))]))
    for i, ln in enumerate(region.lines):
        for lo, hi, j in pieces(region, i):
            if hi >= w_hi and w_hi < yr[1] and segment_stable(region, i, j, interval_point(lo, hi)):
                return True
            if lo <= w_lo and w_lo > yr[0] and root is not None and region.cells.find(int(ln.comp[j])) == root:
                return True
    return False


def _inherit_labels(problem: Problem, old: Cells, lines: list[LineData], cells: Cells, xs: np.ndarray) -> None:
    """Pass the labels of ``old`` cells on to the new cells their checked points reach without a crossing."""
    seeds = [(old.point[r], lab) for r, lab in old.label.items() if lab is not None and r in old.point]
    if not seeds:
        return
    px = np.array([p[0] for p, _ in seeds])
    py = np.array([p[1] for p, _ in seeds])
    idx = np.abs(xs[None, :] - px[:, None]).argmin(axis=1)
    hit = problem.crossing(px, xs[idx], py)
    for (_, lab), i, y, h in zip(seeds, idx, py, hit):
        ln = lines[int(i)]
        if h or np.any(ln.breaks == y):
            continue
        root = cells.find(int(ln.comp[int(np.searchsorted(ln.breaks, y))]))
        if root not in cells.label:
            cells.label[root] = lab
            cells.point[root] = (float(xs[int(i)]), float(y))


# ---------------------------------------------------------------------- the design
def tune(
    G: Any,
    family: ControllerFamily,
    S: Any = None,
    architecture: str = "control_action",
    constraints: Sequence[Constraint] = (),
    *,
    structure: str | None = None,
    F: Any = None,
    x_range: Any = None,
    y_range: Any = None,
    n_lines: int = 161,
) -> TuningResult:
    """Generic H-infinity-region design for any :class:`ControllerFamily` (see :func:`tune_pd`).

    ``x_range`` / ``y_range`` bound the scanned and the maximised gain;
    ``structure`` is the former name of ``architecture`` (FutureWarning).
    """
    t_start = time.perf_counter()
    architecture = _architecture(architecture, structure)
    if not isinstance(family, ControllerFamily):
        raise TypeError(f"family must be a ControllerFamily, got {type(family).__name__}")
    cons = constraint_tuple(constraints)
    if not cons:
        raise ValueError("no constraint: give ms (e.g. ms=2.0) or constraints=[Constraint(...)]")
    n_lines = v.integer_in_range(n_lines, "n_lines", 11, MAX_LINES)
    Gt, S = check_blocks(G, S, architecture, F)
    xr = check_range(x_range, f"{family.x}_range")
    yr = check_range(y_range, f"{family.y}_range")
    tuner = _Tuner(Gt, S, architecture, family, cons, F)
    sx, sy = _scale_estimate(tuner.loop0, family)
    # Without a ky_range the maximised gain is searched within +/- 10^4 times its natural scale (the
    # ultimate gain near the plant's phase crossover), as the scan sweeps kx: far beyond every optimum
    # seen, and a region that reaches this window's top is reported as unbounded, not as a design.
    auto_y = yr is None
    if yr is None:
        yr = (-(10.0**SWEEP_DECADES) * sy, (10.0**SWEEP_DECADES) * sy)
    timings: dict[str, float] = {}

    # ---- frequency data and pass 1: locate the admissible set on a logarithmic sweep
    # kx = 0 and +/- sx 10^k over eight decades (each line is exact in ky), so a region is found at
    # whatever scale it lies; the grid is made valid for the largest gains scanned.
    t0 = time.perf_counter()
    auto = xr is None
    mags = sx * np.logspace(-SWEEP_DECADES, SWEEP_DECADES, 8 * SWEEP_DECADES + 1)
    sweep = np.concatenate([-mags[::-1], [0.0], mags])
    if auto:
        xs1 = sweep
    else:
        xs1 = np.union1d(np.linspace(xr[0], xr[1], _PASS1_LINES), sweep[(sweep > xr[0]) & (sweep < xr[1])])
    # with a lumped shaper in the loop, the inner lines first (_inner_lines): the outer ones need a grid up to
    # the delay ceiling, and are left out when shown to hold nothing above the inner lines' best point
    inner = _inner_lines(tuner, xs1, sx) if auto else None
    problem = _sweep_problem(tuner, family, cons, xs1 if inner is None else xs1[inner], sx, sy, yr)
    weak = weakly_neutral(problem)
    if weak is not None:  # no gain of this family can help: say so at once, with the reason
        region = make_region(problem, family, [], Cells(tuner.loop, problem.ledger, (family.x, family.y)), yr)
        timings["total"] = time.perf_counter() - t_start
        return _with_timings(empty_result(tuner, region, weak), timings)
    skipped = None
    if inner is not None:
        cols = problem.columns  # (a lumped shaper has delays: the ceiling is set)
        top = problem.fd.delay_ceiling or float(cols.omega[cols.n_grid - 1])
        shown, n_probe = forbidden_above(problem, xs1[~inner], 0.0, top)
        unshown = np.zeros(xs1.size, dtype=bool)
        unshown[np.flatnonzero(~inner)[~shown]] = True
        n_unstable = 0 if shown.all() else _unstable_above(problem, family, _sweep_runs(xs1, unshown), sy, yr, 0.0)
        if n_unstable is not None:
            skipped = SkippedLines(xs1[~inner], 0.0, n_probe, int(xs1.size), int(unshown.sum()), n_unstable)
        else:  # the grid extended to the whole sweep's gains
            problem.fd.refine((float(np.max(np.abs(xs1))), 4 * sy), ceiling=problem.fd.delay_ceiling)
            problem = regrid(problem)
    timings["frequency grid"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    region, xs_scanned = _sweep_region(problem, family, xs1 if skipped is None else xs1[inner], yr)
    best = best_piece(region)
    if skipped is not None and not _inner_decides(region, best):  # the whole sweep, as without the inner pass
        skipped = None
        problem = replace(_sweep_problem(tuner, family, cons, xs1, sx, sy, yr), ledger=problem.ledger)
        region, xs_scanned = _sweep_region(problem, family, xs1, yr)
        best = best_piece(region)
    timings["pass 1"] = time.perf_counter() - t0
    per_line = timings["pass 1"] / max(xs_scanned.size, 1)
    v.refuse_large(per_line * n_lines, MAX_SECONDS, f"scanning n_lines = {n_lines} lines (measured {per_line * 1e3:.3g} ms "
                   f"a line for this loop)", f"use n_lines <= {max(11, int(MAX_SECONDS / per_line))}", "s")

    # ---- pass 2: the best component at full resolution, between the sweep lines around it
    t0 = time.perf_counter()
    unbounded_x = False
    if best is not None:
        comp = component_lines(region, best[0], interval_point(best[1], best[2]))
        unbounded_x = bool(auto and (comp.min() == 0 or comp.max() == region.x.size - 1))
        a = float(region.x[max(comp.min() - 1, 0)])
        b = float(region.x[min(comp.max() + 1, region.x.size - 1)])
        if xr is not None:
            a, b = max(a, xr[0]), min(b, xr[1])
        ytop = abs(best[2]) if math.isfinite(best[2]) else sy
        problem.fd.refine((max(abs(a), abs(b)), max(ytop, sy)))
        problem = regrid(problem)
        sweep, xs2 = region, np.linspace(a, b, n_lines)
        whole = None if skipped is None else _whole_sweep(tuner, family, cons, xs1, sx, sy, yr)
        # the exact scan where the answer is: a window around the best component, widened while the
        # admissible set reaches its top (or the component its bottom); beyond it, the sweep's lines
        for win in _windows(problem, sweep, comp, best, yr):
            p2 = problem if win == yr else replace(problem, y_window=win)
            region = _build_region(p2, family, xs2, win, sweep, search_range=yr, whole_sweep=whole, skipped=skipped)
            if win == yr or not _reaches_edge(region, yr):
                problem = p2
                break
    timings["pass 2"] = time.perf_counter() - t0

    # ---- the optimum
    t0 = time.perf_counter()
    result = optimum(tuner, problem, region, yr, unbounded_x, auto_y)
    if problem.fd.capped:  # a grid that could not be refined as the scan assumes: the result says so
        result = replace(result, reason=result.reason + (
            f"; the frequency grid stopped at its {_MAX_GRID:,}-point cap before every interval met the "
            "refinement rule: the region is resolved less finely than stated at the largest gains (a returned "
            "design is still verified independently)"))
    timings["optimum and checks"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_start
    return _with_timings(result, timings)


def _with_timings(r: TuningResult, timings: dict[str, float]) -> TuningResult:
    object.__setattr__(r, "timings", dict(timings))
    return r


# ---------------------------------------------------------------------- public entry points
def tune_pd(
    G: Any,
    S: Any = None,
    architecture: str = "control_action",
    ms: float | None = 2.0,
    *,
    structure: str | None = None,
    F: Any = None,
    constraints: Sequence[Constraint] | Constraint | None = None,
    derivative_filter: float | None = None,
    kp_range: Any = None,
    kd_range: Any = None,
    n_lines: int = 161,
) -> TuningResult:
    """Robust PD ``C = Kp + Kd s`` for a loop with a shaper, by H-infinity regions (seed 001).

    Maximises ``Kp`` (the integral gain of the equivalent PI ``C / s = Kd + Kp / s``
    for ``s G``, seed 001 eq. 16, i.e. minimum integral error, eq. 8) subject to
    ``||S||_inf <= ms`` and any further constraints, over the stabilising gains.

    Parameters
    ----------
    G : plant-like
        Actuator-side plant, proper (a delay ``G e^{-s theta}`` is allowed).
    S : Shaper, plant-like or None
        The shaper (None: no shaper).
    architecture : {'control_action', 'inverse_shaper', 'feedforward'}
        Where the shaper sits (seed 001 Fig. 1-3), as :class:`~posicast.loops.Loop` names it.
    structure : str, optional
        Former name of ``architecture`` (FutureWarning).
    ms : float or None
        Peak sensitivity bound (seed 001 eq. 14); None if ``constraints`` say it all.
    F : plant-like, optional
        Flexible load outside the loop (kept in ``result.loop`` for simulation).
    constraints : Constraint or sequence of Constraint, optional
        Further ``||W X||_inf < gamma`` requirements.
    derivative_filter : float, optional
        ``Tf``: design ``Kp + Kd s / (Tf s + 1)`` instead (realisable; simulable).
    kp_range, kd_range : (low, high), optional
        Bounds of the gains; default: found automatically.
    n_lines : int
        Scan lines in ``Kd`` over the admissible set (its resolution).

    Returns
    -------
    TuningResult
        ``.kp``, ``.kd``, ``.ms`` (achieved), ``.stable``, ``.region``, ``.plot()``.
        An empty region is a result (``.empty``, ``.reason``), not an exception.

    Raises
    ------
    ValueError, TypeError
        Improper plant or loop gain, ``ms`` outside ``[0.001, 100]``, a bad range or
        architecture, coefficients or delays beyond what the frequency grid resolves, or
        ``n_lines`` whose scan would exceed :data:`MAX_SECONDS` (estimated from the
        measured cost of the first pass; the message says which ``n_lines`` fits).

    Examples
    --------
    A double integrator with a lag, PD for ``Ms = 1.6`` (a brute-force scan with
    the Routh-Hurwitz test gives max Kp = 12.992; the top is flat in Kd):

    >>> r = tune_pd(([1.0], [0.1, 1.0, 0.0, 0.0]), ms=1.6)
    >>> r.stable, abs(r.ms - 1.6) < 1e-6
    (True, True)
    >>> round(r.kp, 3), round(r.kd, 1)
    (12.992, 7.4)
    """
    architecture = _architecture(architecture, structure)
    fam = pd_family(derivative_filter)
    return tune(G, fam, S, architecture, constraints_with_ms(ms, constraints), F=F, x_range=kd_range,
                y_range=kp_range, n_lines=n_lines)


def tune_pi(
    G: Any,
    S: Any = None,
    architecture: str = "control_action",
    ms: float | None = 2.0,
    *,
    structure: str | None = None,
    F: Any = None,
    constraints: Sequence[Constraint] | Constraint | None = None,
    kp_range: Any = None,
    ki_range: Any = None,
    n_lines: int = 161,
) -> TuningResult:
    """Robust PI ``C = Kp + Ki / s`` by H-infinity regions: maximum ``Ki`` (seed 001 eq. 8).

    Parameters are those of :func:`tune_pd`, with ``ki_range`` for the integral gain.

    Examples
    --------
    >>> r = tune_pi(([1.0], [1.0, 2.0, 1.0]), ms=1.4)     # 1 / (s + 1)^2
    >>> r.stable, abs(r.ms - 1.4) < 1e-6
    (True, True)
    >>> round(r.ki, 3), round(r.kp, 1)                    # brute force: 1.058 (flat in Kp)
    (1.058, 1.8)
    """
    architecture = _architecture(architecture, structure)
    return tune(G, pi_family(), S, architecture, constraints_with_ms(ms, constraints), F=F, x_range=kp_range,
                y_range=ki_range, n_lines=n_lines)


def tune_pid(
    G: Any,
    S: Any = None,
    architecture: str = "control_action",
    ms: float | None = 2.0,
    *,
    structure: str | None = None,
    fixed: Mapping[str, float],
    maximize: str | None = None,
    F: Any = None,
    constraints: Sequence[Constraint] | Constraint | None = None,
    derivative_filter: float | None = None,
    kp_range: Any = None,
    ki_range: Any = None,
    kd_range: Any = None,
    n_lines: int = 161,
) -> TuningResult:
    """Robust PID ``Kp + Ki / s + Kd s / (Tf s + 1)`` with one gain fixed (``fixed={'kd': 0.5}``).

    The other two gains span the plane; ``maximize`` (default ``'ki'``, or
    ``'kp'`` when ``ki`` is fixed) is the secondary criterion.  Other
    parameters as :func:`tune_pd`.

    Examples
    --------
    ``1 / (s + 1)^3`` with ``Kd = 0.5`` fixed: the derivative action buys
    integral gain at the same robustness (the PI alone reaches ``Ki = 0.461``).
    A brute-force scan (Hurwitz test and ``||S||inf`` on a dense grid over
    ``Kp``, ``Ki``) gives max ``Ki`` 0.8107 and 0.4608:

    >>> G = ([1.0], [1.0, 3.0, 3.0, 1.0])
    >>> r = tune_pid(G, ms=1.6, fixed={"kd": 0.5}, derivative_filter=0.01)
    >>> r.stable, r.kd, abs(r.ms - 1.6) < 1e-6, r.active
    (True, 0.5, True, (True,))
    >>> round(r.ki, 3), round(tune_pi(G, ms=1.6).ki, 3)
    (0.811, 0.461)
    """
    architecture = _architecture(architecture, structure)
    fam = pid_family(fixed, maximize, derivative_filter)
    ranges = {"kp": kp_range, "ki": ki_range, "kd": kd_range}
    return tune(G, fam, S, architecture, constraints_with_ms(ms, constraints), F=F, x_range=ranges[fam.x],
                y_range=ranges[fam.y], n_lines=n_lines)
