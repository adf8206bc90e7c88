"""Lumped-delay (impulse-sequence) shapers: ZV, ZVD^k, MZV, MIS-ZV, MIS-ZVD.

Every formula here is checked in the test suite by the zero-placement test:
``|S(p)| <= 1e-10`` at the mode's pole ``p = -zeta omega + j omega sqrt(1 - zeta^2)``.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import comb, gammaln

from .. import _validate as v
from ..modes import Mode
from .base import MAX_IMPULSES, check_decay, check_mode, sigma_of

__all__ = ["zv_impulses", "zvdk_impulses", "mzv_impulses", "mis_zv_impulses", "mis_zvd_impulses"]


def _logK(mode: Mode, fraction_of_half_period: float = 1.0) -> float:
    """``log K = -zeta pi f / sqrt(1 - zeta^2)``: the decay over ``f`` half damped periods (never underflows)."""
    return -sigma_of(mode.zeta) * math.pi * fraction_of_half_period


def _K(mode: Mode, fraction_of_half_period: float = 1.0) -> float:
    """``K = exp(-zeta pi f / sqrt(1 - zeta^2))``."""
    return math.exp(_logK(mode, fraction_of_half_period))



def zv_impulses(mode: Mode) -> tuple[np.ndarray, np.ndarray]:
    """ZV shaper (seed 000 eq. 4, seed 002 eq. 1, seed 004 eq. 4).

    ``A = [1, K] / (1 + K)`` at ``t = [0, pi / Omega]``.  Seed 000 writes the
    first amplitude as ``e^{beta pi / Omega} / (1 + e^{beta pi / Omega})``, which
    is the same number.
    """
    return zvdk_impulses(mode, 0)


def zvdk_impulses(mode: Mode, k: int) -> tuple[np.ndarray, np.ndarray]:
    """ZVD^k shaper (seed 003 eq. 4): ``k + 2`` impulses, binomial amplitudes.

    ``A_i = C(k+1, i-1) K^{i-1} / sum_j C(k+1, j) K^j``, ``t_i = (i-1) pi / Omega``.
    It is the ``(k+1)``-fold convolution of ZV with itself (``k = 0``: ZV,
    ``k = 1``: ZVD, ``k = 2``: ZVDD, ``k = 3``: ZVDDD; seed 004 eq. 4-7).
    """
    check_mode(mode)
    k = v.integer_in_range(k, "k", 0, MAX_IMPULSES - 2,
                           f" (ZVD^k has k + 2 impulses; at most {MAX_IMPULSES} are supported)")
    check_decay(mode, (k + 1) / 2.0, f"a ZVD^k shaper with k={k}")
    n = k + 1
    j = np.arange(n + 1)
    # comb(n, j) * K**j normalised; computed in log space to stay finite for large k.
    # comb(n, j) overflows a float beyond n ~ 1020: log-gamma there.
    logc = np.log(comb(n, j)) if n <= 1000 else gammaln(n + 1) - gammaln(j + 1) - gammaln(n - j + 1)
    logw = logc + j * _logK(mode)
    w = np.exp(logw - logw.max())
    amps = w / w.sum()
    times = j * (math.pi / mode.damped_omega)
    return times, amps


def mzv_impulses(mode: Mode) -> tuple[np.ndarray, np.ndarray]:
    """MZV: three impulses over 3/4 of the damped period (used by 3D-printer firmware).

    Impulses at ``0, 3T/8, 3T/4`` (``T`` the damped period) rotate the residual
    vector by ``3 pi / 4`` each; ``1 + sqrt(2) e^{-j 3pi/4} + e^{-j 3pi/2} = 0`` makes
    the undamped weights ``[1, sqrt(2), 1]``, and the decay factor
    ``K = exp(-0.75 zeta pi / sqrt(1 - zeta^2))`` per step places the zero exactly on
    the damped pole: ``A = [1, sqrt(2) K, K^2] / (1 + sqrt(2) K + K^2)``.
    """
    check_mode(mode)
    check_decay(mode, 0.75, "an MZV shaper")
    K = _K(mode, 0.75)
    w = np.array([1.0, math.sqrt(2.0) * K, K * K])
    Td = mode.damped_period
    return np.array([0.0, 0.375 * Td, 0.75 * Td]), w / w.sum()


def mis_zv_impulses(mode: Mode, n: int) -> tuple[np.ndarray, np.ndarray]:
    """n-impulse MIS-ZV (seed 004 eq. 9).

    ``A_i = K^{i-1} / sum_j K^j`` at ``t_i = (i-1) T_d / n`` with
    ``K = exp(-2 zeta pi / (n sqrt(1 - zeta^2)))``.  The impulses are ``n``
    equally spaced phasors around the circle, so they cancel at the pole.
    Seed 004 writes the amplitude of the last impulse over ``1 + M`` with
    ``M = K + ... + K^{n-1}``: the same normalisation (sum of amplitudes 1).
    """
    check_mode(mode)
    n = v.integer_in_range(n, "n", 2, MAX_IMPULSES,
                           f" (MIS-ZV has n impulses; at most {MAX_IMPULSES} are supported)")
    check_decay(mode, (n - 1) / n, f"an MIS-ZV shaper with n={n}")
    i = np.arange(n)
    w = np.exp(i * _logK(mode, 2.0 / n))  # K**i
    return i * mode.damped_period / n, w / w.sum()


def mis_zvd_impulses(mode: Mode, n: int, m: int) -> tuple[np.ndarray, np.ndarray]:
    """n x m-impulse MIS-ZVD: the convolution of n- and m-impulse MIS-ZV (seed 004 eq. 10).

    ``n * m`` impulses (at most :data:`~posicast.shapers.base.MAX_IMPULSES`, checked before
    anything is allocated).
    """
    check_mode(mode)
    n = v.integer(n, "n", 2)
    m = v.integer(m, "m", 2)
    if n * m > MAX_IMPULSES:
        raise ValueError(
            f"mis_zvd with n={n:.4g}, m={m:.4g} would have n*m = {float(n * m):.4g} impulses (about "
            f"{48.0 * n * m / 1e9:.3g} GB to build); n*m must be <= {MAX_IMPULSES}: reduce n or m")
    check_decay(mode, (n - 1) / n + (m - 1) / m, f"an MIS-ZVD shaper with n={n}, m={m}")
    t1, a1 = mis_zv_impulses(mode, n)
    t2, a2 = mis_zv_impulses(mode, m)
    return np.add.outer(t1, t2).ravel(), np.multiply.outer(a1, a2).ravel()
