"""Where the roots of a quasi-polynomial can be, and what that means for stability.

A retarded quasi-polynomial ``p_0(s) + sum_k p_k(s) exp(-s tau_k)`` with
``deg p_0 > deg p_k`` has root chains that go left logarithmically, so only
finitely many roots lie right of any vertical line and a rectangle holding all
of them follows from a modulus bound (:func:`root_bound`).  A neutral one
(some ``deg p_k = deg p_0``) has root chains that approach the vertical lines
of the roots of its *difference operator*
``D(s) = 1 + sum_k (c_k / c_0) exp(-s tau_k)`` (leading coefficients);
the supremum ``C_D`` of their real parts decides whether infinitely many
roots sit near or right of the imaginary axis.  Seed 000, Lemma 1: the poles
of a loop with an inverse shaper approach the shaper zeros at high frequency,
because the shaper's numerator *is* the loop's difference operator.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np
from scipy.optimize import brentq

from .._validate import real as _real
from ..core.quasipoly import QuasiPolynomial
from .rootfinder import (
    BudgetExceeded,
    RootFindingError,
    Roots,
    as_quasipolynomial,
    certified_radius,
    check_budget,
    check_ignore,
    roots,
)

__all__ = [
    "root_bound",
    "DifferenceSpectrum",
    "difference_spectrum",
    "spectral_abscissa",
    "SpectralAbscissa",
    "rightmost",
    "Stability",
    "stability",
    "unstable_count",
]


def _prepared(h: Any) -> QuasiPolynomial:
    q = as_quasipolynomial(h)
    q, _ = q.factor_min_delay()
    kind = q.kind
    if kind == "advanced":
        raise ValueError(
            "h is of advanced type (a delayed term has a higher power of s than the undelayed one): "
            "it has roots of arbitrarily large real part; no stability analysis applies"
        )
    return q


def _leading(q: QuasiPolynomial) -> tuple[int, np.ndarray]:
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
    q = _prepared(h)
    alpha = _real(alpha, "alpha")
    n, lead = _leading(q)
    if -alpha * float(q.delays[-1]) > 600.0:  # far left with long delays: exp overflows, no bound
        return math.inf
    w = np.exp(-alpha * q.delays)
    gamma = abs(lead[0]) - float(np.sum(np.abs(lead[1:]) * w[1:]))
    return _bound_from_gamma(q, alpha, gamma)


def _bound_from_gamma(q: QuasiPolynomial, alpha: float, gamma: float) -> float:
    """``R`` with ``gamma |s|^n > sum_j beta_j(alpha) |s|^j`` for ``|s| > R`` (see :func:`root_bound`).

    ``gamma`` is any lower bound of ``|c_0 D(s)|`` on ``Re s >= alpha``.
    """
    if not gamma > 0:
        return math.inf
    n, _ = _leading(q)
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
    # guard the root against rounding: step out until the bound holds
    f = lambda x: gamma * x**n - float(np.polyval(beta[::-1], x))  # noqa: E731
    while f(R) <= 0:
        R = R * (1 + 1e-9) + 1e-12
    return R


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


def _common_step(delays: np.ndarray, max_den: int = 200) -> float | None:
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
    q = _prepared(h)
    if q.kind != "neutral":
        raise ValueError(f"h is {q.kind}, not neutral: it has no difference operator")
    D = q.difference_operator()
    d = D.coeffs[1:, 0]
    theta = D.delays[1:]
    total = float(np.sum(np.abs(d)))
    g = lambda a: float(np.sum(np.abs(d) * np.exp(-a * theta))) - 1.0  # noqa: E731
    lo, hi = -1.0, 1.0
    while g(lo) < 0:
        lo *= 2
    while g(hi) > 0:
        hi *= 2
    hale = brentq(g, lo, hi, xtol=1e-14, rtol=1e-14)
    step = _common_step(D.delays)
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
    lo_re = hale - 1.0
    dl = np.abs(d)
    # left edge: where the largest delay term dominates, no roots
    j = int(np.argmax(theta))
    others = lambda a: 1.0 + float(np.sum(np.delete(dl, j) * np.exp(-a * np.delete(theta, j))))  # noqa: E731
    while dl[j] * math.exp(-lo_re * theta_max) <= others(lo_re):
        lo_re -= 1.0
    Y = 100 * 2 * math.pi / float(theta.min())
    r = roots(D, (lo_re, hale + 1e-3 * max(1.0, abs(hale)), 0.0, Y))
    CD = float(r.roots.real.max()) if r.count else -math.inf
    return DifferenceSpectrum(D, CD, bool(total < 1.0), hale, False, r.roots)


def _min_modulus(D: QuasiPolynomial, alpha: float) -> float:
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
    step = _common_step(D.delays)
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


def _sharp_bound(q: QuasiPolynomial, ds: DifferenceSpectrum | None):
    """``alpha -> R(alpha)`` of :func:`root_bound`, with the difference operator's certified minimum
    modulus (:func:`_min_modulus`) in place of Hale's bound for a neutral ``q``."""
    if ds is None:
        return lambda alpha: root_bound(q, alpha)
    n, lead = _leading(q)
    c0 = abs(lead[0])

    def bound(alpha: float) -> float:
        return _bound_from_gamma(q, alpha, c0 * _min_modulus(ds.operator, alpha))

    return bound


def _upper_half_region(alpha: float, R: float) -> tuple[float, float, float, float]:
    # a thin strip below the real axis keeps real roots off the boundary
    pad = 1e-3 * max(1.0, R)
    return (alpha, max(R, alpha + 1.0) + pad, -pad, R + pad)


def _conjugate_closure(r: Roots) -> np.ndarray:
    """Roots of a real quasi-polynomial from an upper-half search: add the mirror images."""
    z = r.roots
    tol = 1e-12 * np.maximum(1.0, np.abs(z))
    real = z[np.abs(z.imag) <= tol]
    upper = z[z.imag > tol]
    full = np.concatenate([real.real.astype(complex), upper, upper.conj()])
    return full[np.lexsort((-full.imag, -full.real))]


def _search_right_of(
    q: QuasiPolynomial,
    alpha: float,
    ignore: Any,
    budget: dict | None = None,
    bound: Any = None,
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
        full = _conjugate_closure(r)
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


def _check_radius(max_radius: Any) -> float:
    if isinstance(max_radius, (bool, np.bool_)) or not isinstance(max_radius, (int, float, np.integer, np.floating)) \
            or not (math.isfinite(float(max_radius)) and max_radius > 0):
        raise ValueError(f"max_radius must be a finite number > 0, got {max_radius!r}")
    return float(max_radius)


def _neutral_cut(q: QuasiPolynomial, ds: DifferenceSpectrum, bound: Any, max_radius: float) -> float | None:
    """The smallest ``alpha`` (to 60 bisections) right of ``C_D`` with ``R(alpha) <= max_radius``;
    None when ``R`` stays above ``max_radius`` (the roots of the delay-free part can be that far out)."""
    floor = ds.abscissa if ds.commensurate else ds.hale_abscissa
    hi = max(0.0, floor) + 1.0
    for _ in range(60):
        if bound(hi) <= max_radius:
            break
        hi += 2.0 * (hi - floor)
    else:
        return None
    lo = floor
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if bound(mid) > max_radius:
            lo = mid
        else:
            hi = mid
    return hi


def rightmost(
    h: Any, n: int = 1, *, ignore: Any = None, max_alpha_steps: int = 12, max_radius: float = 2e4
) -> np.ndarray:
    """The ``n`` rightmost roots (conjugate pairs complete), by decreasing real part.

    The search line ``Re s = alpha`` moves left until at least ``n`` roots lie
    right of it; :func:`root_bound` closes each search region.  For a neutral
    ``h`` infinitely many roots approach the difference operator's abscissa
    ``C_D``: the search stops short of it, where the root bound (with the
    operator's certified minimum modulus, so also between ``C_D`` and the Hale
    abscissa when the operator is not strongly stable) passes ``max_radius``;
    fewer than ``n`` roots are then returned and the chain is described by
    :func:`difference_spectrum`.

    Examples
    --------
    Appeltans & Michiels (TDS-CONTROL manual, 2023), example 2.6:
    ``s - 1/4 + (1/3 - 3 s / 4) e^{-s} + (s / 2) e^{-2 s}``, a neutral
    quasi-polynomial whose difference operator is not strongly stable:

    >>> from posicast import QuasiPolynomial
    >>> h = QuasiPolynomial([[-0.25, 1.0], [1 / 3, -0.75], [0.0, 0.5]], [0.0, 1.0, 2.0])
    >>> np.round(rightmost(h, 2), 5)
    array([-0.17012+0.82383j, -0.17012-0.82383j])
    """
    q = _prepared(h)
    if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)) or not 1 <= n <= 100_000:
        raise ValueError(f"n must be an integer in [1, 100000], got {n!r}")
    if isinstance(max_alpha_steps, (bool, np.bool_)) or not isinstance(max_alpha_steps, (int, np.integer)) \
            or not 1 <= max_alpha_steps <= 200:
        raise ValueError(f"max_alpha_steps must be an integer in [1, 200], got {max_alpha_steps!r}")
    return _rightmost_all(q, int(n), ignore, int(max_alpha_steps), _check_radius(max_radius))[:n]


def _rightmost_all(q: QuasiPolynomial, n: int, ignore: Any, max_alpha_steps: int, max_radius: float) -> np.ndarray:
    """Every root right of the last search line (at least ``n`` of them when it could get there)."""
    floor = -math.inf
    ds = None
    if q.kind == "neutral":
        ds = difference_spectrum(q)
        floor = ds.abscissa if ds.commensurate else ds.hale_abscissa
    bound = _sharp_bound(q, ds)
    alpha = 0.0 if floor < 0 else floor + 1.0
    step = 1.0
    found = np.zeros(0, complex)
    for _ in range(max_alpha_steps):
        R = bound(alpha)
        if math.isfinite(floor) and R > max_radius:
            break  # too close to the neutral chains' line for a search within max_radius
        got = _search_right_of(q, alpha, ignore, bound=bound)
        if got is not None:
            found = got
            if found.size >= n:
                return found
        if math.isfinite(floor) and alpha - step <= floor:
            if alpha <= floor + 1e-3 * max(1.0, abs(floor)):
                break
            alpha = floor + 0.5 * (alpha - floor)
            continue
        # an irrational fraction keeps the search lines off round numbers, where multiple roots
        # of designed quasi-polynomials (multiplicity-induced dominancy) like to sit
        alpha -= step * 1.0731
        step *= 2.0
    return found


class SpectralAbscissa(float):
    """A spectral abscissa (a ``float``) with its certified error bound.

    Attributes
    ----------
    error : float
        The supremum of the real parts of the roots lies in ``[self - error, self + error]``
        (``inf`` when no disk around the rightmost root could be certified).
    source : str
        ``'root'`` (a located rightmost root or cluster), ``'difference operator'``
        (the neutral chains' abscissa ``C_D``) or ``'none'`` (no root: ``-inf``).
    marginal : bool
        The abscissa is zero to within ``error`` (a root on the imaginary axis, as
        far as floating point can tell); the value is then exactly ``0.0``.
    """

    error: float
    source: str

    def __new__(cls, value: float, error: float = 0.0, source: str = "root") -> "SpectralAbscissa":
        obj = super().__new__(cls, value)
        obj.error = float(error)
        obj.source = source
        return obj

    @property
    def marginal(self) -> bool:
        return float(self) == 0.0 and self.source != "none"

    def __reduce__(self) -> tuple:
        return (SpectralAbscissa, (float(self), self.error, self.source))


def _root_radii(q: QuasiPolynomial, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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


def _abscissa_of_roots(q: QuasiPolynomial, z: np.ndarray) -> SpectralAbscissa:
    """Largest real part of the roots ``z`` and its certified error (0 when zero within it)."""
    top = float(z.real.max())
    near = z[z.real >= top - 1e-6 * max(1.0, abs(top))]
    vals, _, radii = _root_radii(q, near)
    if not np.all(np.isfinite(radii)):
        return SpectralAbscissa(top, math.inf, "root")
    hi = float(np.max(vals.real + radii))
    lo = float(np.max(vals.real - radii))
    err = max(hi - top, top - lo)
    if lo <= 0.0 <= hi:
        return SpectralAbscissa(0.0, max(hi, -lo), "root")
    return SpectralAbscissa(top, err, "root")


def _difference_abscissa(ds: DifferenceSpectrum) -> SpectralAbscissa:
    """``C_D`` with its error: certified disks about the operator's rightmost roots (commensurate
    delays), or up to the Hale abscissa, which bounds ``C_D`` from above (otherwise)."""
    CD = ds.abscissa
    if not math.isfinite(CD):
        return SpectralAbscissa(CD, 0.0, "difference operator")
    if not ds.commensurate:
        return SpectralAbscissa(CD, max(0.0, ds.hale_abscissa - CD), "difference operator")
    r = ds.roots
    near = r[r.real >= CD - 1e-6 * max(1.0, abs(CD))]
    # a multiple root of the operator (ZVD: double) comes out of np.roots as a split pair: group them
    groups: list[list[complex]] = []
    for z in near:
        for g in groups:
            if abs(z - g[0]) <= 1e-5 * max(1.0, abs(z)):
                g.append(complex(z))
                break
        else:
            groups.append([complex(z)])
    hi, lo = -math.inf, -math.inf
    for g in groups:
        c = complex(np.mean(g))
        rad = certified_radius(ds.operator, c, len(g), 0.1 * max(1.0, abs(c)))
        if rad is None:
            return SpectralAbscissa(CD, math.inf, "difference operator")
        hi = max(hi, c.real + rad)
        lo = max(lo, c.real - rad)
    err = max(hi - CD, CD - lo)
    if lo <= 0.0 <= hi:
        return SpectralAbscissa(0.0, max(hi, -lo), "difference operator")
    return SpectralAbscissa(CD, err, "difference operator")


def spectral_abscissa(h: Any, *, ignore: Any = None, max_radius: float = 2e4) -> SpectralAbscissa:
    """Supremum of the real parts of the roots of ``h``, with its certified error bound.

    Retarded or polynomial ``h``: the real part of the rightmost root (a
    certified search, see :func:`rightmost`).  Neutral ``h``: root chains
    accumulate at the difference operator's abscissa ``C_D``, so the result is
    ``max(C_D, rightmost isolated root)``.  Isolated roots are searched right of
    the line ``Re s = alpha`` closest to ``C_D`` at which every such root has
    ``|s| <= max_radius`` (the bound uses the difference operator's certified
    minimum modulus, so roots between ``C_D`` and the Hale abscissa count too
    when the operator is not strongly stable); a chain root between ``C_D`` and
    that line beyond ``|s| = max_radius`` is not resolved (its real part tends to
    ``C_D``).

    Returns
    -------
    SpectralAbscissa
        A ``float`` with ``.error`` (certified: disks about the rightmost roots)
        and ``.source``.  When the abscissa is zero to within ``.error`` (roots
        on the imaginary axis) it is exactly ``0.0`` and ``.marginal`` is True:
        the sign of a rounding-level real part means nothing.

    Examples
    --------
    >>> from posicast import QuasiPolynomial
    >>> round(spectral_abscissa(QuasiPolynomial([[1.0, 1.0]])), 12)   # s + 1
    -1.0
    >>> a = spectral_abscissa(QuasiPolynomial([[0.0, 1.0], [1.0, 0.0]], [0.0, np.pi / 2]))  # s + e^{-s pi/2}
    >>> float(a), a.marginal, a.error < 1e-12          # roots +-j exactly
    (0.0, True, True)
    """
    q = _prepared(h)
    max_radius = _check_radius(max_radius)
    if q.kind == "neutral":
        ds = difference_spectrum(q)
        bound = _sharp_bound(q, ds)
        best = _difference_abscissa(ds)
        # Lines ever closer to C_D (root bounds 64, 512, ... up to max_radius): once roots lie right
        # of a line, every root right of it is known and the others are left of it, so the search
        # stops there instead of crowding the chains near C_D (a dominant root: 5.5 s -> 0.1 s).
        targets = [64.0 * 8.0**k for k in range(12) if 64.0 * 8.0**k < max_radius] + [max_radius]
        for target in targets:
            cut = _neutral_cut(q, ds, bound, target)
            if cut is None:
                if target < max_radius:
                    continue
                raise RootFindingError(
                    f"no search line right of C_D = {ds.abscissa:.4g} closes a region within |s| <= "
                    f"max_radius = {max_radius:g}; raise max_radius"
                )
            got = _search_right_of(q, cut, ignore, bound=bound, edge_tol=1e-9)
            if got is not None and got.size:
                a = _abscissa_of_roots(q, got)
                if float(a) > float(best) or (float(a) == float(best) and a.error > best.error):
                    best = a
                break
        return best
    r = _rightmost_all(q, 1, ignore, 40, max_radius)
    if r.size == 0:
        return SpectralAbscissa(-math.inf, 0.0, "none")
    return _abscissa_of_roots(q, r)


@dataclass(frozen=True)
class Stability:
    """Stability verdict for a characteristic quasi-polynomial.

    Attributes
    ----------
    stable : bool
        Exponentially stable: no root with ``Re s >= 0`` and, if neutral, a
        strongly stable difference operator with ``C_D < 0``.
    kind : str
        ``'polynomial'``, ``'retarded'`` or ``'neutral'``.
    unstable_roots : ndarray of complex
        Every root with ``Re s >= 0`` (conjugates included), by decreasing real part;
        a root on the imaginary axis (to within its certified disk) has its real part
        set to exactly 0.
    difference : DifferenceSpectrum or None
        For a neutral quasi-polynomial.
    reason : str
        One sentence saying why.
    marginal : bool
        Not exponentially stable only because of roots on the imaginary axis: no root
        is certified right of it, and the roots on it are certified to within
        :attr:`axis_error` of ``Re s = 0`` (a critical delay, a pure integrator).
        ``stable`` is False then.
    axis_error : float
        The largest certified radius about the roots on the axis (0 when there are none).
    """

    stable: bool
    kind: str
    unstable_roots: np.ndarray
    difference: DifferenceSpectrum | None
    reason: str
    marginal: bool = False
    axis_error: float = 0.0

    @property
    def difference_abscissa(self) -> float | None:
        return None if self.difference is None else self.difference.abscissa

    @property
    def strongly_stable(self) -> bool | None:
        return None if self.difference is None else self.difference.strongly_stable

    def __bool__(self) -> bool:
        return self.stable


def _split_axis(q: QuasiPolynomial, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Roots found right of ~0: (right of the axis, on the axis with Re = 0, largest axis radius).

    A root within ``1e-6 |s|`` of the axis gets a certified disk (:func:`certified_radius`):
    it is on the axis when the disk meets it, right of it when the whole disk is, and
    dropped when the whole disk is left of it; where no disk can be certified, the sign
    decides beyond ``1e-9 |s|`` and the root counts as on the axis within it.  A root
    farther out is on the side of its sign (the count is certified; Newton's residual puts
    it within rounding of the computed point).
    """
    z = np.asarray(z, dtype=complex)
    close = np.abs(z.real) <= 1e-6 * np.maximum(1.0, np.abs(z))
    right = list(z[~close & (z.real > 0)])
    axis: list[complex] = []
    err = 0.0
    vals, counts, radii = _root_radii(q, z[close])
    for v, m, r in zip(vals, counts, radii):
        if not math.isfinite(r):
            r = 1e-9 * max(1.0, abs(v))
            if abs(v.real) > r:
                r = 0.0
        if v.real - r > 0:
            right += [v] * int(m)
        elif v.real + r >= 0:
            axis += [complex(0.0, v.imag)] * int(m)
            err = max(err, float(r))

    def order(a: list) -> np.ndarray:
        arr = np.array(a, dtype=complex)
        return arr[np.lexsort((-arr.imag, -arr.real))] if arr.size else arr

    return order(right), order(axis), err


def stability(h: Any, *, ignore: Any = None, max_evaluations: float = 5e7, timeout: float = 120.0) -> Stability:
    """Decide exponential stability of ``h(s) = 0`` with a certified search of ``Re s >= 0``.

    ``ignore`` lists known spurious roots (see :func:`posicast.roots`);
    ``max_evaluations`` and ``timeout`` bound each root search of the staircase
    (:class:`~posicast.spectra.rootfinder.BudgetExceeded` past them).

    Roots on the imaginary axis (to within a certified disk, e.g. ``s + e^{-s pi/2}``
    with roots ``+-j``) give the verdict *marginal*: ``stable`` False, ``marginal``
    True, the reason says so.

    Examples
    --------
    >>> from posicast import QuasiPolynomial
    >>> stability(QuasiPolynomial([[1.0, 1.0], [0.5, 0.0]], [0, 1])).stable   # s + 1 + 0.5 e^{-s}
    True
    >>> stability(QuasiPolynomial([[-1.0, 1.0]])).reason
    '1 root with Re s >= 0, the rightmost at 1'
    >>> st = stability(QuasiPolynomial([[0.0, 1.0], [1.0, 0.0]], [0.0, np.pi / 2]))   # s + e^{-s pi/2}
    >>> st.stable, st.marginal, st.unstable_roots
    (False, True, array([0.+1.j, 0.-1.j]))
    """
    q = _prepared(h)
    max_evaluations, timeout = check_budget(max_evaluations, timeout)
    budget = {"max_evaluations": max_evaluations, "timeout": timeout}
    kind = q.kind
    ds = None
    if kind == "neutral":
        ds = difference_spectrum(q)
        if not ds.strongly_stable:
            # The verdict needs no root.  Roots with Re s >= 0 are listed when the chains stay left
            # of the axis (C_D < 0, commensurate delays: the operator's certified minimum modulus
            # bounds them within a modest radius); otherwise those right of the Hale abscissa,
            # where a modest search can afford it (root chains crowd that line and can make it
            # very expensive).
            listed = ""
            small = {"max_evaluations": min(max_evaluations, 2e6), "timeout": timeout}
            bound = _sharp_bound(q, ds)
            marginal, axis_err = False, 0.0
            try:
                if ds.commensurate and ds.abscissa < 0 and bound(0.0) <= 2e3:
                    got = _search_right_of(q, 0.0, ignore, small, bound=bound, edge_tol=1e-9)
                    right, axis, axis_err = _split_axis(q, got)
                    unst = np.concatenate([right, axis])
                else:
                    unst = _search_right_of(q, max(0.0, ds.hale_abscissa) + 1e-3, ignore, small)
            except BudgetExceeded:
                unst, listed = None, "; the roots right of the Hale abscissa are too many to list within the budget"
            return Stability(
                False,
                kind,
                unst if unst is not None else np.zeros(0, complex),
                ds,
                f"neutral with a difference operator that is not strongly stable "
                f"(sum of |coefficients| = {float(np.sum(np.abs(ds.operator.coeffs[1:, 0]))):.4g} >= 1, "
                f"C_D = {ds.abscissa:.4g}){listed}",
                marginal,
                axis_err,
            )
    got = _search_right_of(q, 0.0, ignore, budget, bound=_sharp_bound(q, ds), edge_tol=1e-9)
    if got is None:  # cannot happen: gamma(0) > 0 for retarded or strongly stable neutral h
        raise RuntimeError("no root bound at Re s = 0; please report this quasi-polynomial")
    right, axis, axis_err = _split_axis(q, got)
    unst = np.concatenate([right, axis])
    if right.size:
        return Stability(
            False, kind, unst, ds,
            f"{right.size} root{'s' if right.size > 1 else ''} with Re s > 0, the rightmost at {_fmt(right[0])}"
            if axis.size else
            f"{right.size} root{'s' if right.size > 1 else ''} with Re s >= 0, the rightmost at {_fmt(right[0])}",
            False, axis_err,
        )
    if axis.size:
        multiple = np.unique(axis, return_counts=True)[1].max() > 1
        return Stability(
            False, kind, unst, ds,
            f"marginal: {axis.size} root{'s' if axis.size > 1 else ''} on the imaginary axis "
            f"(real part 0 to within the certified {axis_err:.1g}), at {', '.join(_fmt(z) for z in axis[:4])}"
            f"{', ...' if axis.size > 4 else ''}; no root right of it"
            + ("; a multiple root on the axis: solutions grow polynomially" if multiple else ""),
            True, axis_err,
        )
    extra = f"; neutral chains approach Re s = C_D = {ds.abscissa:.4g}" if ds is not None else ""
    return Stability(True, kind, unst, ds, f"no root with Re s >= 0 (certified count){extra}")


def _axis_path(R: float, axis_points: np.ndarray, eps: np.ndarray) -> list[complex]:
    """Counter-clockwise polygon around ``[0, R] x [-R, R]`` with square detours into ``Re s > 0``.

    Each detour excludes the square ``[0, eps] x [Im p - eps, Im p + eps]`` of an
    imaginary-axis point ``p`` (a known spurious root) from the enclosed region.
    """
    path = [complex(0.0, -R), complex(R, -R), complex(R, R), complex(0.0, R)]
    for p, e in sorted(zip(axis_points.imag, eps), key=lambda t: -t[0]):  # down the imaginary axis
        path += [complex(0.0, p + e), complex(e, p + e), complex(e, p - e), complex(0.0, p - e)]
    return path


def unstable_count(h: Any, *, ignore: Any = None, max_evaluations: float = 2e6) -> int:
    """Certified number of roots with ``Re s >= 0`` by the argument principle alone (no root is located).

    All such roots lie in ``[0, R] x [-R, R]`` with ``R`` from :func:`root_bound`;
    the winding number of ``h`` along that rectangle's boundary is certified
    segment by segment as in :func:`posicast.roots` (rigorous derivative bound
    plus a rounding margin).  Known spurious roots on the imaginary axis
    (``ignore``, e.g. a distributed shaper's removable ``s = 0``) are passed by
    small square detours into ``Re s > 0``, and each detour's square
    ``[-e, e] x [Im p - e, Im p + e]`` is counted separately and must hold exactly
    the ignored multiplicity; ignored points inside the rectangle are subtracted.

    Its cost grows with the rectangle's perimeter, not its area, so this is the
    cheap way to tell an unstable loop with large gains (thousands of roots
    within ``R``) from a stable one; :func:`stability` also lists the roots.

    Parameters
    ----------
    h : QuasiPolynomial
        Retarded, or neutral with a strongly stable difference operator.
    ignore : array_like of complex, optional
        Known spurious roots, one entry per multiplicity (see :func:`posicast.roots`).
    max_evaluations : float
        Budget of evaluations of ``h`` (:class:`BudgetExceeded` past it).

    Returns
    -------
    int

    Raises
    ------
    ValueError
        Advanced ``h``, or neutral ``h`` whose difference operator is not strongly
        stable (root chains may approach the imaginary axis: use :func:`stability`).
    RootFindingError
        A root on (or within rounding of) the imaginary axis: the count is not
        defined there (a marginal loop); or an ignored point that is not
        separated from other roots.

    Examples
    --------
    >>> from posicast import QuasiPolynomial
    >>> unstable_count(QuasiPolynomial([[-1.0, 1.0], [0.5, 0.0]], [0, 1]))   # s - 1 + 0.5 e^{-s}
    1
    >>> unstable_count(QuasiPolynomial([[1.0, 1.0], [0.5, 0.0]], [0, 1]))    # s + 1 + 0.5 e^{-s}
    0
    >>> unstable_count(QuasiPolynomial([[0.0, 2.0, 1.0]]), ignore=[0.0])   # s (s + 2), s = 0 ignored
    0
    """
    from .rootfinder import RootFindingError, _Evaluator, _OnBoundary, _winding

    q = _prepared(h)
    max_evaluations, _ = check_budget(max_evaluations)
    R0 = root_bound(q, 0.0)
    if not math.isfinite(R0):
        raise ValueError("neutral h whose difference operator is not strongly stable: no root bound in Re s >= 0; "
                         "use stability()")
    ign = np.zeros(0, complex) if ignore is None else check_ignore(ignore)
    R = max(R0, 1.0) * (1.0 + 1e-3) + 1e-3
    pts, mult = np.unique(ign, return_counts=True)
    ev = _Evaluator(q, int(max_evaluations), time.monotonic() + 1e9)  # an evaluation budget only: reproducible
    tau_max = float(q.delays[-1])
    step = min(R / 16.0, math.pi / (3.0 * tau_max)) if tau_max > 0 else R / 16.0
    # Ignored points on the imaginary axis get detours of half-width e; those well inside are subtracted.
    # Next to a multiple ignored root |h| is tiny against its terms (they cancel), so a detour that cannot
    # be certified is widened (e x 10, twice) before giving up.
    last: Exception | None = None
    for rel in (1e-4, 1e-3, 1e-2):
        eps_all = rel * np.maximum(1.0, np.abs(pts))
        on_axis = (np.abs(pts.real) <= eps_all) & (np.abs(pts.imag) < R - 2 * eps_all)
        inside = (pts.real > eps_all) & (np.abs(pts) <= R)
        im = np.sort(pts[on_axis].imag)
        if im.size > 1 and np.min(np.diff(im)) < 4 * eps_all[on_axis].max():
            break
        try:
            n = _winding(ev, _axis_path(R, pts[on_axis], eps_all[on_axis]), step, min_len=1e-9 * R)
            for p, e, m in zip(pts[on_axis], eps_all[on_axis], mult[on_axis]):
                square = [complex(-e, p.imag - e), complex(e, p.imag - e), complex(e, p.imag + e),
                          complex(-e, p.imag + e)]
                got = _winding(ev, square, e / 4.0, min_len=1e-7 * e)
                if got != m:
                    raise RootFindingError(
                        f"{got} roots within {e:.3g} of the ignored point {_fmt(complex(p))}, which stands for "
                        f"{m}: another root sits next to it"
                    )
            return int(n - int(np.sum(mult[inside])))
        except _OnBoundary as hit:
            on_detour = any(abs(hit.point - p) <= 2 * e for p, e in zip(pts[on_axis], eps_all[on_axis]))
            last = RootFindingError(f"a root on or within rounding of the imaginary axis near {_fmt(hit.point)}: "
                                    "the loop is marginal there")
            if not on_detour:
                raise last from None
    raise last if last is not None else RootFindingError("ignored points on the imaginary axis are too close "
                                                          "to each other to pass")


def _fmt(z: complex) -> str:
    z = complex(z)
    if z.imag == 0:
        return f"{z.real:.6g}"
    return f"{z.real:.6g}{z.imag:+.6g}j"
