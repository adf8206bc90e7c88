"""Statistics of a time-domain fit: NRMSE fit, residual whiteness (Ljung-Box), and the 95 % intervals of
the poles from the Gauss-Newton or Newey-West (HAC) covariance of the projected residual."""

from __future__ import annotations

import math
from typing import Callable, NamedTuple

import numpy as np
from scipy import special

from .. import _validate as v
from .results import Interval

__all__ = ["fit_percent", "whiteness", "PoleIntervals", "pole_intervals", "numerical_jacobian", "half_power_span"]


class PoleIntervals(NamedTuple):
    """The 95 % intervals of the fitted poles and how they were computed."""

    intervals: list[Interval]
    covariance: str  # "gauss-newton" or "hac": the covariance actually used
    whiteness_p: float  # Ljung-Box p-value of the residual


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

    if n >= 4096:
        full = _acov_fft(e, m)
    elif n > 256:
        # the m + 1 lags np.correlate(e, e, "full") gives, one dot product each: the same numbers (the same
        # dot products), without the 2 n - 1 lags it computes and this drops (O(n m), not O(n^2); issue #15)
        full = np.array([e @ e] + [e[k:] @ e[:-k] for k in range(1, m + 1)])
    else:
        full = np.correlate(e, e, "full")[n - 1:n + m]
    r = full[1:] / full[0]
    q = n * (n + 2) * np.sum(r * r / (n - np.arange(1, m + 1)))
    return float(special.chdtrc(m, q))  # scipy.stats.chi2.sf(q, m), without its argument checks (issue #15)


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


def pole_intervals(theta: np.ndarray, J: np.ndarray, e: np.ndarray, n_lin: int,
                   covariance: str, n_used: int | None = None, *, whiteness_p: float | None = None) -> PoleIntervals:
    """95 % intervals of ``theta = (ln omega_k, zeta_k)`` from the residual ``e`` and its Jacobian ``J``.

    ``covariance="auto"`` uses Newey-West (HAC) when the residual fails the whiteness
    test (p < 0.01), else Gauss-Newton ``s^2 (J^T J)^-1``; Student-t quantile on
    ``n_used - n_lin - len(theta)`` degrees of freedom.  ``whiteness_p``: ``whiteness(e)`` when the
    caller has it already (the output-error fit tests its residual's whiteness first; issue #15).
    """
    n = e.size
    dof = max((n if n_used is None else n_used) - n_lin - theta.size, 1)
    pw = whiteness(e) if whiteness_p is None else whiteness_p
    use = covariance
    if covariance == "auto":
        use = "hac" if (math.isfinite(pw) and pw < 0.01) else "gauss-newton"
    if use == "hac":
        C = _hac(J, e) * n / dof
    else:
        s2 = float(e @ e) / dof
        C = s2 * np.linalg.pinv(J.T @ J)
    tq = float(special.stdtrit(dof, 0.975))  # scipy.stats.t.ppf(0.975, dof)
    out = []
    for i in range(theta.size // 2):
        lw, z = theta[2 * i], theta[2 * i + 1]
        sw = math.sqrt(max(C[2 * i, 2 * i], 0.0))
        sz = math.sqrt(max(C[2 * i + 1, 2 * i + 1], 0.0))
        out.append(Interval((math.exp(lw - tq * sw), math.exp(lw + tq * sw)), (max(z - tq * sz, 0.0), z + tq * sz)))
    return PoleIntervals(out, use, pw)


def numerical_jacobian(fun: Callable[[np.ndarray], np.ndarray], x: np.ndarray) -> np.ndarray:
    """Central-difference Jacobian of ``fun`` at ``x`` (relative step 1e-6)."""
    f0 = fun(x)
    J = np.empty((f0.size, x.size))
    for i in range(x.size):
        dx = 1e-6 * max(abs(x[i]), 1e-3)
        xp, xm = x.copy(), x.copy()
        xp[i] += dx
        xm[i] -= dx
        J[:, i] = (fun(xp) - fun(xm)) / (2 * dx)
    return J


def half_power_span(H: np.ndarray, j: int) -> tuple[int, int]:
    """The first indices left and right of the peak ``j`` where ``|H|`` is at or below ``H[j] / sqrt(2)`` (-3 dB;
    the array's ends when it never falls that far)."""
    half = H[j] / math.sqrt(2.0)
    a = j
    while a > 0 and H[a] > half:
        a -= 1
    b = j
    while b < len(H) - 1 and H[b] > half:
        b += 1
    return a, b
