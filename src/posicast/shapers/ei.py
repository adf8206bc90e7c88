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
/ ``0.15``: EI 0.658 / 0.489, EI "hump" 0.659 / 0.491, 2-hump 0.425 / 0.277,
3-hump 0.306 / 0.191.  Beyond it a ValueError names the range.  Some curves
have a small S-bend near their end (e.g. 2-hump, ``vtol = 0.15``:
``0.2374 < zeta < 0.2402``; 3-hump, ``vtol = 0.05``: ``0.2753 < zeta < 0.2756``)
where three solutions coexist; the one reached first along the curve from
``zeta = 0`` is returned, and past the bend the outermost zero lies above
``2.5 omega_m``.

Sources: undamped EI closed form seed 002 eq. 3; damped EI curve fit seed 004
eq. 8 (printed with errors, see :data:`_SINGHOSE_EI_FIT`) and Singhose 2009
review ("Command shaping for flexible systems: a review of the first 50
years", Int. J. Precision Engineering and Manufacturing 10(4)); multi-hump EI
shapers, seed 004 ref. [15] (Singhose, Porter, Tuttle, Singer 1997).
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass
from numbers import Integral, Real
from typing import Any, Callable

import numpy as np
from scipy.optimize import root

from .. import _validate as _v
from ..modes import Mode

__all__ = ["ei_fit", "ei_exact", "ei_multi_hump", "ei_fit_report",
           "EI_FIT_ZETA_MAX", "EI_FIT_VTOL_MAX", "EI_VTOL_MIN"]

_TWO_PI = 2.0 * math.pi

#: Validity range of Singhose's damped EI curve fit (Singhose 2009 review).
EI_FIT_ZETA_MAX = 0.3
EI_FIT_VTOL_MAX = 0.15
#: Smallest vtol the exact solvers accept (see the module docstring).
EI_VTOL_MIN = 1e-6
#: Most damping ratios one ei_fit_report call solves for (about 10 ms each).
_REPORT_MAX_ZETAS = 1000

# ---------------------------------------------------------------------------
# Singhose's damped EI curve fit and the garbled copy printed in seed 004 eq. 8
# ---------------------------------------------------------------------------
#
# Each entry is a list of (coefficient, power of V, power of zeta).
#
# Seed 004 eq. 8 prints this fit with three transcription errors.  Compared
# with the version below (Singhose 2009 review; the same numbers are in
# Klipper's klippy/extras/shaper_defs.py, which writes 0.24961 for the V term
# of A1 - a 1e-5 difference that changes nothing below), the seed:
#   * A1: prints "0.80008 V zeta" and drops the "1.23328 V zeta" term; the
#     correct terms are "0.80008 zeta + 1.23328 V zeta" (the seed has no
#     first-order zeta term at all in A1);
#   * t2: drops the "4.26169 V zeta^2" term and prints "36.989 V^2 zeta^2"
#     where the fit has "336.989 V^2 zeta^3";
#   * A3: prints -4.9009 for -4.90094 (rounding only, harmless).
# How we know: ei_exact (the definition, solved to ~1e-15) against both sets,
# max over zeta in [0, 0.3] (61 points) and V in {0.02, 0.05, 0.1, 0.15}:
#                      max |dA|   max |dt|/T_d   max |V(omega_m) - vtol|
#   corrected fit       0.0096      0.0065         0.0084   (V = 0.05: 0.0025,
#                                                             0.0004, 0.0020)
#   seed 004 as printed 0.257       0.186          0.136
# The corrected fit is as good as a fit can be (its error at zeta = 0, where
# the exact EI is the closed form, is already 0.0084 in V at V = 0.15); the
# printed one is not: at zeta = 0.2, V = 0.05 it gives A1 = 0.2963 (exact
# 0.4613: the missing 0.80008 zeta (1 - V) + 1.23328 V zeta = 0.165 is the
# damping compensation of the first impulse), t2/T_d = 0.5023 (exact 0.5140)
# and V(omega_m) = 0.0846 instead of 0.05.  Swapping one formula at a time
# (same grid): the printed A1 alone raises max |dA| to 0.257 and max |dV| to
# 0.100; the printed t2 alone raises max |dt|/T_d to 0.186 and max |dV| to
# 0.015; the printed A3 (rounding) changes nothing at 4 decimals.
_SINGHOSE_EI_FIT: dict[str, list[tuple[float, int, int]]] = {
    "A1": [(0.24968, 0, 0), (0.24962, 1, 0), (0.80008, 0, 1), (1.23328, 1, 1),
           (0.49599, 0, 2), (3.17316, 1, 2)],
    "A3": [(0.25149, 0, 0), (0.21474, 1, 0), (-0.83249, 0, 1), (1.41498, 1, 1),
           (0.85181, 0, 2), (-4.90094, 1, 2)],
    "t2": [(0.49990, 0, 0), (0.46159, 1, 1), (4.26169, 1, 2), (1.75601, 1, 3),
           (8.57843, 2, 1), (-108.644, 2, 2), (336.989, 2, 3)],
}

# Seed 004 eq. 8 exactly as printed (kept only to demonstrate that it is wrong).
_SEED004_PRINTED_EI_FIT: dict[str, list[tuple[float, int, int]]] = {
    "A1": [(0.24968, 0, 0), (0.24962, 1, 0), (0.80008, 1, 1), (0.49599, 0, 2),
           (3.17316, 1, 2)],
    "A3": [(0.25149, 0, 0), (0.21474, 1, 0), (-0.83249, 0, 1), (1.41498, 1, 1),
           (0.85181, 0, 2), (-4.9009, 1, 2)],
    "t2": [(0.49990, 0, 0), (0.46159, 1, 1), (1.75601, 1, 3), (8.57843, 2, 1),
           (-108.644, 2, 2), (36.989, 2, 2)],
}


def _poly(terms: list[tuple[float, int, int]], v: float, z: float) -> float:
    return float(sum(c * v**i * z**j for c, i, j in terms))


def _eval_fit(coeffs: dict[str, list[tuple[float, int, int]]], mode: Mode,
              vtol: float) -> tuple[np.ndarray, np.ndarray]:
    z = mode.zeta
    a1 = _poly(coeffs["A1"], vtol, z)
    a3 = _poly(coeffs["A3"], vtol, z)
    td = mode.damped_period
    times = np.array([0.0, _poly(coeffs["t2"], vtol, z) * td, td])
    return times, np.array([a1, 1.0 - (a1 + a3), a3])


def _seed004_printed_ei_fit(mode: Mode, vtol: float) -> tuple[np.ndarray, np.ndarray]:
    """Seed 004 eq. 8 as printed (wrong; used by a test that shows it)."""
    _check_mode(mode)
    return _eval_fit(_SEED004_PRINTED_EI_FIT, mode, _check_vtol(vtol))


# ---------------------------------------------------------------------------
# validation
# ---------------------------------------------------------------------------


def _check_mode(mode: Any) -> Mode:
    if not isinstance(mode, Mode):
        raise TypeError(f"mode must be a posicast Mode, got {type(mode).__name__}")
    return mode


def _check_vtol(vtol: Any, solver: bool = False) -> float:
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
# the residual vibration in dimensionless form (works on complex inputs too,
# which is how the Jacobian is obtained: complex-step differentiation)
# ---------------------------------------------------------------------------


def _response(r: Any, amps: Any, times: Any, sigma: float):
    """``e^{-zeta omega t_n} S(p(omega))`` and its r-derivative, as real/imag parts.

    ``r``: frequency ratios, shape ``(..., m)``; ``amps``, ``times``: shape
    ``(..., n)`` (times in units of T_d); results have shape ``(..., m)``.
    Written with real arithmetic only so that it is complex-analytic in every
    argument (complex-step Jacobians).
    """
    r = r[..., :, None]
    t = times[..., None, :]
    dec = sigma * (t - t[..., -1:])
    e = amps[..., None, :] * np.exp(_TWO_PI * r * dec)
    c = np.cos(_TWO_PI * r * t)
    s = np.sin(_TWO_PI * r * t)
    re = (e * c).sum(-1)
    im = -(e * s).sum(-1)
    dre = _TWO_PI * (e * (dec * c - t * s)).sum(-1)
    dim = -_TWO_PI * (e * (dec * s + t * c)).sum(-1)
    return re, im, dre, dim


def _vib(r: Any, amps: np.ndarray, times: np.ndarray, sigma: float) -> np.ndarray:
    """Real V at frequency ratios ``r`` (1-D; times in units of T_d)."""
    re, im, _, _ = _response(np.atleast_1d(np.asarray(r, dtype=float)), amps, times, sigma)
    return np.hypot(re, im)


# ---------------------------------------------------------------------------
# the problems: unknown vector layout, residual, undamped closed form
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class _Problem:
    """One shaper family.

    ``unpack(x) -> (times, amps)``.  ``freq_index``: where in ``x`` each
    constrained frequency ratio sits (-1: the model frequency, ratio 1), in
    the order: ``n_hump`` humps (``V = vtol`` and ``dV/dr = 0``), ``n_zero``
    exact zeros (``Re = Im = 0``), ``n_vonly`` points with ``V = vtol`` only.
    ``sum_eq``: whether ``sum A = 1`` is an equation (else built into unpack).
    """

    name: str
    unpack: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
    initial: Callable[[float], np.ndarray]
    freq_index: tuple[int, ...]
    n_hump: int
    n_zero: int
    n_vonly: int
    sum_eq: bool

    def freqs(self, x: np.ndarray) -> np.ndarray:
        idx = np.array(self.freq_index)
        return np.where(idx < 0, 1.0, x[..., np.maximum(idx, 0)])

    def residual(self, x: np.ndarray, sigma: float, vtol: float) -> np.ndarray:
        times, amps = self.unpack(x)
        re, im, dre, dim = _response(self.freqs(x), amps, times, sigma)
        h, z = slice(0, self.n_hump), slice(self.n_hump, self.n_hump + self.n_zero)
        o = slice(self.n_hump + self.n_zero, None)
        parts = [amps.sum(-1, keepdims=True) - 1.0] if self.sum_eq else []
        v = np.sqrt(re[..., h] ** 2 + im[..., h] ** 2)
        parts += [v - vtol, (re[..., h] * dre[..., h] + im[..., h] * dim[..., h]) / v]
        parts += [re[..., z], im[..., z]]
        parts += [np.sqrt(re[..., o] ** 2 + im[..., o] ** 2) - vtol]
        return np.concatenate(parts, axis=-1)

    def humps(self, x: np.ndarray) -> np.ndarray:
        return np.sort(self.freqs(x)[: self.n_hump])

    def zeros(self, x: np.ndarray) -> np.ndarray:
        return np.sort(self.freqs(x)[self.n_hump: self.n_hump + self.n_zero])


# EI, definition "singhose": x = [A1, A3, t2, r_lo, r_hi]; A2 = 1 - A1 - A3, t3 = 1
def _ei_b_unpack(x):
    a1, a3, t2 = x[..., 0], x[..., 1], x[..., 2]
    amps = np.stack([a1, 1.0 - a1 - a3, a3], axis=-1)
    times = np.stack([0.0 * t2, t2, 0.0 * t2 + 1.0], axis=-1)
    return times, amps


def _ei_zero0(vtol: float) -> float:
    # undamped: |S| = |(1 - V)/2 + (1 + V)/2 cos(pi r)| vanishes at cos(pi r) = -(1-V)/(1+V)
    return math.acos(-(1.0 - vtol) / (1.0 + vtol)) / math.pi


def _ei_b_initial(vtol):
    rl = _ei_zero0(vtol)
    return np.array([(1 + vtol) / 4, (1 + vtol) / 4, 0.5, rl, 2.0 - rl])


# EI, definition "hump": x = [A1, A2, A3, t2, t3, r_lo, r_hi]
def _ei_a_unpack(x):
    t2, t3 = x[..., 3], x[..., 4]
    return np.stack([0.0 * t2, t2, t3], axis=-1), x[..., 0:3]


def _ei_a_initial(vtol):
    rl = _ei_zero0(vtol)
    return np.array([(1 + vtol) / 4, (1 - vtol) / 2, (1 + vtol) / 4, 0.5, 1.0, rl, 2.0 - rl])


# 2-hump EI: x = [A1..A4, t2, t3, t4, r_h1, r_h2, r_z1, r_z2]
def _h2_unpack(x):
    t = x[..., 4:7]
    return np.concatenate([0.0 * t[..., :1], t], axis=-1), x[..., 0:4]


def _h2_closed_form(vtol: float) -> np.ndarray:
    """Undamped 2-hump EI amplitudes (Singhose et al. 1997)."""
    x = (vtol**2 * (math.sqrt(1.0 - vtol**2) + 1.0)) ** (1.0 / 3.0)
    a1 = (3 * x * x + 2 * x + 3 * vtol**2) / (16 * x)
    return np.array([a1, 0.5 - a1, 0.5 - a1, a1])


def _h2_initial(vtol):
    amps = _h2_closed_form(vtol)
    a1 = amps[0]
    # undamped: S ~ c (8 A1 c^2 + 1 - 8 A1), c = cos(pi r / 2)
    ch = math.sqrt((8 * a1 - 1) / (24 * a1))
    cz = math.sqrt((8 * a1 - 1) / (8 * a1))
    rh = 2 * math.acos(ch) / math.pi
    rz = 2 * math.acos(cz) / math.pi
    return np.concatenate([amps, [0.5, 1.0, 1.5, rh, 2 - rh, rz, 2 - rz]])


# 3-hump EI: x = [A1..A5, t2..t5, r_h1, r_h3, r_z1..r_z4]
def _h3_unpack(x):
    t = x[..., 5:9]
    return np.concatenate([0.0 * t[..., :1], t], axis=-1), x[..., 0:5]


def _h3_closed_form(vtol: float) -> np.ndarray:
    """Undamped 3-hump EI amplitudes (Singhose et al. 1997)."""
    a1 = (1 + 3 * vtol + 2 * math.sqrt(2 * vtol * (vtol + 1))) / 16
    a2 = (1 - vtol) / 4
    return np.array([a1, a2, 1 - 2 * (a1 + a2), a2, a1])


def _h3_initial(vtol):
    amps = _h3_closed_form(vtol)
    a1, a2, a3 = amps[:3]
    # undamped: S ~ a3 + 2 a2 y + 2 a1 (2 y^2 - 1), y = cos(pi r)
    ys = -a2 / (4 * a1)  # dG/dy = 0
    disc = math.sqrt(4 * a2 * a2 - 16 * a1 * (a3 - 2 * a1))
    y_hi, y_lo = (-2 * a2 + disc) / (8 * a1), (-2 * a2 - disc) / (8 * a1)
    rh = math.acos(ys) / math.pi
    rz1, rz2 = math.acos(y_hi) / math.pi, math.acos(y_lo) / math.pi
    return np.concatenate([amps, [0.5, 1.0, 1.5, 2.0, rh, 2 - rh, rz1, rz2, 2 - rz2, 2 - rz1]])


# Equation counts: EI 1 + 2*2 = 5 = 5 unknowns; EI "hump" 1 + 2 + 2*2 = 7;
# 2-hump 1 + 2 (zero at omega_m) + 2*2 (humps) + 2*2 (outer zeros) = 11;
# 3-hump 1 + 3*2 (humps) + 4*2 (zeros) = 15.
_PROBLEMS = {
    "ei": _Problem("EI", _ei_b_unpack, _ei_b_initial, (3, 4, -1), 0, 2, 1, False),
    "ei_hump": _Problem("EI (hump at omega_m)", _ei_a_unpack, _ei_a_initial,
                        (-1, 5, 6), 1, 2, 0, True),
    "2hump": _Problem("2-hump EI", _h2_unpack, _h2_initial, (7, 8, -1, 9, 10), 2, 3, 0, True),
    "3hump": _Problem("3-hump EI", _h3_unpack, _h3_initial,
                      (-1, 9, 10, 11, 12, 13, 14), 3, 4, 0, True),
}


# Zero frequencies are kept below _R_MAX omega_m: near the end of some
# families the outermost zero runs off to infinity (the shaper degenerates:
# its last impulse amplitude or spacing goes to zero).
_R_MAX = 10.0


def _invalid_reason(prob: _Problem, x: np.ndarray, sigma: float, vtol: float) -> str | None:
    """None if ``x`` is an admissible shaper of the family, else why not."""
    if not np.all(np.isfinite(x)):
        return "the solver diverged"
    times, amps = prob.unpack(x)
    if np.any(amps < -1e-12):
        return "an impulse amplitude would go negative"
    if np.any(np.diff(times) <= 0):
        return "the impulse times would stop being increasing"
    # zeros (z) and humps (h) interlaced, at distinct positive frequencies below _R_MAX
    z, h = prob.zeros(x), prob.humps(x)
    pts = np.sort(np.concatenate([z, h]))
    if pts[-1] >= _R_MAX:
        return (f"the outermost zero of V runs off to infinite frequency (past {_R_MAX:g} "
                "omega_m)")
    if pts[0] <= 0.05 or np.any(np.diff(pts) <= 1e-9):
        return "the solver left the branch"
    lab = np.concatenate([np.zeros(len(z)), np.ones(len(h))])[np.argsort(np.concatenate([z, h]))]
    if len(h) and np.any(np.diff(lab) == 0):  # zeros and humps must alternate
        return "the solver left the branch"
    if not (np.sum(z < 1.0 - 1e-12) >= 1 and np.sum(z > 1.0 + 1e-12) >= 1):
        return "the solver left the branch"
    # the humps must be local maxima of V, and the tallest points of the band
    # between the outermost zeros
    if len(h):
        d = 1e-4
        for rh in h:
            vv = _vib(np.array([rh - d, rh, rh + d]), amps, times, sigma)
            if not (vv[1] >= vv[0] and vv[1] >= vv[2]):
                return "a constrained hump is not a local maximum"
        band = _vib(np.linspace(z[0], z[-1], 1001), amps, times, sigma)
        if np.max(band) > vtol * (1.0 + 1e-6):
            return "V would exceed vtol between the outer zeros"
    return None


# ---------------------------------------------------------------------------
# the solver: Newton / hybrj at fixed zeta, pseudo-arclength continuation in zeta
# ---------------------------------------------------------------------------

_TOL = 1e-12  # residual tolerance (dimensionless)
_H_MAX = 0.08  # largest arclength step along a solution curve
_H_MIN = 1e-7
_MAX_POINTS = 600
_CACHE_SIZE = 64  # traced curves kept (one per family and vtol)


def _fun_jac(prob: _Problem, sigma: float, vtol: float):
    """Residual and complex-step Jacobian in ``x`` at fixed ``sigma``."""

    def fj(x):
        n = x.size
        h = 1e-30
        xx = np.empty((n + 1, n), dtype=complex)
        xx[:] = x
        xx[1:] += 1j * h * np.eye(n)
        rr = prob.residual(xx, sigma, vtol)
        return rr[0].real, (rr[1:].imag / h).T

    return fj


def _aug_fun_jac(prob: _Problem, vtol: float):
    """Residual and complex-step Jacobian in ``y = (x, sigma)`` (n x (n + 1))."""

    def fj(y):
        n1 = y.size
        h = 1e-30
        yy = np.empty((n1 + 1, n1), dtype=complex)
        yy[:] = y
        yy[1:] += 1j * h * np.eye(n1)
        rr = prob.residual(yy[:, :-1], yy[:, -1][:, None, None], vtol)
        return rr[0].real, (rr[1:].imag / h).T

    return fj


def _newton(fj, x: np.ndarray, maxit: int) -> tuple[np.ndarray, np.ndarray]:
    """Newton's method with step halving; stops when the residual stops decreasing."""
    f, jac = fj(x)
    for _ in range(maxit):
        norm = np.max(np.abs(f))
        if not np.isfinite(norm) or norm < 1e-15:
            break
        try:
            dx = np.linalg.solve(jac, -f)
        except np.linalg.LinAlgError:
            break
        step = 1.0
        while step > 0.1:
            xn = x + step * dx
            fn, jn = fj(xn)
            if np.max(np.abs(fn)) < norm:  # False for NaN
                break
            step *= 0.5
        else:
            break
        x, f, jac = xn, fn, jn
    return x, f


def _solve_at(prob: _Problem, x0: np.ndarray, sigma: float, vtol: float
              ) -> tuple[np.ndarray | None, str | None]:
    """Solve the square system at fixed ``(sigma, vtol)`` from ``x0``.

    Damped Newton first (cheap from a point on the traced curve); if it
    stalls, MINPACK's hybrj (``scipy.optimize.root``, method "hybr") from
    ``x0``, polished by Newton.  Accepts only residuals below ``_TOL`` and
    admissible shapers.
    """
    fj = _fun_jac(prob, sigma, vtol)
    with np.errstate(all="ignore"):
        x, f = _newton(fj, x0, 8)
        if not np.max(np.abs(f)) < _TOL:
            try:
                sol = root(fj, x0, jac=True, method="hybr", options={"xtol": 1e-14, "maxfev": 40})
            except (np.linalg.LinAlgError, ValueError):
                return None, "the solver failed"
            x, f = _newton(fj, sol.x, 4)
    if not np.max(np.abs(f)) < _TOL:
        return None, "the solver failed to converge"
    reason = _invalid_reason(prob, x, sigma, vtol)
    return (None, reason) if reason else (x, None)


# --- pseudo-arclength continuation of the solution curve from zeta = 0 -------------
#
# For one family and one vtol the solutions form a curve y(s) = (x(s), sigma(s))
# starting at the undamped closed form (sigma = 0).  The curve is traced by
# arclength (so it is followed through turning points), and a request for
# sigma is answered on the *first* stretch of the curve that reaches sigma:
# the answer is the solution connected to the undamped closed form, whatever
# was asked before.  (Some curves have a small S-bend, e.g. the 2-hump EI with
# vtol = 0.1 near zeta = 0.29, where three solutions coexist for a 3e-4 wide
# range of zeta; there the first one along the curve is returned.)


@dataclass
class _Trace:
    sig: list[float]
    xs: list[np.ndarray]
    tau: np.ndarray  # unit tangent at the last point, oriented along the curve
    h: float
    end: str | None = None  # why the curve ends (None: not reached yet)


_traces: OrderedDict[tuple[str, float], _Trace] = OrderedDict()


def _tangent(jac: np.ndarray, tau_prev: np.ndarray) -> np.ndarray:
    a = np.vstack([jac, tau_prev])
    b = np.zeros(len(tau_prev))
    b[-1] = 1.0
    t = np.linalg.solve(a, b)
    return t / np.linalg.norm(t)


def _correct(fj, yp: np.ndarray, tau: np.ndarray) -> np.ndarray | None:
    """Newton on ``F(y) = 0, tau . (y - yp) = 0``; None unless it converges fast."""
    y = yp.copy()
    for _ in range(7):
        f, jac = fj(y)
        if not np.all(np.isfinite(f)):
            return None
        g = np.append(f, tau @ (y - yp))
        if np.max(np.abs(f)) < _TOL and abs(g[-1]) < 1e-12:
            return y
        dy = np.linalg.solve(np.vstack([jac, tau]), -g)
        if np.max(np.abs(dy)) > 0.25:
            return None
        y = y + dy
    f, _ = fj(y)
    return y if np.max(np.abs(f)) < _TOL else None


def _end_reason(prob: _Problem, x: np.ndarray, why: str | None) -> str:
    _, amps = prob.unpack(x)
    top = float(np.max(prob.zeros(x)))
    if top > 0.5 * _R_MAX:
        return "the outermost zero of V runs off to infinite frequency"
    if np.min(amps) < 1e-3:
        return "an impulse amplitude reaches 0 (it would go negative)"
    if why is None or "failed" in why:
        return "the solution curve ends"
    return why


def _extend(prob: _Problem, tr: _Trace, vtol: float, sigma: float) -> None:
    """Trace the curve further until it reaches ``sigma`` or ends."""
    fj = _aug_fun_jac(prob, vtol)
    y = np.append(tr.xs[-1], tr.sig[-1])
    with np.errstate(all="ignore"):
        while tr.end is None and max(tr.sig) < sigma:
            h, why = tr.h, None
            while True:
                try:
                    ynew = _correct(fj, y + h * tr.tau, tr.tau)
                    if ynew is None:
                        why = "the solver failed to converge"
                    elif ynew[-1] < 0:
                        why = "the solution curve turns back (a fold)"
                    else:
                        why = _invalid_reason(prob, ynew[:-1], ynew[-1], vtol)
                    if why is None:
                        tnew = _tangent(fj(ynew)[1], tr.tau)
                        if tnew @ tr.tau < 0.9:  # too sharp a turn: smaller step
                            why = "the solver failed to converge"
                except np.linalg.LinAlgError:
                    why = "the solver failed"
                if why is None:
                    break
                h *= 0.5
                if h < _H_MIN:
                    tr.end = _end_reason(prob, y[:-1], why)
                    return
            grow = h == tr.h
            y, tr.tau = ynew, tnew
            tr.sig.append(float(y[-1]))
            tr.xs.append(y[:-1].copy())
            tr.h = min(_H_MAX, h * 1.6) if grow else h
            smax = max(tr.sig)
            if y[-1] < smax - max(0.05, 0.25 * smax):
                tr.end = "the solution curve turns back (a fold)"
            elif len(tr.sig) > _MAX_POINTS:
                tr.end = "the solution curve could not be followed further"


def _trace(key: str, vtol: float) -> _Trace:
    k = (key, vtol)
    tr = _traces.get(k)
    if tr is None:
        prob = _PROBLEMS[key]
        x0 = prob.initial(vtol)
        y0 = np.append(x0, 0.0)
        fj = _aug_fun_jac(prob, vtol)
        tau0 = np.zeros(len(y0))
        tau0[-1] = 1.0
        try:
            with np.errstate(all="ignore"):
                t0 = _tangent(fj(y0)[1], tau0)
        except np.linalg.LinAlgError:
            t0 = None
        if t0 is None or not np.all(np.isfinite(t0)):
            raise ValueError(f"vtol={vtol:g} is too close to 0 or 1 for the damped {prob.name} shaper: its solution "
                             "curve is singular at zeta = 0 (the undamped closed form has coinciding zeros or a "
                             "vanishing impulse); use a vtol further inside (0, 1)")
        tr = _Trace([0.0], [x0], t0, 0.02)
        _traces[k] = tr
        while len(_traces) > _CACHE_SIZE:
            _traces.popitem(last=False)
    _traces.move_to_end(k)
    return tr


def _sigma_of(zeta: float) -> float:
    return zeta / math.sqrt(1.0 - zeta * zeta)


def _range_error(prob: _Problem, zeta: float, vtol: float, sig_max: float, reason: str | None
                 ) -> ValueError:
    z_ok = sig_max / math.sqrt(1.0 + sig_max * sig_max)
    return ValueError(
        f"zeta={zeta:g} is outside the range where the damped {prob.name} shaper exists "
        f"for vtol={vtol:g}: it works for 0 <= zeta <= {math.floor(z_ok * 1e4) / 1e4:.4f} "
        f"(beyond that {reason}; a smaller vtol widens the range)")


def _solve(key: str, zeta: float, vtol: float) -> np.ndarray:
    """Solution vector for ``(zeta, vtol)``, solved for exactly these inputs.

    The cached traced curve only supplies the starting point (and tells where
    the family ends); the returned solution is solved at the given ``zeta``.
    """
    prob = _PROBLEMS[key]
    sigma = _sigma_of(zeta)
    tr = _trace(key, vtol)
    if max(tr.sig) < sigma:
        _extend(prob, tr, vtol, sigma)
    if max(tr.sig) < sigma:
        raise _range_error(prob, zeta, vtol, max(tr.sig), tr.end)
    if sigma == 0.0:
        x, _ = _solve_at(prob, tr.xs[0], 0.0, vtol)
        if x is None:  # pragma: no cover - the closed form is exact
            raise ValueError(f"{prob.name}: the undamped closed form is not admissible for vtol={vtol:g}; "
                             "use a vtol further inside (0, 1)")
        return x
    for _ in range(40):
        sig = np.array(tr.sig)
        i = int(np.argmax(sig >= sigma)) - 1  # the first crossing of sigma along the curve
        s0, s1 = sig[i], sig[i + 1]
        w = (sigma - s0) / (s1 - s0)
        x0 = tr.xs[i] + w * (tr.xs[i + 1] - tr.xs[i])
        x, _ = _solve_at(prob, x0, sigma, vtol)
        if x is not None and (np.max(np.abs(x - x0)) < 2 * np.max(np.abs(tr.xs[i + 1] - tr.xs[i]))):
            return x
        # refine the segment: a curve point half way along it, then retry
        ya, yb = np.append(tr.xs[i], s0), np.append(tr.xs[i + 1], s1)
        tau = (yb - ya) / np.linalg.norm(yb - ya)
        try:
            with np.errstate(all="ignore"):
                ym = _correct(_aug_fun_jac(prob, vtol), 0.5 * (ya + yb), tau)
        except np.linalg.LinAlgError:
            ym = None
        if ym is None:
            break
        tr.sig.insert(i + 1, float(ym[-1]))
        tr.xs.insert(i + 1, ym[:-1].copy())
    raise ValueError(f"{prob.name}: the solver did not converge at zeta={zeta:g}, vtol={vtol:g} (near the end "
                     "of the family's range); a smaller zeta or vtol is solvable")


def _to_seconds(prob: _Problem, x: np.ndarray, mode: Mode) -> tuple[np.ndarray, np.ndarray]:
    times, amps = prob.unpack(x)
    times = np.asarray(times, dtype=float) * mode.damped_period
    times[0] = 0.0
    return times, np.asarray(amps, dtype=float).copy()


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
    return _eval_fit(_SINGHOSE_EI_FIT, mode, vtol)


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
    if not isinstance(definition, str) or definition not in keys:
        raise ValueError(f"definition must be 'hump' or 'singhose', got {definition!r}")
    prob = _PROBLEMS[keys[definition]]
    return _to_seconds(prob, _solve(keys[definition], mode.zeta, vtol), mode)


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
    return _to_seconds(_PROBLEMS[key], _solve(key, mode.zeta, vtol), mode)


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
        x = _solve("ei", float(zk), vtol)
        te, ae = _to_seconds(_PROBLEMS["ei"], x, m)
        td = m.damped_period
        da[k] = np.max(np.abs(af - ae))
        dt[k] = np.max(np.abs(tf - te)) / td
        s = _sigma_of(float(zk))
        v_m[k] = _vib(1.0, af, tf / td, s)[0]
        lo, hi = _PROBLEMS["ei"].zeros(x)  # the exact shaper's zeros bracket the hump
        band = np.linspace(lo, hi, 2001)
        v_pk[k] = np.max(_vib(band, af, tf / td, s))
        v_ex[k] = np.max(_vib(band, ae, te / td, s))
    return {"zeta": z, "max_abs_amplitude_error": da, "max_abs_time_error": dt,
            "v_at_model": v_m, "v_peak": v_pk, "exact_v_peak": v_ex, "vtol": np.asarray(vtol)}
