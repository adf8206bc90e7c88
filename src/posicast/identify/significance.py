"""Is there a mode at all?  Tests of an identified mode against the no-mode model.

A least-squares fit always returns *a* mode: on pure noise the best of a few
thousand candidate frequencies explains a fraction of a percent of the variance,
and its curvature interval is as tight as on real data.  Each identified mode is
therefore tested against the model without it, and kept only when the data
demand it after allowing for the search over frequency.

* **Regression models** (output error, free decay, ARX): the mode's linear
  coefficients (its numerator and, when fitted, its initial state) are tested by
  a Wald test at the fitted poles, with the other columns partialled out:
  ``W = beta^T Cov(beta)^-1 beta``, F-distributed with ``(k, dof)`` degrees of
  freedom under Gauss-Newton covariance, chi-square with ``k`` under the
  Newey-West covariance used when the residual is coloured.
* **Spectra** (Welch PSD): a likelihood-ratio test on the Whittle likelihood of
  the averaged periodogram (each bin a scaled chi-square with ``2 K`` degrees of
  freedom), model with the mode against the model without it.

The pole's frequency was chosen from the data, so a p-value at the fitted pole
is too optimistic: it is multiplied by the number of independent frequency cells
searched (Bonferroni over ``band width x record length`` Fourier cells).  A mode
is kept when the adjusted p-value is below :data:`ALPHA`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

__all__ = ["ALPHA", "NoModeFound", "ModeTest", "wald_test", "likelihood_ratio_test", "search_cells"]

#: Level of the adjusted test: a mode whose adjusted p-value is not below it is not reported.
ALPHA = 1e-3


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
    c = max(1.0, (f_hi - f_lo) * duration)
    return c * max(1.0, math.log(c))


def _adjust(stat: float, dof: int, p: float, cells: float, explained: float) -> ModeTest:
    return ModeTest(float(stat), int(dof), float(p), float(cells), float(min(1.0, cells * p)),
                    float(min(max(explained, 0.0), 1.0)))


def wald_test(y: np.ndarray, X: np.ndarray, others: np.ndarray | None, residual: np.ndarray, dof: int,
              cells: float, hac: bool) -> ModeTest:
    """Wald test that the coefficients of the columns ``X`` are zero.

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
    hac : bool
        Newey-West covariance (coloured residual) instead of ``s^2 (X^T X)^-1``.
    """
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
    beta, *_ = np.linalg.lstsq(X, y, rcond=None)
    rss = float(residual @ residual)
    fitted = X @ beta
    explained = float(fitted @ fitted) / max(float(fitted @ fitted) + rss, 1e-300)
    dof = max(int(dof), 1)
    if hac:
        from .estimators import _hac  # noqa: PLC0415 (estimators imports this module)

        C = _hac(X, residual) * residual.size / dof
        W = float(beta @ np.linalg.lstsq(C, beta, rcond=None)[0])
        p = float(stats.chi2.sf(W, k))
    else:
        s2 = rss / dof
        W = float(fitted @ fitted) / max(s2, 1e-300)
        p = float(stats.f.sf(W / k, k, dof))
    return _adjust(W, k, p, cells, explained)


def likelihood_ratio_test(P: np.ndarray, model_with: np.ndarray, model_without: np.ndarray, k_segments: float,
                          dof: int, cells: float) -> ModeTest:
    """Whittle likelihood-ratio test of a mode in a Welch PSD.

    ``P`` is the averaged periodogram (``k_segments`` equivalent independent
    segments, each bin ``P_true chi2_{2K} / 2K``), ``model_with`` and
    ``model_without`` the fitted PSDs with and without the mode, ``dof`` the
    number of parameters the mode adds.
    """
    K = max(float(k_segments), 1.0)

    def nll(M: np.ndarray) -> float:
        M = np.maximum(M, 1e-300)
        return float(K * np.sum(np.log(M) + P / M))

    lr = max(2.0 * (nll(model_without) - nll(model_with)), 0.0)
    p = float(stats.chi2.sf(lr, dof))
    dev0 = nll(model_without) - K * float(np.sum(np.log(np.maximum(P, 1e-300)) + 1.0))
    explained = (lr / 2.0) / dev0 if dev0 > 0 else 0.0
    return _adjust(lr, dof, p, cells, explained)


def describe_failure(what: str, candidate: object, test: ModeTest) -> str:
    """One line for :class:`NoModeFound`."""
    freq = getattr(candidate, "freq_hz", float("nan"))
    zeta = getattr(candidate, "zeta", float("nan"))
    return (f"no mode found ({what}): the best candidate, {freq:.4g} Hz with zeta {zeta:.3g}, is no better than "
            f"noise: it {test.describe()}")


def is_finite_positive(x: float) -> bool:
    return math.isfinite(x) and x > 0
