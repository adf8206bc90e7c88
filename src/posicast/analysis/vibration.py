"""Residual vibration, sensitivity curves and insensitivity of shapers.

Residual vibration (seed 004 eq. 1-3, seed 003's "percentage vibration"),
generalised to any shaper through its exact transfer function: a mode with
natural frequency ``omega`` and damping ``zeta`` has the pole
``p = -zeta omega + j omega sqrt(1 - zeta^2)``.  After the shaper has ended
(``t >= t_end``) the shaped impulse response of the mode is
``e^{-beta t} |S(p)| sin(Omega t + phi)``, so

* ``reference="end"`` (default): ``V = e^{-zeta omega t_end} |S(p)|``, the
  amplitude relative to an unshaped impulse applied at ``t_end``.  This is the
  Singer-Seering form printed by seeds 003 and 004 (their
  ``e^{-zeta omega t_n} sqrt(C^2 + S^2)``, with ``t_n`` the last impulse); it is the
  form in which the EI shapers' ``vtol`` is defined, hence the default.
* ``reference="unshaped"``: ``V = |S(p)|``, the amplitude relative to the
  unshaped response at the same time.  It is the only form that makes sense for
  an IIR shaper (infinite duration) and it is the stricter one for damped modes.

For ``zeta = 0`` both coincide.

Numerics.  With ``reference="end"`` every term is evaluated with its decay
folded in, ``A_i e^{zeta omega (t_i - t_end)} e^{-j Omega t_i}`` (exponents
<= 0), so ``V`` stays finite and correct for every ``zeta < 1`` and every
frequency; distributed parts are evaluated the same way (each term of the
exact transfer function scaled by its largest exponential) wherever
``zeta omega t_end > 700``.  With ``reference="unshaped"`` a value beyond the
float range (``|S(p)| > 1.8e308``) is refused.  Frequencies are limited to
``omega * duration <= 1e12`` (:data:`PHASE_MAX`): beyond, the phases
``Omega t_i`` lose more than ``1e-4`` rad to rounding and ``V`` would be noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.polynomial import polynomial as P
from scipy.optimize import brentq, minimize_scalar

from .. import _validate as v
from ..modes import OMEGA_MAX, Mode
from ..shapers.base import Shaper, lumped_sum

__all__ = [
    "residual_vibration",
    "SensitivityCurve",
    "sensitivity_curve",
    "Insensitivity",
    "insensitivity",
    "PHASE_MAX",
    "HUMP_TOL",
]

_REFERENCES = ("end", "unshaped")
#: Largest ``omega * duration`` (rad) at which V is evaluated (phase rounding ~ 1e-4 rad there).
PHASE_MAX = 1e12
#: Default relative tolerance of :func:`insensitivity` for humps above vtol (see there).
HUMP_TOL = 0.05
#: Most exponentials one call evaluates (about 2-4 s); larger requests are refused up front.
_WORK_MAX = 2e8
#: Most exponentials one insensitivity search evaluates (its grid times the shaper's terms).
_INS_WORK_MAX = 6e7


def _check_shaper(shaper: Any) -> Shaper:
    return v.instance_of(shaper, Shaper, "S", "a shaper (a posicast Shaper, from posicast.design)")


def _check_zeta(zeta: Any) -> float:
    return v.real_in_range(zeta, "zeta", 0.0, 1.0, hi_open=True) + 0.0


def _check_reference(reference: Any) -> str:
    return v.choice(reference, "reference", _REFERENCES)


def _n_terms(S: Shaper) -> int:
    """Exponentials per frequency point (the cost unit of an evaluation)."""
    if S.is_lumped:
        return max(1, S.n_impulses)
    tf = S.transfer
    return max(1, tf.num.delays.size + tf.den.delays.size) * 4


def _omega_max(S: Shaper) -> float:
    """Largest frequency at which V is evaluated: ``PHASE_MAX / span`` (and OMEGA_MAX)."""
    span = S.span
    return OMEGA_MAX if span <= 0 else min(OMEGA_MAX, PHASE_MAX / span)


def _scaled_quasi(q: Any, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``q(s) = val * e^c`` term by term, ``c`` the largest real exponent (no overflow)."""
    if q.is_zero:
        return np.zeros(s.shape, dtype=complex), np.zeros(s.shape)
    polys = P.polyval(s, q.coeffs.T)  # (m, N)
    e = -np.multiply.outer(q.delays, s)  # (m, N)
    c = np.max(e.real, axis=0)
    return np.sum(polys * np.exp(e - c), axis=0), c


def _abs_response(S: Shaper, p: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """``|S(p)| e^{shift}`` (``shift <= 0`` real), overflow-free where the value is representable."""
    if S.is_lumped:
        return np.abs(lumped_sum(S.times, S.amplitudes, p, shift))
    out = np.empty(p.shape)
    big = -p.real * S.span > 700.0  # e^{zeta omega t} would overflow: scale term by term
    with np.errstate(over="ignore", invalid="ignore", divide="ignore", under="ignore"):
        if np.any(~big):
            out[~big] = np.abs(np.asarray(S.transfer(p[~big]))) * np.exp(shift[~big])
        if np.any(big):
            tf = S.transfer
            pb = p[big]
            nv, nc = _scaled_quasi(tf.num, pb)
            dv, dc = _scaled_quasi(tf.den, pb)
            ratio = np.abs(nv / dv)
            expo = nc - dc + shift[big]
            out[big] = np.where(ratio > 0, np.exp(np.log(np.where(ratio > 0, ratio, 1.0)) + expo), 0.0)
    return out


@v.renamed_keywords(shaper="S")
def residual_vibration(S: Shaper, omega: Any, zeta: float | None = None, reference: str = "end") -> Any:
    """Residual vibration of a mode ``(omega, zeta)`` (or a :class:`~posicast.modes.Mode`) excited through the shaper ``S``.

    Parameters
    ----------
    S : Shaper
        Lumped, distributed or IIR shaper.
    omega : float or array_like or Mode
        Natural frequency (rad/s) of the actual mode: real, finite, > 0, and
        ``omega * duration <= 1e12`` (:data:`PHASE_MAX`); vectorised (non-empty).
        Or the actual mode as a :class:`~posicast.modes.Mode` (as :func:`posicast.design`
        takes it), and then no ``zeta``.
    zeta : float
        Damping ratio of the actual mode, ``0 <= zeta < 1`` (any value up to 1:
        the decay is folded into each term, see the module docstring).  Required
        with a numeric ``omega``.
    reference : {"end", "unshaped"}
        Normalisation, see the module docstring.  ``"end"`` needs a finite
        shaper duration.

    Returns
    -------
    float or ndarray
        ``V`` (0 = no vibration, 1 = as much as an unshaped step), the shape of ``omega``.

    Raises
    ------
    TypeError
        ``S`` not a Shaper; ``omega`` not real numbers (str, complex, bool);
        ``zeta`` or ``reference`` of the wrong type.
    ValueError
        ``omega`` empty, NaN/inf, <= 0 or above ``PHASE_MAX / duration``;
        ``zeta`` outside [0, 1); an unknown ``reference``; ``"end"`` for an IIR
        shaper; ``"unshaped"`` values beyond the float range; more than
        ``2e8`` exponentials in one call (pass fewer frequencies).

    Examples
    --------
    >>> from posicast import Mode, design
    >>> S = design("zv", Mode(10.0, 0.1))
    >>> float(residual_vibration(S, 10.0, 0.1)) < 1e-12
    True
    >>> float(residual_vibration(S, Mode(10.0, 0.1))) < 1e-12      # the same mode, as design takes it
    True
    >>> round(float(residual_vibration(design("zv", Mode(1.0, 0.0)), 1.1, 0.0)), 6)
    0.156434
    """
    S = _check_shaper(S)
    if isinstance(omega, Mode):
        if zeta is not None:
            raise TypeError("zeta must be omitted when the mode is given as a Mode (it carries its damping)")
        omega, zeta = omega.omega, omega.zeta
    elif zeta is None:
        raise TypeError("zeta is required with a numeric omega (or pass a posicast.Mode)")
    w = v.strict_real_array(omega, "omega")
    z = _check_zeta(zeta)
    ref = _check_reference(reference)
    return _vibration(S, w, z, ref, "omega", 1.0, np.ndim(omega) == 0)


def _vibration(S: Shaper, w: np.ndarray, z: float, ref: str, name: str, unit: float, scalar: bool) -> Any:
    """V at frequencies ``w`` (validated here; ``name``/``unit`` for messages: ``w = unit * name``)."""
    if np.any(w <= 0):
        raise ValueError(f"{name} must be > 0, got min {float(w.min()) / unit:g}")
    w_max = _omega_max(S)
    if np.any(w > w_max):
        raise ValueError(
            f"{name} must be <= {w_max / unit:.6g} for shaper {S.name!r} (omega * duration <= {PHASE_MAX:g}: "
            f"beyond, the phases omega * t_i are lost to rounding), got {float(w.max()) / unit:g}")
    if ref == "end" and not math.isfinite(S.duration):
        raise ValueError(f"shaper {S.name!r} has infinite duration (IIR part): use reference='unshaped'")
    work = float(w.size) * _n_terms(S)
    if work > _WORK_MAX:
        raise ValueError(
            f"{w.size} values of {name} x {_n_terms(S)} terms of shaper {S.name!r} = {work:.3g} exponentials "
            f"(about {work / 5e7:.0f} s) exceed the limit {_WORK_MAX:g}: pass fewer {name} values")
    flat = w.reshape(-1)
    p = flat * complex(-z, math.sqrt((1.0 - z) * (1.0 + z)))
    shift = -z * flat * S.duration if ref == "end" else np.zeros(flat.shape)
    mag = _abs_response(S, p, shift)
    bad = ~np.isfinite(mag)
    if np.any(bad):
        wb = float(flat[int(np.flatnonzero(bad)[0])])
        if ref == "unshaped":
            raise ValueError(
                f"the residual vibration of {S.name!r} relative to the unshaped response exceeds the float range "
                f"at {name}={wb / unit:g}, zeta={z:g} (|S(p)| grows like e^(zeta omega t_end)); "
                "use reference='end' or a smaller omega")
        raise ValueError(  # pragma: no cover - the scaled evaluation is finite
            f"the residual vibration of {S.name!r} cannot be evaluated at {name}={wb / unit:g}, zeta={z:g}")
    mag = mag.reshape(w.shape)
    return float(mag) if scalar else mag


def _design_mode(shaper: Shaper, mode: Mode | None) -> Mode:
    if mode is not None:
        return v.instance_of(mode, Mode, "mode", "a posicast.Mode")
    if len(shaper.modes) != 1:
        raise ValueError("shaper was designed for several modes (or none): pass mode= to choose one")
    return shaper.modes[0]


@dataclass(frozen=True)
class SensitivityCurve:
    """Residual vibration over normalised frequency ``omega / omega_model``.

    Attributes
    ----------
    ratio : ndarray
        ``omega / omega_model``.
    vibration : ndarray
        Residual vibration at each ratio.
    mode : Mode
        The model mode (``ratio = 1``).
    name : str
        The shaper's name.
    reference : str
        Normalisation used.
    """

    ratio: np.ndarray
    vibration: np.ndarray
    mode: Mode
    name: str
    reference: str

    def plot(self, ax: Any = None, **kwargs: Any) -> Any:
        """Draw on ``ax`` (created if None); returns ``(fig, ax)`` (:func:`~posicast.analysis.sensitivity_plot`)."""
        from .plots import sensitivity_plot  # cycle: plots imports this module

        return sensitivity_plot([self], ax=ax, **kwargs)


@v.renamed_keywords(shaper="S")
def sensitivity_curve(
    S: Shaper,
    ratio: Any = None,
    mode: Mode | None = None,
    reference: str = "end",
) -> SensitivityCurve:
    """Sensitivity curve of the shaper ``S`` around its design mode.

    Parameters
    ----------
    S : Shaper
    ratio : array_like, optional
        Frequency ratios ``omega / omega_model`` (finite, > 0, non-empty; flattened),
        default 801 points on [0, 2] (the first point is 1e-3 instead of 0).
    mode : Mode, optional
        Model mode; defaults to the (single) mode the shaper was designed for.
        The damping is held at the model value while the frequency varies.
    reference : {"end", "unshaped"}

    Examples
    --------
    >>> from posicast import Mode, design
    >>> c = sensitivity_curve(design("zvd", Mode(2.0, 0.0)), ratio=[0.9, 1.0, 1.1])
    >>> [round(float(x), 4) for x in c.vibration]
    [0.0245, 0.0, 0.0245]
    """
    S = _check_shaper(S)
    m = _design_mode(S, mode)
    ref = _check_reference(reference)
    if ratio is None:
        r = np.linspace(0.0, 2.0, 801)
        r[0] = 1e-3
    else:
        r = v.strict_real_array(ratio, "ratio").reshape(-1)
    vib = _vibration(S, r * m.omega, m.zeta, ref, "ratio", m.omega, False)
    return SensitivityCurve(r, np.asarray(vib), m, S.name, ref)


@dataclass(frozen=True)
class Insensitivity:
    """The band of ``omega / omega_model`` around the model where the residual vibration is tolerable.

    Attributes
    ----------
    width : float
        ``high - low`` (0 when ``V(model) > vtol (1 + hump_tol)``).
    low, high : float
        Band ends as ratios ``omega / omega_model``: points where ``V = vtol``
        (or the ends of the search range, see ``at_limit``).
    vtol : float
        The tolerance.
    hump_tol : float
        Relative height above ``vtol`` up to which a hump inside the band was
        bridged (see :func:`insensitivity`).
    peak, peak_at : float
        The largest ``V`` inside the band (the ends, where ``V = vtol``, excluded)
        and its ratio: a hump's top, refined by a bounded minimisation, or for a
        band without a hump a grid point next to an end, just below ``vtol``
        (for ``width = 0``: ``V`` at the model, ratio 1).
    bridged : bool
        True if the band contains a hump above ``vtol`` (by more than 1e-9
        relative, which counts as touching).
    excess : float
        ``max(0, peak - vtol)``: how far the bridged hump rises above ``vtol``
        (``excess / vtol`` relative).
    at_limit : bool
        True if the band reaches an end of the search range (``1e-3`` or ``max_ratio``).
    """

    width: float
    low: float
    high: float
    vtol: float
    hump_tol: float = 0.0
    peak: float = 0.0
    peak_at: float = 1.0
    bridged: bool = False
    excess: float = 0.0
    at_limit: bool = False


@v.renamed_keywords(shaper="S")
def insensitivity(
    S: Shaper,
    vtol: float = 0.05,
    mode: Mode | None = None,
    reference: str = "end",
    max_ratio: float = 10.0,
    hump_tol: float = HUMP_TOL,
) -> Insensitivity:
    """Insensitivity: the normalised width of the band around the model with ``V <= vtol``.

    **Definition.**  Let ``C`` be the connected interval of ratios
    ``r = omega / omega_model`` containing 1 on which ``V(r) <= vtol (1 + hump_tol)``
    (empty if ``V(1)`` is above that: width 0).  The band is the smallest
    interval containing 1 and every point of ``C`` with ``V <= vtol``; its ends
    are crossings ``V = vtol``.  So a hump inside the band whose height exceeds
    ``vtol`` by at most ``hump_tol * vtol`` is bridged (reported in ``bridged``,
    ``peak``, ``excess``), while a hump higher than that ends the band.  With
    ``hump_tol=0`` this is the strict definition (a hump touching ``vtol`` to
    1e-9 relative, as an exact EI's, still does not split the band).

    Why a tolerance: EI shapers are built to touch ``vtol`` with their hump, and
    any approximation of them rises slightly above it: the ``"singhose"`` EI by
    0.014 % (``zeta = 0.05``) to 1 % (``zeta = 0.3``), Singhose's curve fit by up
    to 1.3 % at ``vtol = 0.05`` and 4.6 % at ``vtol = 0.02`` or 0.15 (for
    ``zeta <= 0.2``).  The strict definition halves or zeroes their
    insensitivity for such an overshoot (``zeta = 0.05, vtol = 0.05``: fit 0.0
    and singhose 0.218 strictly, 0.433 and 0.432 here, the exact EI 0.433); the
    default ``hump_tol = 0.05`` bridges all of them and says so.

    Parameters
    ----------
    S : Shaper
    vtol : float
        Tolerable residual vibration, in (0, 1).
    mode : Mode, optional
        Model mode; defaults to the shaper's (single) design mode.
    reference : {"end", "unshaped"}
    max_ratio : float
        Right end of the search range (> 1; the left end is 1e-3).
    hump_tol : float
        Relative tolerance for humps above ``vtol``, in [0, 1]; default 0.05.

    Notes
    -----
    ``V`` is sampled on a grid (step ``1e-4`` up to ratio 2 and ``1e-3``
    beyond, finer for long shapers: at least 50 points per oscillation of
    ``V``), the crossings refined with Brent's method (~1e-12) and the peak
    with a bounded scalar minimisation.  A grid of more than ``6e7``
    exponentials is refused (lower ``max_ratio``).

    Examples
    --------
    >>> from posicast import Mode, design
    >>> ins = insensitivity(design("zv", Mode(1.0, 0.0)), 0.05)
    >>> round(ins.width, 4)                  # 2 arcsin(0.05) * 2 / pi
    0.0637
    >>> ins = insensitivity(design("ei", Mode(1.0, 0.05), method="singhose"), 0.05)
    >>> ins.bridged, round(ins.width, 3), round(ins.excess / ins.vtol, 5)
    (True, 0.432, 0.00014)
    """
    S = _check_shaper(S)
    m = _design_mode(S, mode)
    tol = v.real_in_range(vtol, "vtol", 0.0, 1.0, lo_open=True, hi_open=True)
    ref = _check_reference(reference)
    r_lim = _omega_max(S) / m.omega
    max_ratio = v.finite_real(max_ratio, "max_ratio")
    if not 1.0 < max_ratio <= r_lim:
        raise ValueError(f"max_ratio must be in (1, {r_lim:.6g}] for shaper {S.name!r}, got {max_ratio:g}")
    htol = v.real_in_range(hump_tol, "hump_tol", 0.0, 1.0)
    if ref == "end" and not math.isfinite(S.duration):
        raise ValueError(f"shaper {S.name!r} has infinite duration (IIR part): use reference='unshaped'")

    # grid: at least 50 points per oscillation of V (period ~ 2 pi / (omega_m span) in r)
    span = S.span
    osc = 2.0 * math.pi / (m.omega * span) if span > 0 else math.inf
    h1 = min(1e-4, osc / 50.0)
    h2 = min(1e-3, osc / 50.0)
    n_left = int(math.ceil((1.0 - 1e-3) / h1)) + 1
    n_mid = int(math.ceil(min(1.0, max_ratio - 1.0) / h1)) + 1
    n_far = int(math.ceil(max(0.0, max_ratio - 2.0) / h2)) + 1
    work = float(n_left + n_mid + n_far) * _n_terms(S)
    if work > _INS_WORK_MAX:
        raise ValueError(
            f"the insensitivity search of {S.name!r} up to max_ratio={max_ratio:g} needs "
            f"{n_left + n_mid + n_far:.3g} grid points x {_n_terms(S)} terms = {work:.3g} exponentials, above the "
            f"limit {_INS_WORK_MAX:g}: lower max_ratio")

    def V(r: Any) -> Any:
        rr = np.atleast_1d(np.asarray(r, dtype=float))
        out = _vibration(S, rr * m.omega, m.zeta, ref, "ratio", m.omega, False)
        return out if np.ndim(r) else float(out[0])

    touch = tol * (1.0 + 1e-9)
    level = tol * (1.0 + htol) + tol * 1e-9
    v1 = V(1.0)
    if v1 > level:
        return Insensitivity(0.0, 1.0, 1.0, tol, htol, v1, 1.0, False, max(0.0, v1 - tol), False)
    left = np.linspace(1.0, 1e-3, n_left)
    right = np.concatenate([np.linspace(1.0, 1.0 + min(1.0, max_ratio - 1.0), n_mid),
                            np.linspace(2.0, max_ratio, n_far)[1:] if max_ratio > 2.0 else np.zeros(0)])
    edges, limits, samples = [], [], []
    for grid in (left, right):
        vals = V(grid)
        over = np.flatnonzero(vals > level)
        stop = int(over[0]) if over.size else grid.size
        inside = np.flatnonzero(vals[:stop] <= touch)
        samples.append((grid[:stop], vals[:stop]))
        if inside.size == 0:  # V(1) above vtol and no point of this side back below it
            edges.append(1.0)
            limits.append(False)
            continue
        k = int(inside[-1])
        if k == grid.size - 1:
            edges.append(float(grid[k]))  # the band reaches the end of the search range
            limits.append(True)
            continue
        a, b = float(grid[k]), float(grid[k + 1])
        limits.append(False)
        if vals[k] >= tol:  # within the touching slack: the edge is a
            edges.append(a)
            continue
        edges.append(brentq(lambda r: V(r) - tol, a, b, xtol=1e-13, rtol=1e-13))
    lo, hi = min(edges), max(edges)
    # the tallest point of the band (its ends, where V = vtol, count only if nothing lies between them)
    rs = np.concatenate([samples[0][0], samples[1][0]])
    vs = np.concatenate([samples[0][1], samples[1][1]])
    keep = (rs > lo) & (rs < hi)
    rs, vs = (rs[keep], vs[keep]) if np.any(keep) else (np.array([lo, hi]), np.array([V(lo), V(hi)]))
    i = int(np.argmax(vs))
    peak, peak_at = float(vs[i]), float(rs[i])
    if lo < peak_at < hi:
        step = h1 if peak_at <= 2.0 else h2
        a, b = max(lo, peak_at - step), min(hi, peak_at + step)
        res = minimize_scalar(lambda r: -V(r), bounds=(a, b), method="bounded", options={"xatol": 1e-12})
        if -res.fun > peak:
            peak, peak_at = float(-res.fun), float(res.x)
    bridged = peak > touch
    return Insensitivity(hi - lo, lo, hi, tol, htol, peak, peak_at, bool(bridged), max(0.0, peak - tol),
                         bool(any(limits)))
