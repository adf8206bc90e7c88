"""The spectral model of a resonance test's PSD, and the measured spectrum it is fitted to.

The measured acceleration PSD of a resonance test is modelled as

    M(f) = E(f) R(f^2) / prod_k |D_k(j 2 pi f)|^2 + g / f^2 + N,
    D_k(s) = s^2 + 2 zeta_k w_k s + w_k^2

``E`` is the test's excitation shape (:mod:`.excitation`: ``f^2`` for Klipper's
sweep, times Klipper's normalisation for its ``calibration_data`` files), seen
through the machine (``sum_c |H_c|^2 = R / prod |D_k|^2`` for the transmissibility
from the commanded to the measured acceleration, over any number of channels: see
:meth:`SpectralModel.columns`); ``g / f^2`` the slow sweep's lines (below about 15 Hz, where
``|H|`` is nearly constant; modes there are flagged as unresolved) and ``N`` the
sensor floor.  The model is **linear** in the polynomial ``R`` (Chebyshev basis,
degree ``2 n``), ``g`` and ``N``: only the poles ``(ln w_k, zeta_k)`` are searched
(variable projection, :mod:`.spectral`).  It is averaged over each bin the way the estimator
averages the true PSD (the Welch window's main lobe, or a block of the periodogram),
so peaks only a few bins wide are compared like with like.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .. import _validate as v
from .significance import MAX_MODES

__all__ = ["Spectrum", "SpectralModel", "ZETA_BOUNDS", "pole_bounds"]

#: The damping ratios the spectral fit searches.
ZETA_BOUNDS = (2e-3, 0.6)


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
        bins (``1 + 2 sum rho_m^2`` of the estimator's window, :func:`~.welch.window_correlation`);
        estimated from the residual when None.
    dispersion_floor : float, optional
        Known variance of ``psd / true psd`` for noise (``1/K`` for ``K`` averaged
        periodograms); the significance tests never use a smaller dispersion.
    kernel : (offsets, weights), optional
        How each bin averages the true PSD: offsets in bins and weights (summing to 1),
        e.g. :func:`~.welch.welch_kernel` for a Welch estimate (the window's main lobe) or
        :func:`~.welch.block_kernel` for a block average.  The model is averaged the same way, so
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
        f, P, E = _spectrum_arrays(self.freqs, self.psd, self.excitation)
        lo, hi = _band(self.band)
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


def _spectrum_arrays(freqs: object, psd: object, excitation: object) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frequencies (increasing from >= 0 Hz), PSD and excitation (>= 0), 1-D of one length (at least 4)."""
    f = v.strict_real_array(freqs, "freqs")
    P = v.strict_real_array(psd, "psd")
    E = v.strict_real_array(excitation, "excitation")
    if f.ndim != 1 or P.shape != f.shape or E.shape != f.shape or f.size < 4:
        raise ValueError(f"freqs, psd and excitation must be 1-D of one length (at least 4), got {f.shape}, "
                         f"{P.shape}, {E.shape}")
    if np.any(np.diff(f) <= 0) or f[0] < 0:
        raise ValueError("freqs must increase from >= 0 Hz")
    if np.any(P < 0) or np.any(E < 0):
        raise ValueError("psd and excitation must be >= 0")
    return f, P, E


def _band(band: object) -> tuple[float, float]:
    """Two frequencies ``0 <= low < high`` in Hz."""
    try:
        lo, hi = (v.real(b, "band") for b in band)  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        raise ValueError(f"band must be two frequencies (low, high) in Hz, got {band!r}") from None
    if not 0 <= lo < hi:
        raise ValueError(f"band must satisfy 0 <= low < high, got ({lo:g}, {hi:g})")
    return lo, hi


class SpectralModel:
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
        self._factors: dict[tuple[float, float], tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]] = {}

    def _reduce(self, A: np.ndarray) -> np.ndarray:
        """Kernel average of sub-point columns ``[bins * nsub, k]`` onto the bins ``[bins, k]``."""
        if self.nsub == 1:
            return A
        return np.einsum("bsk,s->bk", A.reshape(self.f.size, self.nsub, A.shape[1]), self.kernel_weights)

    def _denominator(self, theta: np.ndarray) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
        """``prod_k |D_k|^2 / w_k^4`` and, per mode, ``d ln(.)/d ln w_k`` and ``d ln(.)/d zeta_k``."""
        den = np.ones_like(self.W2)
        grads = []
        for k in range(theta.size // 2):
            factor, grad = self._mode_factor(float(theta[2 * k]), float(theta[2 * k + 1]))
            den = den * factor
            grads.append(grad)
        return den, grads

    def _mode_factor(self, log_w: float, z: float) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
        """One mode's factor ``|D_k|^2 / w_k^4`` and its two log-gradients, remembered for the last few poles:
        the forward selection screens a new pole with the others held fixed (issue #15; the same numbers)."""
        key = (log_w, z)
        hit = self._factors.get(key)
        if hit is not None:
            return hit
        W2 = self.W2
        w = math.exp(log_w)
        w2 = w * w
        re = w2 - W2
        D2 = re * re + 4.0 * z * z * w2 * W2
        out = (D2 / (w2 * w2), ((4.0 * w2 * re + 8.0 * z * z * w2 * W2) / D2 - 4.0, 8.0 * z * w2 * W2 / D2))
        if len(self._factors) >= 16:
            self._factors.pop(next(iter(self._factors)))
        self._factors[key] = out
        return out

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
        r, jac = self.residual_and_jacobian_lazy(theta)
        return r, jac()

    def residual_and_jacobian_lazy(self, theta: np.ndarray, first: int = 0
                                   ) -> tuple[np.ndarray, Callable[[], np.ndarray]]:
        """The residual at ``theta`` and a function computing the Jacobian's columns ``first:`` there.

        A Levenberg-Marquardt step that is rejected needs no Jacobian, and a fit of the
        last pole alone needs only its two columns (issue #15): both are asked for only when needed.
        """
        A, modal, dl = self._columns(theta)
        U, sv, Vt, scale = self._projection(A)
        y = self.P * self.weights
        proj = U.T @ y

        def jacobian() -> np.ndarray:
            coef = (Vt.T @ (proj / sv)) / scale
            # d(A c)/d theta_k: only the modal columns depend on the poles, each through its factor -g_k
            q = modal @ coef[: modal.shape[1]]
            G = np.column_stack([x for pair in dl for x in pair][first:])
            D = self._reduce(-q[:, None] * G) * self.weights[:, None]
            return -(D - U @ (U.T @ D))

        return y - U @ proj, jacobian


    def screen(self, theta: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, Callable[[], np.ndarray]]:
        """:meth:`residual_and_jacobian_lazy` of the poles ``theta`` plus one new pole per row of ``X``
        (``(ln w, zeta)``), all at once, with the Jacobian along the new pole only.

        Forward selection screens a dozen starts of a new pole with the others held fixed:
        batched, the per-call overhead of small arrays is paid once (issue #15).  Returns the
        residuals ``(C, bins)`` and a function giving the Jacobians ``(C, bins, 2)``.
        """
        den0, _ = self._denominator(theta)
        n = theta.size // 2 + 1
        W2 = self.W2[None, :]
        w2 = np.exp(2.0 * X[:, 0])[:, None]
        z = X[:, 1][:, None]
        re = w2 - W2
        D2 = re * re + 4.0 * z * z * w2 * W2
        den = den0[None, :] * (D2 / (w2 * w2))
        grads = np.stack([(4.0 * w2 * re + 8.0 * z * z * w2 * W2) / D2 - 4.0, 8.0 * z * w2 * W2 / D2], axis=2)
        modal = self.cheb[None, :, : 2 * n + 1] * (self.E_parts[0][None, :] / den)[:, :, None]
        C, k = X.shape[0], modal.shape[2]
        A = np.concatenate([self._reduce_batch(modal), np.broadcast_to(self.extra, (C,) + self.extra.shape)], axis=2)
        Aw = A * self.weights[None, :, None]
        scale = np.linalg.norm(Aw, axis=1)
        scale[scale == 0] = 1.0
        U, sv, Vt = np.linalg.svd(Aw / scale[:, None, :], full_matrices=False)
        keep = sv > 1e-12 * sv[:, :1]
        U = U * keep[:, None, :]  # the rank-truncated columns
        y = self.P * self.weights
        proj = np.einsum("cbk,b->ck", U, y)

        def jacobian() -> np.ndarray:
            inv = np.where(keep, 1.0 / np.where(keep, sv, 1.0), 0.0)
            coef = np.einsum("ckj,ck->cj", Vt, proj * inv) / scale
            q = np.einsum("csk,ck->cs", modal, coef[:, :k])
            D = self._reduce_batch(-q[:, :, None] * grads) * self.weights[None, :, None]
            return -(D - U @ (U.transpose(0, 2, 1) @ D))

        return y[None, :] - np.einsum("cbk,ck->cb", U, proj), jacobian

    def _reduce_batch(self, A: np.ndarray) -> np.ndarray:
        """:meth:`_reduce` of a stack ``[C, bins * nsub, k]``."""
        if self.nsub == 1:
            return A
        C, _, k = A.shape
        return np.einsum("cbsk,s->cbk", A.reshape(C, self.f.size, self.nsub, k), self.kernel_weights)


def _smooth(P: np.ndarray, width: int = 5) -> np.ndarray:
    """Running median: a positive reference level for the first weights."""
    if P.size < width:
        return np.full_like(P, max(float(np.median(P)), 1e-300))
    pad = width // 2
    Q = np.pad(P, pad, mode="edge")
    win = np.lib.stride_tricks.sliding_window_view(Q, width)
    return np.maximum(np.median(win, axis=1), 1e-12 * float(P.max()))


def pole_bounds(model: SpectralModel, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds of ``n`` poles ``(ln w, zeta)``: the fitted band and :data:`ZETA_BOUNDS`."""
    lo = np.tile([math.log(2 * math.pi * model.f[0]), ZETA_BOUNDS[0]], n)
    hi = np.tile([math.log(2 * math.pi * model.f[-1]), ZETA_BOUNDS[1]], n)
    return lo, hi
