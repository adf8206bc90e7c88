"""Certified roots of quasi-polynomials in a rectangle.

``roots(h, region)`` returns every root of ``h(s) = sum_i p_i(s) exp(-s tau_i)``
in ``re_min <= Re s <= re_max``, ``im_min <= Im s <= im_max`` together with a
*certified* count.  The method, in four steps:

1. **Certified count.**  The argument principle on the rectangle's boundary.
   The boundary is sampled adaptively until every segment ``[a, b]`` of length
   ``L`` passes the test ``M L / 2 + e < min(|h(a)|, |h(b)|)``, where ``M`` is a
   rigorous bound of ``|h'|`` on the segment (absolute coefficients, the
   segment's largest ``|s|`` and smallest ``Re s``) and ``e`` bounds the
   rounding error of the evaluation (including the phase of ``exp(-s tau)``,
   rounded to ``eps |s| tau``, which dominates at high frequency).  Next to a
   root, where that bound of ``|h'|`` is too coarse (it ignores the cancellation
   of ``h`` near a multiple root), ``M`` comes from the Taylor coefficients of
   ``h`` about the segment's midpoint.  Under that test ``h`` has no zero on the
   segment and its argument changes by less than ``pi`` along it, so the sum
   of the principal increments is exactly ``2 pi`` times the number of roots
   inside.  A segment that cannot pass the test down to a tiny length means a
   root on (or within rounding of) the boundary: that edge is moved outward
   and the count is redone ("shift and recount"); the region actually used is
   returned.
2. **Candidates.**  As in QPmR (seed 000 ref. [22], Vyhlídal & Zítek 2009) the
   region is covered by a grid whose step follows the delays; the discrete
   winding of ``h`` around every grid cell flags the cells that hold roots.
3. **Refinement.**  Vectorised Newton from the flagged cells; converged points
   are merged, clusters (multiple roots) get their multiplicity from a small
   certified count around them and are polished by Newton on
   ``h^{(m-1)}``.  A cluster whose points are too scattered for that (Newton
   stalls ``(rounding)^(1/m)`` away from an ``m``-fold root) is centred on the
   root of ``h^{(k)}`` next to it; one member already taken for a simple root is
   taken back into it.  Every root is returned with its relative residual
   ``|h(r)| / sum_i |p_i(r)| |exp(-r tau_i)|``.
4. **Reconciliation.**  When the roots found do not add up to the certified
   count, the rectangle is split, each part is counted (certified) and searched
   on a finer grid, recursively, until they do.  If that fails within the
   budget a :class:`RootFindingError` says so: a silent miss is impossible.

Evaluation is scaled by the positive factor ``exp(min(0, Re s) tau_max)`` so
that no exponential overflows; a positive factor changes neither the argument
nor the roots.


Where each step lives: :mod:`~posicast.spectra.checks` (arguments, errors),
:mod:`~posicast.spectra.evaluation` (scaled evaluation, derivative and rounding bounds),
:mod:`~posicast.spectra.argument_principle` (step 1), :mod:`~posicast.spectra.candidates`
(steps 2 and 3: grid and Newton), :mod:`~posicast.spectra.disks` (Pellet disks for
clusters), :mod:`~posicast.spectra.solver` (steps 3 and 4: the roots found, their
multiplicities, reconciliation); this module holds :func:`roots` and its result.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ..core.quasipoly import QuasiPolynomial
from .argument_principle import count_with_shifts
from .candidates import MAX_GRID, grid_shape, grid_step, newton
from .checks import (
    BudgetExceeded,
    RootFindingError,
    as_quasipolynomial,
    check_budget,
    check_ignore,
    check_range,
    check_region,
    normalised,
)
from .disks import certified_radius
from .evaluation import Evaluator, relative_residual
from .solver import Solver

__all__ = [
    "roots",
    "Roots",
    "RootFindingError",
    "BudgetExceeded",
    "as_quasipolynomial",
    "check_region",
    "check_budget",
    "check_ignore",
    "check_range",
    "certified_radius",
]

_MAX_GRID = MAX_GRID  # grid points held at once (complex: 320 MB)


@dataclass(frozen=True)
class Roots:
    """Roots of a quasi-polynomial in a rectangle, with a certified count.

    Attributes
    ----------
    roots : ndarray of complex
        Every root in :attr:`region`, repeated by multiplicity, sorted by
        decreasing real part (ties by imaginary part).
    count : int
        The number of roots in :attr:`region` by the argument principle (certified);
        always ``len(roots)``.
    distinct, multiplicities : ndarray
        The distinct roots and their multiplicities.  A multiple root is
        reported once, at the simple root of ``h^{(m-1)}`` inside a disk where
        a Rouché/Pellet test certifies exactly ``m`` roots; rounding of the
        coefficients splits an exact ``m``-fold root into a tight cluster
        (about ``eps^{1/m}`` wide, e.g. 7e-4 for the fourfold zeros of ZVD^3;
        higher up the rounded delays are no longer exactly commensurate and the
        cluster widens, 3e-3 at 7000 rad/s), and such a cluster is what this
        reports.
    residuals : ndarray of float
        Relative residual ``|h(r)| / sum_i |p_i(r) exp(-r tau_i)|`` of each distinct root.
    region : tuple
        The rectangle actually used: the requested one, with an edge moved
        outward when a root lay on it (:attr:`shifted`).
    requested_region : tuple
    evaluations : int
        Quasi-polynomial evaluations spent.
    """

    roots: np.ndarray
    count: int
    distinct: np.ndarray
    multiplicities: np.ndarray
    residuals: np.ndarray
    region: tuple[float, float, float, float]
    requested_region: tuple[float, float, float, float]
    shifted: bool
    evaluations: int
    removed: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=complex))

    def __len__(self) -> int:
        return int(self.roots.size)

    def __repr__(self) -> str:
        return (
            f"Roots(count={self.count}, distinct={self.distinct.size}, region={self.region}, "
            f"max_residual={self.residuals.max() if self.residuals.size else 0.0:.1e})"
        )

    @property
    def abscissa(self) -> float:
        """Largest real part among the roots (``-inf`` when there are none)."""
        return float(self.roots.real.max()) if self.roots.size else -math.inf


def _sort_key(z: np.ndarray) -> np.ndarray:
    """The order of :attr:`Roots.roots`: decreasing real part, real parts equal to rounding
    (``1e-12 max(1, |z|)``, e.g. the zeros of a ZV shaper on one vertical line) by increasing
    imaginary part, not by the sign of their rounding errors."""
    if z.size < 2:
        return np.arange(z.size)
    o = np.argsort(-z.real, kind="stable")
    re = z.real[o]
    tol = 1e-12 * np.maximum(1.0, np.abs(z[o]))
    starts = np.empty(z.size, dtype=bool)
    starts[0] = True
    starts[1:] = re[:-1] - re[1:] > np.maximum(tol[:-1], tol[1:])
    group = np.empty(z.size, dtype=np.intp)
    group[o] = np.cumsum(starts)
    return np.lexsort((z.imag, group))


def roots(
    h: Any,
    region: Sequence[float],
    *,
    ignore: Any = None,
    max_evaluations: float = 5e7,
    timeout: float = 120.0,
) -> Roots:
    """All roots of a quasi-polynomial in a rectangle, with a certified count.

    Parameters
    ----------
    h : QuasiPolynomial
        ``h(s) = sum_i p_i(s) exp(-s tau_i)`` (or a ``(coeffs, delays)`` pair).
        For a transfer function pass ``.num`` (zeros) or ``.den`` (poles).
    region : (re_min, re_max, im_min, im_max)
        The closed rectangle to search.
    ignore : array_like of complex, optional
        Points that are known spurious roots (e.g. a distributed-delay shaper's
        removable point ``s = 0``); each listed point removes one multiplicity
        of a root within ``1e-7 |s|`` of it.  Removed roots are in ``.removed``.
    max_evaluations : float
        Budget of quasi-polynomial evaluations; :class:`BudgetExceeded` is
        raised before the machine is exhausted.  The grid alone is checked
        before it is allocated.
    timeout : float
        Seconds; :class:`BudgetExceeded` past it.

    Returns
    -------
    Roots

    Raises
    ------
    ValueError, TypeError
        Bad ``h`` (identically zero, not a quasi-polynomial), ``region`` (also one
        so far from the origin that the polynomial terms leave the float range: the
        message gives the size reached and the largest usable ``|s|``), or a
        ``max_evaluations``/``timeout`` that is not a finite number > 0.
    BudgetExceeded
        The region's grid is over the budget (refused up front, with the estimate),
        or the evaluations or time ran out.
    RootFindingError
        The roots found cannot be reconciled with the certified count.

    Examples
    --------
    The zeros of the ZV shaper ``0.6 + 0.4 exp(-s pi)`` (seed 000 eq. 3) lie on
    ``Re s = -ln(0.6 / 0.4) / pi`` at ``Im s = 1, 3, 5, ...``:

    >>> from posicast import QuasiPolynomial
    >>> r = roots(QuasiPolynomial([[0.6], [0.4]], [0.0, np.pi]), (-2, 2, 0, 10))
    >>> r.count
    5
    >>> np.allclose(r.roots.imag, [1, 3, 5, 7, 9]), np.allclose(r.roots.real, -np.log(1.5) / np.pi)
    (True, True)
    """
    q0 = as_quasipolynomial(h)
    rect = check_region(region)
    max_evaluations, timeout = check_budget(max_evaluations, timeout)
    ign = None if ignore is None else check_ignore(ignore)
    q = normalised(q0.factor_min_delay()[0])
    check_range(q, rect)
    ev = Evaluator(q, int(max_evaluations), time.monotonic() + float(timeout))
    step = grid_step(q, rect)
    _check_grid(q, rect, step, max_evaluations)
    count, used, shifted = count_with_shifts(ev, rect, step)
    solver = Solver(ev, used, step)
    if count:
        _find_all(solver, used, count, step)
    a, b, c, d = used
    found = [f for f in solver.found if a <= f.point.real <= b and c <= f.point.imag <= d]
    pts = np.array([f.point for f in found], dtype=complex)
    mult = np.array([f.mult for f in found], dtype=int)
    # real quasi-polynomial: snap numerically real roots onto the axis
    near_real = np.abs(pts.imag) <= 1e-13 * np.maximum(np.abs(pts), 1.0)
    pts[near_real] = pts[near_real].real
    removed: list[complex] = []
    if ign is not None:
        pts, mult, removed = _remove_ignored(pts, mult, ign)
        count -= len(removed)
    order = _sort_key(pts)
    pts, mult = pts[order], mult[order]
    res = relative_residual(q, pts)
    return Roots(
        roots=np.repeat(pts, mult),
        count=int(count),
        distinct=pts,
        multiplicities=mult,
        residuals=res,
        region=used,
        requested_region=rect,
        shifted=shifted,
        evaluations=ev.evaluations,
        removed=np.array(removed, dtype=complex),
    )


def _check_grid(q: QuasiPolynomial, rect: tuple[float, float, float, float], step: float,
                max_evaluations: float) -> None:
    """Refuse, before it is allocated, a candidate grid over the budget."""
    nx, ny = grid_shape(rect, step)
    n_grid = nx * ny
    if n_grid > min(max_evaluations / 2, _MAX_GRID):
        raise BudgetExceeded(
            f"region {rect} needs a {n_grid:.3g}-point grid (step {step:.3g} from the largest delay "
            f"{float(q.delays[-1]):.4g}), over the budget of {min(max_evaluations / 2, _MAX_GRID):.3g} points "
            "(half of max_evaluations, at most 2e7 for memory); split or shrink the region"
        )


def _find_all(solver: Solver, used: tuple[float, float, float, float], count: int, step: float) -> None:
    """Steps 2-4: candidates (a polynomial's own roots first), Newton, classification, reconciliation."""
    ev = solver.ev
    q = ev.q
    if q.is_polynomial:
        desc = q.coeffs[0, ::-1]
        desc = np.trim_zeros(desc, "f")
        cand = np.roots(desc) if desc.size > 1 else np.zeros(0, complex)
        z, ok = newton(ev, cand, max_step=step)
        solver.absorb(z[ok])
        solver.classify()
    if solver.n_in(used) != count:
        solver.search(used, step)
    solver.reconcile(used, count, step, 0)


def _remove_ignored(pts: np.ndarray, mult: np.ndarray, ign: np.ndarray) -> tuple[np.ndarray, np.ndarray, list]:
    """Take one multiplicity off the root within ``1e-7 |p|`` of each ignored point ``p``."""
    removed = []
    for p in ign:
        if pts.size == 0:
            break
        dist = np.abs(pts - p)
        i = int(np.argmin(dist))
        if dist[i] <= 1e-7 * max(1.0, abs(p)) and mult[i] > 0:
            mult[i] -= 1
            removed.append(pts[i])
    keep = mult > 0
    return pts[keep], mult[keep], removed
