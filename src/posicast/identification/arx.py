"""Seed 002's least-squares ARX estimate of one mode (``method="arx"``, the documented baseline).

Biased when the output is noisy (the regressors contain the noise); kept because it
is the seed's method and a reference for the output-error fit.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import signal, special

from .. import _validate as v
from ..modes import Mode
from . import _linalg
from .fit_statistics import fit_percent, whiteness
from .results import Identification, Interval
from .significance import NoModeFound, wald_test

__all__ = ["fit_arx"]


@v.renamed_keywords(fs="sample_rate")
def fit_arx(u: np.ndarray, y: np.ndarray, sample_rate: float, nk: int = 0) -> Identification:
    """Seed 002 eq. 19-25: theta = A_p^+ y_p with rows [u(k), u(k-1), -y(k-1), -y(k-2)].

    ``nk`` delays the input regressors (``nk = 1`` is the structure of a ZOH-sampled
    continuous system, ``u(k-1), u(k-2)``); the seed's eq. 21 is ``nk = 0``.
    """
    fs = sample_rate  # the sample rate [Hz], fs in the formulas
    h = 1.0 / fs
    k0 = max(2, nk + 1)
    ks = np.arange(k0, y.size)
    if ks.size < 4:  # seed 002 eq. 19: P = n + m = 4 rows at least
        raise ValueError(f"arx needs at least {k0 + 4} samples (seed 002 eq. 19), got {y.size}")
    A = np.column_stack([u[ks - nk], u[ks - nk - 1], -y[ks - 1], -y[ks - 2]])  # eq. 22
    yp = y[ks]
    theta = _linalg.lstsq(A, yp)  # eq. 24-25 (pseudo-inverse; np.linalg.lstsq's solution)
    e = yp - A @ theta
    dof = max(ks.size - 4, 1)
    # does the input drive the output through this model?  F-test of its simulated output on the data
    # (offset partialled out, residual whitened if coloured): the autoregressive part alone also fits
    # coloured noise, and a static gain alone also passes a test of all four coefficients
    y_sim = signal.lfilter(theta[:2] if nk == 0 else np.r_[np.zeros(nk), theta[:2]], np.r_[1.0, theta[2:]], u)
    if not np.all(np.isfinite(y_sim)) or np.max(np.abs(y_sim)) > 1e12 * max(float(np.max(np.abs(y))), 1e-300):
        raise NoModeFound("no mode found (arx): the fitted model is unstable")
    ones = np.ones((y.size, 1))
    r_sim = y - y_sim  # also the residual of the result (its y_fit is y_sim)
    pw = whiteness(r_sim)
    test = wald_test(y, y_sim[:, None], ones, r_sim - r_sim.mean(), y.size - 2, 1.0, coloured=pw < 0.01)

    def to_mode(a1: float, a2: float) -> tuple[float, float]:
        r = _poles(a1, a2)
        if abs(r[0].imag) < 1e-12 or np.any(np.abs(r) >= 1.0) or np.any(np.abs(r) == 0.0):
            raise NoModeFound("no mode found (arx): the fitted poles are real or unstable, not a damped oscillation")
        s = np.log(r[0] if r[0].imag > 0 else r[1]) / h
        return float(abs(s)), float(-s.real / abs(s))

    if not test.significant:
        raise NoModeFound("no mode found (arx): the model is no better than noise: it " + test.describe(),
                          None, test)
    w, z = to_mode(theta[2], theta[3])
    if z >= 0.45:  # poles near the origin: no resonant peak (a static gain on noise fits this way)
        raise NoModeFound(f"no mode found (arx): the fitted poles (zeta {z:.2f}) have no resonant peak")
    Jm = np.empty((2, 2))
    for j in range(2):
        d = 1e-7 * max(abs(theta[2 + j]), 1e-3)
        tp, tm = theta[2:].copy(), theta[2:].copy()
        tp[j] += d
        tm[j] -= d
        Jm[:, j] = (np.array(to_mode(*tp)) - np.array(to_mode(*tm))) / (2 * d)
    C = float(e @ e) / dof * np.linalg.pinv(A.T @ A)  # only for a mode that passed (issue #15)
    Cm = Jm @ C[2:, 2:] @ Jm.T
    tq = float(special.stdtrit(dof, 0.975))  # scipy.stats.t.ppf(0.975, dof)
    sw, sz = math.sqrt(max(Cm[0, 0], 0)), math.sqrt(max(Cm[1, 1], 0))
    iv = Interval((w - tq * sw, w + tq * sw), (max(z - tq * sz, 0.0), z + tq * sz))
    return Identification([Mode(w, min(max(z, 0.0), 0.999999))], [iv], "arx", fit_percent(y, y_sim), pw,
                          "delta", y_sim, r_sim, fs, tests=[test],
                          notes=["ARX (seed 002 eq. 21): biased under output noise; intervals assume equation "
                                 "noise and are not honest for output noise"])


def _poles(a1: float, a2: float) -> np.ndarray:
    """The roots of ``z^2 + a1 z + a2``: ``np.roots([1, a1, a2])`` without its argument handling (issue #15: five
    calls per fit), the eigenvalues of the same companion matrix; a zero root when ``a2 == 0``, as np.roots."""
    if a2 == 0.0:
        return np.roots([1.0, a1, a2])
    return _linalg.eigvals(np.array([[-a1, -a2], [1.0, 0.0]]))
