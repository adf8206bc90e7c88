"""Output-only identification from a power spectrum: modes in a resonance test's PSD.

The measured acceleration PSD of a resonance test is modelled as

    M(f) = E(f) R(f^2) / prod_k |D_k(j 2 pi f)|^2 + g / f^2 + N,
    D_k(s) = s^2 + 2 zeta_k w_k s + w_k^2

``E`` is the test's excitation shape (:mod:`.excitation`: ``f^2`` for Klipper's
sweep, times Klipper's normalisation for its ``calibration_data`` files), seen
through the machine (``sum_c |H_c|^2 = R / prod |D_k|^2`` for the transmissibility
from the commanded to the measured acceleration, over any number of channels: see
:meth:`_Model.columns`); ``g / f^2`` the slow sweep's lines (below about 15 Hz, where
``|H|`` is nearly constant; modes there are flagged as unresolved) and ``N`` the
sensor floor.  The model is **linear** in the polynomial ``R`` (Chebyshev basis,
degree ``2 n``), ``g`` and ``N``: only the poles ``(ln w_k, zeta_k)`` are searched
(variable projection).  It is averaged over each bin the way the estimator
averages the true PSD (the Welch window's main lobe, or a block of the periodogram),
so peaks only a few bins wide are compared like with like.

The periodogram average at each bin is the true PSD times a scaled chi-square
variable, so the fit is the Whittle (gamma) maximum likelihood, computed by
iteratively reweighted least squares (weights ``1 / M``).  Its dispersion is
estimated from the residual (and for tests never taken below the estimator's own
``1/K``), the correlation of neighbouring bins comes from the estimator's window, and
both scale the Gauss-Newton covariance of the poles and the deviance tests.

Modes are added greedily from the excitation-normalised spectrum's peaks and each
is kept only when a likelihood-ratio test against the model without it passes
after allowing for the frequency search (:mod:`.significance`).  A mode whose
half-power band leaves the fitted band is a rise at the band edge, not a mode.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
from scipy import fft as sp_fft
from scipy import signal, stats

from .. import _validate as v
from ..modes import Mode
from .significance import MAX_MODES, ModeTest, NoModeFound, search_cells

__all__ = ["Spectrum", "SpectralFit", "SpectralModes", "fit_spectrum", "welch_psd", "smoothed_periodogram",
           "window_correlation", "welch_dispersion", "welch_kernel", "block_kernel", "BROAD_ZETA",
           "KAISER6_CORRELATION"]

_ZETA_BOUNDS = (2e-3, 0.6)
#: A fitted peak this broad (the resonant gain 1/(2 zeta) is near 1) is background, not a resonance.
BROAD_ZETA = 0.45
#: A mode whose peak is below this share of the spectrum's maximum is not reported (Klipper's 1/20).
MINOR_SHARE = 0.05
#: Below this frequency (Hz) a sweeping test's slow-sweep lines dominate the spectrum: modes there are flagged.
LOW_SWEEP_LIMIT = 15.0


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
    kernel : (offsets, weights), optional
        How each bin averages the true PSD: offsets in bins and weights (summing to 1),
        e.g. :func:`welch_kernel` for a Welch estimate (the window's main lobe) or
        :func:`block_kernel` for a block average.  The model is averaged the same way, so
        a peak a few bins wide is not broadened relative to the data (without it, Klipper's
        Kaiser window biased damping by +3-4 %).  None: point values.
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
    kernel: tuple[np.ndarray, np.ndarray] | None = None

    def __post_init__(self) -> None:
        f = v.strict_real_array(self.freqs, "freqs")
        P = v.strict_real_array(self.psd, "psd")
        E = v.strict_real_array(self.excitation, "excitation")
        if f.ndim != 1 or P.shape != f.shape or E.shape != f.shape or f.size < 4:
            raise ValueError(f"freqs, psd and excitation must be 1-D of one length (at least 4), got {f.shape}, "
                             f"{P.shape}, {E.shape}")
        if np.any(np.diff(f) <= 0) or f[0] < 0:
            raise ValueError("freqs must increase from >= 0 Hz")
        if np.any(P < 0) or np.any(E < 0):
            raise ValueError("psd and excitation must be >= 0")
        try:
            lo, hi = (v.real(b, "band") for b in self.band)
        except (TypeError, ValueError):
            raise ValueError(f"band must be two frequencies (low, high) in Hz, got {self.band!r}") from None
        if not 0 <= lo < hi:
            raise ValueError(f"band must satisfy 0 <= low < high, got ({lo:g}, {hi:g})")
        norm = None
        if self.normalisation is not None:
            norm = v.strict_real_array(self.normalisation, "normalisation")
            if norm.shape != f.shape or np.any(norm < 0):
                raise ValueError("normalisation must be >= 0, one value per frequency")
        if math.isfinite(self.resolution) and not self.resolution > 0:
            raise ValueError(f"resolution must be > 0 Hz, got {self.resolution:g}")
        for name in ("correlation", "dispersion_floor"):
            val = getattr(self, name)
            if val is not None and not (math.isfinite(val) and val > 0):
                raise ValueError(f"{name} must be > 0 or None, got {val!r}")
        object.__setattr__(self, "freqs", f)
        object.__setattr__(self, "psd", P)
        object.__setattr__(self, "excitation", E)
        object.__setattr__(self, "band", (lo, hi))
        object.__setattr__(self, "normalisation", norm)


@dataclass
class SpectralFit:
    """Details of a spectral fit beyond :class:`~posicast.identification.Identification`.

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
        self.low = spec.low_frequency and lo < 20.0
        self.weights = 1.0 / _smooth(self.P)
        self.floor = 0.05 / self.weights
        self.correlation = spec.correlation
        self.dispersion_floor = spec.dispersion_floor
        # the model is evaluated on sub-points of each bin and averaged with the estimator's kernel
        offsets, kw = spec.kernel if spec.kernel is not None else (np.zeros(1), np.ones(1))
        step = float(spec.resolution) if math.isfinite(spec.resolution) else float(np.median(np.diff(spec.freqs)))
        ff = (self.f[:, None] + np.asarray(offsets, float)[None, :] * step).ravel()
        ff = np.maximum(ff, 0.05 * step)
        self.kernel_weights = np.asarray(kw, float) / float(np.sum(kw))
        self.nsub = self.kernel_weights.size
        # excitation and normalisation between bins: linear interpolation of the smooth curves
        E = np.interp(ff, spec.freqs, spec.excitation)
        self.norm_f = np.interp(ff, spec.freqs, spec.normalisation) if spec.normalisation is not None else \
            np.ones_like(ff)
        self.E_parts = [E * self.norm_f]
        f2 = ff ** 2
        b0, b1 = self.f[0] ** 2, self.f[-1] ** 2
        x2 = (2 * f2 - (b0 + b1)) / (b1 - b0) if b1 > b0 else f2 * 0.0
        self.cheb = np.polynomial.chebyshev.chebvander(x2, 2 * MAX_MODES)
        self.W2 = (2 * math.pi * ff) ** 2
        extra = [(self.f[0] / ff) ** 2] if self.low else []  # the slow sweep's lines
        self.extra = self._reduce(np.column_stack(extra + [np.ones_like(ff)]) * self.norm_f[:, None])

    def _reduce(self, A: np.ndarray) -> np.ndarray:
        """Kernel average of sub-point columns ``[bins * nsub, k]`` onto the bins ``[bins, k]``."""
        if self.nsub == 1:
            return A
        return np.einsum("bsk,s->bk", A.reshape(self.f.size, self.nsub, A.shape[1]), self.kernel_weights)

    def _denominator(self, theta: np.ndarray) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
        """``prod_k |D_k|^2 / w_k^4`` and, per mode, ``d ln(.)/d ln w_k`` and ``d ln(.)/d zeta_k``."""
        den = np.ones_like(self.W2)
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

    def columns(self, theta: np.ndarray) -> np.ndarray:
        """``E R(f^2) / prod |D_k|^2`` with ``R`` a polynomial of degree ``2 n`` (Chebyshev basis), ``1/f^2``, 1.

        ``sum_c |H_c|^2`` over any number of channels is ``R(f^2) / prod_k |D_k(j 2 pi f)|^2``
        with ``R >= 0`` of degree ``2 n`` in ``f^2`` (the numerators of ``H_c`` have degree
        ``2 n`` in ``s``), and by spectral factorisation every such ``R`` is one channel's
        ``|numerator|^2``: one basis serves a single axis and Klipper's sum of axes.
        """
        return self._columns(theta)[0]

    def _columns(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
        """The columns, the modal columns on the kernel's sub-points, and the pole gradients of ``ln prod``."""
        n = theta.size // 2
        den, dl = self._denominator(theta)
        basis = self.cheb[:, : 2 * n + 1]
        # the slow sweep's lines (below ~15 Hz, where |H|^2 is nearly constant) are an extra column
        # outside the modes: putting them through the modes' denominator with a numerator of their own
        # bent the peaks and biased damping by +1 %; modes under 15 Hz are flagged instead
        modal = basis * (self.E_parts[0] / den)[:, None]
        return np.hstack([self._reduce(modal), self.extra]), modal, dl

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
        A, modal, dl = self._columns(theta)
        U, sv, Vt, scale = self._projection(A)
        y = self.P * self.weights
        proj = U.T @ y
        coef = (Vt.T @ (proj / sv)) / scale
        # d(A c)/d theta_k: only the modal columns depend on the poles, each through its factor -g_k
        q = modal @ coef[: modal.shape[1]]
        J = np.empty((self.f.size, theta.size))
        for k, g in enumerate(x for pair in dl for x in pair):
            d = self._reduce((-q * g)[:, None])[:, 0] * self.weights
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
    """Candidate (frequency, zeta) where the data exceed the current model ``M`` most, most prominent first.

    Peaks of ``log(P / M)`` lightly smoothed (a 3-bin mean: a median would flatten a peak
    one or two bins wide); the damping guess is the half width of the excess ``P/M - 1``.
    """
    ref = model._reduce(model.E_parts[0][:, None])[:, 0] if M is None else np.maximum(M, model.floor)
    R = model.P / ref
    L = np.convolve(np.log(np.maximum(R, 1e-300)), np.ones(3) / 3.0, mode="same")
    idx, props = signal.find_peaks(L, prominence=0.05)
    order = np.argsort(props["prominences"])[::-1] if idx.size else []
    step = float(np.median(np.diff(model.f))) if model.f.size > 1 else 1.0
    out: list[tuple[float, float]] = []
    for i in (idx[order] if idx.size else []):
        i = int(max(i - 1, 0) + np.argmax(R[max(i - 1, 0):i + 2]))  # the highest bin next to the smoothed peak
        fp = float(model.f[i])
        if any(abs(fp - e) < 0.03 * e for e in exclude):
            continue
        X = R - 1.0
        half = 0.5 * X[i]
        a = i
        while a > 0 and X[a] > half:
            a -= 1
        b = i
        while b < R.size - 1 and X[b] > half:
            b += 1
        width = max(float(model.f[b] - model.f[a]) - step, step)  # between the half-power crossings
        out.append((fp, float(np.clip(width / (2.0 * fp), 0.003, 0.4))))
        if len(out) >= k:
            break
    return out


# ----------------------------------------------------------------------------- public


def _record_args(X: Any, name: str, fs: Any, resolution: Any) -> tuple[np.ndarray, float, float]:
    """A record (1-D, or 2-D with one column per channel, made 2-D), its rate and the resolution asked for."""
    X = v.strict_real_array(X, name)
    if X.ndim not in (1, 2):
        raise ValueError(f"{name} must be 1-D or 2-D (columns summed), got shape {X.shape}")
    return np.atleast_2d(X.T).T, v.positive(fs, "fs"), v.positive(resolution, "resolution")


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
    X, fs, resolution = _record_args(X, "X", fs, resolution)
    n = X.shape[0]
    if not 2.0 * fs / n <= resolution <= fs / 8.0:
        raise ValueError(f"resolution must be in [{2.0 * fs / n:.3g}, {fs / 8.0:.3g}] Hz for {n} samples at {fs:g} Hz, "
                         f"got {resolution:g}")
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


def welch_kernel(win: np.ndarray | None = None, half_width: float = 3.0, step: float = 0.5
                 ) -> tuple[np.ndarray, np.ndarray]:
    """How a Welch bin averages the true PSD: the window's power response ``|W(delta)|^2``.

    Sampled every ``step`` bins over ``+-half_width`` bins (Kaiser beta 6, Klipper's
    window, by default: its main lobe spans about +-2.2 bins).  Returns ``(offsets, weights)``.
    """
    win = np.kaiser(256, 6.0) if win is None else np.asarray(win, dtype=float)
    delta = np.arange(-half_width, half_width + 1e-9, step)
    n = np.arange(win.size)
    W = np.abs(np.exp(-2j * math.pi * np.outer(delta, n) / win.size) @ win) ** 2
    return delta, W / W.sum()


def block_kernel(sub: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """How a block average of raw periodogram bins averages the true PSD: uniformly over the block."""
    return (np.arange(sub) + 0.5) / sub - 0.5, np.full(sub, 1.0 / sub)


def window_correlation(win: np.ndarray, lags: int = 4) -> float:
    """``1 + 2 sum_m rho_m^2``: variance inflation of a sum over neighbouring periodogram bins.

    ``rho_m = |sum w^2 e^{-j 2 pi n m / M}| / sum w^2`` is the correlation of the Fourier
    coefficients of a windowed segment ``m`` bins apart (Percival and Walden, ch. 6); the
    power values correlate as ``rho_m^2``.  Kaiser beta 6 (Klipper's window): 1.96.
    """
    W = v.strict_real_array(win, "win") ** 2
    lags = v.integer_in_range(lags, "lags", 1, 64)
    if W.ndim != 1 or W.size < 4 or not W.sum() > 0:
        raise ValueError("win must be a window of at least 4 samples, not all 0")
    n = np.arange(W.size)
    rho = [abs(complex(np.sum(W * np.exp(-2j * math.pi * n * m / W.size)))) / float(W.sum()) for m in range(1, lags + 1)]
    return 1.0 + 2.0 * float(sum(r * r for r in rho))


def welch_dispersion(win: np.ndarray, segments: float) -> float:
    """Variance of ``P_welch / P`` for Gaussian noise: ``(1 + 2 c^2) / K`` with ``c`` the half-overlap correlation."""
    W = v.strict_real_array(win, "win")
    if W.ndim != 1 or W.size < 4 or not float(W @ W) > 0:
        raise ValueError("win must be a window of at least 4 samples, not all 0")
    segments = v.positive(segments, "segments")
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
    Y, fs, resolution = _record_args(y, "y", fs, resolution)
    n = Y.shape[0]
    if n < 64:
        raise ValueError(f"y needs at least 64 samples for a Welch estimate, got {n}")
    if fs / resolution > 1e8:
        raise ValueError(f"fs / resolution = {fs / resolution:.3g} samples per segment; raise resolution")
    M = 1 << int(math.ceil(math.log2(max(fs / resolution, 16))))
    M = min(M, 1 << int(math.floor(math.log2(max(n // 4, 16)))))
    step = M // 2
    k = max(1, (n - M) // step + 1)
    win = np.kaiser(M, 6.0)
    P = np.zeros(M // 2 + 1)
    # single precision for the segments (the estimate averages k of them: 1e-7 relative rounding is far
    # below its scatter), double for the sum
    win32 = win.astype(np.float32)
    for j in range(Y.shape[1]):
        frames = np.lib.stride_tricks.sliding_window_view(Y[:, j].astype(np.float32), M)[::step][:k]
        frames = (frames - frames.mean(axis=1, keepdims=True)) * win32
        Z = sp_fft.rfft(frames, axis=1, workers=-1)
        R = Z.view(np.float32).reshape(k, -1, 2)
        P += np.einsum("kfc,kfc->f", R, R, dtype=np.float64)
    P *= 1.0 / (fs * float(win @ win) * k)
    P[1:-1] *= 2.0  # one-sided (DC and Nyquist once)
    return np.fft.rfftfreq(M, 1.0 / fs), P, float(k)


def fit_spectrum(spec: Spectrum, n_modes: int | str = "auto", *, max_modes: int = 4,
                 progress: Callable[[str], None] | None = None) -> SpectralModes:
    """Fit the modes of a resonance spectrum (module docstring).

    ``n_modes`` is the most modes to fit (1 to 6) or ``"auto"`` (up to ``max_modes``);
    modes the data do not demand are dropped either way.  Raises
    :class:`~posicast.identification.NoModeFound` when no mode passes its test, or the only
    peaks are a rise at the band edge or broad background.
    """
    if not isinstance(spec, Spectrum):
        raise TypeError(f"spec must be a Spectrum, got {type(spec).__name__}")
    if n_modes != "auto":
        n_modes = v.integer_in_range(n_modes, "n_modes", 1, MAX_MODES)
    max_modes = v.integer_in_range(max_modes, "max_modes", 1, MAX_MODES)
    model = _Model(spec)
    if model.f.size < 12:
        raise ValueError(f"only {model.f.size} usable frequency bins in the band {spec.band[0]:g}-{spec.band[1]:g} Hz; "
                         "a PSD needs at least 12")
    fixed = n_modes != "auto"
    target = int(n_modes) if fixed else max_modes
    bin_step = spec.resolution if math.isfinite(spec.resolution) else float(np.median(np.diff(model.f)))
    cells = search_cells(model.f[0], model.f[-1], 1.0 / max(bin_step, 1e-9))
    # the model without modes: excitation through a flat path, sweep lines, floor
    M0 = _fit(model, np.zeros(0), iterations=0)[1]
    # forward: screen the peaks of data / current model by fitting the new pole alone, fit the best
    # jointly, and go on while it lowers the (relative) residual by more than 1 %; which of these modes
    # the data demand is decided afterwards, against the dispersion of the full model
    theta, M_cur = np.zeros(0), M0
    first_model = M0
    rss_cur = float(np.sum(model.residual(theta) ** 2))
    while theta.size // 2 < target:
        have = [math.exp(theta[2 * k]) / (2 * math.pi) for k in range(theta.size // 2)]
        best = None
        for fp, zp in _peaks(model, 4, have, M_cur):
            # the width guess is poor while the model still lacks the mode: try a ladder of dampings too
            starts = [zp] + [z for z in (0.005, 0.02, 0.06, 0.2) if not 0.67 < z / zp < 1.5]
            for z0 in starts:
                th, _ = _fit_new_pole(model, theta, np.array([math.log(2 * math.pi * fp), z0]))
                rss = float(np.sum(model.residual(th) ** 2))
                if best is None or rss < best[0]:
                    best = (rss, th)
        if best is None:
            break
        th, M = _fit(model, best[1], iterations=0, rtol=1e-6)
        rss = float(np.sum(model.residual(th) ** 2))
        # a second start: the n most prominent peaks of the spectrum over the mode-free model, each
        # with its damping guess (greedy steps can settle on one broad mode covering two peaks)
        n_new = theta.size // 2 + 1
        direct = _peaks(model, n_new, [], first_model)
        found = sorted(math.exp(th[2 * k]) / (2 * math.pi) for k in range(n_new))
        same = len(direct) == n_new and all(abs(a - b) < 0.03 * b for a, b in zip(sorted(p for p, _ in direct), found))
        if len(direct) == n_new and not same:  # greedy steps already on those peaks: nothing to gain
            for zl in (None, 0.02, 0.05, 0.1):  # the width guesses, then one damping for all
                th0 = np.array([[math.log(2 * math.pi * fp), zp if zl is None else zl] for fp, zp in direct]).ravel()
                th2, M2 = _fit(model, th0, iterations=0, rtol=1e-6)
                rss2 = float(np.sum(model.residual(th2) ** 2))
                if rss2 < rss:
                    th, M, rss = th2, M2, rss2
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
            # a peak narrower than a bin can sit at several places within each bin: that many more tests
            width = 2.0 * theta[2 * k + 1] * math.exp(theta[2 * k]) / (2 * math.pi)
            cells_k = cells * max(1.0, bin_step / max(width, 1e-12))
            tests.append(ModeTest(lr, 4, p, cells_k, min(1.0, p * cells_k),
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
        if model.low and modes[i].freq_hz < LOW_SWEEP_LIMIT and not edges[i]:
            # the slow sweep's lines (odd multiples of 1/P) dominate there and are not a smooth excitation
            edges[i] = True
            notes.append(f"{modes[i].freq_hz:.1f} Hz lies where the slow sweep's lines dominate (under "
                         f"{LOW_SWEEP_LIMIT:.0f} Hz): reported, not resolved")
        if modes[i].zeta <= 1.5 * _ZETA_BOUNDS[0]:
            edges[i] = True
            notes.append(f"{modes[i].freq_hz:.1f} Hz has the smallest damping the fit allows: the peak is "
                         "narrower than the resolution, its damping is not resolved")
        elif edges[i]:
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
