"""Stability cells: scan-line segments joined across lines, one certified spectrum check each.

Segments of adjacent lines are joined when the horizontal path between them
crosses no D-decomposition boundary (:func:`join_lines`); each joined component
gets one certified spectrum check (:meth:`Loop.stability`, issue #3) at an
interior point, on demand (:meth:`Cells.stable`).  A segment that cannot be
joined is simply checked on its own, so a missed join costs time, never
correctness.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Callable

import numpy as np

from ..loops import Loop
from ..spectra import unstable_count
from ..spectra.rootfinder import RootFindingError

if TYPE_CHECKING:
    from .scan import LineData, Problem

__all__ = ["StabilityLedger", "Cells", "certified_stability", "interval_point", "join_lines"]

# Budgets of the certified checks that label cells, counted in evaluations of the characteristic
# quasi-polynomial, never in seconds: a label must not depend on how busy the machine is.
_COUNT_EVALUATIONS = 2e6
_CHECK_EVALUATIONS = 2e7


def certified_stability(loop: Loop) -> bool | str:
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
    try:
        return unstable_count(loop.characteristic, ignore=loop.cancelled, max_evaluations=_COUNT_EVALUATIONS) == 0
    except (RootFindingError, ValueError):
        pass
    try:
        return bool(loop.stability(max_evaluations=_CHECK_EVALUATIONS, timeout=1e9).stable)
    except (RootFindingError, ValueError) as exc:
        return f"spectrum check failed: {exc}"


@dataclass
class StabilityLedger:
    """The certified spectrum checks of one tuning (shared by its passes): how many, and which failed."""

    calls: int = 0
    failures: list[str] = field(default_factory=list)


class Cells:
    """Components of joined segments (union-find) with their stability labels.

    Each segment of a scan line gets a component id (:meth:`new`);
    :meth:`union` joins two; :meth:`stable` labels a component by one certified
    check of the loop at a point inside it (once per component).
    """

    def __init__(self, loop_factory: Callable[[float, float], Loop], ledger: StabilityLedger,
                 names: tuple[str, str]) -> None:
        self.loop_factory = loop_factory
        self.ledger = ledger
        self.names = names
        self.parent: list[int] = []
        self.label: dict[int, bool | None] = {}
        self.point: dict[int, tuple[float, float]] = {}

    def new(self) -> int:
        self.parent.append(len(self.parent))
        return len(self.parent) - 1

    def new_ids(self, n: int) -> np.ndarray:
        """``n`` new components at once (the ids :meth:`new` would give, in order)."""
        start = len(self.parent)
        self.parent.extend(range(start, start + n))
        return np.arange(start, start + n)

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

    def stable(self, cid: int, x: float, y: float) -> bool | None:
        """Component ``cid``'s label (checked at ``(x, y)`` if it has none yet; None: not certified)."""
        root = self.find(cid)
        if root in self.label:
            return self.label[root]
        self.ledger.calls += 1
        lab = certified_stability(self.loop_factory(x, y))
        if isinstance(lab, str):
            self.ledger.failures.append(f"({self.names[0]}={x:.6g}, {self.names[1]}={y:.6g}): {lab}")
            lab = None
        self.label[root] = lab
        self.point[root] = (x, y)
        return lab


def interval_point(lo: float, hi: float) -> float:
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


#: lines with more segments than this, together, are joined by binary search (fewer: by a merge, cheaper there)
_MERGE_BELOW = 64


def _overlaps(A: LineData, B: LineData, ma: np.ndarray, mb: np.ndarray) -> list[tuple[int, int, float]]:
    """Pairs of wanted segments ``(ja, jb)`` of two adjacent lines that overlap in ``ky``, with a point
    inside the certain part of the overlap (in increasing order of ``ja``, then ``jb``).

    Short lines are merged segment by segment; long ones (a delay loop's lines have hundreds of segments,
    few of them wanted) go to :func:`_overlaps_by_search`, which visits only the wanted segments (issue
    #15: a merge over all of them was most of the joins' time there).  The same pairs either way.
    """
    if A.n_segments + B.n_segments > _MERGE_BELOW:
        return _overlaps_by_search(A, B, ma, mb)
    out = []
    ja = jb = 0
    while ja < A.n_segments and jb < B.n_segments:
        alo, ahi = A.segment_bounds(ja)
        blo, bhi = B.segment_bounds(jb)
        if ma[ja] and mb[jb]:
            _join_point(A, B, ja, jb, alo, ahi, blo, bhi, out)
        if ahi <= bhi:
            ja += 1
        else:
            jb += 1
    return out


def _join_point(A: LineData, B: LineData, ja: int, jb: int, alo: float, ahi: float, blo: float, bhi: float,
                out: list[tuple[int, int, float]]) -> None:
    """Append ``(ja, jb, point)`` if the two segments overlap in more than their ends' uncertainty."""
    lo, hi = max(alo, blo), min(ahi, bhi)
    if lo < hi:
        # the overlap's ends are breaks known to within their uncertainty: join only through
        # its certain part (a skipped join costs one more spectrum check, never a wrong label)
        # a line's uncertainty at an end that is not one of its own breaks is 0: an end strictly inside a
        # segment is none of the (sorted) breaks, so only the line whose break it is gets looked up
        e_lo = max(A.error_at(lo) if not lo > alo else 0.0, B.error_at(lo) if not lo > blo else 0.0)
        e_hi = max(A.error_at(hi) if not hi < ahi else 0.0, B.error_at(hi) if not hi < bhi else 0.0)
        if lo + e_lo < hi - e_hi:
            out.append((ja, jb, interval_point(lo + e_lo, hi - e_hi)))


def _overlaps_by_search(A: LineData, B: LineData, ma: np.ndarray, mb: np.ndarray) -> list[tuple[int, int, float]]:
    """:func:`_overlaps` visiting only the wanted segments: the segments of a line partition the ``ky`` axis
    (its breaks are strictly increasing), so those of ``B`` that overlap segment ``ja`` of ``A`` are a run
    found by two binary searches."""
    wa = np.flatnonzero(ma[: A.n_segments])
    if not wa.size or not np.any(mb):
        return []
    ea = np.concatenate([[-math.inf], A.breaks, [math.inf]])
    eb = np.concatenate([[-math.inf], B.breaks, [math.inf]])
    # B's segments with blo < ahi and bhi > alo: from the one holding alo to the last starting below ahi
    first = np.searchsorted(eb, ea[wa], side="right") - 1
    last = np.minimum(np.searchsorted(eb, ea[wa + 1], side="left") - 1, B.n_segments - 1)
    count = np.maximum(last - first + 1, 0)
    ja = np.repeat(wa, count)
    jb = np.repeat(first, count) + (np.arange(ja.size) - np.repeat(np.cumsum(count) - count, count))
    keep = mb[jb]
    out: list[tuple[int, int, float]] = []
    for i, j in zip(ja[keep].tolist(), jb[keep].tolist()):
        alo, ahi = A.segment_bounds(i)
        blo, bhi = B.segment_bounds(j)
        _join_point(A, B, i, j, alo, ahi, blo, bhi, out)
    return out


def join_lines(problem: Problem, lines: list[LineData], cells: Cells,
               wanted: Callable[[int], np.ndarray] | None = None) -> None:
    """Assign component ids to the segments of ``lines`` and join adjacent ones without a crossing.

    ``wanted(i)`` is a boolean mask over line ``i``'s segments limiting the joins
    to segments of interest (default: all).  All the crossing checks go to one
    vectorised call.
    """
    for ln in lines:
        fresh = np.flatnonzero(ln.comp[: ln.n_segments] < 0)
        ln.comp[fresh] = cells.new_ids(fresh.size)
    masks = [wanted(i) if wanted is not None else np.ones(ln.n_segments, dtype=bool) for i, ln in enumerate(lines)]
    pairs: list[tuple[int, int, int]] = []
    x0s, x1s, ys = [], [], []
    for i in range(len(lines) - 1):
        A, B = lines[i], lines[i + 1]
        if not (masks[i].any() and masks[i + 1].any()):
            continue
        for ja, jb, y in _overlaps(A, B, masks[i], masks[i + 1]):
            pairs.append((i, ja, jb))
            x0s.append(A.x)
            x1s.append(B.x)
            ys.append(y)
    if not pairs:
        return
    hit = problem.crossing(np.array(x0s), np.array(x1s), np.array(ys))
    for (i, ja, jb), h in zip(pairs, hit):
        if not h:
            cells.union(int(lines[i].comp[ja]), int(lines[i + 1].comp[jb]))
