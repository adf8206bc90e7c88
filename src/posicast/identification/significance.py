"""Is there a mode at all?  Tests of an identified mode against the no-mode model.

A least-squares fit always returns *a* mode: on pure noise the best of a few
thousand candidate frequencies explains a fraction of a percent of the variance,
and its curvature interval is as tight as on real data.  Each identified mode is
therefore tested against the model without it, and kept only when the data
demand it after allowing for the search over frequency.

* **Regression models** (output error, free decay, ARX): the mode's linear
  coefficients (with an input, its input-driven columns; for free decay, its
  initial state) are F-tested at the fitted poles with the other columns partialled
  out; when the residual is coloured, everything is first whitened by the residual's
  autoregressive filter (feasible GLS).  ARX is tested through its simulated output.
* **Spectra** (:mod:`.spectral`): the gamma deviance of the model without the mode
  against the model with it (other poles fixed), scaled by the dispersion (never
  below the estimator's own ``1/K``) and the neighbouring bins' correlation.

The pole's frequency was chosen from the data, so a p-value at the fitted pole
is too optimistic: it is multiplied by the number of independent frequency cells
searched (Bonferroni over ``band width x record length`` Fourier cells).  A mode
is kept when the adjusted p-value is below :data:`ALPHA`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy import special

from . import _linalg

if TYPE_CHECKING:
    from ..modes import Mode

__all__ = ["ALPHA", "MAX_MODES", "NoModeFound", "ModeTest", "wald_test", "search_cells", "at_band_edge"]

#: Level of the adjusted test: a mode whose adjusted p-value is not below it is not reported.
ALPHA = 1e-3
#: The most modes one fit takes (time-domain and spectral alike).
MAX_MODES = 6


class NoModeFound(ValueError):
    """The data show no mode: the best candidate is no better than noise.

    Attributes
    ----------
    candidate : object or None
        The best candidate :class:`~posicast.Mode` that failed the test.
    test : ModeTest or None
        Its test.
    """

    def __init__(self, message: str, candidate: object | None = None, test: "ModeTest | None" = None) -> None:
        super().__init__(message)
        self.candidate = candidate
        self.test = test


@dataclass(frozen=True)
class ModeTest:
    """Test of one mode against the model without it.

    Attributes
    ----------
    statistic : float
        Wald or likelihood-ratio statistic.
    dof : int
        Degrees of freedom tested (the mode's coefficients).
    p_value : float
        p-value at the fitted pole.
    cells : float
        Independent frequency cells searched (Bonferroni factor, >= 1).
    p_adjusted : float
        ``min(1, cells * p_value)``.
    explained : float
        Share of the residual variance (or deviance) the mode removes, in [0, 1].
    """

    statistic: float
    dof: int
    p_value: float
    cells: float
    p_adjusted: float
    explained: float

    @property
    def significant(self) -> bool:
        return self.p_adjusted < ALPHA

    def describe(self) -> str:
        return (f"explains {100 * self.explained:.3g} % of the variance, p = {self.p_value:.2g} at the fitted pole, "
                f"{self.p_adjusted:.2g} after {self.cells:.0f} frequency cells (needs < {ALPHA:g})")


def search_cells(f_lo: float, f_hi: float, duration: float) -> float:
    """Effective number of independent tests when a pole is searched in ``[f_lo, f_hi]`` Hz (>= 1).

    ``c = (f_hi - f_lo) duration`` Fourier cells of a record of ``duration`` s, times
    ``ln c`` for the search over damping (peak widths from one cell to the whole band,
    about ``ln c`` octaves of scale).  On white noise (200 seeds of 1000 samples, output
    error and free decay) this puts the share of adjusted p-values below 0.01 at or
    under 0.01; plain Bonferroni over ``c`` gave 0.015-0.025.
    """
    for name, x in (("f_lo", f_lo), ("f_hi", f_hi), ("duration", duration)):
        if not (isinstance(x, (int, float, np.floating, np.integer)) and math.isfinite(x) and x >= 0):
            raise ValueError(f"{name} must be a finite number >= 0, got {x!r}")
    c = max(1.0, (f_hi - f_lo) * duration)
    return c * max(1.0, math.log(c))


def _adjust(stat: float, dof: int, p: float, cells: float, explained: float) -> ModeTest:
    return ModeTest(float(stat), int(dof), float(p), float(cells), float(min(1.0, cells * p)),
                    float(min(max(explained, 0.0), 1.0)))


def wald_test(y: np.ndarray, X: np.ndarray, others: np.ndarray | None, residual: np.ndarray, dof: int,
              cells: float, coloured: bool) -> ModeTest:
    """F-test that the coefficients of the columns ``X`` are zero (the others partialled out).

    Parameters
    ----------
    y : ndarray (n,)
        Data.
    X : ndarray (n, k)
        The mode's columns at the fitted pole.
    others : ndarray (n, m) or None
        The model's other columns (partialled out).
    residual : ndarray (n,)
        Residual of the full model.
    dof : int
        Residual degrees of freedom of the full model.
    cells : float
        Bonferroni factor, see :func:`search_cells`.
    coloured : bool
        The residual is not white: ``y``, ``X`` and the other columns are first filtered by
        the residual's autoregressive whitening filter (order up to 8, Yule-Walker; as
        feasible generalised least squares), so that the F-test's noise is white.  A
        Newey-West covariance with a few lags, used before, let strongly coloured noise
        (AR(1) with rho 0.9) pass as a mode in half the records.
    """
    if coloured:
        a = _whitening_filter(residual)
        # every column through the filter in one pass (the same products and sums per element as one call per
        # array; issue #15), then each part back as its own contiguous array
        k, m = X.shape[1], 0 if others is None else others.shape[1]
        Z = _filtered(np.column_stack([y, X] + ([] if others is None else [others]) + [residual]), a)
        y, X = Z[:, 0].copy(), _laid_out_as(Z[:, 1: 1 + k], X)
        others = None if others is None else _laid_out_as(Z[:, 1 + k: 1 + k + m], others)
        residual = Z[:, -1].copy()
    if others is not None and others.shape[1]:
        Q, _ = np.linalg.qr(others)
        X = X - Q @ (Q.T @ X)
        y = y - Q @ (Q.T @ y)
    nrm = np.linalg.norm(X, axis=0)
    keep = nrm > 1e-12 * max(float(nrm.max(initial=0.0)), 1e-300)
    X = X[:, keep] / nrm[keep]
    k = X.shape[1]
    if k == 0:
        return _adjust(0.0, 0, 1.0, cells, 0.0)
    beta = _linalg.lstsq(X, y)
    fitted = X @ beta
    rss = max(float(y @ y) - float(fitted @ fitted), 0.0) if coloured else float(residual @ residual)
    explained = float(fitted @ fitted) / max(float(fitted @ fitted) + rss, 1e-300)
    dof = max(int(dof), 1)
    s2 = rss / dof
    W = float(fitted @ fitted) / max(s2, 1e-300)
    p = float(special.fdtrc(k, dof, W / k))  # scipy.stats.f.sf(W / k, k, dof), without its checks (issue #15)
    return _adjust(W, k, p, cells, explained)


def _whitening_filter(e: np.ndarray, max_order: int = 8) -> np.ndarray:
    """``[1, -phi_1, ..., -phi_p]`` of an AR(p) fitted to ``e`` by Yule-Walker (p by AIC, at most 8)."""
    e = np.asarray(e, dtype=float) - float(np.mean(e))
    n = e.size
    p_max = int(min(max_order, max(n // 20, 1)))
    r = np.array([float(e[: n - k] @ e[k:]) for k in range(p_max + 1)]) / n
    if r[0] <= 0:
        return np.ones(1)
    best, best_aic = None, n * math.log(r[0])
    lags = np.abs(np.subtract.outer(np.arange(p_max), np.arange(p_max)))  # R[i, j] = r[|i - j|] (Toeplitz)
    for p in range(1, p_max + 1):
        R = r[lags[:p, :p]]
        try:
            phi = _linalg.solve(R, r[1 : p + 1])
        except np.linalg.LinAlgError:
            break
        s2 = r[0] - float(phi @ r[1 : p + 1])
        if s2 <= 0:
            break
        aic = n * math.log(s2) + 2 * p
        if aic < best_aic:
            best, best_aic = phi, aic
    return np.ones(1) if best is None else np.concatenate(([1.0], -best))


def _laid_out_as(part: np.ndarray, like: np.ndarray) -> np.ndarray:
    """A contiguous copy of ``part`` in the memory order of ``like`` (column sums and norms add in memory
    order: the same order gives the same numbers)."""
    return np.array(part, order="F" if like.flags.f_contiguous and not like.flags.c_contiguous else "C")


def _filtered(x: np.ndarray, a: np.ndarray) -> np.ndarray:
    """``x`` filtered by the FIR whitening filter ``a`` (first ``len(a) - 1`` samples dropped)."""
    if a.size == 1:
        return x
    p = a.size - 1
    out = a[0] * x[p:]
    for k in range(1, a.size):
        out = out + a[k] * x[p - k : x.shape[0] - k]
    return out


def describe_failure(what: str, candidate: object, test: ModeTest) -> str:
    """One line for :class:`NoModeFound`."""
    freq = getattr(candidate, "freq_hz", float("nan"))
    zeta = getattr(candidate, "zeta", float("nan"))
    return (f"no mode found ({what}): the best candidate, {freq:.4g} Hz with zeta {zeta:.3g}, is no better than "
            f"noise: it {test.describe()}")


def at_band_edge(mode: Mode, f_lo: float, f_hi: float, zeta_floor: float = 1e-3) -> bool:
    """True when the mode's half-power band ``f (1 +- zeta)`` is not inside ``[f_lo, f_hi]`` Hz.

    Such a mode is a rise at the edge of the band, not a resolved resonance.  ``zeta`` is
    taken at least ``zeta_floor`` (the time-domain fits 1e-3; the spectral fit 2e-3, its
    smallest damping bound).
    """
    f = mode.freq_hz
    half = max(mode.zeta, zeta_floor) * f
    return bool(f - half < f_lo or f + half > f_hi)
