"""The rightmost roots of a quasi-polynomial and its spectral abscissa, with certified errors.

:func:`rightmost` moves a search line ``Re s = alpha`` left until enough roots lie right
of it (each region closed by a root bound, :mod:`posicast.spectra.bounds`).
:func:`spectral_abscissa` is the real part of the rightmost root, or for a neutral
quasi-polynomial ``max(C_D, rightmost isolated root)``, where ``C_D`` is the difference
operator's abscissa (:mod:`posicast.spectra.difference`); its error comes from
certified disks about the rightmost roots (:func:`~posicast.spectra.disks.certified_radius`).
"""

from __future__ import annotations

import math
import warnings
from typing import Any, Callable

import numpy as np

from .. import _validate as v
from ..core.quasipoly import QuasiPolynomial
from .bounds import sharp_bound
from .checks import BudgetExceeded, RootFindingError, prepared
from .difference import DifferenceSpectrum, difference_spectrum
from .disks import certified_radius
from .halfplane import root_radii, search_right_of

__all__ = ["rightmost", "SpectralAbscissa", "spectral_abscissa"]


_NEUTRAL_WORK = 2e6  # evaluations a search line next to neutral chains may cost (about half a second)


def _check_radius(max_radius: Any) -> float:
    return v.positive(max_radius, "max_radius")


def _neutral_cut(
    q: QuasiPolynomial, ds: DifferenceSpectrum, bound: Callable[[float], float], max_radius: float
) -> float | None:
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
    q = prepared(h)
    # a ValueError for every wrong n (a bool too: rightmost(h, True) is documented to say 'n must be')
    if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)) or not 1 <= n <= 100_000:
        raise ValueError(f"n must be an integer in [1, 100000], got {n!r}")
    if isinstance(max_alpha_steps, (bool, np.bool_)) or not isinstance(max_alpha_steps, (int, np.integer)) \
            or not 1 <= max_alpha_steps <= 200:
        raise ValueError(f"max_alpha_steps must be an integer in [1, 200], got {max_alpha_steps!r}")
    found, short = _rightmost_all(q, int(n), ignore, int(max_alpha_steps), _check_radius(max_radius))
    if found.size < n and short:
        warnings.warn(f"rightmost: {found.size} of the {n} roots asked for: {short}", UserWarning, stacklevel=2)
    return found[:n]


def _rightmost_all(
    q: QuasiPolynomial, n: int, ignore: Any, max_alpha_steps: int, max_radius: float
) -> tuple[np.ndarray, str]:
    """Every root right of the last search line (at least ``n`` of them when it could get there), and
    why there are fewer ('' when there are no more roots: a polynomial searched to its Fujiwara bound)."""
    floor = -math.inf
    ds = None
    if q.kind == "neutral":
        ds = difference_spectrum(q)
        floor = ds.abscissa if ds.commensurate else ds.hale_abscissa
    bound = sharp_bound(q, ds)
    # a polynomial's roots all lie in |s| <= its Fujiwara bound: one search right of -bound has them all
    # (before, roots far left or n > degree stepped the line max_alpha_steps times and returned fewer)
    poly_bound = _polynomial_bound(q) if q.is_polynomial else math.inf
    alpha = start = 0.0 if floor < 0 else floor + 1.0
    step = 1.0
    found = np.zeros(0, complex)
    for _ in range(max_alpha_steps):
        R = bound(alpha)
        if math.isfinite(floor) and R > max_radius:
            return found, (f"the roots further left crowd the neutral chains near Re s = C_D = {floor:.4g}, where "
                           f"the root bound passes max_radius={max_radius:g} (see difference_spectrum)")
        if math.isfinite(floor) and alpha < start:
            # next to the chains each step costs about twice the last, mostly in reconciling roots
            # crowding the search line (an inverse ZV of an undamped mode: 13 s for nothing before
            # this budget); a line that needs more stops the search with the reason
            try:
                got = search_right_of(q, alpha, ignore, {"max_evaluations": _NEUTRAL_WORK}, bound=bound)
            except BudgetExceeded:
                return found, (f"the search line Re s = {alpha:.4g} is so close to the neutral chains "
                               f"(C_D = {floor:.4g}) that its search needs more than {_NEUTRAL_WORK:.0e} "
                               "evaluations (see difference_spectrum)")
        else:
            got = search_right_of(q, alpha, ignore, bound=bound)
        if got is not None:
            found = got
            if found.size >= n:
                return found, ""
        if alpha <= -poly_bound:
            return found, ""  # every root of the polynomial
        if math.isfinite(floor) and alpha - step <= floor:
            if alpha <= floor + 1e-3 * max(1.0, abs(floor)):
                return found, (f"the search line reached the neutral chains' abscissa C_D = {floor:.4g}, which "
                               "infinitely many roots approach (see difference_spectrum)")
            alpha = floor + 0.5 * (alpha - floor)
            continue
        # an irrational fraction keeps the search lines off round numbers, where multiple roots
        # of designed quasi-polynomials (multiplicity-induced dominancy) like to sit
        alpha = -poly_bound if math.isfinite(poly_bound) else alpha - step * 1.0731
        step *= 2.0
    return found, (f"the search line stopped at Re s = {alpha:.4g} after max_alpha_steps={max_alpha_steps} "
                   "steps (each twice as far left); raise max_alpha_steps for more")


def _polynomial_bound(q: QuasiPolynomial) -> float:
    """Fujiwara's bound ``2 max_k |c_{n-k} / c_n|^(1/k)`` (the last term halved): every root of the
    polynomial ``q`` has a smaller modulus (with a little margin)."""
    c = q.coeffs[0]
    n = int(np.max(np.nonzero(c)[0])) if np.any(c) else 0
    if n == 0:
        return 0.0
    k = np.arange(1, n + 1)
    ratios = np.abs(c[n - k]) / abs(c[n])
    ratios[-1] /= 2.0
    return 2.0 * float(np.max(ratios ** (1.0 / k))) * (1.0 + 1e-6) + 1e-6


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



def _abscissa_of_roots(q: QuasiPolynomial, z: np.ndarray) -> SpectralAbscissa:
    """Largest real part of the roots ``z`` and its certified error (0 when zero within it)."""
    top = float(z.real.max())
    near = z[z.real >= top - 1e-6 * max(1.0, abs(top))]
    vals, _, radii = root_radii(q, near)
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
    q = prepared(h)
    max_radius = _check_radius(max_radius)
    if q.kind == "neutral":
        ds = difference_spectrum(q)
        bound = sharp_bound(q, ds)
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
            got = search_right_of(q, cut, ignore, bound=bound, edge_tol=1e-9)
            if got is not None and got.size:
                a = _abscissa_of_roots(q, got)
                if float(a) > float(best) or (float(a) == float(best) and a.error > best.error):
                    best = a
                break
        return best
    r, _ = _rightmost_all(q, 1, ignore, 40, max_radius)
    if r.size == 0:
        return SpectralAbscissa(-math.inf, 0.0, "none")
    return _abscissa_of_roots(q, r)
