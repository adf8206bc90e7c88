"""All roots right of a vertical line (a staircase of certified searches), and certified disks about them.

:func:`search_right_of` cuts the half-plane ``Re s >= alpha`` into vertical strips, each
closed at the height of a root bound (:mod:`posicast.spectra.bounds`) and searched by
:func:`posicast.roots`; :func:`root_radii` certifies how far each root found can be from
the true one (:func:`~posicast.spectra.disks.certified_radius`).
"""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from ..core.quasipoly import QuasiPolynomial
from .bounds import root_bound
from .candidates import MAX_GRID, grid_shape, grid_step
from .checks import BudgetExceeded, usable_radius
from .disks import certified_radius
from .rootfinder import Roots, roots

__all__ = ["conjugate_closure", "search_right_of", "root_radii"]


def conjugate_closure(r: Roots) -> np.ndarray:
    """Roots of a real quasi-polynomial from an upper-half search: add the mirror images."""
    z = r.roots
    tol = 1e-12 * np.maximum(1.0, np.abs(z))
    real = z[np.abs(z.imag) <= tol]
    upper = z[z.imag > tol]
    full = np.concatenate([real.real.astype(complex), upper, upper.conj()])
    return full[np.lexsort((-full.imag, -full.real))]


def search_right_of(
    q: QuasiPolynomial,
    alpha: float,
    ignore: Any,
    budget: dict | None = None,
    bound: Callable[[float], float] | None = None,
    edge_tol: float = 0.0,
) -> np.ndarray | None:
    """All roots with Re s >= alpha (conjugates included), or None if unbounded there.

    The half-plane is cut into vertical strips ``[b_i, b_{i+1}]``, each closed
    at the height ``R(b_i)`` of :func:`root_bound` (or of ``bound``), which falls
    quickly with ``b``: a staircase instead of the square ``[alpha, R] x [0, R]``.
    Roots found in the first strip within ``edge_tol (1 + |s|)`` left of ``alpha``
    (the root finder moves an edge outward past a root on it) are kept as well:
    a root *on* the line ``Re s = alpha`` is then returned whatever the sign of the
    rounding in its computed real part.
    """
    bound = bound or (lambda a: root_bound(q, a))
    R = bound(alpha)
    if not math.isfinite(R):
        return None
    lim = usable_radius(q)
    if R > lim:
        raise ValueError(
            f"h's roots with Re s >= {alpha:g} can lie as far out as |s| = {R:.3g} (root bound), but its "
            f"terms leave the float range beyond |s| = {lim:.3g}: the coefficients span too many decades "
            "(rescale the gains or the time unit)"
        )
    found = []
    for i, (lo, hi, Rlo) in enumerate(_staircase(q, alpha, R, bound, budget)):
        pad = 1e-3 * max(1.0, Rlo)
        r = roots(q, (lo, hi, -pad, Rlo + pad), ignore=ignore, **(budget or {}))
        full = conjugate_closure(r)
        left = lo - edge_tol * (1.0 + np.abs(full)) if i == 0 else lo
        found.append(full[(full.real >= left) & (full.real < hi)])
    if not found:
        return np.zeros(0, complex)
    full = np.concatenate(found)
    return full[np.lexsort((-full.imag, -full.real))]



def _grid_sizes(q: QuasiPolynomial, strips: list[tuple[float, float, float]]) -> list[float]:
    """The candidate grid's nodes in each strip ``(lo, hi, R(lo))`` (the first pass of each search)."""
    sizes = []
    for lo, hi, Rlo in strips:
        pad = 1e-3 * max(1.0, Rlo)
        rect = (lo, hi, -pad, Rlo + pad)
        nx, ny = grid_shape(rect, grid_step(q, rect))
        sizes.append(float(nx) * float(ny))
    return sizes


def _staircase(
    q: QuasiPolynomial, alpha: float, R: float, bound: Callable[[float], float], budget: dict | None
) -> list[tuple[float, float, float]]:
    """The strips ``(lo, hi, R(lo))`` of :func:`search_right_of`, refused up front when their grids are
    over the budget (with the estimate): a loop with a huge gain has roots out to ``|s| = R`` and,
    with delays, a grid step of a sixth of the chains' spacing, so a strip's grid alone can need
    billions of points; without this check the strips before it were searched first (tens of seconds)."""
    if q.is_polynomial:
        # no delays: R does not fall with lo, and the grid step is the region's own (a sixteenth of it);
        # one region does what 330 strips did for (s + 1)(s + 1e100)
        return [(alpha, max(R, alpha) + 1.0, R)] if R >= alpha else []
    strips = []
    lo, width, Rlo = alpha, max(1.0, 1e-9 * abs(alpha)), R  # far out, a unit width would not advance lo
    while True:
        if Rlo < lo or (Rlo == 0.0 and lo > 0.0):
            break  # |s| <= R(lo) < lo <= Re s is impossible: nothing further right (R = 0 leaves s = 0)
        hi = min(lo + width, Rlo + 1.0)
        strips.append((lo, hi, Rlo))
        if hi >= Rlo:
            break
        lo, width = hi, 2.0 * width
        Rlo = bound(lo)
    max_evaluations = float((budget or {}).get("max_evaluations", 5e7))
    limit = min(max_evaluations / 2, MAX_GRID)
    sizes = _grid_sizes(q, strips)
    worst = int(np.argmax(sizes)) if sizes else 0
    if sizes and sizes[worst] > limit:  # the same limit as each search's own (rootfinder._check_grid)
        lo, hi, Rlo = strips[worst]
        tau = float(q.delays[-1])
        why = f" (a sixth of the root chains' spacing 2 pi / {tau:.4g})" if tau > 0 else ""
        raise BudgetExceeded(
            f"the roots with Re s >= {alpha:g} can reach |s| = {R:.3g} (root bound): a certified search needs "
            f"about {sum(sizes):.3g} evaluations in {len(strips)} strips, {sizes[worst]:.3g} for the strip "
            f"Re s in [{lo:g}, {hi:g}] up to Im s = {Rlo:.3g} at a grid step of "
            f"{grid_step(q, (lo, hi, 0.0, Rlo)):.3g}{why}; over the {limit:.3g} grid points a search may hold "
            f"(half of max_evaluations={max_evaluations:.3g}, at most {MAX_GRID:.0e}). Such roots come from very large gains or a wide spread of "
            "time scales: reduce them, or raise max_evaluations"
        )
    return strips


def root_radii(q: QuasiPolynomial, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distinct points of ``z`` (repeated by multiplicity), their multiplicities and certified radii.

    A radius is ``inf`` when no disk holding exactly that many roots could be certified.
    """
    z = np.asarray(z, dtype=complex)
    if z.size == 0:
        return z, np.zeros(0, int), np.zeros(0)
    vals, counts = np.unique(z, return_counts=True)
    radii = np.empty(vals.size)
    for i, (v, m) in enumerate(zip(vals, counts)):
        r = certified_radius(q, complex(v), int(m), 0.1 * max(1.0, abs(v)))
        radii[i] = math.inf if r is None else r
    return vals, counts, radii
