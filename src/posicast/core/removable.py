"""Removable points of a ratio ``N / D``: the common roots a quotient does not really have.

A distributed-delay shaper ``N / D`` has ``D = p(s)`` a polynomial whose roots are
also roots of ``N`` (``s = 0`` for every kernel, ``s = +/- 2 pi j / T`` for the
cosine kernel): removable singularities of ``N / D``.  Its poles and zeros, and
the closed-loop poles of a loop it sits in, are the roots of ``D`` and ``N`` (or
of the loop's characteristic quasi-polynomial) less these points.
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial import polynomial as P

from .quasipoly import QuasiPolynomial

__all__ = ["removable_points", "vanishing_order"]

# A Taylor coefficient below this fraction of its magnitude scale counts as zero
# when the vanishing order of a shaper's numerator/denominator is counted.
_VANISH_RTOL = 1e-9
# Polynomial roots closer than this (relative) are one multiple root.
_CLUSTER_RTOL = 1e-6


def vanishing_order(h: QuasiPolynomial, s0: complex, max_order: int = 24) -> int:
    """Number of leading Taylor coefficients of ``h`` about ``s0`` that vanish (relative to their scale).

    >>> vanishing_order(QuasiPolynomial.from_poly([1.0, 0.0, 0.0]), 0j)    # s^2
    2
    """
    if h.is_zero:
        return max_order
    try:
        with np.errstate(over="ignore", invalid="ignore"):
            c, scale = h.taylor(s0, max_order)
    except ValueError:  # |s0| so large that the Taylor terms overflow (a loop with a gain of 1e300):
        return 0  # the point is not shown to vanish, so it stays a root (never hidden)
    k = 0
    while k <= max_order and abs(c[k]) <= _VANISH_RTOL * scale[k]:
        k += 1
    return k


def removable_points(num: QuasiPolynomial, den: QuasiPolynomial) -> np.ndarray:
    """Common roots of ``num`` and ``den`` when ``den`` is a polynomial (times at most one delay).

    Each root of the polynomial ``den`` at which ``num`` also vanishes is returned
    ``min(m_num, m_den)`` times, the vanishing orders being counted with exact
    Taylor coefficients.  An empty array when ``den`` carries several delays (its
    roots are not computed here).

    Examples
    --------
    >>> import posicast
    >>> S = posicast.design("dzv", posicast.Mode(10.0, 0.03))
    >>> removable_points(S.num, S.den)
    array([0.+0.j])
    >>> removable_points(QuasiPolynomial.from_poly([1.0, 2.0]), QuasiPolynomial.from_poly([1.0, 1.0])).size
    0
    """
    for name, q in (("num", num), ("den", den)):
        if not isinstance(q, QuasiPolynomial):
            raise TypeError(f"{name} must be a QuasiPolynomial, got {type(q).__name__}")
    if num.is_zero or den.is_zero or not den.is_polynomial or den.degree < 1:
        return np.zeros(0, dtype=complex)
    row = den.coeffs[0]
    roots = P.polyroots(row)
    # Cluster numerically repeated roots, then count multiplicities exactly.
    centres: list[complex] = []
    members: list[list[complex]] = []
    for r in sorted(roots, key=lambda z: (round(z.real, 6), round(z.imag, 6))):
        r = complex(r)
        for i, c in enumerate(centres):
            if abs(r - c) <= _CLUSTER_RTOL * max(1.0, abs(c)):
                members[i].append(r)
                centres[i] = complex(np.mean(members[i]))
                break
        else:
            centres.append(r)
            members.append([r])
    out: list[complex] = []
    for c in centres:
        if abs(c.imag) <= 1e-14 * max(1.0, abs(c)):
            c = complex(c.real, 0.0)
        if abs(c) <= 1e-14:
            c = 0j
        m = min(vanishing_order(num, c), vanishing_order(den, c))
        out += [c] * m
    return np.array(out, dtype=complex)
