"""Certified disks about a root or a cluster of roots (Rouché/Pellet tests).

With the Taylor coefficients ``a_k`` of ``h`` about a centre ``c`` (and their rounding
errors, and a Cauchy bound of the tail), a radius ``rho`` at which one term dominates,
``|a_m| rho^m > sum_{k != m} |a_k| rho^k + tail``, certifies exactly ``m`` roots in
``|s - c| < rho``.  :func:`pellet` gives a cluster its multiplicity (step 3 of
:func:`posicast.roots`); :func:`certified_radius` bounds how far a root found by Newton
can be from the true one (the stability verdicts on the imaginary axis).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.polynomial import polynomial as P

from ..core.quasipoly import QuasiPolynomial, horner
from .evaluation import EPS

__all__ = ["PelletDisk", "pellet", "certified_radius", "cluster_rho_max"]


class PelletDisk(NamedTuple):
    """A disk about a centre certified by :func:`pellet` to hold exactly :attr:`multiplicity` roots."""

    multiplicity: int
    radius: float  #: the smallest certified radius (an exact multiple root is not merged with a neighbour)
    isolation_radius: float  #: the largest radius certifying the same count: any point inside is one of them


def _taylor_and_tail(
    q: QuasiPolynomial, c: complex, order: int, R0: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Taylor coefficients ``a_k`` of ``h`` about ``c`` (k <= order), their rounding errors and a
    bound ``B`` of ``|h|`` on ``|s - c| = R0``, all times one positive factor ``exp(kappa)``.

    ``kappa = min(0, Re c - R0) tau_max`` keeps every exponential at most 1 (no overflow
    far left with long delays); a common positive factor changes no Pellet/Rouché test.
    The rounding error counts the sums and the phase of ``exp(-c tau)``, rounded to
    ``eps |c| tau`` (see :meth:`~posicast.spectra.evaluation.Evaluator.round_factor`).
    """
    c = complex(c)
    K = order + 1
    tau_max = float(q.delays[-1])
    kappa = min(0.0, c.real - R0) * tau_max
    inv_fact = np.array([1.0 / math.factorial(j) for j in range(K)])
    a = np.zeros(K, dtype=complex)
    scale = np.zeros(K)
    B = 0.0
    for row, tau in zip(q.coeffs, q.delays):
        pt = np.zeros(K, dtype=complex)
        pabs = np.zeros(K)
        prow = np.array(row, dtype=float)
        for l in range(min(K, row.size)):
            pt[l] = horner(c, prow) * inv_fact[l]
            pabs[l] = horner(abs(c), np.abs(prow)) * inv_fact[l]
            prow = P.polyder(prow) if prow.size > 1 else np.zeros(1)
        et = (-tau) ** np.arange(K) * inv_fact
        e0 = np.exp(-c * tau + kappa)
        a += e0 * np.convolve(pt, et)[:K]
        scale += abs(e0) * np.convolve(pabs, np.abs(et))[:K]
        B += float(horner(abs(c) + R0, np.abs(row))) * math.exp(-(c.real - R0) * tau + kappa)
    err = EPS * (8.0 * (order + q.coeffs.size) + 2.0 * abs(c) * tau_max) * scale
    return a, err, np.abs(a), B


def pellet(q: QuasiPolynomial, c: complex, rho_max: float, order: int = 16) -> PelletDisk | None:
    """Certified number of roots in a small disk about ``c`` (Rouché/Pellet test).

    With the Taylor coefficients ``a_k`` of ``h`` about ``c``, if for some
    radius ``rho`` one term dominates, ``|a_m| rho^m > sum_{k != m} |a_k| rho^k``
    plus rounding errors and a Cauchy bound of the tail beyond ``order``, then
    ``h`` has exactly ``m`` roots in ``|s - c| < rho``.

    Radii are tried from small to large.  Returns a :class:`PelletDisk` ``(m, rho, rho_iso)``: the
    smallest certified disk holding ``m >= 1`` roots (so that an exact multiple
    root is not merged with a close simple neighbour), and the largest radius
    ``rho_iso`` that still certifies the same ``m`` (an isolation disk: any other
    point found inside it is one of these ``m`` roots).  ``(0, rho, rho)`` when
    only empty disks are certified, None when no radius up to ``rho_max`` separates
    a dominant term.
    """
    R0 = 4.0 * rho_max
    # |h| <= B on |s - c| = R0, hence |a_k| <= B / R0^k (Cauchy) for the tail k > order
    a, err, absa, B = _taylor_and_tail(q, c, order, R0)
    k = np.arange(order + 1)
    certified: list[tuple[float, int]] = []
    rhos = [rho_max * 10.0 ** (-j / 4.0) for j in range(39, -1, -1)]
    # every radius's terms at once (row i: the same numbers as rho_i**k), the scalar rest per radius
    powers = np.array(rhos)[:, None] ** k
    terms = (absa + err) * powers
    dominant = np.argmax(absa * powers, axis=1)
    sums = np.sum(terms, axis=1)
    for i, rho in enumerate(rhos):
        x = rho / R0
        tail = B * x ** (order + 1) / (1.0 - x)
        m = int(dominant[i])
        lhs = (absa[m] - err[m]) * rho**m
        rhs = float(sums[i] - terms[i, m]) + tail
        if lhs > rhs:
            certified.append((rho, m))
    if not certified:
        return None
    first = next((i for i, (_, m) in enumerate(certified) if m >= 1), None)
    if first is None:
        return PelletDisk(0, certified[-1][0], certified[-1][0])
    m, rho = certified[first][1], certified[first][0]
    rho_iso = rho
    for r2, m2 in certified[first + 1 :]:
        if m2 != m:
            break
        rho_iso = r2
    return PelletDisk(m, rho, rho_iso)


def certified_radius(q: QuasiPolynomial, c: complex, m: int, rho_max: float, order: int = 16) -> float | None:
    """Smallest radius (within a factor 2) of a disk about ``c`` certified to hold exactly ``m`` roots.

    The Pellet/Rouché test of :func:`pellet` for the term ``m``: with the
    Taylor coefficients ``a_k`` of ``h`` about ``c`` (and their rounding errors),
    ``|a_m| rho^m > sum_{k != m} |a_k| rho^k + tail`` means exactly ``m`` roots in
    ``|s - c| < rho``.  The radius starts from the estimate where every lower term
    is small against ``a_m`` and doubles up to ``rho_max``; ``None`` when no radius
    passes.  For a simple root found by Newton this is about ``2 |h(c)| / |h'(c)|``
    plus the rounding level (1e-16 relative at low frequency): the root's real part
    is certified to within that radius.
    """
    c = complex(c)
    if not (1 <= m <= order) or not (rho_max > 0):
        return None
    tau_max = float(q.delays[-1])
    if tau_max > 0:
        # a Cauchy circle R0 = 4 rho_max short against the delays: no exponential under/overflows
        rho_max = min(rho_max, 0.25 / tau_max)
    R0 = 4.0 * rho_max
    a, err, absa, B = _taylor_and_tail(q, c, order, R0)
    lead = absa[m] - err[m]
    if not lead > 0:
        return None
    # no radius below the one where a lower term equals the m-th can pass
    # (the floor is far below the rounding level only for a root next to s = 0, e.g. -1e-300 of a
    # loop with a gain of 1e-300, which is then certified left of the axis)
    est = max([((absa[k] + err[k]) / lead) ** (1.0 / (m - k)) for k in range(m)] + [1e-300 * rho_max])
    if est > rho_max:
        return None
    k = np.arange(order + 1)
    n = int(math.floor(4.0 * math.log2(rho_max / est))) + 1
    # steps of 2^(1/4) (coarser when they would be more than 400)
    rho = est * 2.0 ** (np.arange(n) / 4.0) if n <= 400 else np.geomspace(est, rho_max, 400)
    x = rho / R0
    tail = B * x ** (order + 1) / (1.0 - x)
    with np.errstate(over="ignore", invalid="ignore"):
        terms = (absa + err)[None, :] * rho[:, None] ** k[None, :]
        ok = lead * rho**m > np.sum(terms, axis=1) - terms[:, m] + tail
    return float(rho[np.argmax(ok)]) if np.any(ok) else None


def cluster_rho_max(simple_pts: np.ndarray, centre: complex, step: float) -> float:
    """Largest Pellet radius for a cluster: well short of the nearest simple root and of the grid step."""
    lim = [0.25 * step, 0.05 * max(1.0, abs(centre))]
    if simple_pts.size:
        lim.append(0.4 * float(np.min(np.abs(simple_pts - centre))))
    return min(lim)
