"""The admissible region in a two-gain plane: H-infinity regions intersected with the stable cells.

:class:`Region` is the data of a scan (seed 001 section 3, Algorithm 1): the
scan lines (:mod:`posicast.tune.scan`), their joined D-decomposition cells
(:mod:`posicast.tune.cells`) and the problem they came from.  Its queries are
the free functions of this module (the methods are their short forms); a cell's
stability label is computed the first time a query needs it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from .. import _validate as v
from .cells import Cells, interval_point
from .constraints import Constraint
from .family import ControllerFamily
from .scan import LineData, Problem, intersect

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["Region", "LineData", "SkippedLines", "make_region", "admissible_intervals", "pieces", "best_piece",
           "component_lines", "component_extent", "hinf_intervals", "stable_intervals", "default_window", "extent",
           "area", "contains", "mask", "signed_distance"]

_INF = math.inf
_WHAT = ("admissible", "hinf", "stable")


@dataclass(frozen=True, eq=False)
class Region:
    """Admissible controllers in a gain plane: H-infinity regions intersected with the stability region.

    Built by :func:`posicast.tune_pd` and friends (``result.region``).  The plane
    has the scanned gain :attr:`x_name` horizontally and the maximised gain
    :attr:`y_name` vertically; :attr:`x` are the scan lines (spacing
    :attr:`spacing`).  On each line the admissible ``ky`` set is exact up to the
    frequency grid (see :mod:`posicast.tune.scan`), so the region is resolved to
    the line spacing in ``kx``.

    Attributes
    ----------
    family : ControllerFamily
    x_name, y_name : str
    x : ndarray
        The scan lines.
    spacing : float
    y_range : (float, float)
        The ``ky`` range this region covers: every line is exact over it.  The
        whole search range (:attr:`search_range`), or, for a loop whose frequency
        grid is large (a lumped shaper or a delay in the loop), the window around
        the optimum's component that the final scan refined (:attr:`windowed`).
    constraints : tuple of Constraint
    lines : tuple of LineData
        What the scan found on each line.
    cells : Cells
        The joined D-decomposition cells and their stability labels.
    problem : Problem
        The scan's frequency data and boundaries.
    empty : bool
        No admissible stable controller on any line.
    search_range : (float, float) or None
        The ``ky`` range of the whole search (the tuning's ``ky_range`` or its
        automatic window); None: :attr:`y_range`.
    sweep : Region or None
        The first pass: the whole :attr:`search_range` on the logarithmic sweep
        lines, exact on those lines (coarser in ``kx`` than this region); None
        when this region is that pass, or is not windowed.  With a lumped shaper
        in the loop the design may have needed only the sweep's inner lines
        (:attr:`skipped`); the whole sweep is then scanned when first asked for.
    skipped : SkippedLines or None
        The sweep lines the design left out, and why (None: it scanned them all).
    """

    family: ControllerFamily
    x_name: str
    y_name: str
    x: np.ndarray
    spacing: float
    y_range: tuple[float, float]
    constraints: tuple[Constraint, ...]
    lines: tuple[LineData, ...]
    cells: Cells = field(repr=False)
    problem: Problem = field(repr=False)
    search_range: tuple[float, float] | None = None
    _sweep: Region | Callable[[], Region] | None = field(default=None, repr=False)
    skipped: SkippedLines | None = None
    _admissible: dict[int, np.ndarray] = field(default_factory=dict, init=False, repr=False)

    @property
    def sweep(self) -> Region | None:
        """The first pass over the whole search range (see the class attributes); scanned now if the design
        left its outer lines out (:attr:`skipped`)."""
        s = self._sweep
        if s is not None and not isinstance(s, Region):
            s = s()
            object.__setattr__(self, "_sweep", s)
        return s

    @property
    def sweep_lines(self) -> int:
        """How many lines the first pass has (without scanning a sweep not yet scanned; 0: none)."""
        if self._sweep is None:
            return 0
        if isinstance(self._sweep, Region):
            return int(self._sweep.x.size)
        return int(self.skipped.n_sweep) if self.skipped is not None else int(self.sweep.x.size)

    # ------------------------------------------------------------------ short forms of the queries
    @property
    def empty(self) -> bool:
        return all(admissible_intervals(self, i).size == 0 for i in range(len(self.lines)))

    @property
    def windowed(self) -> bool:
        """Does :attr:`y_range` cover less than :attr:`search_range` (the far parts only in :attr:`sweep`)?"""
        return self.search_range is not None and tuple(self.y_range) != tuple(self.search_range)

    @property
    def stability_checks(self) -> int:
        """Certified spectrum checks made so far (one per D-decomposition component)."""
        return self.problem.ledger.calls

    def admissible_intervals(self, i: int) -> np.ndarray:
        """:func:`admissible_intervals`."""
        return admissible_intervals(self, i)

    def hinf_intervals(self, i: int, constraint: int | None = None) -> np.ndarray:
        """:func:`hinf_intervals`."""
        return hinf_intervals(self, i, constraint)

    def stable_intervals(self, i: int, window: tuple[float, float] | None = None) -> np.ndarray:
        """:func:`stable_intervals`."""
        return stable_intervals(self, i, window)

    def default_window(self) -> tuple[float, float]:
        """:func:`default_window`."""
        return default_window(self)

    def top(self, i: int) -> float:
        """Largest admissible ``ky`` on line ``i`` (``-inf`` if none)."""
        iv = admissible_intervals(self, _line(self, i))
        return float(iv[:, 1].max()) if iv.size else -_INF

    def contains(self, kx: Any, ky: Any) -> np.ndarray:
        """:func:`contains`."""
        return contains(self, kx, ky)

    def extent(self) -> tuple[float, float, float, float] | None:
        """:func:`extent`."""
        return extent(self)

    def area(self) -> float:
        """:func:`area`."""
        return area(self)

    def mask(self, y: np.ndarray, what: str = "admissible", constraint: int | None = None) -> np.ndarray:
        """:func:`mask`."""
        return mask(self, y, what, constraint)

    def field(self, y: np.ndarray, what: str = "admissible", constraint: int | None = None) -> np.ndarray:
        """:func:`signed_distance`."""
        return signed_distance(self, y, what, constraint)

    def plot(self, ax: Axes | None = None, **kwargs: Any) -> tuple[Figure, Axes]:
        """Draw the region (see :func:`posicast.tune.region_plot`)."""
        from .plots import region_plot  # plots imports this module

        return region_plot(self, ax=ax, **kwargs)

    def __repr__(self) -> str:
        ext = extent(self)
        where = "empty" if ext is None else (
            f"{self.x_name} in [{ext[0]:.4g}, {ext[1]:.4g}], {self.y_name} in [{ext[2]:.4g}, {ext[3]:.4g}]")
        win = f"; {self.y_name} window [{self.y_range[0]:.4g}, {self.y_range[1]:.4g}]" if self.windowed else ""
        return f"Region({self.x.size} lines, spacing {self.spacing:.3g}{win}; admissible: {where})"


@dataclass(frozen=True)
class SkippedLines:
    """Sweep lines a design left out: none of them has a stable H-infinity-admissible ``ky`` at or above
    ``floor`` in the search range, and the best component found without them ends inside the lines scanned,
    so the optimum is the same with or without them. Most are shown to have no admissible ``ky`` there at all
    by exact forbidden intervals on ``probe`` frequency columns (grid columns, frequencies up to the delay
    ceiling, the limit columns: :func:`posicast.tune.scan.forbidden_above`); the ``scanned`` others were scanned
    exactly on a grid extended for them, and their admissible pieces there lie in ``unstable`` cells, each
    shown unstable by a certified spectrum check.

    Attributes
    ----------
    x : ndarray
        The lines left out.
    floor : float
        The ``ky`` from which up none of them holds a stable admissible gain.
    probe : int
        How many frequency columns the probe has.
    n_sweep : int
        Lines of the whole sweep.
    scanned : int
        Lines the probe did not show, scanned exactly instead (0: the probe showed every line).
    unstable : int
        Cells of the scanned lines with an admissible piece at or above ``floor``, each shown unstable.
    """

    x: np.ndarray
    floor: float
    probe: int
    n_sweep: int
    scanned: int = 0
    unstable: int = 0


def make_region(problem: Problem, family: ControllerFamily, lines: list[LineData], cells: Cells,
                y_range: tuple[float, float], search_range: tuple[float, float] | None = None,
                sweep: Region | Callable[[], Region] | None = None,
                skipped: SkippedLines | None = None) -> Region:
    """The region of a scan (``search_range``, ``sweep``, ``skipped``: see :class:`Region`; ``sweep`` may be a
    callable that scans it when first asked for)."""
    x = np.array([ln.x for ln in lines])
    spacing = float(np.median(np.diff(x))) if x.size > 1 else 0.0
    return Region(family, family.x, family.y, x, spacing, y_range, problem.fd.constraints, tuple(lines), cells,
                  problem, search_range, sweep, skipped)


# ---------------------------------------------------------------------- argument checks
def _line(region: Region, i: Any) -> int:
    """``i`` as a line index (TypeError/ValueError naming ``i``)."""
    return v.index(i, "i", len(region.lines), "a line index")


def _constraint_index(region: Region, constraint: Any) -> int | None:
    """None (all constraints) or ``constraint`` as an index into the region's constraints."""
    return None if constraint is None else v.index(constraint, "constraint", len(region.constraints),
                                                   "a constraint index")


# ---------------------------------------------------------------------- per line
def segment_stable(region: Region, i: int, j: int, y: float) -> bool | None:
    """Stability label of segment ``j`` of line ``i`` (checked at ``y`` if its cell has none yet)."""
    ln = region.lines[i]
    return region.cells.stable(int(ln.comp[j]), ln.x, y)


def admissible_intervals(region: Region, i: int) -> np.ndarray:
    """Admissible ``ky`` intervals on line ``i`` (H-infinity and stable), clipped to ``y_range``."""
    i = _line(region, i)
    cached = region._admissible.get(i)
    if cached is not None:
        return cached
    out = [(a, b) for a, b, j in pieces(region, i) if segment_stable(region, i, j, interval_point(a, b))]
    arr = np.array(out, dtype=float).reshape(-1, 2)
    region._admissible[i] = arr
    return arr


def pieces(region: Region, i: int) -> list[tuple[float, float, int]]:
    """H-infinity-admissible pieces of line ``i`` within ``y_range``, split at the breaks: ``(lo, hi, segment)``."""
    ln = region.lines[_line(region, i)]
    out = []
    for lo, hi in intersect(ln.hinf, np.array([region.y_range])):
        inner = ln.breaks[(ln.breaks > lo) & (ln.breaks < hi)]
        edges = np.concatenate([[lo], inner, [hi]])
        for a, b in zip(edges[:-1], edges[1:]):
            if a < b:
                out.append((float(a), float(b), int(np.searchsorted(ln.breaks, interval_point(a, b)))))
    return out


def best_piece(region: Region) -> tuple[int, float, float] | None:
    """The admissible piece with the largest upper end: ``(line, lo, hi)``, or None.

    Pieces are checked best-first, so only the cells needed to decide the
    maximum get a spectrum check.
    """
    cand = [(hi, i, lo, j) for i in range(len(region.lines)) for lo, hi, j in pieces(region, i)]
    cand.sort(key=lambda t: -t[0])
    for hi, i, lo, j in cand:
        if segment_stable(region, i, j, interval_point(lo, hi)):
            return i, lo, hi
    return None


def component_lines(region: Region, i: int, y: float) -> np.ndarray:
    """Indices of the lines holding a segment of the same joined component as ``(x[i], y)``."""
    ln = region.lines[i]
    cells = region.cells
    root = cells.find(int(ln.comp[int(np.searchsorted(ln.breaks, y))]))
    return np.array([k for k, other in enumerate(region.lines)
                     if any(cells.find(int(c)) == root for c in other.comp if c >= 0)], dtype=int)


def component_extent(region: Region, lines: np.ndarray, i: int, y: float) -> tuple[float, float]:
    """``(lowest, highest)`` ``ky`` of the admissible pieces on ``lines`` in the joined component of ``(x[i], y)``."""
    ln = region.lines[i]
    cells = region.cells
    root = cells.find(int(ln.comp[int(np.searchsorted(ln.breaks, y))]))
    lo, hi = _INF, -_INF
    for k in lines:
        comp = region.lines[int(k)].comp
        for a, b, j in pieces(region, int(k)):
            if cells.find(int(comp[j])) == root:
                lo, hi = min(lo, a), max(hi, b)
    return lo, hi


def hinf_intervals(region: Region, i: int, constraint: int | None = None) -> np.ndarray:
    """H-infinity-admissible ``ky`` intervals on line ``i`` (all constraints, or one), stability ignored."""
    ln = region.lines[_line(region, i)]
    constraint = _constraint_index(region, constraint)
    return ln.hinf if constraint is None else ln.per_constraint[constraint]


def default_window(region: Region) -> tuple[float, float]:
    """The ``ky`` window shown and labelled by default: the admissible extent with half its height
    either side (or ``y_range``), within the verified gains ``|ky| <= y_valid``."""
    yv = region.problem.y_valid
    ext = extent(region)
    if ext is not None and math.isfinite(ext[2]) and math.isfinite(ext[3]):
        pad = 0.5 * max(ext[3] - ext[2], 1e-12)
        lo, hi = ext[2] - pad, ext[3] + pad
    else:
        lo, hi = region.y_range
    return max(lo, region.y_range[0], -yv), min(hi, region.y_range[1], yv)


def stable_intervals(region: Region, i: int, window: tuple[float, float] | None = None) -> np.ndarray:
    """Stable ``ky`` intervals on line ``i`` within ``window`` (default :func:`default_window`).

    One certified spectrum check per D-decomposition cell not yet checked; the
    window keeps the checks to gains of interest (far out, a delay loop has
    thousands of roots in the search region).
    """
    i = _line(region, i)
    ln = region.lines[i]
    if window is not None:
        lo, hi = v.pair(window, "window", "a (low, high) pair or None")
        window = (v.finite_real(lo, "window[0]"), v.finite_real(hi, "window[1]"))
    w_lo, w_hi = default_window(region) if window is None else window
    # beyond the problem's ky window the segments are not D-decomposition cells (breaks were dropped)
    w_lo, w_hi = max(w_lo, region.problem.y_window[0]), min(w_hi, region.problem.y_window[1])
    out = []
    for j in range(ln.n_segments):
        lo, hi = ln.segment_bounds(j)
        lo, hi = max(lo, w_lo), min(hi, w_hi)
        if lo < hi and segment_stable(region, i, j, interval_point(lo, hi)):
            out.append((lo, hi))
    return np.array(out, dtype=float).reshape(-1, 2)


# ---------------------------------------------------------------------- the whole plane
def contains(region: Region, kx: Any, ky: Any) -> np.ndarray:
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
    x = region.x
    if x.size == 0:  # no line scanned (a loop refused before the scan): nothing is admissible
        return np.zeros(kx.shape, dtype=bool)
    idx = np.clip(np.searchsorted(x, kx), 1, max(x.size - 1, 1))
    if x.size > 1:
        left = x[idx - 1]
        idx = np.where(np.abs(kx - left) <= np.abs(x[np.minimum(idx, x.size - 1)] - kx), idx - 1, idx)
    else:
        idx = np.zeros(kx.shape, dtype=int)
    out = np.zeros(kx.shape, dtype=bool)
    inside_x = (kx >= x[0] - 0.5 * region.spacing) & (kx <= x[-1] + 0.5 * region.spacing)
    for i in np.unique(idx):
        sel = (idx == i) & inside_x
        iv = admissible_intervals(region, int(i))
        if iv.size:
            yy = ky[sel]
            out[sel] = np.any((yy[:, None] > iv[None, :, 0]) & (yy[:, None] < iv[None, :, 1]), axis=1)
    return out


def extent(region: Region) -> tuple[float, float, float, float] | None:
    """``(x_min, x_max, y_min, y_max)`` of the admissible set, or None if empty."""
    xs, ylo, yhi = [], [], []
    for i, ln in enumerate(region.lines):
        iv = admissible_intervals(region, i)
        if iv.size:
            xs.append(ln.x)
            ylo.append(iv[:, 0].min())
            yhi.append(iv[:, 1].max())
    if not xs:
        return None
    return min(xs), max(xs), min(ylo), max(yhi)


def area(region: Region) -> float:
    """Area of the admissible set (line sum; ``inf`` if unbounded)."""
    tot = 0.0
    for i in range(len(region.lines)):
        iv = admissible_intervals(region, i)
        tot += float(np.sum(iv[:, 1] - iv[:, 0])) if iv.size else 0.0
    return tot * region.spacing


def _intervals(region: Region, i: int, what: str, constraint: int | None, y: np.ndarray) -> np.ndarray:
    """Line ``i``'s ``'admissible'``, ``'hinf'`` or ``'stable'`` intervals (stable: within ``y``'s span)."""
    if what == "admissible":
        return admissible_intervals(region, i)
    if what == "hinf":
        return hinf_intervals(region, i, constraint)
    return stable_intervals(region, i, (float(y.min()), float(y.max())) if y.size else None)


def _grid_args(region: Region, y: Any, what: Any, constraint: Any) -> tuple[np.ndarray, int | None]:
    y = v.strict_real_array(y, "y", allow_empty=True)
    if y.ndim != 1:
        raise ValueError(f"y must be a 1-D array of gains, got shape {y.shape}")
    v.choice(what, "what", _WHAT)
    return y, _constraint_index(region, constraint)


def mask(region: Region, y: np.ndarray, what: str = "admissible", constraint: int | None = None) -> np.ndarray:
    """Membership on the grid ``lines x y``: ``'admissible'``, ``'hinf'`` or ``'stable'``."""
    y, constraint = _grid_args(region, y, what, constraint)
    out = np.zeros((region.x.size, y.size), dtype=bool)
    for i in range(region.x.size):
        iv = _intervals(region, i, what, constraint, y)
        if iv.size:
            out[i] = np.any((y[:, None] > iv[None, :, 0]) & (y[:, None] < iv[None, :, 1]), axis=1)
    return out


def signed_distance(region: Region, y: np.ndarray, what: str = "admissible",
                    constraint: int | None = None) -> np.ndarray:
    """Signed distance in ``ky`` to the set's boundary on each line (positive inside), on ``lines x y``.

    Its zero contour joins the exact interval ends of neighbouring lines by
    straight segments: a smooth drawing of the region instead of the
    staircase of :func:`mask`.
    """
    y, constraint = _grid_args(region, y, what, constraint)
    span = float(np.ptp(y)) if y.size > 1 else 1.0
    out = np.full((region.x.size, y.size), -span)
    for i in range(region.x.size):
        iv = _intervals(region, i, what, constraint, y)
        if iv.size:
            lo = np.where(np.isfinite(iv[:, 0]), iv[:, 0], -1e300)
            hi = np.where(np.isfinite(iv[:, 1]), iv[:, 1], 1e300)
            d = np.minimum(y[:, None] - lo[None, :], hi[None, :] - y[:, None]).max(axis=1)
            out[i] = np.clip(d, -span, span)
    return out
