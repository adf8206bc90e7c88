"""The optimum of a region and its independent verification (seed 001 eq. 8, 16; Algorithm 1, step 6).

The design is the admissible point with the largest maximised gain ``ky`` (the
integral gain: minimum integral error, seed 001 eq. 8; for a PD, maximum ``Kp``
through eq. 16).  The best scan line's top is refined to the exact optimum
between its neighbours (:func:`exact_optimum`, following the boundary's
frequency branches with :class:`~posicast.tune.branches.BranchTracker`), then
verified independently (:func:`finish`): the chosen loop's own spectrum check
and its constraint norms from the loop's own channels.  A point that fails is
never returned.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Iterator, NamedTuple

import numpy as np
from scipy.optimize import minimize_scalar

from ..core.transfer import TransferFunction
from ..spectra.rootfinder import RootFindingError
from .axis import OnAxis
from .branches import BranchTracker, active_branches, exact_bottom, exact_top, is_tracked
from .cells import interval_point
from .family import ControllerFamily
from .hinf import Branch, Cut, IntervalEnd
from .refine import exact_end
from .regions import Region, best_piece
from .result import TuningResult
from .scan import LineData, Problem, scan_lines

if TYPE_CHECKING:
    from .design import _Tuner

__all__ = ["optimum", "exact_optimum", "weakly_neutral", "empty_result"]

#: pass 1 sweeps kx over +/- 10^(+/-SWEEP_DECADES) times the natural gain scale
SWEEP_DECADES = 4


class Probe(NamedTuple):
    """The best stable admissible piece on a fresh line: its top, what bounds the top, its bottom."""

    top: float
    end: IntervalEnd
    bottom: float


class Anchor(NamedTuple):
    """An exactly open admissible interval ``(bottom, top)`` on the line ``kx = x`` near scan line ``line``."""

    line: int
    x: float
    top: float
    bottom: float
    end: IntervalEnd


# ---------------------------------------------------------------------- results without a design
def empty_result(tuner: _Tuner, region: Region, reason: str) -> TuningResult:
    nan = math.nan
    return TuningResult(tuner.family, tuner.architecture, None, None, None, nan, nan, nan, False, None,
                        tuple(nan for _ in tuner.constraints), tuple(False for _ in tuner.constraints),
                        tuner.constraints, region, True, False, reason)


def _empty_reason(tuner: _Tuner, problem: Problem, region: Region) -> str:
    fam = tuner.family
    if problem.real.structural:
        return ("every gain leaves a closed-loop pole at s = 0 (the controller's integrator meets a plant "
                "zero at s = 0, or similar): no stabilising controller of this structure exists")
    any_hinf = any(ln.hinf.size and _intersect_any(ln.hinf, region.y_range) for ln in region.lines)
    span = f"{fam.x} in [{region.x[0]:.4g}, {region.x[-1]:.4g}]"
    if not any_hinf:
        return f"no gain with {span} meets {', '.join(c.label for c in tuner.constraints)}"
    failures = problem.ledger.failures
    fails = f"; {len(failures)} spectrum checks failed" if failures else ""
    return f"gains with {span} meet the constraints, but none of them gives a stable loop{fails}"


def _intersect_any(iv: np.ndarray, yr: tuple[float, float]) -> bool:
    return bool(np.any((iv[:, 0] < yr[1]) & (iv[:, 1] > yr[0])))


def _unbounded(tuner: _Tuner, region: Region, i: int, window: str | None = None) -> TuningResult:
    fam = tuner.family
    where = f"every larger {fam.y} is admissible" if window is None else f"every {fam.y} up to {window} is admissible"
    reason = (f"{fam.y} is not bounded by the constraints (at {fam.x} = {region.x[i]:.4g} {where}): "
              f"give {fam.y}_range to bound it")
    r = empty_result(tuner, region, reason)
    object.__setattr__(r, "empty", False)
    object.__setattr__(r, "unbounded", True)
    return r


def weakly_neutral(problem: Problem) -> str | None:
    """Why no controller of the family can stabilise the loop robustly, or None.

    When the gains do not reach the highest power of ``s`` in the characteristic
    quasi-polynomial, its difference operator ``sum_k d_k e^{-s theta_k}`` is the
    same for every controller.  If it is not strongly stable (Hale:
    ``sum_{k>0} |d_k| >= |d_0|`` for a scalar operator), arbitrarily small changes
    of the delays put root chains in the right half-plane, so no gain gives a loop
    that :func:`posicast.stability` (issue #3) calls stable: e.g. an inverse ZVD or
    EI shaper in the loop (impulses 1/4, 1/2, 1/4: 0.75 >= 0.25).
    """
    inf = problem.infinite
    if not inf.neutral_possible or inf.lead_varies:
        return None
    d = np.abs(inf.lead[0])
    if d.size < 2 or float(np.sum(d[1:])) < float(d[0]):
        return None
    return (f"the loop is neutral for every controller of this family, and its difference operator is not "
            f"strongly stable (sum of |d_k| = {float(np.sum(d[1:])):.4g} >= |d_0| = {float(d[0]):.4g}, delays "
            f"{', '.join(f'{t:.4g}' for t in inf.lead_delays)} s): arbitrarily small delay errors make it "
            "unstable, so no gain is admissible; a shaper whose first impulse dominates (ZV) or a "
            "distributed-delay shaper (seed 001 eq. 12) avoids this")


# ---------------------------------------------------------------------- the design
def optimum(tuner: _Tuner, problem: Problem, region: Region, yr: tuple[float, float],
            unbounded_x: bool, auto_y: bool = False) -> TuningResult:
    """The design: the best admissible piece, refined exactly, and verified independently.

    A point that fails its verification (its own loop's spectrum check, or a
    constraint's norm above its bound) is never returned: the next best lines'
    exact optima are tried instead, and if none verifies, the result is empty
    with that reason.
    """
    best = best_piece(region)
    if best is None:
        return empty_result(tuner, region, _empty_reason(tuner, problem, region))
    i, _, y_top = best
    y_cap = min(yr[1], problem.y_valid)  # the largest ky searched and verified
    if y_top == math.inf or ((auto_y or y_cap < yr[1]) and y_top >= y_cap):
        if y_top == math.inf:
            window = None
        elif y_cap < yr[1]:
            window = f"{y_cap:.4g}, the largest gain the frequency grid verifies"
        else:
            window = f"{y_cap:.4g}, the top of the searched window (10^{SWEEP_DECADES} x the loop's ultimate-gain scale)"
        return _unbounded(tuner, region, i, window)
    last = None
    for x, y, e, b, note in _candidates(problem, region, i):
        if e is None and y < yr[1]:
            # the supremum lies on a stability boundary: not attained, step into the open set
            depth = (y - b) if math.isfinite(b) else max(abs(y), 1.0)
            y = y - 1e-3 * depth
            note += "; the boundary there is a stability boundary (not attained): the point is 0.1 % inside"
        reason = _reason_for(tuner.family, e, problem, y, yr, unbounded_x) + note
        result = finish(tuner, problem, region, x, y, reason, unbounded_x, e)
        if result.stable and _meets(result, tuner):
            return result
        last = result
    return empty_result(tuner, region, _failure_reason(tuner, last) + "; please report this case")


def _meets(result: TuningResult, tuner: _Tuner) -> bool:
    return all(n <= c.gamma * (1 + 1e-6) for n, c in zip(result.norms, tuner.constraints))


def _failure_reason(tuner: _Tuner, last: TuningResult | None) -> str:
    fam = tuner.family
    why = "the best admissible points did not pass the independent verification"
    if last is not None:
        bad = [f"{c.label}: {n:.6g}" for n, c in zip(last.norms, tuner.constraints) if n > c.gamma * (1 + 1e-6)]
        why += f" (e.g. {fam.x} = {last.point[0]:.6g}, {fam.y} = {last.point[1]:.6g}: " + (
            "unstable" if not last.stable else "; ".join(bad)) + ")"
    return why


def _candidates(problem: Problem, region: Region, i: int) -> Iterator[tuple[float, float, IntervalEnd, float, str]]:
    """The design point ``(kx, ky, end, bottom, note)``: first the exact optimum near line ``i``, then (only
    if it fails its verification) the next best lines' exact tops, with a note saying so."""
    x_best = float(region.x[i])
    y_best, end, bottom = _probe_top(problem, region, i, x_best)
    if end is not None and not isinstance(end, Cut):
        x_best, y_best, end = exact_optimum(problem, region, i, x_best, y_best, bottom, end,
                                            probe=Probe(y_best, end, bottom))
    later = f"; the best line (at {region.x[i]:.4g}) did not verify: this is the best of the next lines' tops"
    if math.isfinite(y_best):  # -inf: the fresh line found no stable admissible piece there
        yield x_best, y_best, end, bottom, ""
    else:
        later = (f"; a fresh scan at the best line ({region.x[i]:.4g}) found no stable admissible piece: this is "
                 "the best of the next lines' tops, not the exact optimum")
    tops = np.array([region.top(k) for k in range(region.x.size)])
    for k in [int(k) for k in np.argsort(-tops) if np.isfinite(tops[k]) and int(k) != i][:8]:
        x = float(region.x[k])
        y_p, e_p, b = _probe_top(problem, region, k, x)
        if not math.isfinite(y_p):
            continue
        y, e = y_p, e_p
        if e is not None and not isinstance(e, Cut):
            y_x, _, e_x = exact_top(problem.columns, x, y_p, b)
            if math.isfinite(y_x) and y_x > b:
                y, e = y_x, (e_x if e_x is not None else e_p)
        yield x, y, e, b, later


def _reason_for(fam: ControllerFamily, end: IntervalEnd, problem: Problem, y: float, yr: tuple[float, float],
                unbounded: bool) -> str:
    if end is not None:
        c = problem.fd.constraints[end.constraint]
        if isinstance(end, Cut):
            where = f"{end.omega:.4g} rad/s, exact"
        else:
            where = ("its high-frequency limit" if end.column >= problem.columns.n_grid
                     else f"{problem.columns.omega[end.column]:.4g} rad/s")
        text = f"largest {fam.y} on the boundary of {c.label} (active near {where})"
    elif y >= yr[1]:
        text = f"largest {fam.y} allowed by {fam.y}_range (the constraints are not active there)"
    else:
        text = f"largest {fam.y} on a stability boundary (the constraints are not active there)"
    if unbounded:
        text += f"; the admissible set reaches the {fam.x} range edge, so a larger {fam.y} may exist beyond it"
    return text


# ---------------------------------------------------------------------- one fresh line
def _probe_candidates(region: Region, ln: LineData) -> list[tuple[float, float, IntervalEnd]]:
    """The H-infinity-admissible pieces of a fresh line within ``y_range``, split at its breaks, best
    first: ``(top, bottom, end)`` (``end``: what bounds the top, for an interval's top piece only)."""
    cand = []
    for r, (lo, hi) in enumerate(ln.hinf):
        lo, hi = max(lo, region.y_range[0]), min(hi, region.y_range[1])
        if not lo < hi:
            continue
        inner = ln.breaks[(ln.breaks > lo) & (ln.breaks < hi)]
        edges = np.concatenate([[lo], inner, [hi]])
        for k, (a, b) in enumerate(zip(edges[:-1], edges[1:])):
            top_piece = k == len(edges) - 2 and hi == ln.hinf[r][1]
            cand.append((float(b), float(a), ln.ends[r][1] if top_piece else None))
    cand.sort(key=lambda t: -t[0])
    return cand


def _probe_top(problem: Problem, region: Region, i: int, x: float) -> Probe:
    """Largest admissible ``ky`` on a fresh line at ``x``, joined to line ``i`` for its stability labels.

    Pieces are taken best-first; the first stable one decides.
    """
    return _probe_line(problem, region, i, scan_lines(problem, np.array([x]))[0])


def _probe_line(problem: Problem, region: Region, i: int, ln: LineData) -> Probe:
    """:func:`_probe_top` on the freshly scanned line ``ln``."""
    x = ln.x
    ref = region.lines[i]
    cells = region.cells
    ln.comp[:] = cells.new_ids(ln.n_segments)
    cand = _probe_candidates(region, ln)
    if cand:
        ys = np.array([interval_point(a, b) for b, a, _ in cand])
        js = np.searchsorted(ln.breaks, ys)
        jr = np.searchsorted(ref.breaks, ys)
        hit = problem.crossing(ref.x, x, ys)
        for (b, a, end), y, j, jref, h in zip(cand, ys, js, jr, hit):
            if not h:
                cells.union(int(ref.comp[int(jref)]), int(ln.comp[int(j)]))
            if cells.stable(int(ln.comp[int(j)]), x, float(y)):
                return Probe(b, end, a)
    return Probe(-math.inf, None, -math.inf)


def _exact_interval(problem: Problem, region: Region, i: int, x: float,
                    probe: Probe | None = None) -> tuple[float, float, float, IntervalEnd]:
    """The best admissible interval on a fresh line at ``x``, both ends refined exactly.

    ``probe``: :func:`_probe_top` of that line when the caller has it already (issue #15: the best
    line's fresh scan is not repeated).  Returns ``(top, bottom, omega, end)``; ``top <= bottom``
    when the interval is empty exactly (a sliver the grid resolved as open).
    """
    y_probe, end, bot = _probe_top(problem, region, i, x) if probe is None else probe
    if not math.isfinite(y_probe):
        return -math.inf, math.inf, math.nan, None
    if end is None or isinstance(end, Cut):  # a stability break, the range, or an exact cut: exact already
        return y_probe, bot, (end.omega if end is not None else math.nan), end
    y, w, end_exact = exact_top(problem.columns, x, y_probe, bot)
    if not math.isfinite(y):
        y, end_exact = y_probe, end
    b = exact_bottom(problem.columns, x, y_probe, bot)
    return y, b, w, end_exact if end_exact is not None else end


def _open_at(problem: Problem, region: Region, x: float, line: int,
             probe: Probe | None = None) -> tuple[float, float, IntervalEnd] | None:
    """``(top, bottom, end)`` of the exact interval at ``x`` if it is open, else None."""
    y, b_, _, e = _exact_interval(problem, region, line, x, probe)
    return (y, b_, e) if math.isfinite(y) and y > b_ else None


# ---------------------------------------------------------------------- the exact optimum
def _anchor(problem: Problem, region: Region, i: int, x0: float, probe: Probe | None = None) -> Anchor | None:
    """An exactly open interval at ``x0`` on line ``i``, or else on the best scan lines (None: none).
    ``probe``: the fresh line's :func:`_probe_top` at ``x0``, if known."""
    got = _open_at(problem, region, x0, i, probe)
    if got is not None:
        return Anchor(i, x0, *got)
    tops = np.array([region.top(k) for k in range(region.x.size)])
    for line in [int(k) for k in np.argsort(-tops) if np.isfinite(tops[k]) and int(k) != i][:12]:
        got = _open_at(problem, region, float(region.x[line]), line)
        if got is not None:
            return Anchor(line, float(region.x[line]), *got)
    return None


def _bracket_branches(problem: Problem, region: Region, anchor: Anchor, lo_x: float,
                      hi_x: float) -> tuple[list[Branch], list[Branch]]:
    """Branches that may bind anywhere in the bracket, from above and from below: local extrema near
    the anchor's interval, discovered at five positions across it (a branch can be far from binding
    at the anchor itself)."""
    uppers: list[Branch] = [anchor.end]  # type: ignore[list-item]  # a Branch: the caller checked
    lowers: list[Branch] = []
    cols = problem.columns
    xs_all = np.unique(np.concatenate([np.linspace(lo_x, hi_x, 5), [anchor.x]]))
    for xs, ln in zip(xs_all, scan_lines(problem, xs_all)):  # the fresh lines in one scan
        ys, _, bs = _probe_line(problem, region, anchor.line, ln)
        if not (math.isfinite(ys) and ys > bs):
            continue  # closed here: the branches that close it are found where it is open
        for br in active_branches(cols, float(xs), ys, bs, band=0.5):
            if br not in uppers:
                uppers.append(br)
        if math.isfinite(bs):
            for br in active_branches(cols, float(xs), ys, bs, band=0.5, upper=False):
                if br not in lowers:
                    lowers.append(br)
    return uppers, lowers


def _trackers(problem: Problem, branches: list[Branch], upper: bool) -> list[BranchTracker]:
    """One tracker per branch (neighbouring columns of one branch are one tracker)."""
    trk: list[BranchTracker] = []
    for br in sorted(branches):
        if not is_tracked(br, trk):
            trk.append(BranchTracker(problem.columns, br, upper=upper))
    return trk


def _real_floor(problem: Problem, anchor: Anchor) -> bool:
    """Is the anchor's interval closed from below by the real-root line ``t(kx, ky) = 0``?"""
    rc = problem.real.coeffs
    xa, ba = anchor.x, anchor.bottom
    return rc is not None and rc[2] != 0 and math.isfinite(ba) and abs(problem.real.value(xa, ba)) <= 1e-9 * (
        abs(rc[0]) + abs(rc[1] * xa) + abs(rc[2] * ba) + 1e-300)


def _tracked_top(problem: Problem, x: float, up_t: list[BranchTracker], lo_t: list[BranchTracker],
                 real_floor: bool) -> float:
    """The interval's top at ``x`` as the trackers see it (``-inf`` where they say it is closed)."""
    ups = [v for v in (f(x) for f in up_t) if math.isfinite(v)]
    floors = [v for v in (f(x) for f in lo_t) if math.isfinite(v)]
    if real_floor:
        rc = problem.real.coeffs
        floors.append(-(rc[0] + x * rc[1]) / rc[2])  # type: ignore[index]
    t = min(ups) if ups else -math.inf
    return t if not floors or max(floors) < t else -math.inf


def _cut_back(best_x: float, x_try: float, lo_x: float, hi_x: float) -> tuple[float, float]:
    """The bracket cut halfway back from ``x_try`` to the best point."""
    mid = 0.5 * (best_x + x_try)
    return (lo_x, mid) if x_try > best_x else (mid, hi_x)


@dataclass
class _Search:
    """The state of the exact optimum search: the ``kx`` bracket, the best point and the trackers."""

    lo_x: float
    hi_x: float
    best: tuple[float, float, IntervalEnd]
    up_t: list[BranchTracker]
    lo_t: list[BranchTracker]

    def state(self) -> tuple[float, float, tuple[float, float, IntervalEnd], int, int]:
        """What the next step depends on: the bracket, the best point and the trackers (which only
        grow; each tracker's value depends on ``x`` alone)."""
        return self.lo_x, self.hi_x, self.best, len(self.up_t), len(self.lo_t)


def exact_optimum(problem: Problem, region: Region, i: int, x0: float, y0: float, bottom: float,
                  end: IntervalEnd, probe: Probe | None = None) -> tuple[float, float, IntervalEnd]:
    """Refine the best line's top ``(x0, y0)`` to the exact optimum between the neighbouring lines.

    The optimum usually sits where two frequency branches of the boundary cross
    (a kink); a small error of either branch on the grid moves it.  Here the
    branches bounding the admissible interval (from above, and from below: a
    thin region can close from below; and the real-root line ``t(kx, ky) = 0``)
    are followed exactly in frequency while ``x`` moves (adaptive local grids),
    and every move is verified on a freshly computed line with both interval
    ends exact (:func:`_exact_interval`).  A branch that shows up there is
    added and the search repeated; where the region turns out closed, the
    bracket is cut back to the open side.  If the interval at ``x0`` is empty
    exactly (a sliver thinner than the grid error), the scan lines are tried
    best first.  ``probe``: :func:`_probe_top` of the fresh line at ``x0`` when the caller made it
    (it is not scanned again).
    """
    anchor = _anchor(problem, region, i, x0, probe)
    if anchor is None:
        return x0, y0, end
    lo_x = float(region.x[max(anchor.line - 1, 0)])
    hi_x = float(region.x[min(anchor.line + 1, region.x.size - 1)])
    best = (anchor.x, anchor.top, anchor.end)
    if anchor.end is None or isinstance(anchor.end, Cut):
        return best  # bounded by a stability break, the range, or an exact cut: nothing to track
    uppers, lowers = _bracket_branches(problem, region, anchor, lo_x, hi_x)
    real_floor = _real_floor(problem, anchor)
    search = _Search(lo_x, hi_x, best, _trackers(problem, uppers, True), _trackers(problem, lowers, False))
    for _ in range(8):
        if not search.up_t or not search.hi_x > search.lo_x:
            break
        before = search.state()
        if not _search_step(problem, region, anchor, search, real_floor) or search.state() == before:
            # a step that changed nothing would be repeated exactly (the same trackers' optimum, the same
            # exact line) up to the step limit: stop there, with the same answer (issue #15)
            break
    return search.best


def _search_step(problem: Problem, region: Region, anchor: Anchor, s: _Search, real_floor: bool) -> bool:
    """One move of the exact optimum search: the trackers' optimum in the bracket, verified on an exact
    line.  False when the search is done."""
    penalty = 10.0 * (abs(s.best[1]) + 1.0)  # where the trackers say closed (finite: Brent's parabolas)

    def objective(x: float) -> float:
        t = _tracked_top(problem, x, s.up_t, s.lo_t, real_floor)
        return -t if math.isfinite(t) else penalty

    res = minimize_scalar(objective, bounds=(s.lo_x, s.hi_x), method="bounded",
                          options={"xatol": 1e-7 * max(abs(s.lo_x), abs(s.hi_x), 1e-300)})
    if not np.isfinite(res.fun) or res.fun >= penalty:
        return False
    x_try = float(res.x)
    got = _open_at(problem, region, x_try, anchor.line)
    if got is None:
        # closed at x_try although the trackers say open: cut the bracket halfway back to the best point
        s.lo_x, s.hi_x = _cut_back(s.best[0], x_try, s.lo_x, s.hi_x)
        return True
    y_try, b_try, e_try = got
    if y_try > s.best[1]:
        s.best = (x_try, y_try, e_try if e_try is not None else anchor.end)
    cols = problem.columns
    new_up = [br for br in active_branches(cols, x_try, y_try, b_try) if not is_tracked(br, s.up_t)]
    new_lo = [br for br in active_branches(cols, x_try, y_try, b_try, upper=False) if not is_tracked(br, s.lo_t)]
    if not (new_up or new_lo) and abs(y_try + res.fun) <= 1e-6 * max(1.0, abs(y_try)):
        return False
    s.up_t += [BranchTracker(cols, br) for br in new_up]
    s.lo_t += [BranchTracker(cols, br, upper=False) for br in new_lo]
    if not (new_up or new_lo) and y_try < s.best[1]:
        # the trackers disagree with the exact line without a new branch: trust the exact value
        s.lo_x, s.hi_x = _cut_back(s.best[0], x_try, s.lo_x, s.hi_x)
    return True


# ---------------------------------------------------------------------- independent verification
def _peak(tf: TransferFunction, omega: np.ndarray, limit: np.ndarray | None,
          grid_peak: tuple[float, float] | None = None) -> tuple[float, float]:
    """``max |tf(j omega)|``: :func:`_grid_peak` (or ``grid_peak``, when the caller has it for the same
    transfer function and grid), then the limit values, which count as omega = inf."""
    best, where = _grid_peak(tf, omega) if grid_peak is None else grid_peak
    if limit is not None and limit.size:
        lm = float(np.max(np.abs(limit)))
        if lm > best * (1 + 1e-9):
            best, where = lm, math.inf
    return best, where


def _grid_peak(tf: TransferFunction, omega: np.ndarray) -> tuple[float, float]:
    """``max |tf(j omega)|`` over the finite frequencies ``omega``: every grid local maximum within 2 % of
    the top is refined between its neighbours (an optimal design often has two equal peaks)."""
    H = OnAxis(tf)  # the numbers tf.freqresp gives, without its per-call checks
    mag = np.abs(H(np.asarray(omega, dtype=float)))
    mag = np.where(np.isfinite(mag), mag, 0.0)
    top = float(mag.max())
    left = np.concatenate([[-np.inf], mag[:-1]])
    right = np.concatenate([mag[1:], [-np.inf]])
    best, where = top, float(omega[int(np.argmax(mag))])
    for i in np.flatnonzero((mag >= 0.98 * top) & (mag >= left) & (mag >= right)):
        lo, hi = omega[max(i - 1, 0)], omega[min(i + 1, omega.size - 1)]
        if hi <= lo:
            continue
        res = minimize_scalar(lambda w: -abs(H(np.array([w]))[0]), bounds=(lo, hi), method="bounded",
                              options={"xatol": 1e-12 * max(hi, 1.0)})
        if -res.fun > best:
            best, where = float(-res.fun), float(res.x)
    return best, where


def _same_response(a: TransferFunction, b: TransferFunction) -> bool:
    """Are ``a`` and ``b`` the same numerator and denominator (so the same numbers at every frequency)?
    An ``||S||inf`` constraint's channel is the loop's sensitivity itself."""
    return all(np.array_equal(getattr(p, k), getattr(q, k))
               for p, q in ((a.num, b.num), (a.den, b.den)) for k in ("coeffs", "delays"))


def _active_frequency(problem: Problem, kx: float, end: IntervalEnd) -> float:
    """Frequency of the interval end ``end`` at ``kx`` (exact), or nan."""
    if end is None:
        return math.nan
    if isinstance(end, Cut):
        return float(end.omega)
    if end.column >= problem.columns.n_grid:
        return math.nan
    return float(exact_end(problem.columns, kx, end, upper=True)[1])


def finish(tuner: _Tuner, problem: Problem, region: Region, kx: float, ky: float, reason: str,
           unbounded: bool, end: IntervalEnd = None) -> TuningResult:
    """The result at ``(kx, ky)``, verified: peak sensitivity and every constraint's norm from the loop's
    own channels (refined in frequency), and the loop's certified spectrum check."""
    fam = tuner.family
    C = fam.controller(kx, ky)
    loop = tuner.loop(kx, ky)
    fd = problem.fd
    cols = problem.columns
    w = fd.omega[fd.omega > 0]
    # the active frequency (where the constraint holds with equality) may be a resonance narrower than
    # the grid, which was refined for the open-loop terms: add it and a narrow neighbourhood
    w_act = _active_frequency(problem, kx, end)
    if math.isfinite(w_act) and w_act > 0:
        w = np.unique(np.concatenate([w, w_act * (1.0 + np.linspace(-1e-3, 1e-3, 21))]))
    lim = fd.n_grid
    Ulim = cols.u[lim:] + kx * cols.a[lim:] + ky * cols.b[lim:]
    sens = loop.sensitivity
    with np.errstate(divide="ignore"):
        s_peak = _grid_peak(sens, w)
        ms, w_ms = _peak(sens, w, 1.0 / Ulim, s_peak)
    norms, active = [], []
    for ci, c in enumerate(tuner.constraints):
        src, dst = c.channel
        X = loop.transfer(src, dst) * c.weight_tf
        nu, na, nb, w2 = cols.constraints[ci]
        Nlim = nu[lim:] + kx * na[lim:] + ky * nb[lim:]
        with np.errstate(divide="ignore", invalid="ignore"):
            Xlim = np.sqrt(w2[lim:]) * c.gamma * np.abs(Nlim) / np.abs(Ulim)
        # issue #15: an ||S||inf constraint's channel is the sensitivity, whose grid peak is known
        n, _ = _peak(X, w, Xlim, s_peak if _same_response(X, sens) else None)
        norms.append(n)
        active.append(abs(n - c.gamma) <= 1e-6 * c.gamma)
    try:
        st = loop.stability()
        stable = bool(st.stable)
    except (RootFindingError, ValueError) as exc:
        st, stable = None, False
        reason += f"; the spectrum check of the chosen loop failed: {exc}"
    return TuningResult(fam, tuner.architecture, fam.gains(kx, ky), C, loop, ms, w_ms,
                        1.0 / ms if ms > 0 else math.inf, stable, st, tuple(norms), tuple(active),
                        tuner.constraints, region, False, unbounded, reason)
