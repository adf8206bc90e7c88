"""Stability of ``h(s) = 0``: a certified verdict from every root with ``Re s >= 0``.

:func:`stability` searches the closed right half-plane (:mod:`posicast.spectra.halfplane`,
closed by :mod:`posicast.spectra.bounds`) and gives a verdict: stable, marginal (roots on
the imaginary axis only, to within certified disks) or unstable.  A neutral ``h`` whose
difference operator (:mod:`posicast.spectra.difference`) is not strongly stable is
unstable whatever its roots.  :func:`unstable_count` counts the roots with ``Re s >= 0``
by the argument principle alone (:mod:`posicast.spectra.argument_principle`), without
locating them.

This module also re-exports, from where they live: :func:`root_bound`
(:mod:`~posicast.spectra.bounds`), :func:`difference_spectrum` and
:class:`DifferenceSpectrum` (:mod:`~posicast.spectra.difference`), :func:`rightmost`,
:func:`spectral_abscissa` and :class:`SpectralAbscissa` (:mod:`~posicast.spectra.abscissa`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from ..core.quasipoly import QuasiPolynomial
from .abscissa import SpectralAbscissa, rightmost, spectral_abscissa
from .argument_principle import OnBoundary, winding
from .bounds import factored_bound, root_bound, sharp_bound, with_factored
from .checks import BudgetExceeded, RootFindingError, check_budget, check_ignore, prepared
from .difference import DifferenceSpectrum, difference_spectrum
from .evaluation import Evaluator
from .halfplane import root_radii, search_right_of

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


class AxisSplit(NamedTuple):
    """Roots found right of about ``Re s = 0``, with respect to the imaginary axis."""

    right: np.ndarray  #: certified right of the axis, by decreasing real part
    axis: np.ndarray  #: on the axis to within their certified disks; real part set to exactly 0
    error: float  #: the largest certified radius about the roots on the axis (0 when there are none)


def _split_axis(q: QuasiPolynomial, z: np.ndarray) -> AxisSplit:
    """Roots found right of ~0, split into those right of the axis and those on it (with Re = 0).

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
    vals, counts, radii = root_radii(q, z[close])
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

    return AxisSplit(order(right), order(axis), err)


def stability(h: Any, *, ignore: Any = None, max_evaluations: float = 5e7, timeout: float = 120.0) -> Stability:
    """Decide exponential stability of ``h(s) = 0`` with a certified search of ``Re s >= 0``.

    ``ignore`` lists known spurious roots (see :func:`posicast.roots`);
    ``max_evaluations`` and ``timeout`` bound each root search of the staircase
    (:class:`~posicast.spectra.checks.BudgetExceeded` past them).

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
    q = prepared(h)
    max_evaluations, timeout = check_budget(max_evaluations, timeout)
    budget = {"max_evaluations": max_evaluations, "timeout": timeout}
    kind = q.kind
    ds = None
    if kind == "neutral":
        ds = difference_spectrum(q)
        if not ds.strongly_stable:
            return _not_strongly_stable(q, ds, ignore, max_evaluations, timeout)
    got = search_right_of(q, 0.0, ignore, budget, bound=with_factored(q, sharp_bound(q, ds)), edge_tol=1e-9)
    if got is None:  # cannot happen: gamma(0) > 0 for retarded or strongly stable neutral h
        raise RuntimeError("no root bound at Re s = 0; please report this quasi-polynomial")
    return _verdict(kind, ds, _split_axis(q, got))


def _not_strongly_stable(
    q: QuasiPolynomial, ds: DifferenceSpectrum, ignore: Any, max_evaluations: float, timeout: float
) -> Stability:
    """The verdict for a neutral ``q`` whose difference operator is not strongly stable: unstable.

    The verdict needs no root.  Roots with Re s >= 0 are listed when the chains stay left
    of the axis (C_D < 0, commensurate delays: the operator's certified minimum modulus
    bounds them within a modest radius); otherwise those right of the Hale abscissa,
    where a modest search can afford it (root chains crowd that line and can make it
    very expensive).
    """
    listed = ""
    small = {"max_evaluations": min(max_evaluations, 2e6), "timeout": timeout}
    bound = sharp_bound(q, ds)
    marginal, axis_err = False, 0.0
    try:
        if ds.commensurate and ds.abscissa < 0 and bound(0.0) <= 2e3:
            got = search_right_of(q, 0.0, ignore, small, bound=bound, edge_tol=1e-9)
            right, axis, axis_err = _split_axis(q, got)
            unst = np.concatenate([right, axis])
        else:
            unst = search_right_of(q, max(0.0, ds.hale_abscissa) + 1e-3, ignore, small)
    except BudgetExceeded:
        unst, listed = None, "; the roots right of the Hale abscissa are too many to list within the budget"
    return Stability(
        False,
        q.kind,
        unst if unst is not None else np.zeros(0, complex),
        ds,
        f"neutral with a difference operator that is not strongly stable "
        f"(sum of |coefficients| = {float(np.sum(np.abs(ds.operator.coeffs[1:, 0]))):.4g} >= 1, "
        f"C_D = {ds.abscissa:.4g}){listed}",
        marginal,
        axis_err,
    )


def _verdict(kind: str, ds: DifferenceSpectrum | None, split: AxisSplit) -> Stability:
    """The verdict from every root with Re s >= 0: unstable, marginal (roots on the axis only) or stable."""
    right, axis, axis_err = split
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

    All such roots lie in ``[0, R] x [-R, R]`` with ``R`` the smaller of :func:`root_bound` and
    :func:`~posicast.spectra.bounds.factored_bound`;
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
    q = prepared(h)
    max_evaluations, _ = check_budget(max_evaluations)
    R0 = root_bound(q, 0.0)
    if math.isfinite(R0):  # the smaller of the two bounds (a ZV shaper's inverse in a loop: 24 000 against 250)
        R0 = min(R0, factored_bound(q, cap=R0))
    if not math.isfinite(R0):
        raise ValueError("neutral h whose difference operator is not strongly stable: no root bound in Re s >= 0; "
                         "use stability()")
    ign = np.zeros(0, complex) if ignore is None else check_ignore(ignore)
    R = max(R0, 1.0) * (1.0 + 1e-3) + 1e-3
    pts, mult = np.unique(ign, return_counts=True)
    ev = Evaluator(q, int(max_evaluations), time.monotonic() + 1e9)  # an evaluation budget only: reproducible
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
            n = winding(ev, _axis_path(R, pts[on_axis], eps_all[on_axis]), step, min_len=1e-9 * R)
            for p, e, m in zip(pts[on_axis], eps_all[on_axis], mult[on_axis]):
                square = [complex(-e, p.imag - e), complex(e, p.imag - e), complex(e, p.imag + e),
                          complex(-e, p.imag + e)]
                got = winding(ev, square, e / 4.0, min_len=1e-7 * e)
                if got != m:
                    raise RootFindingError(
                        f"{got} roots within {e:.3g} of the ignored point {_fmt(complex(p))}, which stands for "
                        f"{m}: another root sits next to it"
                    )
            return int(n - int(np.sum(mult[inside])))
        except OnBoundary as hit:
            on_detour = any(abs(hit.point - p) <= 2 * e for p, e in zip(pts[on_axis], eps_all[on_axis]))
            last = RootFindingError(f"a root on or within rounding of the imaginary axis near {_fmt(hit.point)}: "
                                    "the loop is marginal there")
            if not on_detour:
                raise last from None
    raise last if last is not None else RootFindingError("ignored points on the imaginary axis are too close "
                                                          "to each other to pass")


def _fmt(z: complex) -> str:
    """A root for a message: ``1.5`` or ``-0.2+3j`` (6 significant digits)."""
    z = complex(z)
    if z.imag == 0:
        return f"{z.real:.6g}"
    return f"{z.real:.6g}{z.imag:+.6g}j"
