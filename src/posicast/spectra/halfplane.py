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
    found = []
    lo, width = alpha, 1.0
    first = True
    while True:
        Rlo = R if first else bound(lo)
        if Rlo < lo or (Rlo == 0.0 and lo > 0.0):
            break  # |s| <= R(lo) < lo <= Re s is impossible: nothing further right (R = 0 leaves s = 0)
        hi = min(lo + width, Rlo + 1.0)
        pad = 1e-3 * max(1.0, Rlo)
        r = roots(q, (lo, hi, -pad, Rlo + pad), ignore=ignore, **(budget or {}))
        full = conjugate_closure(r)
        left = lo - edge_tol * (1.0 + np.abs(full)) if first else lo
        found.append(full[(full.real >= left) & (full.real < hi)])
        first = False
        if hi >= Rlo:
            break
        lo, width = hi, 2.0 * width
    if not found:
        return np.zeros(0, complex)
    full = np.concatenate(found)
    return full[np.lexsort((-full.imag, -full.real))]



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
