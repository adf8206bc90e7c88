"""Robustness margins of a loop from its loop gain on the imaginary axis: data objects and the grid search."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from ..core.transfer import TransferFunction

__all__ = ["NyquistResponse", "Margins", "margins_on_grid"]


@dataclass(frozen=True)
class NyquistResponse:
    """Loop-gain frequency response ``L(j omega)`` (the data behind a Nyquist plot).

    Attributes
    ----------
    omega : ndarray
        Frequencies [rad/s].
    response : ndarray of complex
        ``L(j omega)``.
    name : str
        A label (the loop's architecture and shaper).
    """

    omega: np.ndarray
    response: np.ndarray
    name: str = ""

    @property
    def min_distance(self) -> float:
        """``min |1 + L(j omega)|`` over the grid (the inverse of the grid's peak sensitivity)."""
        return float(np.min(np.abs(1.0 + self.response)))


@dataclass(frozen=True)
class Margins:
    """Robustness margins of a loop, read from its loop gain on the imaginary axis.

    Attributes
    ----------
    ms, omega_ms : float
        Peak sensitivity ``Ms = max |1 / (1 + L(j omega))|`` and where it occurs.
    mt, omega_mt : float
        Peak complementary sensitivity ``Mt = max |L / (1 + L)|`` and where.
    sm : float
        Stability margin ``1 / Ms``: the least distance of the Nyquist curve to -1.
    gm, omega_gm : float
        Gain margin ``1 / |L|`` at a phase crossover (``L`` real negative);
        of several crossovers, the one closest to 1 in ``|log gm|`` (as MATLAB and
        python-control report it).  ``inf``/``nan`` when there is none.
    pm, omega_pm : float
        Phase margin [deg] at a gain crossover (``|L| = 1``), the smallest in
        absolute value.  ``inf``/``nan`` when there is none.

    The margins say nothing about stability by themselves: check
    :meth:`Loop.is_stable` (a loop with delays has infinitely many poles).
    """

    ms: float
    omega_ms: float
    mt: float
    omega_mt: float
    sm: float
    gm: float
    omega_gm: float
    pm: float
    omega_pm: float


def margins_on_grid(Ltf: TransferFunction, S_tf: TransferFunction, T_tf: TransferFunction, w: np.ndarray) -> Margins:
    """Peaks of ``S_tf`` and ``T_tf`` and the gain/phase margins of ``Ltf`` on the grid ``w`` [rad/s].

    Peaks and crossovers found on the (sorted, nonnegative) grid are refined by a
    1-D search between the neighbouring grid points.
    """

    def peak(tf: TransferFunction) -> tuple[float, float]:
        mag = np.abs(tf.freqresp(w))
        mag = np.where(np.isfinite(mag), mag, np.inf)
        i = int(np.argmax(mag))
        if not np.isfinite(mag[i]):
            return math.inf, float(w[i])
        lo, hi = w[max(i - 1, 0)], w[min(i + 1, w.size - 1)]
        res = minimize_scalar(
            lambda x: -abs(tf(1j * x)), bounds=(lo, hi), method="bounded", options={"xatol": 1e-10 * max(hi, 1e-300)}
        )
        if -res.fun > mag[i]:
            return float(-res.fun), float(res.x)
        return float(mag[i]), float(w[i])

    ms, w_ms = peak(S_tf)
    mt, w_mt = peak(T_tf)
    L = Ltf.freqresp(w)
    fin = np.isfinite(L)

    def L_at(x: float) -> complex:
        return complex(Ltf(1j * x))

    # gain crossovers |L| = 1
    pm, w_pm = math.inf, math.nan
    g = np.abs(L) - 1.0
    for i in np.flatnonzero(fin[:-1] & fin[1:] & (np.sign(g[:-1]) != np.sign(g[1:]))):
        x = brentq(lambda t: abs(L_at(t)) - 1.0, w[i], w[i + 1], xtol=1e-14 * w[i + 1])
        p = math.degrees(np.angle(-L_at(x)))
        if abs(p) < abs(pm):
            pm, w_pm = p, x
    # phase crossovers: L real negative
    gm, w_gm = math.inf, math.nan
    im = L.imag
    cand = fin[:-1] & fin[1:] & (np.sign(im[:-1]) != np.sign(im[1:])) & (L.real[:-1] + L.real[1:] < 0)
    for i in np.flatnonzero(cand):
        x = brentq(lambda t: L_at(t).imag, w[i], w[i + 1], xtol=1e-14 * w[i + 1])
        lx = L_at(x)
        if lx.real >= 0 or x <= 0:
            continue
        gmi = -1.0 / lx.real
        if abs(math.log(gmi)) < abs(math.log(gm)):
            gm, w_gm = gmi, x
    return Margins(ms, w_ms, mt, w_mt, 1.0 / ms if ms > 0 else math.inf, gm, w_gm, pm, w_pm)
