"""Extra-insensitive (EI) input shapers for damped modes, solved from their definitions.

Conventions
-----------
A lumped shaper is a train of impulses ``A_i delta(t - t_i)`` with ``t_1 = 0``,
sorted times and ``sum A_i = 1``; its transfer function is
``S(s) = sum_i A_i exp(-s t_i)``.  For a mode of natural frequency ``omega`` and
the design damping ``zeta`` (held at the model value while ``omega`` varies),
``p(omega) = -zeta omega + j omega sqrt(1 - zeta^2)`` and the residual vibration
(Singer-Seering form, seed 003 and seed 004 eq. 1-3, and the form Singhose's EI
curve fits use) is::

    V(omega) = exp(-zeta omega t_n) |S(p(omega))|,   t_n = last impulse time.

``omega_m = mode.omega`` is the modelled frequency and
``T_d = 2 pi / (omega_m sqrt(1 - zeta^2))`` the damped period.

Internally everything is dimensionless: frequencies are ratios
``r = omega / omega_m`` and times are in units of ``T_d``.  Then, with
``sigma = zeta / sqrt(1 - zeta^2)``::

    e^{-zeta omega t_n} S(p(omega)) = sum_i A_i exp(2 pi r sigma (t_i - t_n)) exp(-2 pi j r t_i)

so the designs depend on ``zeta`` only through ``sigma`` and scale with ``T_d``.

Definitions used here (all solved numerically: Newton's method with a
complex-step Jacobian, falling back on ``scipy.optimize.root`` (MINPACK
``hybrj``), started from a pseudo-arclength continuation of the solution curve
in ``zeta`` from the undamped closed form; residuals < 1e-12):

* **EI**, ``definition="singhose"`` (:func:`ei_exact` with that keyword,
  ``design("ei", mode, method="singhose")``): three impulses
  with ``t_3 = T_d`` fixed; unknowns ``A_1, A_3, t_2`` (``A_2 = 1 - A_1 - A_3``)
  and two zero frequencies ``omega_lo < omega_m < omega_hi``; equations
  ``V(omega_m) = vtol`` and ``S(p(omega_lo)) = S(p(omega_hi)) = 0`` (5 x 5).
  This is the shaper Singhose's published damped curve fit (:func:`ei_fit`)
  approximates: at ``vtol = 0.05, zeta = 0.3`` the fit's ``t_2/T_d = 0.53311``
  against 0.53351 here, whereas the "hump exactly at omega_m" variant gives
  ``t_2/T_d = 0.52064`` with ``t_3/T_d = 0.97657`` (fit: exactly 1); over
  ``zeta <= 0.3``, ``V <= 0.15`` the fit's times are 6x closer to this
  definition (max error 0.0065 T_d against 0.039 T_d).  For ``zeta > 0`` the
  hump of this shaper sits slightly *below* ``omega_m`` and peaks slightly
  above ``vtol`` (``zeta = 0.3``, ``vtol = 0.05``: 0.0505 at 0.976 omega_m).
* **EI**, ``definition="hump"`` (the *exact EI* of posicast: the default of
  :func:`ei_exact` and ``design("ei", mode, method="exact")``, which return the
  same shaper): three impulses, ``t_3`` free; the hump is
  exactly at ``omega_m``: ``V(omega_m) = vtol``, ``dV/domega(omega_m) = 0``,
  two exact zeros, ``sum A = 1`` (7 x 7).  Identical to the above at ``zeta = 0``.
* **2-hump EI** (:func:`ei_multi_hump`, ``humps=2``): four impulses; an exact
  zero at ``omega_m``, two humps (local maxima of ``V``) of height exactly
  ``vtol`` on either side, two exact zeros outside them (11 x 11 with
  ``sum A = 1``).
* **3-hump EI** (``humps=3``): five impulses; the middle hump exactly at
  ``omega_m`` (``V = vtol``, ``dV/domega = 0``), two side humps of height
  ``vtol``, four exact zeros between and outside them (15 x 15 with
  ``sum A = 1``).

The exact solvers need ``vtol >= 1e-6`` (:data:`EI_VTOL_MIN`): as ``vtol -> 0``
the two zeros of every family merge at ``omega_m`` (the shaper tends to ZVD,
ZVDD, ZVDDD) and the Jacobian of the constraint set becomes singular; below
about ``1e-8`` the solver fails.  Use ``design("zvd")`` etc. for that limit.

Existence.  Each family exists from ``zeta = 0`` up to a limit that falls as
``vtol`` grows (solutions whose outermost zero lies beyond 10 omega_m are not
returned: there the family degenerates, an impulse amplitude or spacing going
to zero while that zero runs off to infinite frequency).  With ``vtol = 0.05``
/ ``0.15``: EI 0.658 / 0.489, EI "hump" 0.659 / 0.491, 2-hump 0.425 / 0.2

Where it lives: this module holds the public functions and their argument checks;
:mod:`~posicast.shapers.ei_fit` the curve fit's coefficients;
:mod:`~posicast.shapers.ei_families` the definitions as equations;
:mod:`~posicast.shapers.ei_solver` the Newton/continuation solver.
"""

from __future__ import annotations

import math
from numbers import Integral, Real
from typing import Any

import numpy as np

from .. import _validate as _v
from ..modes import Mode
from .ei_families import FAMILIES, vibration
from .ei_fit import EI_FIT_VTOL_MAX, EI_FIT_ZETA_MAX, SEED004_PRINTED_EI_FIT, SINGHOSE_EI_FIT, eval_fit
from .ei_solver import sigma_of, solve, to_seconds
from .ei_solver import traces as _traces  # noqa: F401  (the warm-start cache; a test clears it)

__all__ = ["ei_fit", "ei_exact", "ei_multi_hump", "ei_fit_report",
           "EI_FIT_ZETA_MAX", "EI_FIT_VTOL_MAX", "EI_VTOL_MIN"]

#: Smallest vtol the exact solvers accept (see the module docstring).
EI_VTOL_MIN = 1e-6
#: Most damping ratios one ei_fit_report call solves for (about 10 ms each).
_REPORT_MAX_ZETAS = 1000


# ---------------------------------------------------------------------------
# validation
# ---------------------------------------------------------------------------


def _check_mode(mode: Any) -> Mode:
    return _v.instance_of(mode, Mode, "mode", "a posicast Mode")


def _check_vtol(vtol: Any, solver: bool = False) -> float:
    # not _validate.real: NaN and inf are out of (0, 1) here, with the interval in the message
    if isinstance(vtol, (bool, np.bool_)) or not isinstance(vtol, (Real, np.floating, np.integer)):
        raise TypeError(f"vtol must be a real number, got {type(vtol).__name__}")
    try:
        v = float(vtol)
    except OverflowError:  # an integer too large for a float
        v = math.inf
    if not (math.isfinite(v) and 0.0 < v < 1.0):
        raise ValueError(f"vtol must be in (0, 1), got {vtol!r}")
    if solver and v < EI_VTOL_MIN:
        raise ValueError(
            f"vtol must be in [{EI_VTOL_MIN:g}, 1) for the exact EI solvers, got {v:g} (as vtol -> 0 "
            "the EI zeros merge and the shaper tends to ZVD/ZVDD/ZVDDD: design those instead)")
    return v


def _check_humps(humps: Any) -> int:
    if isinstance(humps, (bool, np.bool_)) or not isinstance(humps, (Integral, np.integer)):
        raise ValueError(f"humps must be 2 or 3, got {humps!r}")
    if int(humps) not in (2, 3):
        raise ValueError(f"humps must be 2 or 3, got {humps!r}")
    return int(humps)


# ---------------------------------------------------------------------------
# public API
# ---------------------------------------------------------------------------


def ei_fit(mode: Mode, vtol: float, *, extrapolate: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Singhose's published curve fit of the damped EI shaper.

    Seed 004 eq. 8 prints this fit garbled; this is the corrected version
    (Singhose 2009 review), verified against :func:`ei_exact` with
    ``definition="singhose"`` (the EI with ``t_3 = T_d`` that the fit approximates)::

        A1 = 0.24968 + 0.24962 V + 0.80008 z + 1.23328 V z + 0.49599 z^2 + 3.17316 V z^2
        A3 = 0.25149 + 0.21474 V - 0.83249 z + 1.41498 V z + 0.85181 z^2 - 4.90094 V z^2
        A2 = 1 - (A1 + A3)
        t2 = (0.49990 + 0.46159 V z + 4.26169 V z^2 + 1.75601 V z^3
              + 8.57843 V^2 z - 108.644 V^2 z^2 + 336.989 V^2 z^3) T_d
        t1 = 0, t3 = T_d

    Parameters
    ----------
    mode : Mode
        The modelled mode (``z = mode.zeta``, ``T_d = mode.damped_period``).
    vtol : float
        Tolerable residual vibration at the modelled frequency, in (0, 1).
    extrapolate : bool, optional
        The fit is valid for ``0 <= zeta <= 0.3`` and ``vtol <= 0.15``;
        outside that range a ValueError is raised unless this is True.

    Returns
    -------
    times, amplitudes : numpy.ndarray
        Impulse times (s) and amplitudes (sum 1).

    Raises
    ------
    TypeError, ValueError
        Bad ``mode`` / ``vtol``, or outside the fit's range without ``extrapolate``.

    Examples
    --------
    >>> t, a = ei_fit(Mode(2 * math.pi, 0.1), 0.05)
    >>> [round(float(v), 4) for v in a], round(float(t[1]), 4)
    ([0.3549, 0.453, 0.1921], 0.5072)
    """
    _check_mode(mode)
    vtol = _check_vtol(vtol)
    if not extrapolate and (mode.zeta > EI_FIT_ZETA_MAX or vtol > EI_FIT_VTOL_MAX):
        raise ValueError(
            f"the EI curve fit is valid for 0 <= zeta <= {EI_FIT_ZETA_MAX} and 0 < vtol <= "
            f"{EI_FIT_VTOL_MAX}, got zeta={mode.zeta:g}, vtol={vtol:g}; use ei_exact "
            "(or extrapolate=True)")
    return eval_fit(SINGHOSE_EI_FIT, mode, vtol)


def _seed004_printed_ei_fit(mode: Mode, vtol: float) -> tuple[np.ndarray, np.ndarray]:
    """Seed 004 eq. 8 as printed (wrong; used by a test that shows it)."""
    _check_mode(mode)
    return eval_fit(SEED004_PRINTED_EI_FIT, mode, _check_vtol(vtol))


def ei_exact(mode: Mode, vtol: float, *, definition: str = "hump"
             ) -> tuple[np.ndarray, np.ndarray]:
    """Damped EI shaper solved numerically from its definition.

    ``definition="hump"`` (default; the same shaper as
    ``design("ei", mode, vtol=vtol, method="exact")``): three impulses, ``t_3``
    free, ``V(omega_m) = vtol`` and ``dV/domega(omega_m) = 0`` (the hump of
    height ``vtol`` exactly at the model frequency), exact zeros
    ``S(p(omega_lo)) = S(p(omega_hi)) = 0`` with ``omega_lo < omega_m < omega_hi``.
    ``definition="singhose"`` (``method="singhose"`` in :func:`posicast.design`):
    ``t_3 = T_d`` fixed instead of ``dV/domega(omega_m) = 0``; this is what
    Singhose's curve fit (:func:`ei_fit`) approximates, and its hump sits
    slightly below ``omega_m`` and above ``vtol`` when ``zeta > 0``.
    Both reduce at ``zeta = 0`` to ``A = [(1+V)/4, (1-V)/2, (1+V)/4]``,
    ``t = [0, T/2, T]`` (seed 002 eq. 3).

    Solved numerically (Newton / ``scipy.optimize.root``) from a point of the
    solution curve traced from the undamped closed form by continuation in
    ``zeta``; the traced curve is cached per ``vtol`` as a warm start only:
    every answer is solved for the exact inputs (residuals < 1e-12).  See the
    module docstring for the ``zeta`` range where each definition has a
    solution.

    Parameters
    ----------
    mode : Mode
        The modelled mode.
    vtol : float
        Residual vibration at the modelled frequency, in ``[1e-6, 1)``.
    definition : {"hump", "singhose"}, optional
        Which EI definition (see above); default ``"hump"``.

    Returns
    -------
    times, amplitudes : numpy.ndarray
        Impulse times (s) and nonnegative amplitudes (sum 1).

    Raises
    ------
    TypeError
        ``mode`` not a Mode, ``vtol`` not a real number, ``definition`` not a string.
    ValueError
        Bad ``vtol``/``definition``, or no admissible shaper exists for this
        ``zeta`` (the message gives the ``zeta`` range that works).

    Examples
    --------
    >>> t, a = ei_exact(Mode(2 * math.pi, 0.0), 0.05)
    >>> [round(float(v), 6) for v in a], [round(float(v), 6) for v in t]
    ([0.2625, 0.475, 0.2625], [0.0, 0.5, 1.0])
    >>> t, a = ei_exact(Mode(2 * math.pi, 0.2), 0.05, definition="singhose")
    >>> round(float(a[0]), 4), round(float(t[1] / Mode(2 * math.pi, 0.2).damped_period), 4)
    (0.4613, 0.514)
    >>> t, a = ei_exact(Mode(2 * math.pi, 0.2), 0.05)      # hump at omega_m: t_3 < T_d
    >>> round(float(t[2] / Mode(2 * math.pi, 0.2).damped_period), 5)
    0.98872
    """
    _check_mode(mode)
    vtol = _check_vtol(vtol, solver=True)
    keys = {"singhose": "ei", "hump": "ei_hump"}
    _v.choice(definition, "definition", ("hump", "singhose"))
    prob = FAMILIES[keys[definition]]
    return to_seconds(prob, solve(keys[definition], mode.zeta, vtol), mode)


def ei_multi_hump(mode: Mode, vtol: float, humps: int) -> tuple[np.ndarray, np.ndarray]:
    """Damped 2-hump or 3-hump EI shaper solved from its definition.

    * ``humps=2``: four impulses; ``S(p(omega_m)) = 0``; two humps (local
      maxima of ``V``) of height exactly ``vtol`` below and above ``omega_m``;
      two exact zeros outside them; ``sum A = 1`` (11 equations, 11 unknowns:
      4 amplitudes, ``t_2..t_4``, 2 hump and 2 zero frequencies).  Undamped:
      ``X = (V^2 (sqrt(1 - V^2) + 1))^(1/3)``, ``A1 = A4 = (3X^2 + 2X + 3V^2)/(16X)``,
      ``A2 = A3 = 1/2 - A1``, ``t = [0, T/2, T, 3T/2]``.
    * ``humps=3``: five impulses; the middle hump exactly at ``omega_m``
      (``V = vtol``, ``dV/domega = 0``); side humps of height ``vtol``; four exact
      zeros; ``sum A = 1`` (15 equations, 15 unknowns: 5 amplitudes, ``t_2..t_5``,
      2 side-hump and 4 zero frequencies).  Undamped:
      ``A1 = A5 = (1 + 3V + 2 sqrt(2V(V+1)))/16``, ``A2 = A4 = (1 - V)/4``,
      ``A3 = 1 - 2(A1 + A2)``, ``t = [0, T/2, T, 3T/2, 2T]``.

    Solved like :func:`ei_exact` (continuation in ``zeta`` from the undamped
    closed form, residuals < 1e-12).  Exists for ``zeta`` up to 0.425 (2 humps)
    / 0.306 (3 humps) at ``vtol = 0.05`` and 0.277 / 0.191 at ``vtol = 0.15``.

    Parameters
    ----------
    mode : Mode
        The modelled mode.
    vtol : float
        Height of the humps, in ``[1e-6, 1)``.
    humps : int
        2 or 3.

    Returns
    -------
    times, amplitudes : numpy.ndarray
        Impulse times (s) and nonnegative amplitudes (sum 1).

    Raises
    ------
    ValueError
        Bad ``vtol``/``humps``, or no admissible shaper exists for this
        ``zeta`` (the message gives the ``zeta`` range that works).

    Examples
    --------
    >>> t, a = ei_multi_hump(Mode(2 * math.pi, 0.0), 0.05, 3)
    >>> len(t), round(float(t[-1]), 9), round(float(a.sum()), 12)
    (5, 2.0, 1.0)
    >>> t, a = ei_multi_hump(Mode(2 * math.pi, 0.1), 0.05, 2)
    >>> bool(np.all(a >= 0)), round(float(t[-1]), 3)
    (True, 1.489)
    """
    _check_mode(mode)
    vtol = _check_vtol(vtol, solver=True)
    key = {2: "2hump", 3: "3hump"}[_check_humps(humps)]
    return to_seconds(FAMILIES[key], solve(key, mode.zeta, vtol), mode)


def ei_fit_report(vtol: float = 0.05, zetas: Any = None) -> dict[str, np.ndarray]:
    """How far Singhose's EI curve fit is from the exact EI over ``zeta``.

    Parameters
    ----------
    vtol : float, optional
        Residual vibration tolerance, in ``[1e-6, 1)`` (the fit is meant for <= 0.15).
    zetas : array_like, optional
        Damping ratios in [0, 1), at most 1000 of them; default ``numpy.linspace(0, 0.3, 31)``.

    Returns
    -------
    dict
        ``"zeta"``; ``"max_abs_amplitude_error"`` (max over the three
        impulses of ``|A_fit - A_exact|``); ``"max_abs_time_error"``
        (``max |t_fit - t_exact| / T_d``); ``"v_at_model"`` (``V(omega_m)`` of
        the fit, ideally ``vtol``); ``"v_peak"`` (the height of the fit's hump:
        its largest ``V`` between the exact shaper's two zero frequencies);
        ``"exact_v_peak"`` (the same for the exact shaper, which has
        ``V(omega_m) = vtol`` but its hump slightly below ``omega_m`` and
        slightly above ``vtol`` when ``zeta > 0``); and ``"vtol"`` (0-d array).  The
        exact shaper is :func:`ei_exact` with ``definition="singhose"``.

    Examples
    --------
    >>> rep = ei_fit_report(0.05, [0.0, 0.1, 0.3])
    >>> bool(np.all(rep["max_abs_amplitude_error"] < 3e-3))
    True
    >>> [round(float(v), 4) for v in rep["v_at_model"]]
    [0.0488, 0.0506, 0.048]
    """
    vtol = _check_vtol(vtol, solver=True)
    if zetas is None:
        zetas = np.linspace(0.0, 0.3, 31)
    z = np.atleast_1d(_v.strict_real_array(zetas, "zetas"))
    if z.ndim != 1 or np.any(z < 0) or np.any(z >= 1):
        raise ValueError("zetas must be a 1-D array of damping ratios in [0, 1)")
    if z.size > _REPORT_MAX_ZETAS:
        raise ValueError(f"zetas has {z.size} entries (one EI solve each, about {0.01 * z.size:.0f} s); "
                         f"at most {_REPORT_MAX_ZETAS} are accepted: pass fewer zetas")
    da, dt, v_m, v_pk, v_ex = (np.empty(z.size) for _ in range(5))
    for k, zk in enumerate(z):
        m = Mode(1.0, float(zk))
        tf, af = ei_fit(m, vtol, extrapolate=True)
        x = solve("ei", float(zk), vtol)
        te, ae = to_seconds(FAMILIES["ei"], x, m)
        td = m.damped_period
        da[k] = np.max(np.abs(af - ae))
        dt[k] = np.max(np.abs(tf - te)) / td
        s = sigma_of(float(zk))
        v_m[k] = vibration(1.0, af, tf / td, s)[0]
        lo, hi = FAMILIES["ei"].zeros(x)  # the exact shaper's zeros bracket the hump
        band = np.linspace(lo, hi, 2001)
        v_pk[k] = np.max(vibration(band, af, tf / td, s))
        v_ex[k] = np.max(vibration(band, ae, te / td, s))
    return {"zeta": z, "max_abs_amplitude_error": da, "max_abs_time_error": dt,
            "v_at_model": v_m, "v_peak": v_pk, "exact_v_peak": v_ex, "vtol": np.asarray(vtol)}
