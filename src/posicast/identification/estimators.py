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
from .significance import MAX_MODES, ModeTest, NoModeFound, describe_failure, search_cells, wald_test

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
    tests: list[ModeTest] = field(default_factory=list)
    at_edge: list[bool] = field(default_factory=list)

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
    e = v.real_array(e, "e")
    if e.ndim != 1 or e.size < 8:
        raise ValueError(f"e must be a one-dimensional residual of at least 8 samples, got shape {e.shape}")
    lags = v.integer(lags, "lags", 1)
    e = e - np.mean(e)
    n = e.size
    m = min(lags, n // 4)
    if not np.any(e):
        return 1.0  # a zero residual shows no colour

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

    def basis(self, theta: np.ndarray) -> np.ndarray:
        return self.columns(theta)[0]

    def columns(self, theta: np.ndarray) -> tuple[np.ndarray, list[list[int]]]:
        """The regression columns at ``theta`` and, per mode, the indices of the columns that make it a mode
        of this data: its input-driven columns when there is an input, else its free response."""
        cols: list[np.ndarray] = []
        groups: list[list[int]] = []
        for i in range(self.n):
            start = len(cols)
            w = math.exp(theta[2 * i])
            z = min(max(theta[2 * i + 1], _ZMIN), _ZMAX)
            p = complex(-z * w, w * math.sqrt(1.0 - z * z))
            lam = np.exp(p * self.h)
            if self.u is not None:
                a = [1.0, -2.0 * lam.real, abs(lam) ** 2]
                x1 = signal.lfilter([0.0, 1.0], a, self.u)
                x2 = np.concatenate(([0.0], x1[:-1]))
                cols += [x1, x2]
            forced = len(cols)
            if self.initial_state:
                r = np.exp(p.real * self.h * self.k)
                ph = p.imag * self.h * self.k
                cols += [r * np.cos(ph), r * np.sin(ph)]
            # with an input, a mode of the system is one the input drives: a free response alone also fits
            # a slow drift or coloured noise that has nothing to do with the input (see mode_tests)
            groups.append(list(range(start, forced)) if self.u is not None else list(range(start, len(cols))))
            self._free[i] = list(range(forced, len(cols)))
        if self.feedthrough:
            cols.append(self.u)
        if self.offset:
            cols.append(np.ones_like(self.y))
        return np.column_stack(cols), groups

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

    @property
    def n_used(self) -> int:
        return int(self.y.size if self.w is None else np.count_nonzero(self.w))

    def project(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
        """Residual (0 on left-out samples), model output (every sample) and rank, at ``theta``."""
        Phi = self.basis(theta)
        Pw, yw = (Phi, self.y) if self.w is None else (Phi * self.w[:, None], self.y * self.w)
        nrm = np.linalg.norm(Pw, axis=0)
        nrm[nrm == 0] = 1.0
        Pw = Pw / nrm
        # projection through the (small) Gram matrix, eigen-truncated for rank deficiency
        # (a step at k = 0 makes the forced response a combination of offset and free response)
        lam, V = np.linalg.eigh(Pw.T @ Pw)
        keep = lam > lam[-1] * 1e-13
        W = V[:, keep] / lam[keep]
        coef = W @ (V[:, keep].T @ (Pw.T @ yw))
        return yw - Pw @ coef, (Phi / nrm) @ coef, int(keep.sum())

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
                    covariance: str, n_used: int | None = None) -> tuple[list[Interval], str, float]:
    n = e.size
    dof = max((n if n_used is None else n_used) - n_lin - theta.size, 1)
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
    Y2 = np.convolve(np.abs(np.fft.rfft(np.diff(y, prepend=y[0]), nfft)) ** 2, ker, mode="same")
    du = None if u is None else np.diff(u, prepend=0.0)
    if du is None or not np.any(du):
        return f, np.sqrt(Y2)
    U2 = np.convolve(np.abs(np.fft.rfft(du, nfft)) ** 2, ker, mode="same")
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
        method: str = "oe", weights: np.ndarray | None = None) -> tuple[Identification, float, int]:
    terms = {"feedthrough": feedthrough, "offset": offset, "initial_state": initial_state}
    auto = [name for name, val in terms.items() if val == "auto"]
    if auto:
        # Nuisance terms chosen by the data: fit without the "auto" ones (a position output of a
        # system at rest under a held input has no direct term, offset or initial state), then
        # F-test each of them at the fitted poles (one projection each, 0.1 % level) and refit
        # with the ones the data ask for.  Fitting unneeded free-response columns costs zeta
        # bias: on seed 002's single step at 5 % noise +1.3 % with them, +0.65 % without.
        base = {name: (False if val == "auto" else bool(val)) for name, val in terms.items()}
        out, rss, k = _oe(t, u, y, fs, n_modes, covariance=covariance, start=start, method=method, weights=weights,
                          **base)
        th = np.array([[math.log(m.omega), m.zeta] for m in out.modes]).ravel()
        n_lin = k - th.size
        chosen = dict(base)
        for name in auto:
            trial = dict(base)
            trial[name] = True
            e1, _, n_lin1 = _OEModel(u, y, 1.0 / fs, n_modes, weights=weights, **trial).project(th)
            extra = n_lin1 - n_lin
            dof = (y.size if weights is None else int(np.count_nonzero(weights))) - k - extra
            if extra <= 0 or dof <= 0:
                continue
            rss1 = float(e1 @ e1)
            F = ((rss - rss1) / extra) / max(rss1 / dof, 1e-300)
            if F > stats.f.ppf(0.999, extra, dof):
                chosen[name] = True
        if chosen == base:
            return out, rss, k
        return _oe(t, u, y, fs, n_modes, covariance=covariance, start=start, method=method, weights=weights,
                   **chosen)
    h = 1.0 / fs
    model = _OEModel(u, y, h, n_modes, feedthrough=feedthrough, offset=offset, initial_state=initial_state,
                     weights=weights)
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
    ivs, used, pw = _intervals_from(th, J, e, n_lin, covariance, model.n_used)
    cells = search_cells(0.5 / (y.size * h), 0.49 / h, y.size * h)
    tests = model.mode_tests(th, e, n_lin, used == "hac", cells)
    order = np.argsort(th[0::2])
    modes = [Mode(math.exp(th[2 * i]), float(th[2 * i + 1])) for i in order]
    ivs = [ivs[i] for i in order]
    out = Identification(modes, ivs, method, fit_percent(y, y_hat), pw, used, y_hat, e, fs,
                         tests=[tests[i] for i in order])
    rss = float(e @ e)
    return out, rss, n_lin + th.size


def clipped_samples(y: np.ndarray) -> np.ndarray | None:
    """Samples at a saturated extreme: the largest (or smallest) value held for 3 or more samples
    in a row at least twice, and reached by at least 0.5 % of the record; None otherwise.

    A sensor or an amplifier that saturates holds its limit, again on each swing; an
    unsaturated record reaches its extreme on isolated samples, and a response that
    settles at its largest value holds it once.
    """
    out = np.zeros(y.size, dtype=bool)
    for ext in (float(np.max(y)), float(np.min(y))):
        at = y == ext
        if at.sum() < max(4, 0.005 * y.size):
            continue
        runs = np.diff(np.flatnonzero(np.diff(np.r_[0, at.astype(np.int8), 0])))[::2]
        if np.count_nonzero(runs >= 3) >= 2:
            out |= at
    return out if out.any() else None


def at_band_edge(mode: Mode, f_lo: float, f_hi: float) -> bool:
    """True when the mode's half-power band ``f (1 +- zeta)`` is not inside ``[f_lo, f_hi]`` Hz."""
    f = mode.freq_hz
    half = max(mode.zeta, 1e-3) * f
    return bool(f - half < f_lo or f + half > f_hi)


def _significant_oe(t: np.ndarray, u: np.ndarray | None, y: np.ndarray, fs: float, n_modes: int,
                    kw: dict[str, Any], *, start: Sequence[Mode] | None = None,
                    method: str = "oe") -> tuple[Identification, float, int]:
    """:func:`_oe` keeping only the modes the data demand (see :mod:`.significance`).

    The least significant failing mode is dropped and the rest refitted from their
    estimates, until every mode passes; :class:`NoModeFound` when none does.
    """
    dropped: list[str] = []
    while True:
        out, rss, k = _oe(t, u, y, fs, n_modes, start=start, method=method, **kw)
        bad = [i for i, tst in enumerate(out.tests) if not tst.significant]
        if not bad:
            out.notes += dropped
            return out, rss, k
        worst = max(bad, key=lambda i: out.tests[i].p_adjusted)
        m, tst = out.modes[worst], out.tests[worst]
        if n_modes == 1:
            raise NoModeFound(describe_failure(method, m, tst), m, tst)
        dropped.append(f"a candidate at {m.freq_hz:.4g} Hz (zeta {m.zeta:.3g}) was dropped: it {tst.describe()}")
        start = [mm for i, mm in enumerate(out.modes) if i != worst]
        n_modes -= 1


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
    # does the input drive the output through this model?  F-test of its simulated output on the data
    # (offset partialled out, residual whitened if coloured): the autoregressive part alone also fits
    # coloured noise, and a static gain alone also passes a test of all four coefficients
    y_sim = signal.lfilter(theta[:2] if nk == 0 else np.r_[np.zeros(nk), theta[:2]], np.r_[1.0, theta[2:]], u)
    if not np.all(np.isfinite(y_sim)) or np.max(np.abs(y_sim)) > 1e12 * max(float(np.max(np.abs(y))), 1e-300):
        raise NoModeFound("no mode found (arx): the fitted model is unstable")
    ones = np.ones((y.size, 1))
    r_sim = y - y_sim
    test = wald_test(y, y_sim[:, None], ones, r_sim - r_sim.mean(), y.size - 2, 1.0,
                     coloured=whiteness(r_sim) < 0.01)
    C = float(e @ e) / dof * np.linalg.pinv(A.T @ A)

    def to_mode(a1: float, a2: float) -> tuple[float, float]:
        r = np.roots([1.0, a1, a2])
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
    Cm = Jm @ C[2:, 2:] @ Jm.T
    tq = float(stats.t.ppf(0.975, dof))
    sw, sz = math.sqrt(max(Cm[0, 0], 0)), math.sqrt(max(Cm[1, 1], 0))
    iv = Interval((w - tq * sw, w + tq * sw), (max(z - tq * sz, 0.0), z + tq * sz))
    y_hat = signal.lfilter(theta[:2] if nk == 0 else np.r_[np.zeros(nk), theta[:2]], np.r_[1.0, theta[2:]], u)
    pw = whiteness(y - y_hat)
    return Identification([Mode(w, min(max(z, 0.0), 0.999999))], [iv], "arx", fit_percent(y, y_hat), pw,
                          "delta", y_hat, y - y_hat, fs, tests=[test],
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
          feedthrough: bool, offset: bool, initial_state: bool, weights: np.ndarray | None = None) -> Identification:
    """Seed 002 section 3.2.2 (eq. 26-27) with its iterative refinement."""
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
    model = _OEModel(u, y, h, 1, feedthrough=feedthrough, offset=offset, initial_state=initial_state,
                     weights=weights)
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
    ivs, used, pw = _intervals_from(th, J, e, n_lin, covariance, model.n_used)
    if not refine:
        notes.append("no refinement: intervals are the local OE curvature at a non-optimal point")
    mode = Mode(math.exp(th[0]), float(th[1]))
    test = model.mode_tests(th, e, n_lin, used == "hac", search_cells(f_lo_ok, f_hi_ok, n * h))[0]
    if not test.significant:
        raise NoModeFound(describe_failure("freq", mode, test), mode, test)
    edge = at_band_edge(mode, f_lo_ok, f_hi_ok)
    if edge:
        notes.append(f"the mode at {mode.freq_hz:.4g} Hz lies at the edge of the excited band "
                     f"[{f_lo_ok:.4g}, {f_hi_ok:.4g}] Hz: its damping is not resolved")
    return Identification([mode], ivs, "freq", fit_percent(y, y_hat), pw, used,
                          y_hat, e, fs, notes=notes, tests=[test], at_edge=[edge])


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
        raise NoModeFound("no mode found (decay): no decaying oscillation in y (is it a ring-down record?)")
    return modes[:n_modes]


def _psd(y: np.ndarray, fs: float, n_modes: int | str, *, band: tuple[float, float] | None,
         excitation_slope: float) -> Identification:
    """Output-only: Welch PSD (1 Hz resolution) fitted by :func:`posicast.identification.spectral.fit_spectrum`
    with an excitation ``E(f) = f^excitation_slope``."""
    from .spectral import (KAISER6_CORRELATION, Spectrum, fit_spectrum,  # noqa: PLC0415 (spectral imports this)
                           welch_dispersion, welch_kernel, welch_psd)

    resolution = max(1.0, 8.0 * fs / y.size)  # at least 8 segments
    f, P, K = welch_psd(y - np.mean(y), fs, resolution)
    lo, hi = band if band is not None else (max(2.0, 2.0 * float(f[1])), 0.45 * fs)
    E = np.where(f > 0, np.maximum(f, 1e-300) ** excitation_slope, 0.0)
    spec = Spectrum(f, P, E, (lo, hi), low_frequency=False, resolution=float(f[1] - f[0]),
                    source="Welch PSD of y", correlation=KAISER6_CORRELATION,
                    dispersion_floor=welch_dispersion(np.kaiser(2 * (f.size - 1), 6.0), K), kernel=welch_kernel())
    r = fit_spectrum(spec, n_modes)
    return Identification(r.modes, [Interval(*iv) for iv in r.intervals], "psd", float("nan"), float("nan"),
                          "whittle", r.fit.model, None, fs, freqs=r.fit.freqs, spectrum=r.fit.psd,
                          amplitudes=r.shares, tests=r.tests, at_edge=r.at_edge,
                          notes=[f"output-only PSD fit on [{lo:.1f}, {hi:.1f}] Hz, excitation ~ f^{excitation_slope:g}"]
                          + r.notes)


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
                         "(posicast.identification.load_csv resamples files)")
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
    n_modes : int in [1, 6] or "auto"
        Number of modes; ``"auto"`` picks 1..``max_modes`` (at most 6) by BIC (``"oe"``
        only).  Six modes is the most one fit takes (the cost of the output-error fit
        and its backward elimination grows as about ``n_modes^4``: 13 modes of a
        400-sample record took 5 s); fit a wider band in pieces.
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
    >>> from posicast.identification import synthetic
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
        if method not in ("oe", "psd"):
            raise ValueError("n_modes='auto' is available for method='oe' and 'psd' only")
        max_modes = v.integer_in_range(max_modes, "max_modes", 1, MAX_MODES)
    else:
        n_modes = v.integer_in_range(n_modes, "n_modes", 1, MAX_MODES)
    t, uu, yy, fs = _check_signals(t, u, y, need_u=method in ("oe", "arx", "freq"))
    spread = float(np.ptp(yy))
    if spread <= 1e-12 * max(float(np.max(np.abs(yy))), 1e-300):
        raise NoModeFound(f"no mode found ({method}): the output is constant ({float(yy[0]):.6g} throughout)")
    clip = clipped_samples(yy)
    weights = None if clip is None else (~clip).astype(float)
    clip_note = [] if clip is None else [
        f"the output is clipped (held at {float(np.max(yy)):.6g} / {float(np.min(yy)):.6g}) on {int(clip.sum())} "
        f"samples of {yy.size}: " + ("they are left out of the fit" if method in ("oe", "freq", "decay") else
                                     "this method cannot leave them out; use method='oe'")]
    out = _dispatch(method, t, uu, yy, fs, n_modes, auto, weights, covariance=covariance, feedthrough=feedthrough,
                    offset=offset, initial_state=initial_state, max_modes=max_modes, refine=refine, band=band,
                    excitation_slope=excitation_slope, nk=nk)
    out.notes += clip_note
    return out


def _dispatch(method: str, t: np.ndarray, uu: np.ndarray | None, yy: np.ndarray, fs: float, n_modes: Any,
              auto: bool, weights: np.ndarray | None, *, covariance: str, feedthrough: Any, offset: Any,
              initial_state: Any, max_modes: int, refine: bool, band: Any, excitation_slope: float,
              nk: int) -> Identification:
    if method == "arx":
        if n_modes != 1:
            raise ValueError("method='arx' (seed 002 eq. 20) fits one mode; n_modes must be 1")
        return _arx(t, uu, yy, fs, nk=v.integer(nk, "nk", 0))
    if method == "freq":
        if n_modes != 1:
            raise ValueError("method='freq' (seed 002 section 3.2.2) fits one mode; n_modes must be 1")
        return _freq(t, uu, yy, fs, refine=refine, covariance=covariance, feedthrough=feedthrough is True,
                     offset=offset is not False, initial_state=initial_state is not False, weights=weights)
    if method == "psd":
        if band is not None:
            lo, hi = (v.positive(band[0], "band[0]"), v.positive(band[1], "band[1]"))
            if not lo < hi <= fs / 2:
                raise ValueError(f"band must satisfy 0 < low < high <= fs/2 = {fs / 2:g}, got {band}")
            band = (lo, hi)
        slope = v.real(excitation_slope, "excitation_slope")
        if not -4.0 <= slope <= 4.0:
            raise ValueError(f"excitation_slope must be in [-4, 4], got {slope:g}")
        return _psd(yy, fs, n_modes, band=band, excitation_slope=slope)
    if method == "decay":
        start = _matrix_pencil(yy - np.mean(yy), 1.0 / fs, int(n_modes))
        return _significant_oe(t, None, yy, fs, len(start), dict(
            covariance=covariance, feedthrough=False, offset=offset is not False, initial_state=True,
            weights=weights), start=start, method="decay")[0]
    for name, val in (("feedthrough", feedthrough), ("offset", offset), ("initial_state", initial_state)):
        if val != "auto" and not isinstance(val, bool):
            raise ValueError(f"{name} must be True, False or 'auto', got {val!r}")
    kw = dict(covariance=covariance, feedthrough=feedthrough, offset=offset, initial_state=initial_state,
              weights=weights)
    if not auto:
        return _significant_oe(t, uu, yy, fs, int(n_modes), kw)[0]
    best, scores = None, {}
    for n in range(1, max_modes + 1):
        r, rss, k = _significant_oe(t, uu, yy, fs, n, kw)
        if len(r.modes) < n:  # a mode of this order was not significant: higher orders add only noise
            break
        bic = yy.size * math.log(max(rss, 1e-300) / yy.size) + k * math.log(yy.size)
        scores[n] = bic
        if best is None or bic < best[1]:
            best = (r, bic)
    if best is None:
        raise ValueError(f"max_modes must be >= 1, got {max_modes}")
    best[0].order_scores = scores
    return best[0]
