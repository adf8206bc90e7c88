"""Scaled evaluation of a quasi-polynomial, its derivative bounds and its rounding error.

Step 1 of :func:`posicast.roots` (see :mod:`posicast.spectra.rootfinder`) needs, on
every boundary segment, the value of ``h``, a rigorous bound of ``|h'|`` and a bound of
the rounding error; Newton needs ``h / h'``.  Evaluation is scaled by the positive
factor ``exp(min(0, Re s) tau_max)`` so that no exponential overflows; a positive factor
changes neither the argument nor the roots.  :class:`Evaluator` also counts the
evaluations against the budget (:class:`~posicast.spectra.checks.BudgetExceeded`).
"""

from __future__ import annotations

import math
import time

import numpy as np
from numpy.polynomial import polynomial as P

from ..core.quasipoly import QuasiPolynomial, horner, horner_rows
from .checks import BudgetExceeded

__all__ = ["EPS", "TWO_PI", "Evaluator", "scaled_eval", "relative_residual"]

EPS = np.finfo(float).eps
TWO_PI = 2.0 * math.pi


class Evaluator:
    """Scaled evaluation of ``h``, ``h'`` and the derivative bound, counting evaluations.

    Every evaluation is charged against ``budget`` (a number of evaluations) and ``deadline``
    (``time.monotonic()`` seconds): :class:`BudgetExceeded` past either.
    """

    def __init__(self, q: QuasiPolynomial, budget: int, deadline: float) -> None:
        self.q = q
        self.tau = q.delays
        self.tau_max = float(q.delays[-1])
        self.c = q.coeffs
        self.abs_c = np.abs(q.coeffs)
        d = q.coeffs.shape[1] - 1
        # |d/ds (p_k(s) e^{-s tau_k})| <= sum_j ((j+1)|c_{k,j+1}| + tau_k |c_{k,j}|) R^j e^{-Re s tau_k}
        b = self.tau[:, None] * self.abs_c
        if d > 0:
            b[:, :-1] += self.abs_c[:, 1:] * np.arange(1, d + 1)
        self.deriv_bound_coeffs = b
        self.n_terms = q.coeffs.size + 2
        self.evaluations = 0
        self.budget = budget
        self.deadline = deadline
        self._taylor_rows: list | None = None  # built on first use (taylor_deriv_bound)
        # Per-evaluator constants for the small arrays of the boundary walk (issue #15: the Python
        # overhead of numpy calls dominates there): the columns of c, |c| and the derivative bound's
        # coefficients as (m, 1) arrays, and -tau as a column; the same operations in the same order
        # as horner(s, c.T) and exp(-outer(tau, s) + shift) (equal to rounding).
        self._cols = q.plan().cols
        self._abs_cols = [np.ascontiguousarray(col[:, None]) for col in self.abs_c.T]
        self._db_cols = [np.ascontiguousarray(col[:, None]) for col in b.T]
        self._neg_tau = np.ascontiguousarray(-self.tau[:, None])
        self._dq: QuasiPolynomial | None = None

    @property
    def dq(self) -> QuasiPolynomial:
        """``h'`` (built on first use: most boundary walks never need it)."""
        if self._dq is None:
            self._dq = self.q.derivative()
        return self._dq

    def _taylor_data(self) -> list:
        """Per row: the columns of ``pder`` are the coefficients of ``p^{(l)}(s) / l!``, l = 0..d;
        the (K+1) x (d+1) matrix ``E[k, l] = (-tau)^(k-l) / (k-l)!`` convolves them with the series
        of ``exp(-tau t)``.  ``K = d + 12``: the tail beyond it is bounded explicitly."""
        if self._taylor_rows is None:
            d = self.q.coeffs.shape[1] - 1
            K = self.taylor_order = d + 12
            self._inv_fact = np.array([1.0 / math.factorial(j) for j in range(K + 2)])
            rows = []
            kk = np.arange(K + 1)[:, None] - np.arange(d + 1)[None, :]
            kp = np.maximum(kk, 0)
            for row, tau in zip(self.q.coeffs, self.tau):
                pder = np.zeros((d + 1, d + 1))
                cur = np.array(row, dtype=float)
                for l in range(d + 1):
                    pder[: cur.size, l] = cur / math.factorial(l)
                    cur = P.polyder(cur) if cur.size > 1 else np.zeros(1)
                E = np.where(kk >= 0, (-float(tau)) ** kp * self._inv_fact[kp], 0.0)
                rows.append((float(tau), pder, np.abs(pder), E, np.abs(E)))
            self._taylor_rows = rows
            # every row's pder side by side, column l m + r for p_r^{(l)} / l! (degree <= d - l), as
            # ((d + 1) m, 1) columns: one triangular Horner pass for all rows (_taylor_horner)
            both = np.stack([r[1] for r in rows], axis=2).reshape(d + 1, -1)
            self._taylor_cols = tuple(both[:, :, None])
            self._taylor_abs_cols = tuple(np.abs(both)[:, :, None])
        return self._taylor_rows

    def _taylor_horner(self, z: np.ndarray, cols: tuple) -> np.ndarray:
        """``p_r^{(l)}(z) / l!`` for every row ``r`` and ``l``, shape ``(m, d + 1, n)`` (C order).

        Horner's rule on the columns still nonzero: ``p^{(l)}`` has degree ``d - l``, so at the
        power ``j`` only the columns ``l <= d - j`` (a prefix in this order) have begun; the others
        are zero, where Horner's rule would multiply zeros.  The same values as the full pass.
        """
        m, d = len(self.tau), len(cols) - 1
        out = np.zeros((cols[0].shape[0], z.size), dtype=np.result_type(z, float))
        for j in range(d, -1, -1):
            part = out[: (d - j + 1) * m]
            part *= z
            part += cols[j][: part.shape[0]]
        return np.ascontiguousarray(out.reshape(d + 1, m, z.size).transpose(1, 0, 2))

    def taylor_deriv_bound(self, c: np.ndarray, rho: np.ndarray, shift: np.ndarray) -> np.ndarray:
        """Bound of ``|h'(s)| exp(shift)`` on the disks ``|s - c| <= rho`` (needs ``rho tau_max <= 1/2``).

        From the Taylor coefficients ``A_k`` of ``h`` about ``c`` (``sum_k k |A_k| rho^(k-1)``,
        with their rounding errors, plus an explicit bound of the series' tail).  Unlike
        :meth:`deriv_bound`, which adds absolute values of the coefficients, this keeps the
        cancellation of ``h`` near a multiple root: next to a sixfold root at distance ``d``
        it is about ``6 d^5``, not ``sum |c_j| j R^(j-1)``, so a path can pass much closer.
        """
        self._charge(c.size * len(self.tau))
        rows = self._taylor_data()
        K = self.taylor_order
        n = c.size
        A = np.zeros((K + 1, n), dtype=complex)
        S = np.zeros((K + 1, n))
        tail = np.zeros(n)
        absc = np.abs(c)
        d1 = rows[0][1].shape[1]
        l = np.arange(d1)[:, None]
        j0 = K + 1 - l  # the tail: k = l + j > K
        e0 = np.exp(self._neg_tau * c + shift)  # (m, n)
        # (m, d + 1, n): p^{(l)}(c) / l! of every row, scaled, and the same with absolute values
        pl_all = self._taylor_horner(c, self._taylor_cols)
        pl_all *= e0[:, None, :]
        pa_all = self._taylor_horner(absc, self._taylor_abs_cols)
        pa_all *= np.abs(e0)[:, None, :]
        rho_l = rho[None, :] ** (l - 1)
        for (tau, _, _, E, aE), pl, pa in zip(rows, pl_all, pa_all):
            # the real matrix E on the real and imaginary parts side by side (a real product)
            A += (E @ pl.view(np.float64)).view(complex)
            S += aE @ pa
            if tau > 0:
                # rho^(l-1) sum_{j >= j0} (l + j) x^j / j!, x = rho tau <= 1/2: ratio <= 2 x / (j0 + 1)
                x = rho[None, :] * tau
                t0 = (l + j0) * x**j0 * self._inv_fact[j0]
                tail += np.sum(pa * rho_l * t0 / (1.0 - 2.0 * x / (j0 + 1)), axis=0)
        k = np.arange(1, K + 1)[:, None]
        err = self.round_factor(absc + rho) * (1.0 + K) * S[1:]
        with np.errstate(over="ignore", invalid="ignore"):  # past the float range: no bound (inf)
            out = np.sum(k * (np.abs(A[1:]) + err) * rho[None, :] ** (k - 1), axis=0) + tail
        return np.where(np.isnan(out), np.inf, out)

    def round_factor(self, r: np.ndarray | float) -> np.ndarray | float:
        """Bound of the relative rounding error of a scaled evaluation at ``|s| = r``.

        ``8 eps`` per term (polynomial and exponential), plus the phase: ``s tau`` is rounded
        to ``eps |s| tau``, which is the relative error of ``exp(-s tau)`` (it dominates at
        high frequency, e.g. 1e-12 at ``|s| tau = 1e4``).
        """
        return EPS * (8.0 * self.n_terms + 2.0 * np.asarray(r) * self.tau_max)

    def _charge(self, n: int) -> None:
        self.evaluations += n
        if self.evaluations > self.budget:
            raise BudgetExceeded(
                f"root finding needed more than max_evaluations={self.budget:.3g} evaluations; "
                "shrink the region or raise max_evaluations"
            )
        if time.monotonic() > self.deadline:
            raise BudgetExceeded("root finding exceeded its time budget (timeout); shrink the region or raise timeout")

    def value_parts(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`value` of a 1-D complex ``z``, with ``|z|`` and the scaling exponent
        ``min(0, Re z) tau_max`` it used: ``(h rho, sum |terms| rho, |z|, log rho)``."""
        self.evaluations += z.size
        if self.evaluations > self.budget or time.monotonic() > self.deadline:
            self._charge(0)
        shift = np.minimum(z.real, 0.0) * self.tau_max
        e = np.exp(self._neg_tau * z + shift)
        az = np.abs(z)
        val = np.add.reduce(horner_rows(z, self._cols) * e, axis=0)
        mag = np.add.reduce(horner_rows(az, self._abs_cols) * np.abs(e), axis=0)
        return val, mag, az, shift

    def value(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Scaled ``h(s) rho(s)`` and the scaled magnitude ``sum |terms| rho(s)``."""
        s = np.asarray(s, dtype=complex)
        val, mag, _, _ = self.value_parts(s.reshape(-1))
        return val.reshape(s.shape), mag.reshape(s.shape)

    def newton_step(
        self, s: np.ndarray, q: QuasiPolynomial | None = None, dq: QuasiPolynomial | None = None
    ) -> np.ndarray:
        """``h(s) / h'(s)`` (or ``q / dq`` for a derivative ``q`` of ``h``), evaluated with the same scaling."""
        if q is None:
            q, dq = self.q, self.dq
        elif dq is None:
            dq = q.derivative()
        self._charge(2 * s.size)
        shift = np.minimum(s.real, 0.0) * self.tau_max
        if s.ndim == 1 and not q.is_zero and not dq.is_zero and q.delays.shape == dq.delays.shape \
                and (q.delays == dq.delays).all():
            # one exponential per delay for both (the same operations as scaled_eval of each)
            e = np.exp(q.plan().neg_tau * s + shift)
            f = np.add.reduce(horner_rows(s, q.plan().cols) * e, axis=0)
            df = np.add.reduce(horner_rows(s, dq.plan().cols) * e, axis=0)
        else:
            f = scaled_eval(q, s, shift)
            df = scaled_eval(dq, s, shift)
        with np.errstate(divide="ignore", invalid="ignore"):
            return f / df

    def deriv_bound(self, za: np.ndarray, zb: np.ndarray) -> np.ndarray:
        """Bound of ``|h'| rho_seg`` on segments, ``rho_seg = exp(min(0, min Re) tau_max)``."""
        return self.deriv_bound_at(np.maximum(np.abs(za), np.abs(zb)), np.minimum(za.real, zb.real))

    def deriv_bound_at(self, R: np.ndarray, a: np.ndarray) -> np.ndarray:
        """:meth:`deriv_bound` from the segments' largest ``|s|`` (``R``) and smallest ``Re s`` (``a``), 1-D."""
        e = np.exp(self._neg_tau * a + np.minimum(a, 0.0) * self.tau_max)
        return np.add.reduce(horner_rows(R, self._db_cols) * e, axis=0)


def scaled_eval(q: QuasiPolynomial, s: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """``q(s) exp(shift)`` (zero for a zero ``q``), with every exponential scaled by ``exp(shift)``."""
    if q.is_zero:
        return np.zeros(s.shape, dtype=complex)
    if s.ndim == 1:  # (the same operations with the quasi-polynomial's constant columns)
        plan = q.plan()
        return np.add.reduce(horner_rows(s, plan.cols) * np.exp(plan.neg_tau * s + shift), axis=0)
    e = np.exp(-np.multiply.outer(q.delays, s) + shift)
    return np.sum(horner(s, q.coeffs.T) * e, axis=0)


def relative_residual(q: QuasiPolynomial, z: np.ndarray) -> np.ndarray:
    """``|q(z)| / sum_i |p_i(z) exp(-z tau_i)|`` (``|q(z)|`` where the terms vanish), scaled as above."""
    z = np.asarray(z, dtype=complex)
    if z.size == 0:
        return np.zeros(0)
    tau_max = float(q.delays[-1])
    shift = np.minimum(z.real, 0.0) * tau_max
    e = np.exp(-np.multiply.outer(q.delays, z) + shift)
    val = np.abs(np.sum(horner(z, q.coeffs.T) * e, axis=0))
    mag = np.sum(horner(np.abs(z), np.abs(q.coeffs).T) * np.abs(e), axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(mag > 0, val / mag, val)
