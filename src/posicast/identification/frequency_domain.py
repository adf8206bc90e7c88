"""Seed 002's frequency-domain estimate of one mode (``method="freq"``, section 3.2.2).

FFT ratio of the differenced output and input, spectral peak, -3 dB bandwidth to the
pole radius (eq. 26, corrected for a resonance away from fs/4: :func:`resonator_bandwidth`),
pole by eq. 27, the spectrum resampled so the peak is on the grid, then the seed's
step-up/step-down refinement of omega and zeta on the response error.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy import optimize

from .. import _validate as v
from ..modes import Mode
from .fit_statistics import fit_percent, half_power_span, numerical_jacobian, pole_intervals
from .output_error import ZETA_MAX, ZETA_MIN, OEModel
from .results import Identification
from .significance import NoModeFound, at_band_edge, describe_failure, search_cells

__all__ = ["fit_freq", "resonator_bandwidth"]


def resonator_bandwidth(r: float, theta: float) -> float:
    """Exact -3 dB bandwidth (rad/sample) of ``1 / ((1 - r e^{j theta} z^-1)(1 - r e^{-j theta} z^-1))``.

    Seed 002 eq. 26, ``2 arccos(sqrt(6 r^2 - r^4 - 1) / (2 r))``, is this
    bandwidth only for ``theta = pi/2`` (resonance at fs/4).

    Examples
    --------
    >>> r = 0.95
    >>> eq26 = 2 * math.acos(math.sqrt(6 * r**2 - r**4 - 1) / (2 * r))
    >>> abs(resonator_bandwidth(r, math.pi / 2) - eq26) < 1e-6
    True
    """
    x = np.linspace(max(theta - 8 * (1 - r) - 0.05, 0.0), min(theta + 8 * (1 - r) + 0.05, math.pi), 20001)
    g = 1.0 / (np.abs(1 - r * np.exp(1j * (theta - x))) * np.abs(1 - r * np.exp(-1j * (theta + x)))) ** 2
    i = int(np.argmax(g))
    half = g[i] / 2
    lo = np.nonzero(g[:i] < half)[0]
    hi = np.nonzero(g[i:] < half)[0]
    if lo.size == 0 or hi.size == 0:
        return float("nan")
    a, b = lo[-1], i + hi[0]
    xa = np.interp(half, [g[a], g[a + 1]], [x[a], x[a + 1]])
    xb = np.interp(half, [g[b], g[b - 1]], [x[b], x[b - 1]])
    return float(xb - xa)


def _radius_from_bandwidth(dw: float, theta: float) -> float:
    """Invert :func:`resonator_bandwidth` for r (seed 002 eq. 26, corrected for theta != pi/2)."""
    def f(r: float) -> float:
        bw = resonator_bandwidth(r, theta)
        return (bw if math.isfinite(bw) else math.pi) - dw

    lo, hi = 0.5, 0.99995
    try:
        if f(lo) * f(hi) > 0:
            return max(1.0 - dw / 2.0, 0.2)
        return float(optimize.brentq(f, lo, hi, xtol=1e-10))
    except (ValueError, RuntimeError):
        return max(1.0 - dw / 2.0, 0.2)


class SpectralPole(NamedTuple):
    """The spectral estimate of :func:`fit_freq` before refinement, and the band the input excites (Hz)."""

    omega: float
    zeta: float
    f_lo: float
    f_hi: float


def _spectral_pole(u: np.ndarray, y: np.ndarray, fs: float) -> SpectralPole:
    """Seed 002 section 3.2.2: peak of the smoothed FFT ratio, -3 dB bandwidth, pole by eq. 26-27."""
    h = 1.0 / fs
    n = y.size
    nfft = max(n, int(round(fs)))  # seed: a one-second window
    # differenced from rest (u = 0 and y = y[0] before the record): a step at sample 0 is an impulse
    du, dy = np.diff(u, prepend=0.0), np.diff(y, prepend=y[0])
    if not np.any(du):
        raise ValueError("freq: the input is zero throughout; there is no excitation to identify from")
    Y, U = np.fft.rfft(dy, nfft), np.fft.rfft(du, nfft)
    f = np.fft.rfftfreq(nfft, h)
    aU = np.abs(U)
    H = np.abs(Y) / np.maximum(aU, 1e-300)
    inband = (f > 2 * fs / n) & (f < 0.45 * fs)
    # only where the input carries power: the ratio of two small numbers is noise (a chirp's
    # spectrum beyond its end frequency made a 180 Hz "mode" of a 28 Hz system)
    ok = inband & (aU**2 > 0.1 * float(np.mean(aU[inband] ** 2)))
    if np.count_nonzero(ok) < 8:
        raise ValueError("freq: the input has power at fewer than 8 frequencies of the band; use a richer input")
    f_lo_ok, f_hi_ok = float(f[ok].min()), float(f[ok].max())
    Hd = np.where(ok, H, 0.0)
    Hd = np.convolve(Hd, np.ones(3) / 3, mode="same")  # moving average (seed 3.2.2)
    i = int(np.argmax(Hd))
    f_max = float(f[i])
    # resample the spectrum so that the peak falls on the grid (seed: fs a multiple of f_max):
    # linear interpolation onto a grid of spacing f_max / M, M >= 16 per original bin
    df = f[1] - f[0]
    M = max(1, int(math.ceil(16 * f_max / df)))
    fg = np.arange(0.0, f[-1], f_max / M)
    Hg = np.interp(fg, f, Hd)
    j = int(np.argmax(Hg))
    f_max = float(fg[j])
    half = Hg[j] / math.sqrt(2.0)  # -3 dB
    a, b = half_power_span(Hg, j)
    fa = np.interp(half, [Hg[a], Hg[a + 1]], [fg[a], fg[a + 1]])
    fb = np.interp(half, [Hg[b], Hg[b - 1]], [fg[b], fg[b - 1]])
    dw = 2 * math.pi * (fb - fa) / fs
    theta = 2 * math.pi * f_max / fs
    r = _radius_from_bandwidth(dw, theta)  # eq. 26 (exact for any theta)
    zp = r * complex(math.cos(theta), math.sin(theta))  # eq. 27
    s = np.log(zp) / h
    return SpectralPole(float(abs(s)), float(np.clip(-s.real / abs(s), ZETA_MIN, 0.9)), f_lo_ok, f_hi_ok)


def _refine(model: OEModel, th: np.ndarray, z0: float) -> np.ndarray:
    """Seed 002: step omega up/down while the response error decreases, then zeta; halve the steps."""
    cost = lambda x: float(np.sum(model.residual(x) ** 2))  # noqa: E731
    c = cost(th)
    steps = np.array([0.01, 0.1 * max(z0, 0.01)])
    it = 0
    while np.any(steps > np.array([1e-7, 1e-7])) and it < 2000:
        improved = False
        for p in (0, 1):
            for sgn in (1.0, -1.0):
                while True:
                    x = th.copy()
                    x[p] += sgn * steps[p]
                    if p == 1 and not ZETA_MIN <= x[1] <= ZETA_MAX:
                        break
                    cx = cost(x)
                    it += 1
                    if cx < c:
                        th, c, improved = x, cx, True
                    else:
                        break
        if not improved:
            steps /= 2.0
    return th


@v.renamed_keywords(fs="sample_rate")
def fit_freq(u: np.ndarray, y: np.ndarray, sample_rate: float, *, refine: bool, covariance: str,
             feedthrough: bool, offset: bool, initial_state: bool, weights: np.ndarray | None = None) -> Identification:
    """Seed 002 section 3.2.2 (eq. 26-27) with its iterative refinement on the output-error model."""
    fs = sample_rate  # the sample rate [Hz], fs in the formulas
    h = 1.0 / fs
    w0, z0, f_lo_ok, f_hi_ok = _spectral_pole(u, y, fs)
    model = OEModel(u, y, h, 1, feedthrough=feedthrough, offset=offset, initial_state=initial_state,
                    weights=weights)
    th = np.array([math.log(w0), z0])
    notes = [f"spectral estimate before refinement: f = {w0 / 2 / math.pi:.4f} Hz, zeta = {z0:.4f}"]
    if refine:
        th = _refine(model, th, z0)
    e, y_hat, n_lin = model.project(th)
    J = numerical_jacobian(model.residual, th)
    ivs, used, pw = pole_intervals(th, J, e, n_lin, covariance, model.n_used)
    if not refine:
        notes.append("no refinement: intervals are the local OE curvature at a non-optimal point")
    mode = Mode(math.exp(th[0]), float(th[1]))
    test = model.mode_tests(th, e, n_lin, used == "hac", search_cells(f_lo_ok, f_hi_ok, y.size * h))[0]
    if not test.significant:
        raise NoModeFound(describe_failure("freq", mode, test), mode, test)
    edge = at_band_edge(mode, f_lo_ok, f_hi_ok)
    if edge:
        notes.append(f"the mode at {mode.freq_hz:.4g} Hz lies at the edge of the excited band "
                     f"[{f_lo_ok:.4g}, {f_hi_ok:.4g}] Hz: its damping is not resolved")
    return Identification([mode], ivs, "freq", fit_percent(y, y_hat), pw, used,
                          y_hat, e, fs, notes=notes, tests=[test], at_edge=[edge])
