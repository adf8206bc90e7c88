"""Power spectral density estimates of a record, and how each bin of an estimate averages the true PSD.

* :func:`welch_psd`: Klipper's estimator (Kaiser window beta 6, half overlap), so its
  spectra and ours agree where the segment lengths do;
* :func:`smoothed_periodogram`: the whole record's periodogram averaged over blocks
  (Daniell), which keeps a resonance's ringing that Welch's segments cut;
* :func:`welch_kernel`, :func:`block_kernel`: each bin's averaging kernel (the spectral
  model is averaged the same way, :class:`~.spectral_model.Spectrum`);
* :func:`window_correlation`, :func:`welch_dispersion`: the correlation of neighbouring
  bins and the scatter of an estimate, for the significance tests.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
from scipy import fft as sp_fft
from scipy import signal

from .. import _validate as v

__all__ = ["PSDEstimate", "BinKernel", "welch_psd", "smoothed_periodogram", "welch_kernel", "block_kernel",
           "window_correlation", "welch_dispersion", "KAISER6_CORRELATION"]


class PSDEstimate(NamedTuple):
    """A one-sided PSD estimate: bin frequencies (Hz), the PSD, and how many raw estimates each bin averages
    (Welch segments, or periodogram bins per block)."""

    freqs: np.ndarray
    psd: np.ndarray
    averaged: float


class BinKernel(NamedTuple):
    """How a bin averages the true PSD: offsets in bins and weights (summing to 1)."""

    offsets: np.ndarray
    weights: np.ndarray


def _record_args(X: Any, name: str, fs: Any, resolution: Any) -> tuple[np.ndarray, float, float]:
    """A record (1-D, or 2-D with one column per channel, made 2-D), its rate and the resolution asked for."""
    X = v.strict_real_array(X, name)
    if X.ndim not in (1, 2):
        raise ValueError(f"{name} must be 1-D or 2-D (columns summed), got shape {X.shape}")
    return np.atleast_2d(X.T).T, v.positive(fs, "sample_rate"), v.positive(resolution, "resolution")


@v.renamed_keywords(fs="sample_rate")
def smoothed_periodogram(X: np.ndarray, sample_rate: float, resolution: float = 1.0) -> PSDEstimate:
    """Periodogram of the whole record (columns summed), averaged over blocks of ``resolution`` Hz.

    The Fourier transform of a whole record of a linear system's response is exactly
    ``H X``, transients included; Welch's segments cut the ringing of a resonance at
    every boundary and broaden its peak (by about the decay time over the segment:
    +0.7 % in damping for 0.05 s against 1.28 s).  Averaging neighbouring bins instead
    (Daniell's estimator) keeps ``|H|^2 |X|^2`` exact up to ``|H|^2``'s curvature over a
    block.  A 1 % cosine taper at the ends keeps a record that does not start or end
    at rest from leaking.  Returns ``(freqs, psd, bins_per_block)``.
    """
    fs = sample_rate  # the sample rate [Hz], fs in the formulas
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
    return PSDEstimate(f, blocks, k)


def welch_kernel(win: np.ndarray | None = None, half_width: float = 3.0, step: float = 0.5) -> BinKernel:
    """How a Welch bin averages the true PSD: the window's power response ``|W(delta)|^2``.

    Sampled every ``step`` bins over ``+-half_width`` bins (Kaiser beta 6, Klipper's
    window, by default: its main lobe spans about +-2.2 bins).  Returns ``(offsets, weights)``.
    """
    win = np.kaiser(256, 6.0) if win is None else np.asarray(win, dtype=float)
    delta = np.arange(-half_width, half_width + 1e-9, step)
    n = np.arange(win.size)
    W = np.abs(np.exp(-2j * math.pi * np.outer(delta, n) / win.size) @ win) ** 2
    return BinKernel(delta, W / W.sum())


def block_kernel(sub: int = 8) -> BinKernel:
    """How a block average of raw periodogram bins averages the true PSD: uniformly over the block."""
    return BinKernel((np.arange(sub) + 0.5) / sub - 0.5, np.full(sub, 1.0 / sub))


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


@v.renamed_keywords(fs="sample_rate")
def welch_psd(y: np.ndarray, sample_rate: float, resolution: float = 1.0) -> PSDEstimate:
    """One-sided Welch PSD with segments of about ``1/resolution`` s (power of two samples).

    Klipper's estimator (shaper_calibrate.py: Kaiser window, beta 6, half overlap, each
    segment's mean removed), so that its spectra and ours agree where the segment
    lengths do; the columns of a 2-D ``y`` are summed (Klipper's ``psd_xyz``).  All
    segments of all columns go through one batched FFT.  Returns ``(freqs, psd, n_segments)``.
    """
    fs = sample_rate  # the sample rate [Hz], fs in the formulas
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
    return PSDEstimate(np.fft.rfftfreq(M, 1.0 / fs), P, float(k))
