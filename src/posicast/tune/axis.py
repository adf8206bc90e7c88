"""A transfer function on the imaginary axis, evaluated many times at few points each (issue #15).

The tuner evaluates the plant and each constraint's factors at ``s = j omega``
thousands of times per design (the grid, every polish round, every exact end),
mostly at 9 to 100 frequencies a call.  :meth:`TransferFunction.__call__` then
spends most of its time on what does not change from call to call: checking its
argument, converting the coefficients, looking for its Taylor expansion points.
:class:`OnAxis` does that once: numerator and denominator by Horner's rule and
their exponentials, as :meth:`QuasiPolynomial.__call__` computes them (the same
operations in the same order, so the same numbers), and the points that need
more (within the Taylor radius of an expansion point, or ``0 / 0``) through the
transfer function itself.  A constant is a constant.
"""

from __future__ import annotations

import numpy as np

from ..core.quasipoly import QuasiPolynomial, horner
from ..core.transfer import TransferFunction

__all__ = ["OnAxis"]


class _Sum:
    """One quasi-polynomial ``sum_i p_i(s) exp(-s tau_i)`` at complex ``s``, as ``QuasiPolynomial._eval``."""

    def __init__(self, q: QuasiPolynomial) -> None:
        self.zero = q.is_zero
        self.coeffs = np.ascontiguousarray(q.coeffs.T)  # (degree + 1, rows): horner's layout
        self.delays = np.asarray(q.delays, dtype=float)
        # one undelayed row: exp(-0 s) = 1 exactly, and p * (1 + 0j) = p, so the product is skipped
        self.plain = self.delays.size == 1 and self.delays[0] == 0.0

    def __call__(self, s: np.ndarray) -> np.ndarray:
        if self.zero:
            return np.zeros_like(s)
        with np.errstate(all="ignore"):
            polys = horner(s, self.coeffs)
            if self.plain:
                return polys[0]
            exps = np.exp(-np.multiply.outer(self.delays, s))
            return np.sum(polys * exps, axis=0)


class OnAxis:
    """``H(j omega)`` for real arrays ``omega``: the numbers ``H(1j * omega)`` gives, faster.

    >>> H = TransferFunction.from_poly([1.0], [1.0, 1.0], delay=0.5)
    >>> w = np.array([0.0, 0.3, 2.0])
    >>> bool(np.array_equal(OnAxis(H)(w), H(1j * w)))
    True
    """

    def __init__(self, tf: TransferFunction) -> None:
        self.tf = tf
        num, den = tf.num, tf.den
        self.constant: complex | None = None
        if num.is_zero:
            self.constant = 0j
        elif num.coeffs.shape == (1, 1) and den.coeffs.shape == (1, 1) and not tf.has_delays:
            self.constant = complex(tf(0.0))
        self._num, self._den = _Sum(num), _Sum(den)
        tau = tf.max_delay
        pts = tf._points()
        # the Taylor radius of TransferFunction.__call__ about each expansion point
        self._near = [(complex(p), 0.5 / max(tau, 1.0 / (1.0 + abs(p)))) for p in pts]

    @staticmethod
    def quasi(q: QuasiPolynomial) -> _Sum:
        """The unchecked evaluator of one quasi-polynomial at complex ``s`` (inf/NaN where it overflows)."""
        return _Sum(q)

    def __call__(self, w: np.ndarray) -> np.ndarray:
        if self.constant is not None:
            return np.full(np.shape(w), self.constant)
        return self.parts(w)[0]

    def parts(self, w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(H, N, D)`` at ``j omega``: the value and its numerator and denominator."""
        w = np.asarray(w, dtype=float)
        flat = (1j * w).reshape(-1)
        N, D = self._num(flat), self._den(flat)
        if self.constant is not None:
            H = np.full(flat.shape, self.constant)
        else:
            with np.errstate(divide="ignore", invalid="ignore"):
                H = N / D
            # as TransferFunction.__call__: the Taylor series about each expansion point within its radius,
            # then the points still not finite (0 / 0, poles) through the transfer function itself
            for p, radius in self._near:
                near = np.abs(flat - p) <= radius
                if near.any():
                    H[near] = self.tf._taylor_ratio(p, flat[near] - p)
            bad = ~np.isfinite(H)
            if bad.any():
                H[bad] = np.asarray(self.tf(flat[bad]), dtype=complex)
        return H.reshape(w.shape), N.reshape(w.shape), D.reshape(w.shape)
