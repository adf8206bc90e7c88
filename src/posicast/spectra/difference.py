"""The difference operator of a neutral quasi-polynomial and where its roots lie.

A neutral quasi-polynomial (some ``deg p_k = deg p_0``) has root chains that approach
the vertical lines of the roots of its *difference operator*
``D(s) = 1 + sum_k (c_k / c_0) exp(-s tau_k)`` (leading coefficients); the supremum
``C_D`` of their real parts decides whether infinitely many roots sit near or right of
the imaginary axis.  Seed 000, Lemma 1: the poles of a loop with an inverse shaper
approach the shaper zeros at high frequency, because the shaper's numerator *is* the
loop's difference operator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np
from scipy.optimize import brentq

from ..core.quasipoly import QuasiPolynomial
from .checks import prepared
from .rootfinder import roots

__all__ = ["DifferenceSpectrum", "difference_spectrum", "common_step", "min_modulus"]


@dataclass(frozen=True)
class DifferenceSpectrum:
    """Spectrum of the difference operator of a neutral quasi-polynomial.

    Attributes
    ----------
    operator : QuasiPolynomial
        ``D(s) = 1 + sum_k d_k exp(-s theta_k)``.
    abscissa : float
        ``C_D``, the supremum of the real parts of the roots of ``D``.  The
        neutral root chains of ``h`` approach the lines ``Re s = Re(root of D)``.
    strongly_stable : bool
        ``sum_k |d_k| < 1`` (Hale and Verduyn Lunel): the difference operator is
        exponentially stable for *every* small change of the delays, not only
        the nominal ones.
    hale_abscissa : float
        The real ``alpha`` with ``sum_k |d_k| exp(-alpha theta_k) = 1``; no root
        of ``D`` lies right of it, and ``C_D <= hale_abscissa`` with equality
        for a single delay.
    commensurate : bool
        Whether ``C_D`` is exact (commensurate delays: roots of a polynomial in
        ``exp(-s theta)``) or estimated from the roots in a wide strip.
    roots : ndarray of complex
        Roots of ``D`` with ``0 <= Im s <`` one period (commensurate case) or in
        the scanned strip.
    """

    operator: QuasiPolynomial
    abscissa: float
    strongly_stable: bool
    hale_abscissa: float
    commensurate: bool
    roots: np.ndarray


def common_step(delays: np.ndarray, max_den: int = 200) -> float | None:
    """Largest ``theta`` with every delay an integer multiple (within 1e-9), or None."""
    pos = delays[delays > 0]
    if pos.size == 0:
        return None
    base = pos[0]
    fracs = []
    for t in pos:
        f = Fraction(float(t / base)).limit_denominator(max_den)
        if abs(float(f) - t / base) > 1e-9 * max(1.0, t / base):
            return None
        fracs.append(f)
    den = math.lcm(*[f.denominator for f in fracs])
    num_gcd = math.gcd(*[(f * den).numerator for f in fracs])
    return float(base * num_gcd / den)


def difference_spectrum(h: Any) -> DifferenceSpectrum:
    """Difference operator of a neutral quasi-polynomial and its spectral abscissa ``C_D``.

    Examples
    --------
    The inverse-ZV loop's operator is the ZV numerator normalised, here
    ``1 + 0.5 e^{-s}``: ``C_D = ln 0.5``.

    >>> from posicast import QuasiPolynomial
    >>> d = difference_spectrum(QuasiPolynomial([[1.0, 2.0], [0.0, 1.0]], [0, 1]))
    >>> bool(round(d.abscissa, 12) == round(np.log(0.5), 12)), d.strongly_stable
    (True, True)
    """
    q = prepared(h)
    if q.kind != "neutral":
        raise ValueError(f"h is {q.kind}, not neutral: it has no difference operator")
    D = q.difference_operator()
    d = D.coeffs[1:, 0]
    theta = D.delays[1:]
    total = float(np.sum(np.abs(d)))
    g = lambda a: float(np.sum(np.abs(d) * np.exp(-a * theta))) - 1.0  # noqa: E731
    # start at |a theta| = 1: with delays of thousands of seconds (a shaper for a 0.002 rad/s mode) a = -1
    # overflowed exp; doubling from here meets g >= 0 before a theta passes ~700 (|d| >= 1e-305)
    unit = min(1.0, 1.0 / float(theta.max()))
    lo, hi = -unit, unit
    while g(lo) < 0:
        lo *= 2
    while g(hi) > 0:
        hi *= 2
    hale = brentq(g, lo, hi, xtol=1e-14, rtol=1e-14)
    step = common_step(D.delays)
    if step is not None:
        # D(s) = sum_k c_k z^{n_k}, z = exp(-s step): roots z_j give Re s = -ln|z_j| / step
        powers = np.rint(D.delays / step).astype(int)
        poly = np.zeros(powers.max() + 1)
        np.add.at(poly, powers, D.coeffs[:, 0])
        z = np.roots(poly[::-1])
        z = z[z != 0]
        s = -np.log(z.astype(complex)) / step  # principal branch: 0 <= Im s < 2 pi / step up to sign
        s = s.real + 1j * np.mod(s.imag, 2 * math.pi / step)
        CD = float(s.real.max()) if s.size else -math.inf
        return DifferenceSpectrum(D, CD, bool(total < 1.0), hale, True, np.sort_complex(s))
    # incommensurate delays: scan a wide strip (C_D is a supremum; this is an estimate from below)
    theta_max = float(theta.max())
    unit = min(1.0, 1.0 / theta_max)  # e^{-a theta_max} grows at most e-fold a step (no overflow)
    lo_re = hale - unit
    dl = np.abs(d)
    # left edge: where the largest delay term dominates, no roots
    j = int(np.argmax(theta))
    others = lambda a: 1.0 + float(np.sum(np.delete(dl, j) * np.exp(-a * np.delete(theta, j))))  # noqa: E731
    while dl[j] * math.exp(-lo_re * theta_max) <= others(lo_re):
        lo_re -= unit
    Y = 100 * 2 * math.pi / float(theta.min())
    r = roots(D, (lo_re, hale + 1e-3 * max(1.0, abs(hale)), 0.0, Y))
    CD = float(r.roots.real.max()) if r.count else -math.inf
    return DifferenceSpectrum(D, CD, bool(total < 1.0), hale, False, r.roots)


def min_modulus(D: QuasiPolynomial, alpha: float) -> float:
    """Certified lower bound of ``|D(s)|`` on the half-plane ``Re s >= alpha`` (0 when there is none).

    Always at least Hale's ``1 - sum_k |d_k| exp(-alpha theta_k)``.  For commensurate
    delays ``D(s) = P(z)`` with ``z = exp(-s theta)`` and ``Re s >= alpha`` is the disk
    ``|z| <= r = exp(-alpha theta)``: ``P`` is sampled on the circle ``|z| = r`` (FFT);
    with the Lipschitz bound ``L = sum_k k |p_k| r^(k-1)`` of ``P`` on it, ``min |P| >=
    min(samples) - L pi r / N - rounding``.  When that is positive the samples' winding
    number is exact; zero means no root of ``P`` in the disk, and the minimum modulus
    principle puts the minimum over the disk on the circle.  This bound is positive for
    every ``alpha > C_D`` (not only right of the Hale abscissa), which is what closes a
    search region between ``C_D`` and the Hale abscissa of a neutral quasi-polynomial whose
    difference operator is not strongly stable.
    """
    d = D.coeffs[1:, 0]
    theta = D.delays[1:]
    hale = 1.0 - float(np.sum(np.abs(d) * np.exp(-alpha * theta)))
    lower = max(0.0, hale)
    step = common_step(D.delays)
    if step is None:
        return lower
    powers = np.rint(D.delays / step).astype(int)
    deg = int(powers.max())
    if deg > 1 << 14:
        return lower
    p = np.zeros(deg + 1)
    np.add.at(p, powers, D.coeffs[:, 0])
    r = math.exp(-alpha * step)
    k = np.arange(deg + 1)
    with np.errstate(over="ignore"):
        cr = np.abs(p) * r**k
    if not np.all(np.isfinite(cr)):
        return lower
    lip = float(np.sum(k[1:] * np.abs(p[1:]) * r ** (k[1:] - 1)))
    N = 1 << max(6, int(math.ceil(math.log2(8 * (deg + 1)))))
    while N <= 1 << 18:
        v = np.fft.ifft(p * r**k, n=N) * N  # P(r exp(2 pi j i / N)), i = 0..N-1
        # FFT rounding: at most c eps log2(N) ||y||_2 per output, ||y||_2 <= sqrt(N) ||coefficients||_1
        err = 8.0 * np.finfo(float).eps * (math.log2(N) + 4) * math.sqrt(N) * float(np.sum(cr))
        low = float(np.min(np.abs(v))) - lip * math.pi * r / N - err
        if low > 0:
            wind = float(np.sum(np.angle(np.roll(v, -1) / v))) / (2.0 * math.pi)
            if round(wind) != 0:
                return 0.0  # roots of D right of alpha
            return max(lower, low)
        if float(np.min(np.abs(v))) <= err:
            return lower  # a root of D on (or within rounding of) the line Re s = alpha
        N *= 4
    return lower
