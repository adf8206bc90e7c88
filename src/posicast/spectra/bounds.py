"""How far out the roots right of a vertical line can be: modulus bounds that close a search region.

A retarded quasi-polynomial ``p_0(s) + sum_k p_k(s) exp(-s tau_k)`` with
``deg p_0 > deg p_k`` has root chains that go left logarithmically, so only finitely
many roots lie right of any vertical line and a rectangle holding all of them follows
from a modulus bound (:func:`root_bound`).  For a neutral one the bound uses the
difference operator's certified minimum modulus (:func:`sharp_bound`), which is
positive right of ``C_D`` (:mod:`posicast.spectra.difference`).
"""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from .._validate import real as _real
from ..core.quasipoly import QuasiPolynomial
from .checks import prepared
from .difference import DifferenceSpectrum, min_modulus

__all__ = ["leading", "root_bound", "bound_from_gamma", "sharp_bound"]


def leading(q: QuasiPolynomial) -> tuple[int, np.ndarray]:
    """The degree ``n`` of ``q`` and the coefficients of ``s^n``, one per delay."""
    n = q.degree
    return n, q.coeffs[:, n]


def root_bound(h: Any, alpha: float) -> float:
    """Radius ``R`` such that every root with ``Re s >= alpha`` has ``|s| <= R``.

    For ``Re s >= alpha`` the leading part ``s^n D(s)`` has modulus at least
    ``gamma |s|^n`` with ``gamma = |c_0| - sum_{k>0} |c_k| exp(-alpha tau_k)``
    and the rest at most ``sum_j beta_j |s|^j``; ``R`` is the positive root of
    ``gamma r^n - sum_j beta_j r^j`` (unique, by Descartes' rule).  Returns
    ``inf`` when ``gamma <= 0`` (a neutral chain at or right of ``alpha``).

    Examples
    --------
    >>> from posicast import QuasiPolynomial
    >>> round(root_bound(QuasiPolynomial([[1.0, 1.0], [2.0, 0.0]], [0, 1]), 0.0), 6)  # s + 1 + 2 e^{-s}
    3.0
    """
    q = prepared(h)
    alpha = _real(alpha, "alpha")
    n, lead = leading(q)
    if -alpha * float(q.delays[-1]) > 600.0:  # far left with long delays: exp overflows, no bound
        return math.inf
    w = np.exp(-alpha * q.delays)
    gamma = abs(lead[0]) - float(np.sum(np.abs(lead[1:]) * w[1:]))
    return bound_from_gamma(q, alpha, gamma)


def bound_from_gamma(q: QuasiPolynomial, alpha: float, gamma: float) -> float:
    """``R`` with ``gamma |s|^n > sum_j beta_j(alpha) |s|^j`` for ``|s| > R`` (see :func:`root_bound`).

    ``gamma`` is any lower bound of ``|c_0 D(s)|`` on ``Re s >= alpha``.
    """
    if not gamma > 0:
        return math.inf
    n, _ = leading(q)
    if n == 0:
        return 0.0
    if -float(alpha) * float(q.delays[-1]) > 600.0:  # far left with long delays: exp overflows
        return math.inf
    w = np.exp(-float(alpha) * q.delays)
    beta = np.sum(np.abs(q.coeffs[:, :n]) * w[:, None], axis=0)  # ascending powers 0..n-1
    if not np.any(beta):
        return 0.0
    if not np.all(np.isfinite(beta)):
        return math.inf
    desc = np.concatenate([[gamma], -beta[::-1]])
    r = np.roots(desc)
    pos = r[(np.abs(r.imag) <= 1e-9 * np.maximum(1.0, np.abs(r))) & (r.real > 0)].real
    R = float(pos.max()) if pos.size else 0.0
    # guard the root against rounding: step out until the bound holds.  The test is divided by
    # x^n (gamma > sum_j beta_j x^(j-n)), so a huge R (a gain of 1e300) does not overflow x**n.
    k = np.arange(n)

    def holds(x: float) -> bool:
        return x > 0 and gamma > float(np.sum(beta * np.exp((k - n) * math.log(x))))

    while not holds(R):
        R = R * (1 + 1e-9) + 1e-12
    return R



def sharp_bound(q: QuasiPolynomial, ds: DifferenceSpectrum | None) -> Callable[[float], float]:
    """``alpha -> R(alpha)`` of :func:`root_bound`, with the difference operator's certified minimum
    modulus (:func:`min_modulus`) in place of Hale's bound for a neutral ``q``."""
    if ds is None:
        return lambda alpha: root_bound(q, alpha)
    n, lead = leading(q)
    c0 = abs(lead[0])

    def bound(alpha: float) -> float:
        return bound_from_gamma(q, alpha, c0 * min_modulus(ds.operator, alpha))

    return bound
