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

__all__ = ["leading", "root_bound", "bound_from_gamma", "sharp_bound", "factored_bound", "with_factored"]

_U = float(np.finfo(float).eps) / 2.0  # unit roundoff


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



def _root_moduli(m_desc: np.ndarray) -> np.ndarray | None:
    """Certified upper bounds of the moduli of the roots of the monic polynomial ``m_desc`` (descending
    coefficients), one per root with multiplicity; None when no inclusion is found.

    Weierstrass's corrections ``W_i = m(z_i) / prod_{j != i} (z_i - z_j)`` at distinct approximations
    ``z_i`` make ``m`` the characteristic polynomial of ``diag(z) - W 1^T`` (Lagrange interpolation), so
    Gerschgorin's discs ``|s - (z_i - W_i)| <= (n - 1) |W_i|`` hold the roots, a connected union of ``k``
    discs exactly ``k`` of them (Smith 1970, Elsner 1973).  Each root's bound is the largest ``|s|`` on its
    union; the rounding of ``m(z_i)`` and of the products is added to ``|W_i|``."""
    n = m_desc.size - 1
    with np.errstate(all="ignore"):
        z = np.roots(m_desc)
        if z.size != n or not np.all(np.isfinite(z)):
            return None
        d = z[:, None] - z[None, :]
        np.fill_diagonal(d, 1.0)
        if np.any(d == 0):  # a multiple root computed exactly: spread its copies (the discs still hold them)
            z = z + 1e-8 * np.maximum(1.0, np.abs(z)) * np.exp(2j * np.pi * np.arange(n) / n)
            d = z[:, None] - z[None, :]
            np.fill_diagonal(d, 1.0)
        den = np.prod(d, axis=1)
        aden = np.abs(den)
        if not np.all(aden > 0) or not np.all(np.isfinite(aden)):
            return None
        W = np.polyval(m_desc, z) / den
        err = np.polyval(np.abs(m_desc), np.abs(z)) * (8.0 * (n + 2) * _U) / aden
        dW = err + np.abs(W) * (8.0 * (n + 2) * _U)
        centre = z - W
        radius = (n - 1) * (np.abs(W) + dW) + dW
        rho = (np.abs(centre) + radius) * (1.0 + 8.0 * _U)
        if not np.all(np.isfinite(rho)):
            return None
        # the unions: discs that overlap, closed transitively
        reach = np.abs(centre[:, None] - centre[None, :]) <= (radius[:, None] + radius[None, :]) * (1.0 + 1e-9)
        for _ in range(max(1, int(n).bit_length())):
            reach = (reach.astype(np.float64) @ reach.astype(np.float64)) > 0
    return np.max(np.where(reach, rho[None, :], 0.0), axis=1)


def factored_bound(h: Any, cap: float = math.inf) -> float:
    """Radius ``R`` (at most ``cap``) such that every root with ``Re s >= 0`` has ``|s| <= R``, from the roots
    of the undelayed polynomial.

    With ``p_0`` the undelayed polynomial (degree ``n``, leading coefficient ``c_0``), ``m = p_0 / c_0``
    and ``c_k`` the ``s^n`` coefficients of the delayed ones, ``h = m(s) D(s) + sum_k r_k(s) e^{-s tau_k}``
    with ``D(s) = sum_k c_k e^{-s tau_k}`` and ``r_k = p_k - c_k m`` of degree below ``n``.  On
    ``Re s >= 0``, ``|D| >= gamma = |c_0| - sum_{k>0} |c_k|`` and ``|m(s)| >= prod_i (|s| - rho_i)``
    (``rho_i`` certified bounds of the moduli of ``m``'s roots), so ``h`` has no root where
    ``gamma prod_i (1 - rho_i / |s|) > sum_j beta_j |s|^(j - n)``, ``beta_j = sum_k |r_kj|``: the left side
    grows with ``|s|``, the right one falls.

    :func:`root_bound` bounds ``|m(s)|`` by its coefficients instead: for a neutral loop whose difference
    operator is nearly on the imaginary axis (a ZV shaper's inverse in the loop, ``gamma = 0.012``) it
    divides the undelayed polynomial's second coefficient by ``gamma`` (24 000 on the seed 001 crane, where
    the roots of ``m`` are within 250).  The smaller of the two is the one to use; ``inf`` when ``gamma <= 0``
    or no inclusion of ``m``'s roots is found.  Found on 400 geometric steps below ``cap`` (within 5 % of
    the smallest such radius).

    Examples
    --------
    ``(s + 10)^2 (1 + 0.9 e^{-s}) + 1``: ``m = s^2 + 20 s + 101`` (roots of modulus ``sqrt(101)``),
    ``r_1 = -0.9``, ``gamma = 0.1``, so the smallest such radius is ``sqrt(101) + 3``; the coefficient bound
    solves ``0.1 r^2 = 38 r + 191``:

    >>> from posicast import QuasiPolynomial
    >>> h = QuasiPolynomial([[101.0, 20.0, 1.0], [90.0, 18.0, 0.9]], [0, 1])
    >>> round(root_bound(h, 0.0), 2), round((38 + (38**2 + 4 * 0.1 * 191) ** 0.5) / 0.2, 2)
    (384.96, 384.96)
    >>> R = factored_bound(h)
    >>> bool(101**0.5 + 3 <= R <= 1.05 * (101**0.5 + 3))
    True
    """
    q = prepared(h)
    n, lead = leading(q)
    c0 = float(lead[0])
    if n == 0 or c0 == 0.0:
        return math.inf if n else 0.0
    scale = abs(c0) + float(np.sum(np.abs(lead[1:])))
    gamma = abs(c0) - float(np.sum(np.abs(lead[1:]))) - 4.0 * (lead.size + 2) * _U * scale
    if not gamma > 0:
        return math.inf
    p0 = q.coeffs[0, : n + 1]
    m = p0 / c0
    rho = _root_moduli(m[::-1])
    if rho is None:
        return math.inf
    ratio = lead[1:] / c0
    rk = q.coeffs[1:, :n] - ratio[:, None] * p0[None, :n]
    slack = (np.abs(q.coeffs[1:, :n]) + np.abs(ratio[:, None] * p0[None, :n])) * (8.0 * _U)
    beta = np.sum(np.abs(rk) + slack, axis=0)  # ascending powers 0..n-1
    top = float(rho.max())
    hi = cap if math.isfinite(cap) else max(top, 1.0) * 1e12
    if not top < hi:
        return math.inf
    r = np.geomspace(max(top * (1.0 + 1e-6), hi * 1e-12, 1e-300), hi, 400)
    with np.errstate(all="ignore"):
        left = gamma * np.prod(1.0 - rho[None, :] / r[:, None], axis=1)
        right = np.sum(beta[None, :] * np.exp(np.outer(np.log(r), np.arange(n) - n)), axis=1)
    ok = np.flatnonzero(left * (1.0 - 16.0 * (n + 2) * _U) > right * (1.0 + 16.0 * (n + 2) * _U))
    return float(r[ok[0]]) if ok.size else math.inf


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


def with_factored(q: QuasiPolynomial, bound: Callable[[float], float]) -> Callable[[float], float]:
    """``alpha -> R(alpha)`` of ``bound``, and for ``alpha >= 0`` no more than :func:`factored_bound` (valid on
    ``Re s >= 0``, so on every half-plane inside it; computed once, on the first such call)."""
    memo: list[float] = []

    def both(alpha: float) -> float:
        R = bound(alpha)
        if alpha < 0 or not math.isfinite(R):
            return R
        if not memo:
            memo.append(factored_bound(q, cap=R))
        return min(R, memo[0])

    return both

