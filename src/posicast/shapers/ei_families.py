"""The EI shaper families as square systems of equations (the definitions in :mod:`posicast.shapers.ei`).

Each family (:data:`FAMILIES`: EI with ``t_3 = T_d``, EI with its hump at ``omega_m``,
2-hump and 3-hump EI) is a :class:`ShaperFamily`: how the unknown vector holds the
impulses and the constrained frequencies, its residual (humps of height ``vtol``, exact
zeros, ``sum A = 1``), and its undamped closed form (the start of the continuation in
``zeta``, :mod:`posicast.shapers.ei_solver`).  Everything is dimensionless: frequency
ratios ``r = omega / omega_m`` and times in units of ``T_d`` (see the conventions in
:mod:`posicast.shapers.ei`).  :func:`invalid_reason` says why a solution is not an
admissible shaper of its family.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

__all__ = ["response", "vibration", "ShaperFamily", "FAMILIES", "R_MAX", "invalid_reason"]

_TWO_PI = 2.0 * math.pi

# ---------------------------------------------------------------------------
# the residual vibration in dimensionless form (works on complex inputs too,
# which is how the Jacobian is obtained: complex-step differentiation)
# ---------------------------------------------------------------------------


def response(r: Any, amps: Any, times: Any, sigma: float):
    """``e^{-zeta omega t_n} S(p(omega))`` and its r-derivative, as real/imag parts.

    ``r``: frequency ratios, shape ``(..., m)``; ``amps``, ``times``: shape
    ``(..., n)`` (times in units of T_d); results have shape ``(..., m)``.
    Written with real arithmetic only so that it is complex-analytic in every
    argument (complex-step Jacobians).
    """
    t = times[..., None, :]
    dec, e, c, s = _terms(r[..., :, None], amps, t, sigma)
    re = (e * c).sum(-1)
    im = -(e * s).sum(-1)
    dre = _TWO_PI * (e * (dec * c - t * s)).sum(-1)
    dim = -_TWO_PI * (e * (dec * s + t * c)).sum(-1)
    return re, im, dre, dim


def _terms(r: Any, amps: Any, t: Any, sigma: float) -> tuple[Any, Any, Any, Any]:
    """Per frequency ratio ``r[..., m, 1]`` and impulse ``t[..., 1, n]``: the decay exponent's factor
    ``sigma (t - t_n)``, the decayed amplitudes and the cosine and sine of the phase (computed once)."""
    dec = sigma * (t - t[..., -1:])
    e = amps[..., None, :] * np.exp(_TWO_PI * r * dec)
    phase = _TWO_PI * r * t
    return dec, e, np.cos(phase), np.sin(phase)


def vibration(r: Any, amps: np.ndarray, times: np.ndarray, sigma: float) -> np.ndarray:
    """Real V at frequency ratios ``r`` (1-D; times in units of T_d): the values of :func:`response`, without
    its r-derivatives (issue #15: the admissibility scan of every traced EI solution)."""
    _, e, c, s = _terms(np.atleast_1d(np.asarray(r, dtype=float))[..., :, None], amps, times[..., None, :], sigma)
    return np.hypot((e * c).sum(-1), -(e * s).sum(-1))


# ---------------------------------------------------------------------------
# the problems: unknown vector layout, residual, undamped closed form
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class ShaperFamily:
    """One shaper family: its unknowns, residual and undamped start.

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
        re, im, dre, dim = response(self.freqs(x), amps, times, sigma)
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
FAMILIES = {
    "ei": ShaperFamily("EI", _ei_b_unpack, _ei_b_initial, (3, 4, -1), 0, 2, 1, False),
    "ei_hump": ShaperFamily("EI (hump at omega_m)", _ei_a_unpack, _ei_a_initial,
                        (-1, 5, 6), 1, 2, 0, True),
    "2hump": ShaperFamily("2-hump EI", _h2_unpack, _h2_initial, (7, 8, -1, 9, 10), 2, 3, 0, True),
    "3hump": ShaperFamily("3-hump EI", _h3_unpack, _h3_initial,
                      (-1, 9, 10, 11, 12, 13, 14), 3, 4, 0, True),
}


# Zero frequencies are kept below R_MAX omega_m: near the end of some
# families the outermost zero runs off to infinity (the shaper degenerates:
# its last impulse amplitude or spacing goes to zero).
R_MAX = 10.0


def invalid_reason(prob: ShaperFamily, x: np.ndarray, sigma: float, vtol: float) -> str | None:
    """None if ``x`` is an admissible shaper of the family, else why not."""
    if not np.all(np.isfinite(x)):
        return "the solver diverged"
    times, amps = prob.unpack(x)
    if np.any(amps < -1e-12):
        return "an impulse amplitude would go negative"
    if np.any(np.diff(times) <= 0):
        return "the impulse times would stop being increasing"
    # zeros (z) and humps (h) interlaced, at distinct positive frequencies below R_MAX
    z, h = prob.zeros(x), prob.humps(x)
    pts = np.sort(np.concatenate([z, h]))
    if pts[-1] >= R_MAX:
        return (f"the outermost zero of V runs off to infinite frequency (past {R_MAX:g} "
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
            vv = vibration(np.array([rh - d, rh, rh + d]), amps, times, sigma)
            if not (vv[1] >= vv[0] and vv[1] >= vv[2]):
                return "a constrained hump is not a local maximum"
        band = vibration(np.linspace(z[0], z[-1], 1001), amps, times, sigma)
        if np.max(band) > vtol * (1.0 + 1e-6):
            return "V would exceed vtol between the outer zeros"
    return None
