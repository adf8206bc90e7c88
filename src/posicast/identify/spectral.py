"""Output-only identification from a power spectrum: modes in a resonance test's PSD.

The measured acceleration PSD of a resonance test is modelled as

    M(f) = E(f) sum_c |H_c(j 2 pi f)|^2 + g / f^2 + N,
    H_c(s) = c_c0 + sum_k (a_ck w_k^2 + b_ck w_k s) / (s^2 + 2 zeta_k w_k s + w_k^2)

``E`` is the test's excitation shape (:mod:`.excitation`: ``f^2`` for Klipper's
sweep, times Klipper's normalisation for its ``calibration_data`` files), ``H_c``
the transmissibility from the commanded to the measured acceleration in channel
``c`` (modes shared, residues free; a sum of channels such as Klipper's ``psd_xyz``
is covered), ``g / f^2`` the slow sweep's lines below 10 Hz, ``N`` the sensor
floor.  Writing ``sum_c |H_c|^2 = v^T Q v`` with the real basis
``v = [1, w_k^2/D_k, w_k s/D_k, ...]`` makes the model **linear** in ``Q`` (a
symmetric matrix), ``g`` and ``N``: only the poles ``(ln w_k, zeta_k)`` are searched
(variable projection).

The periodogram average at each bin is the true PSD times a scaled chi-square
variable, so the fit is the Whittle (gamma) maximum likelihood, computed by
iteratively reweighted least squares (weights ``1 / M``).  Its dispersion is
estimated from the residual, the correlation of neighbouring bins (window leakage
and overlap) from the residual's autocorrelation, and both scale the
Gauss-Newton covariance of the poles and the likelihood-ratio tests.

Modes are added greedily from the excitation-normalised spectrum's peaks and each
is kept only when a likelihood-ratio test against the model without it passes
after allowing for the frequency search (:mod:`.significance`).  A mode whose
half-power band leaves the fitted band is a rise at the band edge, not a mode.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy import fft as sp_fft
from scipy import optimize, signal, stats

from ..modes import Mode
from .significance import ALPHA, ModeTest, NoModeFound, search_cells

__all__ = ["Spectrum", "SpectralFit", "SpectralModes", "fit_spectrum", "welch_psd", "smoothed_periodogram",
           "window_correlation", "welch_dispersion", "BROAD_ZETA", "KAISER6_CORRELATION"]

_ZETA_BOUNDS = (2e-3, 0.6)
_MAX_MODES = 6
#: A fitted peak this broad (the resonant gain 1/(2 zeta) is near 1) is background, not a resonance.
BROAD_ZETA = 0.45
#: A mode whose peak is below this share of the spectrum's maximum is not reported (Klipper's 1/20).
MINOR_SHARE = 0.05


@dataclass(frozen=True)
class Spectrum:
    """A measured PSD ready for :func:`fit_spectrum`.

    Attributes
    ----------
    freqs : ndarray
        Bin frequencies, Hz, increasing.
    psd : ndarray
        The PSD as measured (any scale), >= 0.
    excitation : ndarray
        Excitation shape ``E(f)`` on the same bins (any scale; 0 where not excited).
    band : (float, float)
        The band to fit, Hz (inside the excited band).
    low_frequency : bool
        Include the ``g / f^2`` term of a slow sweep.
    normalisation : ndarray or None
        A known factor applied to the whole PSD by the firmware (Klipper's
        ``calibration_data``); multiplies every model term.
    resolution : float
        Bin spacing, Hz.
    source : str
        Where it came from (for notes and plots).
    correlation : float, optional
        Known variance inflation of a sum over bins from the correlation of neighbouring
        bins (``1 + 2 sum rho_m^2`` of the estimator's window, :func:`window_correlation`);
        estimated from the residual when None.
    dispersion_floor : float, optional
        Known variance of ``psd / true psd`` for noise (``1/K`` for ``K`` averaged
        periodograms); the significance tests never use a smaller dispersion.
    """

    freqs: np.ndarray
    psd: np.ndarray
    excitation: np.ndarray
    band: tuple[float, float]
    low_frequency: bool = True
    normalisation: np.ndarray | None = None
    resolution: float = float("nan")
    source: str = ""
    correlation: float | None = None
    dispersion_floor: float | None = None


@dataclass
class SpectralFit:
    """Details of a spectral fit beyond :class:`~posicast.identify.Identification`.

    Attributes
    ----------
    freqs, psd : ndarray
        The fitted bins and data.
    model : ndarray
        Fitted PSD on ``freqs``.
    background : ndarray
        Fitted PSD without any mode (excitation through a flat path, sweep, floor).
    components : list of ndarray
        Per mode: model minus the model refitted without that mode.
    dispersion : float
        Residual variance of ``psd / model`` (``1/K`` for ``K`` averaged periodograms).
    correlation : float
        Variance inflation from correlated neighbouring bins (>= 1).
    """

    freqs: np.ndarray
    psd: np.ndarray
    model: np.ndarray
    background: np.ndarray
    components: list[np.ndarray] = field(default_factory=list)
    dispersion: float = float("nan")
    correlation: float = 1.0


@dataclass
class SpectralModes:
    """What :func:`fit_spectrum` found.

    Attributes
    ----------
    modes : list of Mode
        Resonances, by frequency.
    intervals : list of ((omega_lo, omega_hi), (zeta_lo, zeta_hi))
        95 % intervals.
    tests : list of ModeTest
        Each mode against the model without it.
    at_edge : list of bool
        The mode's half-power band leaves the fitted band.
    shares : list of float
        Each mode's share of the fitted spectrum's power.
    fit : SpectralFit
    notes : list of str
    """

    modes: list[Mode]
    intervals: list[tuple[tuple[float, float], tuple[float, float]]]
    tests: list[ModeTest]
    at_edge: list[bool]
    shares: list[float]
    fit: SpectralFit
    notes: list[str] = field(default_factory=list)


# ----------------------------------------------------------------------------- the model


class _Model:
    """``M(f; poles, Q, g, N)`` on fixed bins, linear in everything but the poles."""

    def __init__(self, spec: Spectrum) -> None:
        lo, hi = spec.band
        sel = (spec.freqs >= lo) & (spec.freqs <= hi) & (spec.psd > 0) & (spec.excitation > 0)
        self.f = spec.freqs[sel]
        self.P = spec.psd[sel]
        self.E = spec.excitation[sel]
        self.norm = np.ones_like(self.f) if spec.normalisation is None else spec.normalisation[sel]
        self.s = 2j * math.pi * self.f
        self.low = spec.low_frequency and lo < 20.0
        self.weights = 1.0 / _smooth(self.P)
        self.floor = 0.05 / self.weights
        self.correlation = spec.correlation
        self.dispersion_floor = spec.dispersion_floor
        f2 = self.f ** 2
        x2 = (2 * f2 - (f2[0] + f2[-1])) / (f2[-1] - f2[0]) if f2.size > 1 else f2 * 0.0
        self.cheb = np.polynomial.chebyshev.chebvander(x2, 2 * _MAX_MODES)
        self.W2 = (2 * math.pi * self.f) ** 2
        extra = [(self.f[0] / self.f) ** 2] if self.low else []
        self.extra = np.column_stack(extra + [np.ones_like(self.f)]) * self.norm[:, None]

    def _denominator(self, theta: np.ndarray) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
        """``prod_k |D_k|^2 / w_k^4`` and, per mode, ``d ln(.)/d ln w_k`` and ``d ln(.)/d zeta_k``."""
        den = np.ones_like(self.f)
        grads = []
        W2 = self.W2
        for k in range(theta.size // 2):
            w, z = math.exp(theta[2 * k]), theta[2 * k + 1]
            w2 = w * w
            re = w2 - W2
            D2 = re * re + 4.0 * z * z * w2 * W2
            den = den * (D2 / (w2 * w2))
            grads.append(((4.0 * w2 * re + 8.0 * z * z * w2 * W2) / D2 - 4.0, 8.0 * z * w2 * W2 / D2))
        return den, grads

    def columns(self, theta: np.ndarray, grads: bool = False) -> np.ndarray | tuple[np.ndarray, list[np.ndarray]]:
        """``E R(f^2) / prod |D_k|^2`` with ``R`` a polynomial of degree ``2 n`` (Chebyshev basis), ``1/f^2``, 1.

        ``sum_c |H_c|^2`` over any number of channels is ``R(f^2) / prod_k |D_k(j 2 pi f)|^2``
        with ``R >= 0`` of degree ``2 n`` in ``f^2`` (the numerators of ``H_c`` have degree
        ``2 n`` in ``s``), and by spectral factorisation every such ``R`` is one channel's
        ``|numerator|^2``: one basis serves a single axis and Klipper's sum of axes.
        With ``grads``, also the derivative of the columns with respect to each pole parameter.
        """
        n = theta.size // 2
        den, dl = self._denominator(theta)
        modal = self.cheb[:, : 2 * n + 1] * (self.E * self.norm / den)[:, None]
        extra = self.extra
        A = np.hstack([modal, extra])
        if not grads:
            return A
        dA = []
        zeros = np.zeros_like(extra)
        for gw, gz in dl:
            dA.append(np.hstack([-modal * gw[:, None], zeros]))
            dA.append(np.hstack([-modal * gz[:, None], zeros]))
        return A, dA

    def _projection(self, A: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """SVD of the weighted, column-scaled design (rank-truncated): U, s, Vt, column scales."""
        Aw = A * self.weights[:, None]
        scale = np.linalg.norm(Aw, axis=0)
        scale[scale == 0] = 1.0
        U, sv, Vt = np.linalg.svd(Aw / scale, full_matrices=False)
        keep = sv > 1e-12 * sv[0]
        return U[:, keep], sv[keep], Vt[keep], scale

    def solve(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Weighted linear least squares for the linear coefficients; returns (model, coefficients)."""
        A = self.columns(theta)
        U, sv, Vt, scale = self._projection(A)
        coef = (Vt.T @ ((U.T @ (self.P * self.weights)) / sv)) / scale
        return A @ coef, coef

    def residual(self, theta: np.ndarray) -> np.ndarray:
        M, _ = self.solve(theta)
        return (self.P - M) * self.weights

    def jacobian(self, theta: np.ndarray) -> np.ndarray:
        """Kaufman's variable-projection Jacobian ``-P_perp W (dA/dtheta_k) c`` (analytic column derivatives)."""
        return self.residual_and_jacobian(theta)[1]

    def residual_and_jacobian(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        A, dA = self.columns(theta, grads=True)
        U, sv, Vt, scale = self._projection(A)
        y = self.P * self.weights
        proj = U.T @ y
        coef = (Vt.T @ (proj / sv)) / scale
        J = np.empty((self.f.size, theta.size))
        for k, dAk in enumerate(dA):
            d = (dAk @ coef) * self.weights
            J[:, k] = -(d - U @ (U.T @ d))
        return y - U @ proj, J


def _smooth(P: np.ndarray, width: int = 5) -> np.ndarray:
    """Running median: a positive reference level for the first weights."""
    if P.size < width:
        return np.full_like(P, max(float(np.median(P)), 1e-300))
    pad = width // 2
    Q = np.pad(P, pad, mode="edge")
    win = np.lib.stride_tricks.sliding_window_view(Q, width)
    return np.maximum(np.median(win, axis=1), 1e-12 * float(P.max()))


def _bounds(model: _Model, n: int) -> tuple[np.ndarray, np.ndarray]:
    lo = np.tile([math.log(2 * math.pi * model.f[0]), _ZETA_BOUNDS[0]], n)
    hi = np.tile([math.log(2 * math.pi * model.f[-1]), _ZETA_BOUNDS[1]], n)
    return lo, hi


def _fit(model: _Model, theta0: np.ndarray, iterations: int = 3, rtol: float = 1e-8) -> tuple[np.ndarray, np.ndarray]:
    """Poles by least squares on relative errors, then Whittle IRLS steps (weights ``1/M``).

    The first pass weights by the smoothed data, which cannot run away when the model
    is still missing a mode; each reweighting is kept only if the gamma deviance drops
    and the model stays positive.
    """
    lo, hi = _bounds(model, theta0.size // 2)
    th = np.clip(theta0, lo + 1e-9, hi - 1e-9)
    model.weights = 0.05 / model.floor

    def run(x: np.ndarray) -> np.ndarray:
        return _levenberg_marquardt(model.residual_and_jacobian, x, lo, hi, rtol=rtol)

    th = run(th)
    M, _ = model.solve(th)
    dev = _deviance(model, M) if np.all(M > 0) else math.inf
    for _ in range(iterations):
        if not np.all(M > 0):
            break
        w_old = model.weights
        model.weights = 1.0 / M
        th_new = run(th)
        M_new, _ = model.solve(th_new)
        dev_new = _deviance(model, M_new) if np.all(M_new > 0) else math.inf
        if dev_new >= dev - 1e-9 * abs(dev):
            model.weights = w_old
            break
        th, M, dev = th_new, M_new, dev_new
    return th, M


def _deviance(model: _Model, M: np.ndarray) -> float:
    """Gamma deviance (unit dispersion): ``2 sum(-log(P/M) + (P - M)/M)``; M floored at 5 % of the data."""
    P = model.P
    M = np.maximum(M, model.floor)
    r = P / M
    return float(2.0 * np.sum(-np.log(np.maximum(r, 1e-300)) + r - 1.0))


def _dispersion(model: _Model, M: np.ndarray, n_par: int) -> tuple[float, float, np.ndarray]:
    """Dispersion (Pearson) and the correlation inflation ``1 + 2 sum (1 - l/(L+1)) rho_l``."""
    r = model.P / np.maximum(M, model.floor) - 1.0
    n = r.size
    phi = float(r @ r) / max(n - n_par, 1)
    rc = r - r.mean()
    L = max(2, int(round(4 * (n / 100.0) ** (2 / 9))))
    c0 = float(rc @ rc)
    infl = 1.0
    if c0 > 0:
        for lag in range(1, min(L, n - 1) + 1):
            infl += 2.0 * (1.0 - lag / (L + 1.0)) * float(rc[lag:] @ rc[:-lag]) / c0
    return phi, max(infl, 1.0), r


def _levenberg_marquardt(fun: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]], x0: np.ndarray,
                         lo: np.ndarray, hi: np.ndarray, *, max_iter: int = 60, rtol: float = 1e-9) -> np.ndarray:
    """Levenberg-Marquardt (Marquardt's diagonal scaling) with steps clipped to the bounds.

    A few poles on a few hundred bins: scipy's trust-region reflective solver spent
    most of its time in its own bookkeeping here (60 iterations per fit at 1e-10
    tolerances); this stops when the cost changes by less than ``rtol``.
    """
    x = np.clip(np.asarray(x0, float), lo, hi)
    if x.size == 0:
        return x
    r, J = fun(x)
    cost = float(r @ r)
    lam = 1e-3
    for _ in range(max_iter):
        g = J.T @ r
        H = J.T @ J
        d = np.diag(H).copy()
        d[d <= 0] = 1.0
        improved = False
        for _ in range(12):
            try:
                step = np.linalg.solve(H + lam * np.diag(d), -g)
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            xn = np.clip(x + step, lo, hi)
            rn, Jn = fun(xn)
            cn = float(rn @ rn)
            if cn < cost:
                improved = True
                break
            lam *= 4.0
        if not improved:
            break
        done = cost - cn <= rtol * cost
        x, r, J, cost = xn, rn, Jn, cn
        lam = max(lam / 5.0, 1e-12)
        if done:
            break
    return x


def _fit_new_pole(model: _Model, theta: np.ndarray, new: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fit only the new pole, the others fixed (a cheap screen of a candidate)."""
    lo, hi = _bounds(model, 1)
    k = theta.size

    def fun(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r, J = model.residual_and_jacobian(np.r_[theta, x])
        return r, J[:, k:]

    x = _levenberg_marquardt(fun, new, lo + 1e-9, hi - 1e-9, max_iter=15, rtol=1e-5)
    th = np.r_[theta, x]
    return th, model.solve(th)[0]


def _peaks(model: _Model, k: int, exclude: list[float], M: np.ndarray | None = None) -> list[tuple[float, float]]:
    """Candidate (frequency, zeta) where the data exceed the current model ``M`` most, most prominent first."""
    ref = model.E * model.norm if M is None else np.maximum(M, model.floor)
    R = _smooth(model.P / ref, 3)
    idx, props = signal.find_peaks(np.log(R), prominence=0.05)
    order = np.argsort(props["prominences"])[::-1] if idx.size else []
    out: list[tuple[float, float]] = []
    for i in (idx[order] if idx.size else []):
        fp = float(model.f[i])
        if any(abs(fp - e) < 0.03 * e for e in exclude):
            continue
        half = R[i] / 2.0
        a = i
        while a > 0 and R[a] > half:
            a -= 1
        b = i
        while b < R.size - 1 and R[b] > half:
            b += 1
        z = (model.f[b] - model.f[a]) / (2.0 * fp)
        out.append((fp, float(np.clip(z, 0.01, 0.4))))
        if len(out) >= k:
            break
    return out


# ----------------------------------------------------------------------------- public


def smoothed_periodogram(X: np.ndarray, fs: float, resolution: float = 1.0) -> tuple[np.ndarray, np.ndarray, int]:
    """Periodogram of the whole record (columns summed), averaged over blocks of ``resolution`` Hz.

    The Fourier transform of a whole record of a linear system's response is exactly
    ``H X``, transients included; Welch's segments cut the ringing of a resonance at
    every boundary and broaden its peak (by about the decay time over the segment:
    +0.7 % in damping for 0.05 s against 1.28 s).  Averaging neighbouring bins instead
    (Daniell's estimator) keeps ``|H|^2 |X|^2`` exact up to ``|H|^2``'s curvature over a
    block.  A 1 % cosine taper at the ends keeps a record that does not start or end
    at rest from leaking.  Returns ``(freqs, psd, bins_per_block)``.
    """
    X = np.atleast_2d(np.asarray(X).T).T
    n = X.shape[0]
    taper = signal.windows.tukey(n, 0.02).astype(np.float32)
    nfft = sp_fft.next_fast_len(n, real=True)
    # single precision: the blocks average hundreds of bins, 1e-7 relative rounding is far below their scatter
    Xc = X.astype(np.float32)
    Xc -= X.mean(axis=0).astype(np.float32)
    Xc *= taper[:, None]
    Z = sp_fft.rfft(Xc, nfft, axis=0, workers=-1)
    del Xc
    P = np.einsum("ij,ij->i", Z.view(np.float32).reshape(Z.shape[0], -1), Z.view(np.float32).reshape(Z.shape[0], -1),
                  dtype=np.float64)
    P *= 2.0 / (fs * float(np.sum(taper.astype(float) ** 2)))
    k = max(1, int(round(resolution * nfft / fs)))
    m = (P.size - 1) // k
    blocks = P[1:1 + m * k].reshape(m, k).mean(axis=1)
    f = (np.arange(m) * k + (k + 1) / 2.0) * fs / nfft
    return f, blocks, k


def window_correlation(win: np.ndarray, lags: int = 4) -> float:
    """``1 + 2 sum_m rho_m^2``: variance inflation of a sum over neighbouring periodogram bins.

    ``rho_m = |sum w^2 e^{-j 2 pi n m / M}| / sum w^2`` is the correlation of the Fourier
    coefficients of a windowed segment ``m`` bins apart (Percival and Walden, ch. 6); the
    power values correlate as ``rho_m^2``.  Kaiser beta 6 (Klipper's window): 1.96.
    """
    W = np.asarray(win, dtype=float) ** 2
    n = np.arange(W.size)
    rho = [abs(complex(np.sum(W * np.exp(-2j * math.pi * n * m / W.size)))) / float(W.sum()) for m in range(1, lags + 1)]
    return 1.0 + 2.0 * float(sum(r * r for r in rho))


def welch_dispersion(win: np.ndarray, segments: float) -> float:
    """Variance of ``P_welch / P`` for Gaussian noise: ``(1 + 2 c^2) / K`` with ``c`` the half-overlap correlation."""
    W = np.asarray(win, dtype=float)
    h = W.size // 2
    c = float(W[h:] @ W[: W.size - h]) / float(W @ W)
    return (1.0 + 2.0 * c * c) / max(float(segments), 1.0)


#: :func:`window_correlation` of Klipper's Welch window (Kaiser, beta 6): its PSD files' bins.
KAISER6_CORRELATION = 1.96


def welch_psd(y: np.ndarray, fs: float, resolution: float = 1.0) -> tuple[np.ndarray, np.ndarray, float]:
    """One-sided Welch PSD with segments of about ``1/resolution`` s (power of two samples).

    Klipper's estimator (shaper_calibrate.py: Kaiser window, beta 6, half overlap, each
    segment's mean removed), so that its spectra and ours agree where the segment
    lengths do; the columns of a 2-D ``y`` are summed (Klipper's ``psd_xyz``).  All
    segments of all columns go through one batched FFT.  Returns ``(freqs, psd, n_segments)``.
    """
    Y = np.atleast_2d(np.asarray(y, dtype=float).T).T
    n = Y.shape[0]
    M = 1 << int(math.ceil(math.log2(max(fs / resolution, 16))))
    M = min(M, 1 << int(math.floor(math.log2(max(n // 4, 16)))))
    step = M // 2
    k = max(1, (n - M) // step + 1)
    win = np.kaiser(M, 6.0)
    P = np.zeros(M // 2 + 1)
    for j in range(Y.shape[1]):
        frames = np.lib.stride_tricks.sliding_window_view(Y[:, j], M)[::step][:k]
        frames = (frames - frames.mean(axis=1, keepdims=True)) * win
        P += np.sum(np.abs(sp_fft.rfft(frames, axis=1, workers=-1)) ** 2, axis=0)
    P *= 1.0 / (fs * float(win @ win) * k)
    P[1:-1] *= 2.0  # one-sided (DC and Nyquist once)
    return np.fft.rfftfreq(M, 1.0 / fs), P, float(k)


def fit_spectrum(spec: Spectrum, n_modes: int | str = "auto", *, max_modes: int = 4,
                 progress: Callable[[str], None] | None = None) -> SpectralModes:
    """Fit the modes of a resonance spectrum (module docstring).

    Raises :class:`~posicast.identify.NoModeFound` when no mode passes its test, or
    the only peaks are a rise at the band edge or broad background.
    """
    model = _Model(spec)
    if model.f.size < 12:
        raise ValueError(f"only {model.f.size} usable frequency bins in the band {spec.band[0]:g}-{spec.band[1]:g} Hz; "
                         "a PSD needs at least 12")
    fixed = n_modes != "auto"
    target = int(n_modes) if fixed else max_modes
    cells = search_cells(model.f[0], model.f[-1], 1.0 / max(spec.resolution if math.isfinite(spec.resolution)
                                                             else float(np.median(np.diff(model.f))), 1e-9))
    # the model without modes: excitation through a flat path, sweep lines, floor
    M0 = _fit(model, np.zeros(0), iterations=0)[1]
    # forward: screen the peaks of data / current model by fitting the new pole alone, fit the best
    # jointly, and go on while it lowers the (relative) residual by more than 1 %; which of these modes
    # the data demand is decided afterwards, against the dispersion of the full model
    theta, M_cur = np.zeros(0), M0
    rss_cur = float(np.sum(model.residual(theta) ** 2))
    while theta.size // 2 < target:
        have = [math.exp(theta[2 * k]) / (2 * math.pi) for k in range(theta.size // 2)]
        best = None
        for fp, zp in _peaks(model, 4, have, M_cur):
            th, _ = _fit_new_pole(model, theta, np.array([math.log(2 * math.pi * fp), zp]))
            rss = float(np.sum(model.residual(th) ** 2))
            if best is None or rss < best[0]:
                best = (rss, th)
        if best is None:
            break
        th, M = _fit(model, best[1], iterations=0, rtol=1e-6)
        rss = float(np.sum(model.residual(th) ** 2))
        if rss > 0.99 * rss_cur:
            break
        theta, M_cur, rss_cur = th, M, rss
        if progress:
            progress(f"fitted {theta.size // 2} mode(s): " + ", ".join(
                f"{math.exp(theta[2 * k]) / (2 * math.pi):.2f} Hz" for k in range(theta.size // 2)))
    M0 = _fit(model, np.zeros(0), iterations=3)[1]
    dev0 = _deviance(model, M0)
    if theta.size:
        theta, M_cur = _fit(model, theta, iterations=3)  # Whittle reweighting of the final model
    dev_cur = _deviance(model, M_cur)
    # backward: test each mode against the model without it, the other poles fixed (dispersion of the full model);
    # drop the least significant failing one and refit, until all pass
    while True:
        n = theta.size // 2
        if n == 0:
            raise NoModeFound(_no_mode_message(model, M0, cells))
        phi, infl, _ = _dispersion(model, M_cur, 2 * n + 2 * n + 3)
        if model.correlation is not None:
            infl = model.correlation
        scale = max(phi * infl, 1e-12)  # the intervals' scale: the scatter observed
        test_scale = max(max(phi, model.dispersion_floor or 0.0) * infl, 1e-12)  # tests: never below theory
        tests, comps = [], []
        for k in range(n):
            # the other poles stay where they are: refitted, a spurious mode would move in to replace it
            Mk = model.solve(np.delete(theta, [2 * k, 2 * k + 1]))[0]
            dk = _deviance(model, Mk)
            lr = max(dk - dev_cur, 0.0) / test_scale
            p = float(stats.chi2.sf(lr, 4))  # its pole and two numerator coefficients
            tests.append(ModeTest(lr, 4, p, cells, min(1.0, p * cells),
                                  float(min(max((dk - dev_cur) / max(dev0 - dev_cur, 1e-300), 0.0), 1.0))))
            comps.append(M_cur - Mk)
        bad = [k for k in range(n) if not tests[k].significant]
        if not bad:  # a fixed n_modes is the most asked for: modes the data do not demand still go
            break
        worst = max(bad, key=lambda k: tests[k].p_adjusted)
        if progress:
            progress(f"dropped {math.exp(theta[2 * worst]) / (2 * math.pi):.2f} Hz: {tests[worst].describe()}")
        if n == 1:
            raise NoModeFound(_no_mode_message(model, M0, cells))
        theta, M_cur = _fit(model, np.delete(theta, [2 * worst, 2 * worst + 1]))
        dev_cur = _deviance(model, M_cur)
        model.weights = 1.0 / np.maximum(M_cur, model.floor)
    notes: list[str] = []
    # covariance of the poles: Gauss-Newton of the weighted residual, scaled by dispersion x correlation
    J = model.jacobian(theta)
    JTJ = J.T @ J
    try:
        C = np.linalg.inv(JTJ) * scale
    except np.linalg.LinAlgError:
        C = np.linalg.pinv(JTJ) * scale
    tq = float(stats.norm.ppf(0.975))
    modes, ivs, edges, shares = [], [], [], []
    total = float(np.sum(np.maximum(M_cur, 0.0)))
    for k in range(n):
        lw, z = theta[2 * k], theta[2 * k + 1]
        sw = math.sqrt(max(C[2 * k, 2 * k], 0.0))
        sz = math.sqrt(max(C[2 * k + 1, 2 * k + 1], 0.0))
        m = Mode(math.exp(lw), float(z))
        modes.append(m)
        # an unresolved pole (singular curvature) gets an interval as wide as the band allows
        w_lo, w_hi = math.log(math.pi * model.f[0]), math.log(4 * math.pi * model.f[-1])
        ivs.append(((math.exp(max(lw - tq * sw, w_lo)), math.exp(min(lw + tq * sw, w_hi))),
                    (max(z - tq * sz, 0.0), min(z + tq * sz, 0.999))))
        edges.append(_at_edge(m, model.f[0], model.f[-1]))
        shares.append(float(np.sum(np.maximum(comps[k], 0.0))) / max(total, 1e-300))
    order = [int(i) for i in np.argsort([m.omega for m in modes])]
    fit = SpectralFit(model.f, model.P, M_cur, M0, [comps[i] for i in order], phi, infl)
    broad = [i for i in order if modes[i].zeta >= BROAD_ZETA]
    for i in broad:
        notes.append(f"a broad feature at {modes[i].freq_hz:.1f} Hz (zeta {modes[i].zeta:.2f}) is part of the "
                     "fitted background, not a resonance")
    # a mode whose own peak stays under 1/20 of the spectrum's maximum cannot matter to a shaper (it is
    # Klipper's threshold too): a feature of the fit (the slow sweep's lines, a ripple), not reported
    top = float(np.max(M_cur))
    minor = [i for i in order if i not in broad and float(np.max(comps[i])) < MINOR_SHARE * top]
    for i in minor:
        notes.append(f"a small peak at {modes[i].freq_hz:.1f} Hz (under {100 * MINOR_SHARE:.0f} % of the "
                     "spectrum's maximum) is fitted but not reported")
    keep = [i for i in order if i not in broad and i not in minor]
    if not [i for i in keep if not edges[i]]:
        i = keep[-1] if keep else max(order, key=lambda j: float(np.max(comps[j])))
        m = modes[i]
        what = ("a rise at the edge of the excited band" if edges[i] else
                "a broad feature with no resonant peak" if i in broad else "too small to matter")
        raise NoModeFound(f"no resonance found in {model.f[0]:.1f}-{model.f[-1]:.1f} Hz: the only peak "
                          f"({m.freq_hz:.1f} Hz, zeta {m.zeta:.2f}) is {what}", m, tests[i])
    for i in keep:
        if edges[i]:
            notes.append(f"{modes[i].freq_hz:.1f} Hz lies at the edge of the excited band: reported, not resolved")
    return SpectralModes([modes[i] for i in keep], [ivs[i] for i in keep], [tests[i] for i in keep],
                         [edges[i] for i in keep], [shares[i] for i in keep], fit, notes)


def _at_edge(mode: Mode, f_lo: float, f_hi: float) -> bool:
    f = mode.freq_hz
    half = max(mode.zeta, 2e-3) * f
    return bool(f - half < f_lo or f + half > f_hi)


def _no_mode_message(model: _Model, M0: np.ndarray, cells: float) -> str:
    ratio = model.P / np.maximum(M0, 1e-300)
    i = int(np.argmax(ratio))
    return (f"no resonance found in {model.f[0]:.1f}-{model.f[-1]:.1f} Hz: the spectrum is explained by the "
            f"excitation and the noise floor (largest excess {ratio[i]:.2g}x at {model.f[i]:.1f} Hz is within "
            f"noise after {cells:.0f} frequency cells)")
