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

import functools
import math
from dataclasses import dataclass
from typing import Callable, NamedTuple, Sequence

import numpy as np
from scipy.linalg import lapack

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


class _Poles(NamedTuple):
    """Poles on the model's sub-points: ``1 / prod_k |D_k|^2 / w_k^4`` and, per pole (rows), ``w^2``,
    ``zeta``, ``w^2 - W^2`` and ``|D|^2`` (what the gradients need)."""

    inv_den: np.ndarray
    w2: np.ndarray
    z: np.ndarray
    re: np.ndarray
    D2: np.ndarray


class _Basis(NamedTuple):
    """One linear solve: an orthonormal basis ``Q`` of the weighted, scaled columns (one column per design
    column; zero columns for directions a rank-deficient design lacks), ``Q^T y``, the map from ``Q^T y`` to the
    scaled coefficients, and the column scales (coefficients ``pinv @ proj / scale``)."""

    Q: np.ndarray
    proj: np.ndarray
    pinv: np.ndarray
    scale: np.ndarray


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
        self._cw: dict[int, np.ndarray] = {}  # 2n + 1 -> the modal columns' fixed part, (bins, nsub, 2n + 1)
        self._held: tuple[bytes, np.ndarray] | None = None  # a batch's held poles and their 1 / denominator
        self._one = np.ones_like(self.W2)

    @property
    def weights(self) -> np.ndarray:
        """The residual's weights per bin (``1/M`` in the Whittle steps)."""
        return self._weights

    @weights.setter
    def weights(self, w: np.ndarray) -> None:
        self._weights = np.asarray(w, dtype=float)
        self._weighted_cache: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    def _weighted(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For the current weights: the weighted data ``y``, the weighted extra columns and their norms."""
        if self._weighted_cache is None:
            w = self._weights
            ew = self.extra * w[:, None]
            self._weighted_cache = (self.P * w, ew, np.linalg.norm(ew, axis=0))
        return self._weighted_cache

    def _reduce(self, A: np.ndarray) -> np.ndarray:
        """Kernel average of sub-point columns ``[bins * nsub, k]`` onto the bins ``[bins, k]``."""
        if self.nsub == 1:
            return A
        return np.einsum("bsk,s->bk", A.reshape(self.f.size, self.nsub, A.shape[1]), self.kernel_weights)

    def _fixed_columns(self, k: int) -> np.ndarray:
        """``kernel weight x E x T_j(x(f^2))`` on the sub-points, ``(bins, nsub, k)``: a modal column's kernel
        average is then one contraction with ``1 / prod |D|^2`` (issue #15: no sub-point matrix per evaluation)."""
        cw = self._cw.get(k)
        if cw is None:
            F, ns = self.f.size, self.nsub
            fixed = (self.E_parts[0].reshape(F, ns) * self.kernel_weights[None, :])[:, :, None]
            cw = np.ascontiguousarray(self.cheb[:, :k].reshape(F, ns, k) * fixed)
            self._cw[k] = cw
        return cw

    def _poles(self, theta: np.ndarray, product: bool = True) -> _Poles:
        """The poles ``theta`` on the sub-points: ``1 / prod_k |D_k|^2 / w_k^4`` (``product=False``: left at 1)
        and, per pole (rows), what the gradients need."""
        # the per-pole constants in Python floats (a few poles: numpy's per-call overhead, issue #15), the same
        # operations in the same order; math.exp, as numpy's SIMD exp may differ by an ulp
        zs = theta[1::2].tolist()
        w = [math.exp(x) for x in theta[0::2].tolist()]
        sq = [wk * wk for wk in w]
        w2 = np.array(sq)[:, None]
        re = w2 - self.W2
        D2 = re * re
        D2 += np.array([4.0 * zk * zk * wk * wk for zk, wk in zip(zs, w)])[:, None] * self.W2
        inv_den = self._one
        if product and w:
            den = D2[0] / (sq[0] * sq[0])
            for j in range(1, len(w)):
                den *= D2[j] / (sq[j] * sq[j])
            inv_den = 1.0 / den
        z = np.array(zs)[:, None]
        return _Poles(inv_den, w2, z, re, D2)

    def _gradients(self, p: _Poles) -> np.ndarray:
        """Per pole, ``d ln(|D_k|^2 / w_k^4) / d ln w_k`` and ``d ln(.) / d zeta_k``: rows ``(2 n, sub-points)``."""
        W2 = self.W2
        zw = p.z * p.w2
        G = np.empty((2 * p.w2.shape[0], W2.size))
        # G[0::2] = (4 w2 re + 8 z zw W2) / D2 - 4 and G[1::2] = 8 zw W2 / D2, in place (the same operations)
        gw, gz = G[0::2], G[1::2]
        np.multiply(4.0 * p.w2, p.re, out=gw)
        gw += (8.0 * p.z * zw) * W2
        gw /= p.D2
        gw -= 4.0
        np.multiply(8.0 * zw, W2, out=gz)
        gz /= p.D2
        return G

    def _scaled(self, inv_den: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        """The weighted design ``[modal, extra]`` with unit columns, and its column norms, for ``1 / den`` on the
        sub-points (``(sub-points,)``, or ``(C, sub-points)`` for a stack of designs).

        The modal columns ``E T_j(x) / prod |D|^2`` averaged over each bin are one product of ``1 / den``
        with :meth:`_fixed_columns` per bin.
        """
        F, ns = self.f.size, self.nsub
        _, ew, en = self._weighted()
        lead = inv_den.shape[:-1]
        A = np.empty(lead + (F, k + ew.shape[1]))
        # per bin, (designs, nsub) @ (nsub, k): one small product per bin, not one per bin and design
        modal = np.matmul(inv_den.reshape(-1, F, ns).transpose(1, 0, 2), self._fixed_columns(k))  # (F, C, k)
        np.multiply(modal.transpose(1, 0, 2).reshape(lead + (F, k)), self._weights[:, None], out=A[..., :k])
        A[..., k:] = ew
        scale = np.empty(lead + (k + ew.shape[1],))
        scale[..., :k] = np.sqrt(np.einsum("...bk,...bk->...k", A[..., :k], A[..., :k]))
        scale[..., k:] = en
        if not scale.all():
            scale[scale == 0] = 1.0
        A /= scale[..., None, :]
        return A, scale

    def _basis(self, As: np.ndarray, scale: np.ndarray) -> _Basis:
        """An orthonormal basis of the weighted, column-scaled design ``As`` and its pseudo-inverse.

        Householder QR while the scaled design is clearly of full rank (``sigma_min / sigma_max > 1e-10``,
        bounded below by ``1 / (|R|_F |R^-1|_F)``); otherwise the SVD truncated at ``1e-12 sigma_max``.
        Both span the same space: the residual and coefficients agree to rounding (issue #15: a QR of
        a tall, thin matrix costs a fifth of its SVD).
        """
        y = self._weighted()[0]
        k = As.shape[1]
        if k <= As.shape[0]:
            qr, tau, _, info = lapack.dgeqrf(As)
            if info == 0:
                R = qr[:k] * _upper(k)
                Rinv, info = lapack.dtrtri(R)
                if info == 0 and float(np.vdot(R, R)) * float(np.vdot(Rinv, Rinv)) < 1e20:
                    Q = lapack.dorgqr(qr, tau)[0]
                    return _Basis(Q, Q.T @ y, Rinv, scale)
        U, sv, Vt = np.linalg.svd(As, full_matrices=False)
        drop = sv <= 1e-12 * sv[0]  # the truncated directions: zero columns, so every basis has k columns
        U[:, drop] = 0.0
        pinv = Vt.T / np.where(drop, 1.0, sv)
        pinv[:, drop] = 0.0
        return _Basis(U, U.T @ y, pinv, scale)

    def _pole_jacobian(self, b: _Basis, inv_den: np.ndarray, G: np.ndarray, k: int) -> np.ndarray:
        """Kaufman's columns ``-P_perp W d(A c)/d theta`` for the gradient rows ``G`` (``(m, sub-points)``).

        Only the modal columns depend on the poles, each through its factor ``-g``: ``d(A c)`` is the
        kernel average of ``-g E R(f^2) / prod |D|^2``, ``R`` the fitted numerator.
        """
        F, ns = self.f.size, self.nsub
        coef = (b.pinv @ b.proj) / b.scale
        h = (self._fixed_columns(k).reshape(F * ns, k) @ coef[:k]) * inv_den
        D = np.einsum("gbs,bs->bg", G.reshape(-1, F, ns), h.reshape(F, ns))
        D *= -self._weights[:, None]
        return -(D - b.Q @ (b.Q.T @ D))

    def columns(self, theta: np.ndarray) -> np.ndarray:
        """``E R(f^2) / prod |D_k|^2`` with ``R`` a polynomial of degree ``2 n`` (Chebyshev basis), ``1/f^2``, 1.

        ``sum_c |H_c|^2`` over any number of channels is ``R(f^2) / prod_k |D_k(j 2 pi f)|^2``
        with ``R >= 0`` of degree ``2 n`` in ``f^2`` (the numerators of ``H_c`` have degree
        ``2 n`` in ``s``), and by spectral factorisation every such ``R`` is one channel's
        ``|numerator|^2``: one basis serves a single axis and Klipper's sum of axes.
        The slow sweep's lines (below ~15 Hz, where ``|H|^2`` is nearly constant) are an extra
        column outside the modes: putting them through the modes' denominator with a numerator
        of their own bent the peaks and biased damping by +1 %; modes under 15 Hz are flagged instead.
        """
        F, ns, k = self.f.size, self.nsub, theta.size + 1
        modal = np.matmul(self._poles(theta).inv_den.reshape(F, 1, ns), self._fixed_columns(k))[:, 0, :]
        return np.hstack([modal, self.extra])

    def solve(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Weighted linear least squares for the linear coefficients; returns (model, coefficients)."""
        b = self._basis(*self._scaled(self._poles(theta).inv_den, theta.size + 1))
        y = self._weighted()[0]
        coef = (b.pinv @ b.proj) / b.scale
        return (y - (y - b.Q @ b.proj)) / self._weights, coef

    def residual(self, theta: np.ndarray) -> np.ndarray:
        return self.residual_and_jacobian_lazy(theta)[0]

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
        p = self._poles(theta)
        k = theta.size + 1
        b = self._basis(*self._scaled(p.inv_den, k))
        r = self._weighted()[0] - b.Q @ b.proj
        return r, lambda: self._pole_jacobian(b, p.inv_den, self._gradients(p)[first:], k)

    def batch(self, theta: np.ndarray, X: np.ndarray) -> Batch:
        """The poles ``theta`` (held) plus, per row of ``X``, the poles of that row (free): the residuals of
        every row at once, and the Jacobians along the free poles on demand (:class:`Batch`).

        Several fits of the same size run side by side (the screened starts of a new pole, the second
        starts of the forward selection): the held poles' denominator is formed once and every row's
        modal columns in one product (issue #15).  Rows are the same numbers as
        :meth:`residual_and_jacobian_lazy` of ``[theta, row]`` with ``first = theta.size``, to rounding.
        """
        key = theta.tobytes()
        if self._held is None or self._held[0] != key:
            self._held = (key, self._poles(theta).inv_den)
        C, m = X.shape[0], X.shape[1] // 2
        p = self._poles(X.ravel(), product=False)  # rows: C x m free poles
        fac = (p.w2 * p.w2) / p.D2
        inv = self._held[1] * fac[0::m]
        for j in range(1, m):
            inv *= fac[j::m]
        k = theta.size + X.shape[1] + 1
        As, scale = self._scaled(inv, k)
        bases = [self._basis(As[c], scale[c]) for c in range(C)]
        y = self._weighted()[0]
        r = np.empty((C, y.size))
        for c, b in enumerate(bases):
            np.subtract(y, b.Q @ b.proj, out=r[c])
        return Batch(self, bases, inv, p, k, r)


class Batch:
    """Rows of :meth:`SpectralModel.batch`: residuals ``r`` ``(C, bins)``; :meth:`jacobian` of chosen rows."""

    def __init__(self, model: SpectralModel, bases: list[_Basis], inv_den: np.ndarray, free: _Poles, k: int,
                 r: np.ndarray) -> None:
        self.model, self.bases, self.inv_den, self.free, self.k, self.r = model, bases, inv_den, free, k, r

    def _gradients(self, rows: np.ndarray) -> np.ndarray:
        """The gradient rows of the chosen rows' free poles, ``(len(rows), 2 m, bins, nsub)``: only those rows'
        (a fit asks for the Jacobians of the few rows whose step was accepted; issue #15)."""
        model, p, C = self.model, self.free, self.r.shape[0]
        m = p.w2.shape[0] // C
        if rows.size < C:
            poles = (rows[:, None] * m + np.arange(m)).ravel()
            p = _Poles(p.inv_den, p.w2[poles], p.z[poles], p.re[poles], p.D2[poles])
        return model._gradients(p).reshape(rows.size, 2 * m, model.f.size, model.nsub)

    def jacobian(self, rows: Sequence[int] | np.ndarray) -> np.ndarray:
        """The Jacobians ``(len(rows), bins, 2 m)`` of the chosen rows along their ``m`` free poles (Kaufman's
        columns, as :meth:`SpectralModel._pole_jacobian` row by row)."""
        model, rows = self.model, np.asarray(rows, dtype=int)
        F, ns, k = model.f.size, model.nsub, self.k
        G = self._gradients(rows)
        if rows.size == 1:
            b = self.bases[rows[0]]
            Q, coef = b.Q[None], ((b.pinv @ b.proj) / b.scale)[None]
        else:
            Q = np.stack([self.bases[c].Q for c in rows])
            coef = np.stack([(self.bases[c].pinv @ self.bases[c].proj) / self.bases[c].scale for c in rows])
        h = (coef[:, :k] @ model._fixed_columns(k).reshape(F * ns, k).T) * self.inv_den[rows]
        D = np.einsum("cgbs,cbs->cbg", G, h.reshape(-1, F, ns))
        D *= -model.weights[:, None]
        return -(D - Q @ (Q.transpose(0, 2, 1) @ D))


@functools.lru_cache(maxsize=None)
def _upper(k: int) -> np.ndarray:
    """The ``k x k`` upper-triangular mask (ones on and above the diagonal)."""
    return np.triu(np.ones((k, k)))


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
