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

from ..core.quasipoly import QuasiPolynomial
from .rootfinder import BudgetExceeded, Roots, as_quasipolynomial, roots

__all__ = [
    "root_bound",
    "DifferenceSpectrum",
    "difference_spectrum",
    "spectral_abscissa",
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
    if not math.isfinite(float(alpha)):
        raise ValueError(f"alpha must be finite, got {alpha}")
    n, lead = _leading(q)
    w = np.exp(-float(alpha) * q.delays)
    gamma = abs(lead[0]) - float(np.sum(np.abs(lead[1:]) * w[1:]))
    if gamma <= 0:
        return math.inf
    if n == 0:
        return 0.0 if gamma > 0 else math.inf
    beta = np.sum(np.abs(q.coeffs[:, :n]) * w[:, None], axis=0)  # ascending powers 0..n-1
    if not np.any(beta):
        return 0.0
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


def _search_right_of(q: QuasiPolynomial, alpha: float, ignore: Any, budget: dict | None = None) -> np.ndarray | None:
    """All roots with Re s >= alpha (conjugates included), or None if unbounded there.

    The half-plane is cut into vertical strips ``[b_i, b_{i+1}]``, each closed
    at the height ``R(b_i)`` of :func:`root_bound`, which falls quickly with
    ``b``: a staircase instead of the square ``[alpha, R] x [0, R]``.
    """
    R = root_bound(q, alpha)
    if not math.isfinite(R):
        return None
    found = []
    lo, width = alpha, 1.0
    while True:
        Rlo = root_bound(q, lo)
        if Rlo < lo or (Rlo == 0.0 and lo > 0.0):
            break  # |s| <= R(lo) < lo <= Re s is impossible: nothing further right (R = 0 leaves s = 0)
        hi = min(lo + width, Rlo + 1.0)
        pad = 1e-3 * max(1.0, Rlo)
        r = roots(q, (lo, hi, -pad, Rlo + pad), ignore=ignore, **(budget or {}))
        full = _conjugate_closure(r)
        found.append(full[(full.real >= lo) & (full.real < hi)])
        if hi >= Rlo:
            break
        lo, width = hi, 2.0 * width
    if not found:
        return np.zeros(0, complex)
    full = np.concatenate(found)
    return full[np.lexsort((-full.imag, -full.real))]


def rightmost(h: Any, n: int = 1, *, ignore: Any = None, max_alpha_steps: int = 12) -> np.ndarray:
    """The ``n`` rightmost roots (conjugate pairs complete), by decreasing real part.

    The search line ``Re s = alpha`` moves left until at least ``n`` roots lie
    right of it; :func:`root_bound` closes each search region.  For a neutral
    ``h`` the search stops at the difference operator's abscissa (infinitely
    many roots approach it); fewer than ``n`` roots are then returned and the
    chain is described by :func:`difference_spectrum`.
    """
    q = _prepared(h)
    if not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be an integer >= 1, got {n!r}")
    floor = -math.inf
    if q.kind == "neutral":
        ds = difference_spectrum(q)
        floor = ds.hale_abscissa
    alpha = 0.0 if floor < 0 else floor + 1.0
    step = 1.0
    found = np.zeros(0, complex)
    for _ in range(max_alpha_steps):
        got = _search_right_of(q, alpha, ignore)
        if got is not None:
            found = got
            if found.size >= n:
                return found[:n]
        if math.isfinite(floor) and alpha - step <= floor:
            if alpha <= floor + 1e-3 * max(1.0, abs(floor)):
                break
            alpha = floor + 0.5 * (alpha - floor)
            continue
        alpha -= step
        step *= 2.0
    return found[:n]


def spectral_abscissa(h: Any, *, ignore: Any = None, max_radius: float = 2e4) -> float:
    """Supremum of the real parts of the roots of ``h``.

    Retarded or polynomial ``h``: the real part of the rightmost root (a
    certified search, see :func:`rightmost`).  Neutral ``h``: root chains
    accumulate at the difference operator's abscissa ``C_D``, so the result is
    ``max(C_D, rightmost isolated root)``.  Isolated roots are searched right of
    the line ``Re s = alpha`` closest to the Hale abscissa at which every such
    root has ``|s| <= max_radius``; a chain root between ``C_D`` and that line
    beyond ``|s| = max_radius`` is not resolved (its real part tends to ``C_D``).

    Examples
    --------
    >>> from posicast import QuasiPolynomial
    >>> round(spectral_abscissa(QuasiPolynomial([[1.0, 1.0]])), 12)   # s + 1
    -1.0
    """
    q = _prepared(h)
    if isinstance(max_radius, bool) or not isinstance(max_radius, (int, float)) or not (
        math.isfinite(max_radius) and max_radius > 0
    ):
        raise ValueError(f"max_radius must be a finite number > 0, got {max_radius!r}")
    if q.kind == "neutral":
        ds = difference_spectrum(q)
        hale = ds.hale_abscissa
        hi = max(0.0, hale) + 1.0
        while root_bound(q, hi) > max_radius:
            hi += 2.0 * (hi - hale)
        lo = hale
        for _ in range(60):  # the smallest alpha with R(alpha) <= max_radius
            mid = 0.5 * (lo + hi)
            if root_bound(q, mid) > max_radius:
                lo = mid
            else:
                hi = mid
        got = _search_right_of(q, hi, ignore)
        best = ds.abscissa
        if got is not None and got.size:
            best = max(best, float(got.real.max()))
        return best
    r = rightmost(q, 1, ignore=ignore, max_alpha_steps=40)
    if r.size == 0:
        return -math.inf
    return float(r.real.max())


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
        Every root with ``Re s >= 0`` (conjugates included), by decreasing real part.
    difference : DifferenceSpectrum or None
        For a neutral quasi-polynomial.
    reason : str
        One sentence saying why.
    """

    stable: bool
    kind: str
    unstable_roots: np.ndarray
    difference: DifferenceSpectrum | None
    reason: str

    @property
    def difference_abscissa(self) -> float | None:
        return None if self.difference is None else self.difference.abscissa

    @property
    def strongly_stable(self) -> bool | None:
        return None if self.difference is None else self.difference.strongly_stable

    def __bool__(self) -> bool:
        return self.stable


def stability(h: Any, *, ignore: Any = None, max_evaluations: float = 5e7, timeout: float = 120.0) -> Stability:
    """Decide exponential stability of ``h(s) = 0`` with a certified search of ``Re s >= 0``.

    ``ignore`` lists known spurious roots (see :func:`posicast.roots`);
    ``max_evaluations`` and ``timeout`` bound each root search of the staircase
    (:class:`~posicast.spectra.rootfinder.BudgetExceeded` past them).

    Examples
    --------
    >>> from posicast import QuasiPolynomial
    >>> stability(QuasiPolynomial([[1.0, 1.0], [0.5, 0.0]], [0, 1])).stable   # s + 1 + 0.5 e^{-s}
    True
    >>> stability(QuasiPolynomial([[-1.0, 1.0]])).reason
    '1 root with Re s >= 0, the rightmost at 1'
    """
    q = _prepared(h)
    budget = {"max_evaluations": max_evaluations, "timeout": timeout}
    kind = q.kind
    ds = None
    if kind == "neutral":
        ds = difference_spectrum(q)
        if not ds.strongly_stable:
            # The verdict needs no root: the roots to the right of the Hale abscissa are listed where a
            # modest search can afford it (root chains crowd that line and can make it very expensive).
            listed = ""
            small = {"max_evaluations": min(max_evaluations, 2e6), "timeout": timeout}
            try:
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
            )
    unst = _search_right_of(q, 0.0, ignore, budget)
    if unst is None:  # cannot happen: gamma(0) > 0 for retarded or strongly stable neutral h
        raise RuntimeError("no root bound at Re s = 0; please report this quasi-polynomial")
    if unst.size:
        return Stability(
            False, kind, unst, ds,
            f"{unst.size} root{'s' if unst.size > 1 else ''} with Re s >= 0, the rightmost at {_fmt(unst[0])}",
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
    if not (isinstance(max_evaluations, (int, float)) and max_evaluations > 0):
        raise ValueError(f"max_evaluations must be > 0, got {max_evaluations!r}")
    R0 = root_bound(q, 0.0)
    if not math.isfinite(R0):
        raise ValueError("neutral h whose difference operator is not strongly stable: no root bound in Re s >= 0; "
                         "use stability()")
    ign = np.zeros(0, complex) if ignore is None else np.atleast_1d(np.asarray(ignore, dtype=complex)).ravel()
    if not np.all(np.isfinite(ign)):
        raise ValueError("ignore must contain finite points (no NaN or inf)")
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
