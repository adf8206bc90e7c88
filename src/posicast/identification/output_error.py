"""Output-error fit of a continuous-time modal model by variable projection (``method="oe"``, the default).

The model is ``y = sum_k (b0_k + b1_k s) / (s^2 + 2 zeta_k omega_k s + omega_k^2) u + d u + c``
plus each mode's free response (unknown initial state), sampled exactly under a
zero-order hold.  The numerators, the feed-through ``d`` (an accelerometer's ``s^2``
term) and the offset ``c`` enter linearly and are projected out; only
``(ln omega_k, zeta_k)`` are searched (trust-region reflective, :mod:`.trust_region`), from the peaks
of the empirical transfer function.  Output noise does not bias it (the criterion
is the simulated, not the predicted, output).  Intervals: :mod:`.fit_statistics`.
Modes the data do not demand are dropped (:mod:`.significance`).
"""

from __future__ import annotations

import cmath
import functools
import math
from dataclasses import dataclass
from typing import NamedTuple, Sequence

import numpy as np
from scipy import signal, special
from scipy.linalg import lapack

from .. import _validate as v
from ..modes import Mode
from .fit_statistics import fit_percent, half_power_span, pole_intervals, whiteness
from .results import Identification, PeakGuess
from .trust_region import TRFResult, trust_region_reflective
from .significance import ModeTest, NoModeFound, describe_failure, search_cells, wald_test

__all__ = ["ZETA_MIN", "ZETA_MAX", "OEModel", "OESettings", "OEFit", "fit_oe", "significant_oe"]

#: Records longer than this are padded less for the empirical transfer function of the start (issue #15).
_LONG_RECORD = 1 << 16
#: The first samples of a long record on which its start is ranked and first fitted.
_HEAD = 1 << 15
#: How many start candidates ranked on the start of a long record are ranked again on all of it.
_SHORTLIST = 4
#: Elements of the stacked regression columns per batch when the start's candidates are ranked (16 MB).
_BATCH = 1 << 21
#: The numerator z^-1 of the forced response.
_DELAY = np.array([0.0, 1.0])
try:  # scipy's compiled filter, which lfilter runs after its array-API conversions: half the cost on short records
    from scipy.signal._sigtools import _linear_filter
except ImportError:  # pragma: no cover - a scipy that moved it
    _linear_filter = None
#: The damping ratios the time-domain fits search (also the clip of the frequency-domain and decay starts).
ZETA_MIN, ZETA_MAX = 1e-5, 0.95


class OEFit(NamedTuple):
    """One output-error fit: the result, its residual sum of squares and its number of parameters."""

    identification: Identification
    rss: float
    n_params: int


@dataclass(frozen=True)
class OESettings:
    """How :func:`fit_oe` is run: the interval method and the nuisance terms (bool or ``"auto"``)."""

    covariance: str
    feedthrough: bool | str
    offset: bool | str
    initial_state: bool | str
    weights: np.ndarray | None = None  # 0 on samples left out of the fit (clipped), else None


# ----------------------------------------------------------------------------- the model


class OEModel:
    """Variable-projection residual of the continuous modal model under ZOH."""

    def __init__(self, u: np.ndarray | None, y: np.ndarray, h: float, n_modes: int, *,
                 feedthrough: bool = True, offset: bool = True, initial_state: bool = True,
                 weights: np.ndarray | None = None) -> None:
        self.u, self.y, self.h, self.n = u, y, h, n_modes
        self.w = weights  # 0 on samples left out of the fit (clipped), else None
        self.feedthrough = feedthrough and u is not None
        self.offset = offset
        self.initial_state = initial_state or u is None
        self.k = np.arange(y.size, dtype=float)
        self.n_lin_last = 0
        self._free: dict[int, list[int]] = {}
        self._last: tuple[bytes, _Projection] | None = None

    def basis(self, theta: np.ndarray) -> np.ndarray:
        return self.columns(theta)[0]

    def columns(self, theta: np.ndarray) -> tuple[np.ndarray, list[list[int]]]:
        """The regression columns at ``theta`` and, per mode, the indices of the columns that make it a mode
        of this data: its input-driven columns when there is an input, else its free response."""
        return self._fit(theta).rows.T, self._groups()

    def _rows(self, theta: np.ndarray) -> tuple[np.ndarray, list[tuple]]:
        """The regression columns as rows ``(k, N)`` (each contiguous) and per mode what its derivatives need: ``(first row, lambda, x1 or None, lambda^k or None, omega, zeta)``."""
        per = self._per_mode()
        rows = np.empty((self._width(), self.y.size))
        th = theta.tolist()
        parts = [(i * per,) + self._mode_rows(th[2 * i], th[2 * i + 1], rows[i * per: (i + 1) * per])
                 for i in range(self.n)]
        j = self.n * per
        if self.feedthrough:
            rows[j] = self.u
            j += 1
        if self.offset:
            rows[j] = 1.0
        return rows, parts

    def _groups(self) -> list[list[int]]:
        """Per mode, the indices of the columns that make it a mode of this data (see :meth:`columns`)."""
        per = self._per_mode()
        forced = 2 if self.u is not None else 0
        groups = []
        for i in range(self.n):
            start = i * per
            # with an input, a mode of the system is one the input drives: a free response alone also fits
            # a slow drift or coloured noise that has nothing to do with the input (see mode_tests)
            groups.append(list(range(start, start + (forced if forced else per))))
            self._free[i] = list(range(start + forced, start + per))
        return groups

    def _mode_rows(self, lw: float, zeta: float, out: np.ndarray) -> tuple:
        """Fill ``out`` with one mode's rows (the forced response ``x1`` and ``z^-1 x1`` when there is an input,
        then ``Re, Im lambda^k`` with the initial state); returns ``(lambda, x1, lambda^k, omega, zeta)``."""
        w = math.exp(lw)
        z = min(max(zeta, ZETA_MIN), ZETA_MAX)
        p = complex(-z * w, w * math.sqrt(1.0 - z * z))
        lam = cmath.exp(p * self.h)
        x1 = powers = None
        j = 0
        if self.u is not None:
            x1 = _forced(lam, self.u)
            out[0] = x1
            out[1, 0] = 0.0
            out[1, 1:] = x1[:-1]
            j = 2
        if self.initial_state:
            self._free_rows(p, out[j: j + 2])
            powers = out[j] + 1j * out[j + 1]
        return lam, x1, powers, w, z

    def _free_rows(self, p: complex, out: np.ndarray) -> None:
        """``Re, Im lambda^k`` into ``out`` (2, N): ``e^(Re(p) h k) (cos, sin)(Im(p) h k)``, numpy's complex
        exp in real passes (4x faster)."""
        mag, ang = np.exp((p.real * self.h) * self.k), (p.imag * self.h) * self.k
        np.multiply(mag, np.cos(ang), out=out[0])
        np.multiply(mag, np.sin(ang), out=out[1])

    def term_rows(self, name: str, theta: np.ndarray) -> np.ndarray | None:
        """The rows the nuisance term ``name`` (feedthrough, offset, initial_state) adds to this model at
        ``theta``, or None when this model has it already (or cannot: a direct term without an input)."""
        if name == "feedthrough":
            return None if self.feedthrough or self.u is None else self.u[None, :]
        if name == "offset":
            return None if self.offset else np.ones((1, self.y.size))
        if self.initial_state:
            return None
        out = np.empty((2 * self.n, self.y.size))
        for i, (_, _, _, _, w, z) in enumerate(self._fit(theta).parts):
            self._free_rows(complex(-z * w, w * math.sqrt(1.0 - z * z)), out[2 * i: 2 * i + 2])
        return out

    def _per_mode(self) -> int:
        return (2 if self.u is not None else 0) + (2 if self.initial_state else 0)

    def _width(self) -> int:
        """The number of regression columns."""
        return self.n * self._per_mode() + int(self.feedthrough) + int(self.offset)

    def mode_tests(self, theta: np.ndarray, e: np.ndarray, n_lin: int, hac: bool, cells: float) -> list[ModeTest]:
        """Wald test of each mode's coefficients at ``theta`` (see :mod:`.significance`)."""
        Phi, groups = self.columns(theta)
        y = self.y
        if self.w is not None:
            Phi, y = Phi * self.w[:, None], y * self.w
        dof = self.n_used - n_lin - theta.size
        out = []
        for i, g in enumerate(groups):
            rest = [j for j in range(Phi.shape[1]) if j not in g]
            if self.u is not None and self._free.get(i) and rest:
                # a step from the first sample: the forced response is an offset minus a free response, so
                # the input's part cannot be told from them; then the mode's columns are tested together
                Q, _ = np.linalg.qr(Phi[:, rest])
                X = Phi[:, g]
                left = np.linalg.norm(X - Q @ (Q.T @ X)) / max(float(np.linalg.norm(X)), 1e-300)
                if left < 1e-2:
                    g = g + self._free[i]
                    rest = [j for j in range(Phi.shape[1]) if j not in g]
            out.append(wald_test(y, Phi[:, g], Phi[:, rest], e, dof, cells, hac))
        return out

    def head(self, length: int) -> OEModel:
        """The same model on the first ``length`` samples."""
        return OEModel(None if self.u is None else self.u[:length], self.y[:length], self.h, self.n,
                       feedthrough=self.feedthrough, offset=self.offset, initial_state=self.initial_state,
                       weights=None if self.w is None else self.w[:length])

    @property
    def n_used(self) -> int:
        return int(self.y.size if self.w is None else np.count_nonzero(self.w))

    def project(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
        """Residual (0 on left-out samples), model output (every sample) and rank, at ``theta``."""
        fit = self._fit(theta)
        return fit.residual, fit.coef @ fit.rows, fit.rank

    def _fit(self, theta: np.ndarray) -> _Projection:
        """The projection at ``theta`` (the last one is kept: the search asks for the residual, then the Jacobian)."""
        key = theta.tobytes()
        if self._last is not None and self._last[0] == key:
            return self._last[1]
        rows, parts = self._rows(theta)
        Rw, yw = (rows, self.y) if self.w is None else (rows * self.w, self.y * self.w)
        fit = _Projection(rows, Rw, *_project(Rw, yw), parts)
        self._last = (key, fit)
        return fit

    def costs(self, thetas: Sequence[np.ndarray]) -> np.ndarray:
        """The residual sum of squares at each of ``thetas`` (as :meth:`residual`, batched: the start's ranking)."""
        if self.n == 1 and self._width() == 2 and self.u is not None and self.w is None:
            return self._forced_costs(thetas)
        out = np.empty(len(thetas))
        N = self.y.size
        yw = self.y if self.w is None else self.y * self.w
        for lo in range(0, len(thetas), max(1, _BATCH // (N * (self._width() + 1)))):
            chunk = thetas[lo: lo + max(1, _BATCH // (N * (self._width() + 1)))]
            X = np.empty((len(chunk),) + (self._width(), N))
            X[0] = self._rows(chunk[0])[0]
            a, b = (self.n - 1) * self._per_mode(), self.n * self._per_mode()  # the rows of the last mode
            first = chunk[0][:-2].tolist()
            for c, th in enumerate(chunk[1:], 1):
                th = th.tolist()
                if th[:-2] != first:
                    X[c] = self._rows(np.array(th))[0]
                    continue
                # the candidates differ in their last mode only: the other rows are the first candidate's
                if a:
                    X[c, :a] = X[0, :a]
                if b < X.shape[1]:
                    X[c, b:] = X[0, b:]
                self._mode_rows(th[-2], th[-1], X[c, a:b])
            if self.w is not None:
                X *= self.w
            gram = X @ X.transpose(0, 2, 1)
            nrm = np.sqrt(np.diagonal(gram, axis1=1, axis2=2))
            nrm = np.where(nrm == 0, 1.0, nrm)
            lam, V = np.linalg.eigh(gram / nrm[:, :, None] / nrm[:, None, :])
            inv = np.where(lam > lam[:, -1:] * 1e-13, 1.0 / np.where(lam > 0, lam, 1.0), 0.0)
            pinv = (V * inv[:, None, :]) @ V.transpose(0, 2, 1)
            coef = (pinv @ ((X @ yw) / nrm)[:, :, None])[:, :, 0] / nrm
            r = yw - (coef[:, None, :] @ X)[:, 0, :]
            out[lo: lo + len(chunk)] = np.einsum("ij,ij->i", r, r)
        return out

    def _forced_costs(self, thetas: Sequence[np.ndarray]) -> np.ndarray:
        """:meth:`costs` of one mode driven by the input, without nuisance terms (the start of every default fit):
        the columns ``x1`` and ``z^-1 x1`` of each candidate, their 2 x 2 unit-norm Gram matrices inverted in
        closed form (truncated as :func:`_gram_pinv`), the residual of each.

        The same costs as the general path to rounding (they only rank the candidates); the general path's
        per-candidate rows and batched eigen-decompositions were most of a short record's start (issue #15).
        """
        y, N = self.y, self.y.size
        out = np.empty(len(thetas))
        step = max(1, _BATCH // (3 * N))
        for lo in range(0, len(thetas), step):
            chunk = thetas[lo: lo + step]
            X = np.empty((len(chunk), N))
            for c, th in enumerate(chunk):
                lw, zeta = th.tolist()
                w, z = math.exp(lw), min(max(zeta, ZETA_MIN), ZETA_MAX)
                X[c] = _forced(cmath.exp(complex(-z * w, w * math.sqrt(1.0 - z * z)) * self.h), self.u)
            head = X[:, :-1]  # z^-1 x1 without its leading zero
            g00 = np.einsum("ij,ij->i", X, X)
            g11 = np.einsum("ij,ij->i", head, head)
            g01 = np.einsum("ij,ij->i", X[:, 1:], head)
            n0, n1 = np.sqrt(g00), np.sqrt(g11)
            n0[n0 == 0], n1[n1 == 0] = 1.0, 1.0
            a, c, b = g00 / (n0 * n0), g11 / (n1 * n1), g01 / (n0 * n1)  # unit-norm Gram [[a, b], [b, c]]
            half, mean = np.hypot(0.5 * (a - c), b), 0.5 * (a + c)
            big, small = mean + half, mean - half  # its eigenvalues
            full = small > big * 1e-13
            # the inverse where both eigenvalues are kept, else the top eigenvector's part only
            vx, vy = np.where(np.abs(a - small) >= np.abs(c - small), a - small, b), np.where(
                np.abs(a - small) >= np.abs(c - small), b, c - small)  # (big's eigenvector, unnormalised)
            vn = np.hypot(vx, vy)
            vn[vn == 0] = 1.0
            vx, vy = vx / vn, vy / vn
            top = np.where(big > 0, 1.0 / np.where(big > 0, big, 1.0), 0.0)
            det = np.where(full, a * c - b * b, 1.0)
            p00 = np.where(full, c / det, top * vx * vx)
            p11 = np.where(full, a / det, top * vy * vy)
            p01 = np.where(full, -b / det, top * vx * vy)
            b0 = (X @ y) / n0
            b1 = (head @ y[1:]) / n1
            c0, c1 = (p00 * b0 + p01 * b1) / n0, (p01 * b0 + p11 * b1) / n1
            r = y - c0[:, None] * X
            r[:, 1:] -= c1[:, None] * head
            out[lo: lo + len(chunk)] = np.einsum("ij,ij->i", r, r)
        return out

    def residual(self, theta: np.ndarray) -> np.ndarray:
        return self._fit(theta).residual

    def jacobian(self, theta: np.ndarray) -> np.ndarray:
        """The exact Jacobian of :meth:`residual` (Golub and Pereyra's, for the projected residual).

        With ``Phi`` the (weighted) columns, ``c`` their coefficients, ``P`` the
        projection on them and ``r = (I - P) y``:
        ``dr = -(I - P) dPhi c - (Phi^+)^T dPhi^T r``.  Each column's derivative
        is itself the output of a linear filter: the forced response
        ``x1 = z^-1 / A(z) u`` gives ``dx1 = -(dA / A) x1`` (one ``lfilter``), the
        free response ``lambda^k`` gives ``k h dp lambda^k``; ``d lambda = lambda h dp``
        with ``dp / d ln(omega) = p`` and ``dp / d zeta = omega (-1 - j zeta / sqrt(1 - zeta^2))``.
        """
        fit = self._fit(theta)
        Rw, r = fit.weighted, fit.residual
        dphi_c = np.empty((2 * self.n, self.y.size))  # dPhi c, one row per parameter
        g = np.zeros((2 * self.n, Rw.shape[0]))  # dPhi^T r (unit-norm columns), one row per parameter
        coef, nrm = fit.coef.tolist(), fit.nrm.tolist()
        for i, (start, lam, x1, powers, w, z) in enumerate(fit.parts):
            p = complex(-z * w, w * math.sqrt(1.0 - z * z))
            zeta_free = ZETA_MIN < float(theta[2 * i + 1]) < ZETA_MAX  # the clip holds zeta still outside the bounds
            dps = (p, complex(-w, -w * z / math.sqrt(1.0 - z * z)) if zeta_free else 0j)
            col = start
            if x1 is not None:
                # columns x1 and x2 = z^-1 x1 with d x1 = -(da1 z^-1 + da2 z^-2) / A(z) x1 = -(da1 s1 + da2 z^-1 s1):
                # one filter for both parameters, and dPhi c, dPhi^T r from shifts of s1
                s1 = _forced(lam, x1)
                rw = r if self.w is None else r * self.w
                c0, c1 = coef[col], coef[col + 1]
                q = c0 * s1
                q[1:] += c1 * s1[:-1]  # (c0 + c1 z^-1) s1
                dots = [float(s1 @ rw), float(s1[:-1] @ rw[1:]), float(s1[:-2] @ rw[2:])]  # (z^-m s1) . r, m = 0, 1, 2
                nrm0, nrm1 = nrm[col], nrm[col + 1]
                for j, dp in enumerate(dps):
                    dlam = lam * self.h * dp
                    da1, da2 = -2.0 * dlam.real, 2.0 * (lam.conjugate() * dlam).real
                    row = dphi_c[2 * i + j]
                    np.multiply(q, -da1, out=row)
                    row[1:] -= da2 * q[:-1]
                    if self.w is not None:
                        row *= self.w
                    g[2 * i + j, col] = -(da1 * dots[0] + da2 * dots[1]) / nrm0
                    g[2 * i + j, col + 1] = -(da1 * dots[1] + da2 * dots[2]) / nrm1
                col += 2
            else:
                dphi_c[2 * i: 2 * i + 2] = 0.0
            if powers is not None:  # the free response lambda^k: d lambda^k = k h dp lambda^k
                kp = self.k * powers
                for j, dp in enumerate(dps):
                    dpow = (self.h * dp) * kp
                    drows = np.array([dpow.real, dpow.imag])
                    if self.w is not None:
                        drows = drows * self.w
                    dphi_c[2 * i + j] += fit.coef[col: col + 2] @ drows
                    g[2 * i + j, col: col + 2] = (drows @ r) / fit.nrm[col: col + 2]
        # dr = -(I - P) dPhi c - (Phi^+)^T dPhi^T r, with P = Rn^T pinv Rn and the unit-norm columns Rn = Rw / nrm
        corr = ((((dphi_c @ Rw.T) / fit.nrm - g) @ fit.pinv) / fit.nrm) @ Rw
        return -(dphi_c - corr).T


class _Projection(NamedTuple):
    """One projection of :class:`OEModel`: its columns (raw and weighted, as rows), their norms, the
    pseudo-inverse of the unit-norm Gram matrix, the raw coefficients, the residual, the rank and the
    per-mode data for the Jacobian."""

    rows: np.ndarray
    weighted: np.ndarray
    nrm: np.ndarray
    pinv: np.ndarray
    coef: np.ndarray
    residual: np.ndarray
    rank: int
    parts: list


def _project(Rw: np.ndarray, yw: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """Least squares of ``yw`` on the rows ``Rw``: the rows' norms, the pseudo-inverse of the unit-norm rows'
    Gram matrix, the coefficients (of the raw rows), the residual and the rank."""
    gram = Rw @ Rw.T
    nrm = np.sqrt(gram.diagonal())
    if not nrm.all():
        nrm = np.where(nrm == 0, 1.0, nrm)
    pinv, rank = _gram_pinv(gram / np.multiply.outer(nrm, nrm))
    coef = (pinv @ ((Rw @ yw) / nrm)) / nrm
    return nrm, pinv, coef, yw - coef @ Rw, rank


def _forced(lam: complex, x: np.ndarray) -> np.ndarray:
    """``z^-1 / A(z) x`` with ``A(z) = (1 - lambda z^-1)(1 - conj(lambda) z^-1)`` (the mode's forced response)."""
    a = np.array([1.0, -2.0 * lam.real, abs(lam) ** 2])
    if _linear_filter is not None and x.dtype == np.float64:
        return _linear_filter(_DELAY, a, x, -1)
    return signal.lfilter(_DELAY, a, x)


def _gram_pinv(gram: np.ndarray) -> tuple[np.ndarray, int]:
    """Pseudo-inverse and rank of the unit-norm columns' Gram matrix, eigen-truncated at 1e-13 of its largest
    eigenvalue (a step at k = 0 makes the forced response a combination of offset and free response)."""
    lam, V, info = lapack.dsyevd(gram)  # numpy's eigh, without its per-call checks (issue #15)
    if info != 0:
        lam, V = np.linalg.eigh(gram)
    if lam[0] > lam[-1] * 1e-13:  # full rank
        return (V / lam) @ V.T, lam.size
    keep = lam > lam[-1] * 1e-13
    return (V[:, keep] / lam[keep]) @ V[:, keep].T, int(keep.sum())


def _bounds(n: int, h: float, w_min: float) -> tuple[np.ndarray, np.ndarray]:
    lo = np.tile([math.log(w_min), ZETA_MIN], n)
    hi = np.tile([math.log(0.98 * math.pi / h), ZETA_MAX], n)
    return lo, hi


def _least_squares(model: OEModel, theta0: np.ndarray, w_min: float) -> tuple[np.ndarray, TRFResult]:
    """Trust-region reflective least squares on the projected residual, within :func:`_bounds`
    (:mod:`.trust_region`: scipy's method without its per-call bookkeeping; issue #15).

    On a long record the search is first run on its first ``_HEAD`` samples; the fit on the whole
    record then starts from there if that lowers its cost (a few steps instead of about ten; issue #15).
    """
    lo, hi = _bounds(model.n, model.h, w_min)
    x0 = np.clip(theta0, lo + 1e-9, hi - 1e-9)
    opts = {"xtol": 1e-10, "ftol": 1e-12, "gtol": 1e-12, "max_nfev": 200 * len(x0)}
    if model.y.size > _LONG_RECORD:
        short = model.head(_HEAD)
        x1 = np.clip(trust_region_reflective(short.residual, short.jacobian, x0, lo, hi, **opts).x,
                     lo + 1e-9, hi - 1e-9)
        r0, r1 = model.residual(x0), model.residual(x1)
        if float(r1 @ r1) < float(r0 @ r0):
            x0 = x1
    res = trust_region_reflective(model.residual, model.jacobian, x0, lo, hi, **opts)
    return res.x, res


# ----------------------------------------------------------------------------- starting point


def _etfe(u: np.ndarray | None, y: np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Smoothed empirical transfer function |Y/U| of the differenced signals (|Y| when u is None).

    The auto-spectra are averaged over about 3 resolution bins (the classical
    smoothed ETFE) so that a noise spike does not outrank a resonance.
    """
    n = y.size
    f, ker, nfft = _etfe_grid(n, fs)
    Y2 = _smoothed_power(np.diff(y, prepend=y[0]), nfft, ker)
    du = None if u is None else np.diff(u, prepend=0.0)
    if du is None or not np.any(du):
        return f, np.sqrt(Y2)
    U2 = _input_power(du, nfft, ker)
    H = np.sqrt(Y2 / np.maximum(U2, 1e-300))
    H[U2 < 1e-4 * U2.max()] = np.nan
    return f, H


@functools.lru_cache(maxsize=32)
def _etfe_grid(n: int, fs: float) -> tuple[np.ndarray, np.ndarray, int]:
    """The ETFE's frequencies, smoothing kernel and FFT length for ``n`` samples at ``fs`` Hz (read-only; kept:
    a Monte-Carlo study fits many records of one length, issue #15)."""
    # zero padding to a fine frequency grid; a long record's own grid is already finer than any peak
    # (the smoothing below is fixed in Hz), and 8x padding made this FFT a quarter of a 200k-sample fit
    pad = 8 if n <= _LONG_RECORD else 1
    nfft = 1 << int(np.ceil(np.log2(max(pad * n, 256))))
    f = np.fft.rfftfreq(nfft, 1.0 / fs)
    w = max(1, int(round(3 * nfft / n)))
    ker = np.hanning(w + 2)[1:-1]
    ker /= ker.sum()
    f.flags.writeable = ker.flags.writeable = False
    return f, ker, nfft


def _smoothed_power(x: np.ndarray, nfft: int, ker: np.ndarray) -> np.ndarray:
    """``|FFT(x, nfft)|^2`` smoothed by ``ker`` (the ETFE's auto-spectrum)."""
    return np.convolve(np.abs(np.fft.rfft(x, nfft)) ** 2, ker, mode="same")


#: (key, smoothed power) of the last input seen by :func:`_input_power` (one tuple: read and replaced whole).
_last_input: list[tuple] = [(None, None)]


def _input_power(du: np.ndarray, nfft: int, ker: np.ndarray) -> np.ndarray:
    """:func:`_smoothed_power` of the differenced input; for a record of at most ``_LONG_RECORD`` samples the
    last one is kept: repeated experiments (and a Monte-Carlo study) fit many records made with one command
    (issue #15)."""
    if du.size > _LONG_RECORD:
        return _smoothed_power(du, nfft, ker)
    key = (nfft, ker.size, du.tobytes())
    last_key, power = _last_input[0]
    if last_key != key:
        power = _smoothed_power(du, nfft, ker)
        power.flags.writeable = False
        _last_input[0] = (key, power)
    return power


def _peaks(f: np.ndarray, H: np.ndarray, f_lo: float, f_hi: float, k: int) -> list[PeakGuess]:
    """The ``k`` most prominent peaks (Hz) of ``H`` in ``(f_lo, f_hi)`` with half-power damping guesses."""
    ok = (f > f_lo) & (f < f_hi) & np.isfinite(H)
    Hm = np.where(ok, H, 0.0)
    idx, props = signal.find_peaks(Hm, prominence=0.0)
    if idx.size == 0:
        idx, prom = np.array([int(np.argmax(Hm))]), np.array([1.0])
    else:
        prom = props["prominences"]
    out = []
    for i in idx[np.argsort(prom)[::-1][:k]].tolist():
        j0, j1 = half_power_span(Hm, i)
        # Python floats: the same arithmetic as numpy's scalars, without their overhead (issue #15)
        fi, f0, f1 = float(f[i]), float(f[j0]), float(f[j1])
        zeta = (f1 - f0) / (2.0 * fi) if fi > 0 else 0.05
        out.append(PeakGuess(fi, min(max(zeta, 0.003), 0.5)))  # np.clip(zeta, 0.003, 0.5)
    return out


def _start(model: OEModel, u: np.ndarray | None, y: np.ndarray, fs: float, n_modes: int) -> np.ndarray:
    """Starting (ln omega, zeta) per mode: spectral peaks ranked by the projected cost (greedy).

    On a long record (more than ``_LONG_RECORD`` samples) the candidates are first ranked on its
    first ``_HEAD`` samples and only the best ``_SHORTLIST`` of them on the whole record
    (issue #15: the ranking was a third of a 200k-sample fit).
    """
    f, H = _etfe(u, y, fs)
    cands = _peaks(f, H, 2.0 * fs / y.size, 0.45 * fs, max(8, 2 * n_modes))
    cands += _grid_candidates(y.size, fs)
    short = model.head(_HEAD) if y.size > _LONG_RECORD else None
    chosen: list[tuple[float, float]] = []
    full_n = model.n
    for j in range(n_modes):
        todo = [(fp, zp) for fp, zp in cands if not any(abs(fp - c[0]) < 0.02 * fp for c in chosen)]
        if short is not None:
            ranked = _costs(short, chosen, todo, j)
            todo = [todo[i] for i in sorted(range(len(todo)), key=lambda i: (ranked[i], i))][:_SHORTLIST]
        if not todo:
            raise ValueError(
                f"n_modes={full_n}: the spectrum has fewer distinct peaks than modes to fit; ask for fewer modes"
            )
        costs = _costs(model, chosen, todo, j)
        chosen.append(todo[int(np.argmin(costs))])  # the first of equal costs, as a strict < scan
    model.n = full_n
    return np.array([[math.log(2 * math.pi * a), b] for a, b in chosen]).ravel()


@functools.lru_cache(maxsize=32)
def _grid_candidates(n: int, fs: float) -> tuple[tuple[float, float], ...]:
    """The start's fixed candidates: 12 frequencies log-spaced from 2 bins to 0.4 fs, zeta 0.05 (kept per record
    length and rate, immutable; issue #15)."""
    return tuple((fp, zp) for fp in np.geomspace(2.0 * fs / n, 0.4 * fs, 12).tolist() for zp in (0.05,))


def _costs(model: OEModel, chosen: list[tuple[float, float]], cands: list[tuple[float, float]], j: int) -> np.ndarray:
    """The projected cost of the modes ``chosen`` plus each of ``cands`` (``j + 1`` modes)."""
    model.n = j + 1
    return model.costs([np.array([[math.log(2 * math.pi * a), b] for a, b in chosen + [c]]).ravel() for c in cands])


# ----------------------------------------------------------------------------- the fit


@v.renamed_keywords(fs="sample_rate")
def fit_oe(u: np.ndarray | None, y: np.ndarray, sample_rate: float, n_modes: int, settings: OESettings, *,
           start: Sequence[Mode] | None = None, method: str = "oe") -> OEFit:
    """Output-error fit of ``n_modes`` modes (every mode kept; see :func:`significant_oe`).

    Nuisance terms set to ``"auto"`` are chosen by the data: see :func:`_fit_auto_terms`.
    """
    fs = sample_rate  # the sample rate [Hz], fs in the formulas
    terms = {"feedthrough": settings.feedthrough, "offset": settings.offset, "initial_state": settings.initial_state}
    auto = [name for name, val in terms.items() if val == "auto"]
    if auto:
        return _fit_auto_terms(u, y, fs, n_modes, settings, terms, auto, start=start, method=method)
    return _fit_fixed_terms(u, y, fs, n_modes, settings.covariance, terms, start=start, method=method,
                            weights=settings.weights)


def _fit_auto_terms(u: np.ndarray | None, y: np.ndarray, fs: float, n_modes: int, settings: OESettings,
                    terms: dict[str, bool | str], auto: list[str], *, start: Sequence[Mode] | None,
                    method: str) -> OEFit:
    """Nuisance terms chosen by the data.

    Fit without the "auto" ones (a position output of a system at rest under a held
    input has no direct term, offset or initial state), then F-test each of them at the
    fitted poles (one projection each, 0.1 % level) and refit with the ones the data ask
    for.  Fitting unneeded free-response columns costs zeta bias: on seed 002's single
    step at 5 % noise +1.3 % with them, +0.65 % without.
    """
    weights = settings.weights
    base = {name: (False if val == "auto" else bool(val)) for name, val in terms.items()}
    (out, rss, k), model, th = _fit_fixed(u, y, fs, n_modes, settings.covariance, base, start=start,
                                          method=method, weights=weights)
    n_lin = k - th.size
    rows = model.basis(th).T  # the fitted model's columns at its poles; each trial adds its term's
    chosen = dict(base)
    for name in auto:
        more = model.term_rows(name, th)
        if more is None:
            continue
        Rw = np.vstack([rows, more])
        e1, n_lin1 = _project(Rw if weights is None else Rw * weights, y if weights is None else y * weights)[3:]
        extra = n_lin1 - n_lin
        dof = (y.size if weights is None else int(np.count_nonzero(weights))) - k - extra
        if extra <= 0 or dof <= 0:
            continue
        rss1 = float(e1 @ e1)
        F = ((rss - rss1) / extra) / max(rss1 / dof, 1e-300)
        if F > special.fdtri(extra, dof, 0.999):  # scipy.stats.f.ppf without its argument checks (issue #15)
            chosen[name] = True
    if chosen == base:
        return OEFit(out, rss, k)
    return _fit_fixed_terms(u, y, fs, n_modes, settings.covariance, chosen, start=start, method=method,
                            weights=weights)


def _fit_fixed_terms(u: np.ndarray | None, y: np.ndarray, fs: float, n_modes: int, covariance: str,
                     terms: dict[str, bool], *, start: Sequence[Mode] | None, method: str,
                     weights: np.ndarray | None) -> OEFit:
    """The fit with each nuisance term on or off: best of three damping scales for one mode, intervals, tests."""
    return _fit_fixed(u, y, fs, n_modes, covariance, terms, start=start, method=method, weights=weights)[0]


def _fit_fixed(u: np.ndarray | None, y: np.ndarray, fs: float, n_modes: int, covariance: str,
               terms: dict[str, bool], *, start: Sequence[Mode] | None, method: str,
               weights: np.ndarray | None) -> tuple[OEFit, OEModel, np.ndarray]:
    """:func:`_fit_fixed_terms`, with its model and the fitted ``(ln omega, zeta)`` (in the model's order)."""
    h = 1.0 / fs
    model = OEModel(u, y, h, n_modes, weights=weights, **terms)
    if start is None:
        theta0 = _start(model, u, y, fs, n_modes)
    else:
        theta0 = np.array([[math.log(m.omega), m.zeta] for m in start]).ravel()
    w_min = 2 * math.pi * 0.5 / (y.size * h)
    best = None
    for scale in (1.0, 0.5, 2.0) if n_modes == 1 else (1.0,):
        th0 = theta0.copy()
        th0[1::2] = np.clip(th0[1::2] * scale, 0.002, 0.6)
        th, res = _least_squares(model, th0, w_min)
        if best is None or res.cost < best[1].cost * (1 - 1e-9):
            best = (th, res)
        if scale == 1.0:
            first_res = res
            first_p = whiteness(res.fun)  # the residual's whiteness: also the intervals' (issue #15: computed once)
            if _white(first_p):
                break
    th, res = best
    e, y_hat, n_lin = model.project(th)
    J = model.jacobian(th)
    ivs, used, pw = pole_intervals(th, J, e, n_lin, covariance, model.n_used,
                                   whiteness_p=first_p if best[1] is first_res else None)
    cells = search_cells(0.5 / (y.size * h), 0.49 / h, y.size * h)
    tests = model.mode_tests(th, e, n_lin, used == "hac", cells)
    order = np.argsort(th[0::2])
    modes = [Mode(math.exp(th[2 * i]), float(th[2 * i + 1])) for i in order]
    ivs = [ivs[i] for i in order]
    out = Identification(modes, ivs, method, fit_percent(y, y_hat), pw, used, y_hat, e, fs,
                         tests=[tests[i] for i in order])
    rss = float(e @ e)
    return OEFit(out, rss, n_lin + th.size), model, th


@v.renamed_keywords(fs="sample_rate")
def significant_oe(u: np.ndarray | None, y: np.ndarray, sample_rate: float, n_modes: int, settings: OESettings, *,
                   start: Sequence[Mode] | None = None, method: str = "oe") -> OEFit:
    """:func:`fit_oe` keeping only the modes the data demand (see :mod:`.significance`).

    The least significant failing mode is dropped and the rest refitted from their
    estimates, until every mode passes; :class:`NoModeFound` when none does.
    """
    fs = sample_rate  # the sample rate [Hz], fs in the formulas
    dropped: list[str] = []
    while True:
        out, rss, k = fit_oe(u, y, fs, n_modes, settings, start=start, method=method)
        bad = [i for i, tst in enumerate(out.tests) if not tst.significant]
        if not bad:
            out.notes += dropped
            return OEFit(out, rss, k)
        worst = max(bad, key=lambda i: out.tests[i].p_adjusted)
        m, tst = out.modes[worst], out.tests[worst]
        if n_modes == 1:
            raise NoModeFound(describe_failure(method, m, tst), m, tst)
        dropped.append(f"a candidate at {m.freq_hz:.4g} Hz (zeta {m.zeta:.3g}) was dropped: it {tst.describe()}")
        start = [mm for i, mm in enumerate(out.modes) if i != worst]
        n_modes -= 1


def _white(p: float) -> bool:
    """Accept the first start when its residual looks white (nothing left to explain): ``p`` is its whiteness."""
    return bool(math.isfinite(p) and p > 1e-3)
