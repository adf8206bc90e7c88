"""A transfer function on the imaginary axis, evaluated many times at few points each (issue #15).

The tuner evaluates the plant and each constraint's factors at ``s = j omega``
thousands of times per design (the grid, every polish round, every exact end),
mostly at 9 to 100 frequencies a call.  :meth:`TransferFunction.__call__` then
spends most of its time on what does not change from call to call: checking its
argument, converting the coefficients, looking for its Taylor expansion points.
:class:`OnAxis` does that once: numerator and denominator through the
quasi-polynomials' own unchecked evaluator (``QuasiPolynomial._eval``, with its
per-object constants: the numbers :meth:`QuasiPolynomial.__call__` gives), and the
points that need more (within the Taylor radius of an expansion point, or ``0 / 0``)
through the transfer function itself.  A constant is a constant.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..core.quasipoly import QuasiPolynomial
from ..core.transfer import TransferFunction

__all__ = ["OnAxis"]


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
        self._num, self._den = num._eval, den._eval
        tau = tf.max_delay
        pts = tf._points()
        # the Taylor radius of TransferFunction.__call__ about each expansion point
        self._near = [(complex(p), 0.5 / max(tau, 1.0 / (1.0 + abs(p)))) for p in pts]

    @staticmethod
    def quasi(q: QuasiPolynomial) -> Callable[[np.ndarray], np.ndarray]:
        """The unchecked evaluator of one quasi-polynomial at complex ``s`` (inf/NaN where it overflows)."""
        return q._eval

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
