"""Estimators of lightly damped modes (omega, zeta) with 95 % confidence intervals.

Methods of :func:`identify`:

``"oe"`` (default)
    Output-error fit of a continuous-time modal model by variable projection.
    The model is ``y = sum_k (b0_k + b1_k s) / (s^2 + 2 zeta_k omega_k s + omega_k^2) u
    + d u + c`` plus each mode's free response (unknown initial state), sampled
    exactly under a zero-order hold.  The numerators, feed-through ``d`` (an
    accelerometer's ``s^2`` term) and offset ``c`` enter linearly and are
    projected out; only ``(ln omega_k, zeta_k)`` are searched
    (scipy.optimize.least_squares), from the peaks of the empirical transfer
    function.  Valid for position and acceleration outputs.  Output noise does
    not bias it (the criterion is the simulated, not the predicted, output).
    Intervals: Gauss-Newton covariance ``s^2 (J^T J)^-1`` of the projected
    residual; when the residual fails the whiteness test, a Newey-West (HAC)
    covariance is used instead.
``"arx"``
    Seed 002's least squares (eq. 19-25), the documented baseline: biased
    when the output is noisy (the regressors contain the noise).
``"freq"``
    Seed 002 section 3.2.2: FFT ratio, spectral peak, -3 dB bandwidth to the
    pole radius (eq. 26, corrected), poles by eq. 27, spectrum resampled so
    the peak is on the grid, then the seed's step-up/step-down refinement of
    omega and zeta on the response error.
``"decay"``
    Free-decay (ring-down) data, ``u`` ignored: matrix pencil (Hua & Sarkar)
    on the record, then the OE refinement of the free response.
``"psd"``
    Output-only (input not recorded, e.g. a Klipper resonance test): Welch
    PSD fitted by a sum of modal power peaks on a smooth background.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, NamedTuple, Sequence

import numpy as np
from scipy import linalg, optimize, signal, stats

from .. import _validate as v
from ..modes import Mode

__all__ = ["Interval", "Identification", "identify", "METHODS", "whiteness", "fit_percent"]

METHODS = ("oe", "arx", "freq", "decay", "psd")
_ZMIN, _ZMAX = 1e-5, 0.95


class Interval(NamedTuple):
    """95 % confidence intervals of one mode: ``omega`` (rad/s) and ``zeta``, each ``(low, high)``.

    Indexable by position (``iv[0]``), attribute (``iv.omega``) or name (``iv["zeta"]``).
    """

    omega: tuple[float, float]
    zeta: tuple[float, float]

    def __getitem__(self, key: Any) -> Any:  # type: ignore[override]
        if isinstance(key, str):
            return getattr(self, key)
        return tuple.__getitem__(self, key)

    @property
    def freq_hz(self) -> tuple[float, float]:
        return (self.omega[0] / (2 * math.pi), self.omega[1] / (2 * math.pi))

    def contains(self, mode: Mode) -> bool:
        """True when ``mode`` lies inside both intervals."""
        return self.omega[0] <= mode.omega <= self.omega[1] and self.zeta[0] <= mode.zeta <= self.zeta[1]


@dataclass
class Identification:
    """Result of :func:`identify`.

    Attributes
    ----------
    modes : list of Mode
        Identified modes, sorted by frequency.
    intervals : list of Interval
        95 % confidence intervals, one per mode.
    method : str
    fit_percent : float
        ``100 (1 - ||y - y_hat|| / ||y - mean y||)`` (NRMSE fit), NaN for ``psd``.
    whiteness_p : float
        Ljung-Box p-value of the residual (20 lags); small = coloured residual.
    covariance : str
        ``"gauss-newton"``, ``"hac"`` (Newey-West) or ``"delta"`` (ARX).
    y_fit : ndarray or None
        Model output (``psd``: model PSD on ``freqs``).
    order_scores : dict
        BIC per number of modes when the order was chosen automatically.
    notes : list of str
    """

    modes: list[Mode]
    intervals: list[Interval]
    method: str
    fit_percent: float = float("nan")
    whiteness_p: float = float("nan")
    covariance: str = "gauss-newton"
    y_fit: np.ndarray | None = None
    residual: np.ndarray | None = None
    fs: float = float("nan")
    order_scores: dict[int, float] = field(default_factory=dict)
    freqs: np.ndarray | None = None
    spectrum: np.ndarray | None = None
    amplitudes: list[float] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def summary(self) -> str:
        lines = [f"method {self.method}: {len(self.modes)} mode(s)"]
        for m, iv in zip(self.modes, self.intervals):
            f0, f1 = iv.freq_hz
            lines.append(f"  f = {m.freq_hz:.4f} Hz [{f0:.4f}, {f1:.4f}], zeta = {m.zeta:.4f} "
                         f"[{iv.zeta[0]:.4f}, {iv.zeta[1]:.4f}]")
        if math.isfinite(self.fit_percent):
            lines.append(f"  fit {self.fit_percent:.2f} %, residual whiteness p = {self.whiteness_p:.3g} "
                         f"({self.covariance} intervals)")
        lines.extend("  note: " + n for n in self.notes)
        return "\n".join(lines)


# ----------------------------------------------------------------------------- statistics


def fit_percent(y: np.ndarray, y_hat: np.ndarray) -> float:
    """NRMSE fit in percent (100 = perfect)."""
    d = np.linalg.norm(y - np.mean(y))
    return float(100.0 * (1.0 - np.linalg.norm(y - y_hat) / d)) if d > 0 else float("nan")


def whiteness(e: np.ndarray, lags: int = 20) -> float:
    """Ljung-Box p-value of the residual ``e`` over ``lags`` lags.

    Examples
    --------
    >>> whiteness(np.random.default_rng(0).standard_normal(2000)) > 0.01
    True
    >>> whiteness(np.sin(np.arange(500) * 0.1)) < 1e-6
    True
    """
    e = np.asarray(e, float) - np.mean(e)
    n = e.size
    m = min(lags, n // 4)
    if m < 1 or not np.any(e):
        return float("nan")
    full = np.correlate(e, e, "full")[n - 1:n + m] if n < 4096 else _acov_fft(e, m)
    r = full[1:] / full[0]
    q = n * (n + 2) * np.sum(r * r / (n - np.arange(1, m + 1)))
    return float(stats.chi2.sf(q, m))


def _acov_fft(e: np.ndarray, m: int) -> np.ndarray:
    nf = 1 << int(np.ceil(np.log2(2 * e.size)))
    f = np.fft.rfft(e, nf)
    return np.fft.irfft(f * np.conj(f), nf)[: m + 1]


def _hac(J: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Newey-West covariance of least-squares parameters (Bartlett weights)."""
    n = e.size
    L = int(math.floor(4.0 * (n / 100.0) ** (2.0 / 9.0)))
    Gm = J * e[:, None]
    S = Gm.T @ Gm
    for lag in range(1, L + 1):
        w = 1.0 - lag / (L + 1.0)
        C = Gm[lag:].T @ Gm[:-lag]
        S += w * (C + C.T)
    A = np.linalg.pinv(J.T @ J)
    return A @ S @ A


# ----------------------------------------------------------------------------- OE model


class _OEModel:
    """Variable-projection residual of the continuous modal model under ZOH."""

    def __init__(self, u: np.ndarray | None, y: np.ndarray, h: float, n_modes: int, *,
                 feedthrough: bool = True, offset: bool = True, initial_state: bool = True) -> None:
        self.u, self.y, self.h, self.n = u, y, h, n_modes
        self.feedthrough = feedthrough and u is not None
        self.offset = offset
        self.initial_state = initial_state or u is None
        self.k = np.arange(y.size, dtype=float)
        self.n_lin_last = 0

    def basis(self, theta: np.ndarray) -> np.ndarray:
        cols = []
        for i in range(self.n):
            w = math.exp(theta[2 * i])
            z = min(max(theta[2 * i + 1], _ZMIN), _ZMAX)
            p = complex(-z * w, w * math.sqrt(1.0 - z * z))
            lam = np.exp(p * self.h)
            if self.u is not None:
                a = [1.0, -2.0 * lam.real, abs(lam) ** 2]
                x1 = signal.lfilter([0.0, 1.0], a, self.u)
                x2 = np.concatenate(([0.0], x1[:-1]))
                cols += [x1, x2]
            if self.initial_state:
                r = np.exp(p.real * self.h * self.k)
                ph = p.imag * self.h * self.k
                cols += [r * np.cos(ph), r * np.sin(ph)]
        if self.feedthrough:
            cols.append(self.u)
        if self.offset:
            cols.append(np.ones_like(self.y))
        return np.column_stack(cols)

    def project(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
        Phi = self.basis(theta)
        nrm = np.linalg.norm(Phi, axis=0)
        nrm[nrm == 0] = 1.0
        Phi = Phi / nrm
        # projection through the (small) Gram matrix, eigen-truncated for rank deficiency
        # (a step at k = 0 makes the forced response a combination of offset and free response)
        lam, V = np.linalg.eigh(Phi.T @ Phi)
        keep = lam > lam[-1] * 1e-13
        W = V[:, keep] / lam[keep]
        y_hat = Phi @ (W @ (V[:, keep].T @ (Phi.T @ self.y)))
        return self.y - y_hat, y_hat, int(keep.sum())

    def residual(self, theta: np.ndarray) -> np.ndarray:
        return self.project(theta)[0]


def _bounds(n: int, h: float, w_min: float) -> tuple[np.ndarray, np.ndarray]:
    lo = np.tile([math.log(w_min), _ZMIN], n)
    hi = np.tile([math.log(0.98 * math.pi / h), _ZMAX], n)
    return lo, hi


def _fit_oe(model: _OEModel, theta0: np.ndarray, w_min: float) -> tuple[np.ndarray, Any]:
    lo, hi = _bounds(model.n, model.h, w_min)
    x0 = np.clip(theta0, lo + 1e-9, hi - 1e-9)
    res = optimize.least_squares(model.residual, x0, bounds=(lo, hi), method="trf", x_scale="jac",
                                 xtol=1e-10, ftol=1e-12, gtol=1e-12, max_nfev=200 * len(x0))
    return res.x, res


def _intervals_from(theta: np.ndarray, J: np.ndarray, e: np.ndarray, n_lin: int,
                    covariance: str) -> tuple[list[Interval], str, float]:
    n = e.size
    dof = max(n - n_lin - theta.size, 1)
    pw = whiteness(e)
    use = covariance
    if covariance == "auto":
        use = "hac" if (math.isfinite(pw) and pw < 0.01) else "gauss-newton"
    if use == "hac":
        C = _hac(J, e) * n / dof
    else:
        s2 = float(e @ e) / dof
        C = s2 * np.linalg.pinv(J.T @ J)
    tq = float(stats.t.ppf(0.975, dof))
    out = []
    for i in range(theta.size // 2):
        lw, z = theta[2 * i], theta[2 * i + 1]
        sw = math.sqrt(max(C[2 * i, 2 * i], 0.0))
        sz = math.sqrt(max(C[2 * i + 1, 2 * i + 1], 0.0))
        out.append(Interval((math.exp(lw - tq * sw), math.exp(lw + tq * sw)), (max(z - tq * sz, 0.0), z + tq * sz)))
    return out, use, pw


def _marginal(J: np.ndarray, k: int) -> np.ndarray:
    """Jacobian of the first ``k`` parameters with the others projected out (their marginal covariance)."""
    if J.shape[1] == k:
        return J
    Q, _ = np.linalg.qr(J[:, k:])
    return J[:, :k] - Q @ (Q.T @ J[:, :k])


def _numjac(fun: Any, x: np.ndarray) -> np.ndarray:
    f0 = fun(x)
    J = np.empty((f0.size, x.size))
    for i in range(x.size):
        dx = 1e-6 * max(abs(x[i]), 1e-3)
        xp, xm = x.copy(), x.copy()
        xp[i] += dx
        xm[i] -= dx
        J[:, i] = (fun(xp) - fun(xm)) / (2 * dx)
    return J


# ----------------------------------------------------------------------------- starting point


def _etfe(u: np.ndarray | None, y: np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Smoothed empirical transfer function |Y/U| of the differenced signals (|Y| when u is None).

    The auto-spectra are averaged over about 3 resolution bins (the classical
    smoothed ETFE) so that a noise spike does not outrank a resonance.
    """
    n = y.size
    pad = 8
    nfft = 1 << int(np.ceil(np.log2(max(pad * n, 256))))
    f = np.fft.rfftfreq(nfft, 1.0 / fs)
    w = max(1, int(round(3 * nfft / n)))
    ker = np.hanning(w + 2)[1:-1]
    ker /= ker.sum()
    Y2 = np.convolve(np.abs(np.fft.rfft(np.diff(y), nfft)) ** 2, ker, mode="same")
    if u is None or not np.any(np.diff(u)):
        return f, np.sqrt(Y2)
    U2 = np.convolve(np.abs(np.fft.rfft(np.diff(u), nfft)) ** 2, ker, mode="same")
    H = np.sqrt(Y2 / np.maximum(U2, 1e-300))
    H[U2 < 1e-4 * U2.max()] = np.nan
    return f, H


def _peaks(f: np.ndarray, H: np.ndarray, f_lo: float, f_hi: float, k: int) -> list[tuple[float, float]]:
    """The ``k`` most prominent peaks (Hz) of ``H`` in ``(f_lo, f_hi)`` with half-power damping guesses."""
    ok = (f > f_lo) & (f < f_hi) & np.isfinite(H)
    Hm = np.where(ok, H, 0.0)
    idx, props = signal.find_peaks(Hm, prominence=0.0)
    if idx.size == 0:
        idx, prom = np.array([int(np.argmax(Hm))]), np.array([1.0])
    else:
        prom = props["prominences"]
    out = []
    for i in idx[np.argsort(prom)[::-1][:k]]:
        half = Hm[i] / math.sqrt(2.0)
        j0 = i
        while j0 > 0 and Hm[j0] > half:
            j0 -= 1
        j1 = i
        while j1 < len(Hm) - 1 and Hm[j1] > half:
            j1 += 1
        zeta = (f[j1] - f[j0]) / (2.0 * f[i]) if f[i] > 0 else 0.05
        out.append((float(f[i]), float(np.clip(zeta, 0.003, 0.5))))
    return out


def _start(model: "_OEModel", u: np.ndarray | None, y: np.ndarray, fs: float, n_modes: int) -> np.ndarray:
    """Starting (ln omega, zeta) per mode: spectral peaks ranked by the projected cost (greedy)."""
    f, H = _etfe(u, y, fs)
    cands = _peaks(f, H, 2.0 * fs / y.size, 0.45 * fs, max(8, 2 * n_modes))
    cands += [(fp, zp) for fp in np.geomspace(2.0 * fs / y.size, 0.4 * fs, 12) for zp in (0.05,)]
    chosen: list[tuple[float, float]] = []
    full_n = model.n
    for j in range(n_modes):
        model.n = j + 1
        best = None
        for fp, zp in cands:
            if any(abs(fp - c[0]) < 0.02 * fp for c in chosen):
                continue
            th = np.array([[math.log(2 * math.pi * a), b] for a, b in chosen + [(fp, zp)]]).ravel()
            r = model.residual(th)
            c = float(r @ r)
            if best is None or c < best[0]:
                best = (c, (fp, zp))
        if best is None:
            raise ValueError(
                f"n_modes={full_n}: the spectrum has fewer distinct peaks than modes to fit; ask for fewer modes"
            )
        chosen.append(best[1])
    model.n = full_n
    return np.array([[math.log(2 * math.pi * a), b] for a, b in chosen]).ravel()


# ----------------------------------------------------------------------------- estimators


def _oe(t: np.ndarray, u: np.ndarray | None, y: np.ndarray, fs: float, n_modes: int, *, covariance: str,
        feedthrough: bool | str, offset: bool | str, initial_state: bool | str, start: Sequence[Mode] | None = None,
        method: str = "oe") -> tuple[Identification, float, int]:
    terms = {"feedthrough": feedthrough, "offset": offset, "initial_state": initial_state}
    auto = [name for name, val in terms.items() if val == "auto"]
    if auto:
        # Nuisance terms chosen by the data: fit without the "auto" ones (a position output of a
        # system at rest under a held input has no direct term, offset or initial state), then
        # F-test each of them at the fitted poles (one projection each, 0.1 % level) and refit
        # with the ones the data ask for.  Fitting unneeded free-response columns costs zeta
        # bias: on seed 002's single step at 5 % noise +1.3 % with them, +0.65 % without.
        base = {name: (False if val == "auto" else bool(val)) for name, val in terms.items()}
        out, rss, k = _oe(t, u, y, fs, n_modes, covariance=covariance, start=start, method=method, **base)
        th = np.array([[math.log(m.omega), m.zeta] for m in out.modes]).ravel()
        n_lin = k - th.size
        chosen = dict(base)
        for name in auto:
            trial = dict(base)
            trial[name] = True
            e1, _, n_lin1 = _OEModel(u, y, 1.0 / fs, n_modes, **trial).project(th)
            extra = n_lin1 - n_lin
            dof = y.size - k - extra
            if extra <= 0 or dof <= 0:
                continue
            rss1 = float(e1 @ e1)
            F = ((rss - rss1) / extra) / max(rss1 / dof, 1e-300)
            if F > stats.f.ppf(0.999, extra, dof):
                chosen[name] = True
        if chosen == base:
            return out, rss, k
        return _oe(t, u, y, fs, n_modes, covariance=covariance, start=start, method=method, **chosen)
    h = 1.0 / fs
    model = _OEModel(u, y, h, n_modes, feedthrough=feedthrough, offset=offset, initial_state=initial_state)
    if start is None:
        theta0 = _start(model, u, y, fs, n_modes)
    else:
        theta0 = np.array([[math.log(m.omega), m.zeta] for m in start]).ravel()
    w_min = 2 * math.pi * 0.5 / (y.size * h)
    best = None
    for scale in (1.0, 0.5, 2.0) if n_modes == 1 else (1.0,):
        th0 = theta0.copy()
        th0[1::2] = np.clip(th0[1::2] * scale, 0.002, 0.6)
        th, res = _fit_oe(model, th0, w_min)
        if best is None or res.cost < best[1].cost * (1 - 1e-9):
            best = (th, res)
        if scale == 1.0 and _good(res, model):
            break
    th, res = best
    e, y_hat, n_lin = model.project(th)
    J = _numjac(model.residual, th)
    ivs, used, pw = _intervals_from(th, J, e, n_lin, covariance)
    order = np.argsort(th[0::2])
    modes = [Mode(math.exp(th[2 * i]), float(th[2 * i + 1])) for i in order]
    ivs = [ivs[i] for i in order]
    out = Identification(modes, ivs, method, fit_percent(y, y_hat), pw, used, y_hat, e, fs)
    rss = float(e @ e)
    return out, rss, n_lin + th.size


def _good(res: Any, model: _OEModel) -> bool:
    """Accept the first start when its residual looks white (nothing left to explain)."""
    p = whiteness(res.fun)
    return bool(math.isfinite(p) and p > 1e-3)


def _arx(t: np.ndarray, u: np.ndarray, y: np.ndarray, fs: float, nk: int = 0) -> Identification:
    """Seed 002 eq. 19-25: theta = A_p^+ y_p with rows [u(k), u(k-1), -y(k-1), -y(k-2)].

    ``nk`` delays the input regressors (``nk = 1`` is the structure of a ZOH-sampled
    continuous system, ``u(k-1), u(k-2)``); the seed's eq. 21 is ``nk = 0``.
    """
    h = 1.0 / fs
    k0 = max(2, nk + 1)
    ks = np.arange(k0, y.size)
    if ks.size < 4:  # seed 002 eq. 19: P = n + m = 4 rows at least
        raise ValueError(f"arx needs at least {k0 + 4} samples (seed 002 eq. 19), got {y.size}")
    A = np.column_stack([u[ks - nk], u[ks - nk - 1], -y[ks - 1], -y[ks - 2]])  # eq. 22
    yp = y[ks]
    theta, *_ = np.linalg.lstsq(A, yp, rcond=None)  # eq. 24-25 (pseudo-inverse)
    e = yp - A @ theta
    dof = max(ks.size - 4, 1)
    C = float(e @ e) / dof * np.linalg.pinv(A.T @ A)

    def to_mode(a1: float, a2: float) -> tuple[float, float]:
        r = np.roots([1.0, a1, a2])
        if abs(r[0].imag) < 1e-12 or np.any(np.abs(r) >= 1.0) or np.any(np.abs(r) == 0.0):
            raise ValueError("arx found no stable oscillatory mode (real or unstable discrete poles)")
        s = np.log(r[0] if r[0].imag > 0 else r[1]) / h
        return float(abs(s)), float(-s.real / abs(s))

    w, z = to_mode(theta[2], theta[3])
    Jm = np.empty((2, 2))
    for j in range(2):
        d = 1e-7 * max(abs(theta[2 + j]), 1e-3)
        tp, tm = theta[2:].copy(), theta[2:].copy()
        tp[j] += d
        tm[j] -= d
        Jm[:, j] = (np.array(to_mode(*tp)) - np.array(to_mode(*tm))) / (2 * d)
    Cm = Jm @ C[2:, 2:] @ Jm.T
    tq = float(stats.t.ppf(0.975, dof))
    sw, sz = math.sqrt(max(Cm[0, 0], 0)), math.sqrt(max(Cm[1, 1], 0))
    iv = Interval((w - tq * sw, w + tq * sw), (max(z - tq * sz, 0.0), z + tq * sz))
    y_hat = signal.lfilter(theta[:2] if nk == 0 else np.r_[np.zeros(nk), theta[:2]], np.r_[1.0, theta[2:]], u)
    pw = whiteness(y - y_hat)
    return Identification([Mode(w, min(max(z, 0.0), 0.999999))], [iv], "arx", fit_percent(y, y_hat), pw,
                          "delta", y_hat, y - y_hat, fs,
                          notes=["ARX (seed 002 eq. 21): biased under output noise; intervals assume equation "
                                 "noise and are not honest for output noise"])


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


def _freq(t: np.ndarray, u: np.ndarray, y: np.ndarray, fs: float, *, refine: bool, covariance: str,
          feedthrough: bool, offset: bool, initial_state: bool) -> Identification:
    """Seed 002 section 3.2.2 (eq. 26-27) with its iterative refinement."""
    h = 1.0 / fs
    n = y.size
    nfft = max(n, int(round(fs)))  # seed: a one-second window
    Y, U = np.fft.rfft(np.diff(y), nfft), np.fft.rfft(np.diff(u), nfft)
    f = np.fft.rfftfreq(nfft, h)
    aU = np.abs(U)
    H = np.abs(Y) / np.maximum(aU, 1e-300)
    ok = (aU > 1e-2 * aU.max()) & (f > 2 * fs / n) & (f < 0.45 * fs)
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
    a = j
    while a > 0 and Hg[a] > half:
        a -= 1
    b = j
    while b < len(Hg) - 1 and Hg[b] > half:
        b += 1
    fa = np.interp(half, [Hg[a], Hg[a + 1]], [fg[a], fg[a + 1]])
    fb = np.interp(half, [Hg[b], Hg[b - 1]], [fg[b], fg[b - 1]])
    dw = 2 * math.pi * (fb - fa) / fs
    theta = 2 * math.pi * f_max / fs
    r = _radius_from_bandwidth(dw, theta)  # eq. 26 (exact for any theta)
    zp = r * complex(math.cos(theta), math.sin(theta))  # eq. 27
    s = np.log(zp) / h
    w0, z0 = float(abs(s)), float(np.clip(-s.real / abs(s), _ZMIN, 0.9))
    model = _OEModel(u, y, h, 1, feedthrough=feedthrough, offset=offset, initial_state=initial_state)
    th = np.array([math.log(w0), z0])
    notes = [f"spectral estimate before refinement: f = {w0 / 2 / math.pi:.4f} Hz, zeta = {z0:.4f}"]
    if refine:
        # seed 002: step omega up/down while the response error decreases, then zeta; halve the steps
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
                        if p == 1 and not _ZMIN <= x[1] <= _ZMAX:
                            break
                        cx = cost(x)
                        it += 1
                        if cx < c:
                            th, c, improved = x, cx, True
                        else:
                            break
            if not improved:
                steps /= 2.0
    e, y_hat, n_lin = model.project(th)
    J = _numjac(model.residual, th)
    ivs, used, pw = _intervals_from(th, J, e, n_lin, covariance)
    if not refine:
        notes.append("no refinement: intervals are the local OE curvature at a non-optimal point")
    return Identification([Mode(math.exp(th[0]), float(th[1]))], ivs, "freq", fit_percent(y, y_hat), pw, used,
                          y_hat, e, fs, notes=notes)


def _matrix_pencil(y: np.ndarray, h: float, n_modes: int) -> list[Mode]:
    """Matrix pencil (Hua & Sarkar 1990) on a free decay: poles of the 2 n_modes dominant components."""
    n = y.size
    L = n // 3
    Yh = linalg.hankel(y[: n - L], y[n - L - 1:])
    U, s, Vt = np.linalg.svd(Yh, full_matrices=False)
    M = 2 * n_modes + 1  # + 1 for an offset
    V = Vt[:M].T
    V1, V2 = V[:-1], V[1:]
    z = np.linalg.eigvals(np.linalg.pinv(V1) @ V2)
    modes = []
    for zi in z:
        if zi.imag <= 1e-9 or abs(zi) >= 1.0:
            continue
        s_ = np.log(zi) / h
        modes.append(Mode(float(abs(s_)), float(np.clip(-s_.real / abs(s_), _ZMIN, 0.9))))
    modes.sort(key=lambda m: m.omega)
    if not modes:
        raise ValueError("decay: no decaying oscillation found in y (is it a ring-down record?)")
    return modes[:n_modes]


def _psd(y: np.ndarray, fs: float, n_modes: int, *, band: tuple[float, float] | None,
         excitation_slope: float, freqs: np.ndarray | None = None, psd: np.ndarray | None = None,
         nperseg: int | None = None) -> Identification:
    """Output-only: fit ``P(f) = (f/f0)^a (sum_k A_k L_k(f) + B0 + B1 f^2)`` to the Welch PSD.

    ``L_k(f) = f_k^4 / ((f_k^2 - f^2)^2 + (2 zeta_k f_k f)^2)`` is the power of one
    mode; cross terms between modes are neglected, and the excitation is
    assumed smooth, ``f^a`` (Klipper's sweep: a = 2).  Fitted on relative
    (1/P-weighted) errors, a Welch PSD's natural scale.  Limits: the half-power
    width 2 zeta f must span several frequency bins; modes closer than about
    their half-power width are not separated; intervals come from the fit
    residual (HAC over bins), not from the PSD's chi-square statistics.
    """
    if psd is None:
        n = y.size
        if nperseg is None:
            nperseg = 1 << int(np.floor(np.log2(max(n // 8, 64))))
        freqs, psd = signal.welch(y - np.mean(y), fs=fs, nperseg=min(nperseg, n), detrend="constant")
    if freqs is None or psd is None:
        raise ValueError("psd: give both freqs and psd, or neither")
    lo, hi = band if band is not None else (max(freqs[1], 2.0), 0.45 * fs)
    sel = (freqs >= lo) & (freqs <= hi) & (psd > 0)
    f, P = freqs[sel], psd[sel]
    if f.size < 8 * n_modes:
        raise ValueError(f"psd: only {f.size} frequency bins in the band [{lo:g}, {hi:g}] Hz")
    fref = float(np.median(f))
    ex = (f / fref) ** excitation_slope
    Ps = P / ex
    pk = _peaks(f, Ps, lo, hi, n_modes)
    while len(pk) < n_modes:
        pk.append((min(1.5 * pk[-1][0], hi), 0.05))
    theta0 = np.array([[math.log(2 * math.pi * fp), max(zp, 0.01)] for fp, zp in pk]).ravel()
    wgt = 1.0 / P

    def cols(th: np.ndarray) -> np.ndarray:
        c = []
        for i in range(n_modes):
            fk = math.exp(th[2 * i]) / (2 * math.pi)
            zk = th[2 * i + 1]
            c.append(ex * fk**4 / ((fk * fk - f * f) ** 2 + (2 * zk * fk * f) ** 2))
        c += [ex, np.ones_like(f)]  # direct path through the excitation; sensor noise floor
        return np.column_stack(c)

    def resid(th: np.ndarray) -> np.ndarray:
        A = cols(th) * wgt[:, None]
        coef, *_ = np.linalg.lstsq(A, np.ones_like(f), rcond=None)
        return A @ coef - 1.0

    lo_b = np.tile([math.log(2 * math.pi * lo), 1e-3], n_modes)
    hi_b = np.tile([math.log(2 * math.pi * hi), 0.6], n_modes)
    res = optimize.least_squares(resid, np.clip(theta0, lo_b + 1e-9, hi_b - 1e-9), bounds=(lo_b, hi_b),
                                 x_scale="jac", xtol=1e-10, ftol=1e-12)
    th1 = res.x
    A = cols(th1) * wgt[:, None]
    coef, *_ = np.linalg.lstsq(A, np.ones_like(f), rcond=None)
    # Stage 2: coherent modal model |c0 + sum_k (a_k + b_k s) / (s^2 + 2 zeta_k w_k s + w_k^2)|^2
    # with real partial-fraction coefficients (a real transfer function), plus a noise floor,
    # fitted on log(P): the power-sum model above ignores the interference of close modes.
    s_ = 2j * math.pi * f
    lf = np.log(P)

    def coherent(x: np.ndarray) -> np.ndarray:
        H = np.full(f.shape, x[2 * n_modes], dtype=complex)
        for i in range(n_modes):
            w, z = math.exp(x[2 * i]), x[2 * i + 1]
            a, b = x[2 * n_modes + 1 + 2 * i], x[2 * n_modes + 2 + 2 * i]
            H += (a * w * w + b * w * s_) / (s_ * s_ + 2 * z * w * s_ + w * w)
        return ex * np.abs(H) ** 2 + x[-1] ** 2

    def resid2(x: np.ndarray) -> np.ndarray:
        return np.log(coherent(x)) - lf

    best = None
    scale = math.sqrt(max(float(np.median(Ps)), 1e-300))
    floor = math.sqrt(max(float(coef[n_modes + 1]), 1e-6 * scale**2))
    for signs in np.ndindex(*(2,) * n_modes):
        x0 = list(th1)
        x0.append(math.sqrt(max(coef[n_modes], 0.0)) or 1e-3 * scale)
        for i in range(n_modes):
            x0 += [(1 - 2 * signs[i]) * math.sqrt(max(coef[i], 1e-12 * scale**2)), 0.0]
        x0.append(floor)
        x0 = np.array(x0)
        lo2 = np.r_[lo_b, np.full(2 * n_modes + 2, -np.inf)]
        hi2 = np.r_[hi_b, np.full(2 * n_modes + 2, np.inf)]
        r2 = optimize.least_squares(resid2, np.clip(x0, lo2 + 1e-9, hi2 - 1e-9), bounds=(lo2, hi2),
                                    x_scale="jac", xtol=1e-10, ftol=1e-12)
        if best is None or r2.cost < best.cost:
            best = r2
    if best is None:  # the start loop always runs at least once
        raise RuntimeError("psd fit: no starting point could be evaluated")
    x = best.x
    e = resid2(x)
    J = _numjac(resid2, x)
    ivs, used, pw = _intervals_from(x[: 2 * n_modes], _marginal(J, 2 * n_modes), e, J.shape[1], "hac")
    th = x[: 2 * n_modes]
    model = coherent(x)
    order = np.argsort(th[0::2])
    modes = [Mode(math.exp(th[2 * i]), float(th[2 * i + 1])) for i in order]
    amps = [float(math.hypot(x[2 * n_modes + 1 + 2 * i], x[2 * n_modes + 2 + 2 * i])) for i in order]
    out = Identification(modes, [ivs[i] for i in order], "psd", float("nan"), pw, used, model, e, fs,
                         freqs=f, spectrum=P, amplitudes=amps,
                         notes=[f"output-only PSD fit on [{lo:.1f}, {hi:.1f}] Hz, excitation ~ f^{excitation_slope:g}"])
    return out


# ----------------------------------------------------------------------------- public entry


def _check_signals(t: Any, u: Any, y: Any, need_u: bool) -> tuple[np.ndarray, np.ndarray | None, np.ndarray, float]:
    t = v.real_array(t, "t")
    y = v.real_array(y, "y")
    if t.ndim != 1 or y.ndim != 1:
        raise ValueError("t and y must be one-dimensional arrays")
    if t.size != y.size:
        raise ValueError(f"t and y must have the same length, got {t.size} and {y.size}")
    if y.size < 16:
        raise ValueError(f"y must have at least 16 samples, got {y.size}")
    dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.nonzero(dt <= 0)[0][0]) + 1
        raise ValueError(f"t must be strictly increasing (sample {k}: {t[k]:g} after {t[k - 1]:g})")
    h = float(np.median(dt))
    if np.max(np.abs(dt - h)) > 0.01 * h:
        raise ValueError("t must be evenly sampled (steps vary by more than 1 %); resample first "
                         "(posicast.identify.load_csv resamples files)")
    uu = None
    if u is not None:
        uu = v.real_array(u, "u")
        if uu.shape != y.shape:
            raise ValueError(f"u must have the same shape as y, got {uu.shape} and {y.shape}")
    elif need_u:
        raise ValueError("u is required for this method (use method='psd' or 'decay' for output-only data)")
    return t, uu, y, 1.0 / h


def identify(t: Any, u: Any, y: Any, n_modes: int | str = 1, method: str = "oe", *,
             covariance: str = "auto", feedthrough: bool | str = "auto", offset: bool | str = "auto",
             initial_state: bool | str = "auto", max_modes: int = 4, refine: bool = True,
             band: tuple[float, float] | None = None, excitation_slope: float = 0.0, nk: int = 0) -> Identification:
    """Identify lightly damped modes from sampled data.

    Parameters
    ----------
    t : array_like
        Sample times (s), strictly increasing and evenly spaced (1 % tolerance).
    u : array_like or None
        Input (same length), or None for output-only methods ``"psd"``, ``"decay"``.
    y : array_like
        Measured output (position, velocity or acceleration).
    n_modes : int >= 1 or "auto"
        Number of modes; ``"auto"`` picks 1..``max_modes`` by BIC (``"oe"`` only).
    method : {"oe", "arx", "freq", "decay", "psd"}
        See the module docstring.  ``"arx"`` and ``"freq"`` fit one mode.
    covariance : {"auto", "gauss-newton", "hac"}
        Interval method; ``"auto"`` switches to Newey-West when the residual is coloured.
    feedthrough, offset, initial_state : bool or "auto"
        Nuisance terms of the OE model: a direct input-to-output term, a constant
        offset, a free response from a nonzero initial state.  ``"auto"``
        (default) fits without them and adds each only when an F-test at the
        fitted poles asks for it (an acceleration output has a direct term; a
        record that starts moving has an initial state).  Fitting unneeded
        terms costs ζ bias: +1.3 % instead of +0.65 % on seed 002's single
        step at 5 % noise.
    refine : bool
        ``"freq"``: run seed 002's iterative refinement.
    band : (float, float), optional
        ``"psd"``: frequency band in Hz.
    excitation_slope : float
        ``"psd"``: excitation PSD ~ f^a (Klipper sweep: 2).
    nk : int
        ``"arx"``: input delay (seed eq. 21: 0).

    Returns
    -------
    Identification
        ``.modes`` (list of Mode), ``.intervals`` (95 %), fit and whiteness.

    Examples
    --------
    >>> from posicast.identify import synthetic
    >>> d = synthetic(Mode.from_hz(28.0, 0.05), "step", n=800, noise=0.05, seed=3)
    >>> r = identify(d.t, d.u, d.y)
    >>> m, iv = r.modes[0], r.intervals[0]
    >>> abs(m.freq_hz - 28.0) < 0.1 and abs(m.zeta - 0.05) < 0.01
    True
    >>> iv.omega[0] < m.omega < iv.omega[1]
    True
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}; got {method!r}")
    if covariance not in ("auto", "gauss-newton", "hac"):
        raise ValueError(f"covariance must be 'auto', 'gauss-newton' or 'hac', got {covariance!r}")
    auto = isinstance(n_modes, str)
    if auto:
        if n_modes != "auto":
            raise ValueError(f"n_modes must be an integer >= 1 or 'auto', got {n_modes!r}")
        if method != "oe":
            raise ValueError("n_modes='auto' is available for method='oe' only")
        max_modes = v.integer(max_modes, "max_modes", 1)
    else:
        n_modes = v.integer(n_modes, "n_modes", 1)
    t, uu, yy, fs = _check_signals(t, u, y, need_u=method in ("oe", "arx", "freq"))
    if method == "arx":
        if n_modes != 1:
            raise ValueError("method='arx' (seed 002 eq. 20) fits one mode; n_modes must be 1")
        return _arx(t, uu, yy, fs, nk=v.integer(nk, "nk", 0))
    if method == "freq":
        if n_modes != 1:
            raise ValueError("method='freq' (seed 002 section 3.2.2) fits one mode; n_modes must be 1")
        return _freq(t, uu, yy, fs, refine=refine, covariance=covariance, feedthrough=feedthrough is True,
                     offset=offset is not False, initial_state=initial_state is not False)
    if method == "psd":
        if band is not None:
            lo, hi = (v.positive(band[0], "band[0]"), v.positive(band[1], "band[1]"))
            if not lo < hi <= fs / 2:
                raise ValueError(f"band must satisfy 0 < low < high <= fs/2 = {fs / 2:g}, got {band}")
            band = (lo, hi)
        return _psd(yy, fs, int(n_modes), band=band, excitation_slope=v.real(excitation_slope, "excitation_slope"))
    if method == "decay":
        start = _matrix_pencil(yy - np.mean(yy), 1.0 / fs, int(n_modes))
        out, _, _ = _oe(t, None, yy, fs, len(start), covariance=covariance, feedthrough=False,
                        offset=offset is not False, initial_state=True, start=start, method="decay")
        return out
    for name, val in (("feedthrough", feedthrough), ("offset", offset), ("initial_state", initial_state)):
        if val != "auto" and not isinstance(val, bool):
            raise ValueError(f"{name} must be True, False or 'auto', got {val!r}")
    kw = dict(covariance=covariance, feedthrough=feedthrough, offset=offset, initial_state=initial_state)
    if not auto:
        return _oe(t, uu, yy, fs, int(n_modes), **kw)[0]
    best, scores = None, {}
    for n in range(1, max_modes + 1):
        r, rss, k = _oe(t, uu, yy, fs, n, **kw)
        bic = yy.size * math.log(max(rss, 1e-300) / yy.size) + k * math.log(yy.size)
        scores[n] = bic
        if best is None or bic < best[1]:
            best = (r, bic)
    if best is None:
        raise ValueError(f"max_modes must be >= 1, got {max_modes}")
    best[0].order_scores = scores
    return best[0]
