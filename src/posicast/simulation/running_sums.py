"""A shaper's delayed FIR taps as a short recursion plus a few far taps (the kernels as running sums).

A distributed kernel discretised at step ``h`` (:func:`~posicast.simulation.streaming.discretize`)
spans hundreds of taps, and with a kernel that starts at ``t = 0`` (DZV, seed 000
eq. 6) the first of them acts one step later: the loop's history enters every
step.  Its taps are samples of a piecewise polynomial (uniform: constant;
triangular and decreasing: linear) or of ``1 - cos`` (cosine kernel), so a
short filter ``D(z^-1)`` annihilates them but at the kernel's breakpoints:

* uniform: ``D = 1 - z^-1`` (the running sum ``q_j = q_{j-1} + tap (xs_{j-1} - xs_{j-M})``),
* triangular, decreasing: ``D = (1 - z^-1)^2``,
one factor per kernel (products of kernels from ``S1 * S2``: the product of the
factors, seed 001 eq. 12).  ``R = D * taps`` is then sparse: a head (delays
``1 .. deg D``) that acts within a step or two, and far taps at the kernel's
breakpoints.  The delayed FIR output is ``D q = R xs``: a recursion of order
``deg D`` driven by the near history and by far taps that only read the shaper
input's past, so the loop is a linear system with a known input over blocks as
long as the nearest far tap (the method of steps on blocks of the shortest far
delay, :class:`~posicast.simulation.shaped_loop.ShapedLoop`).

A cosine kernel (seed 001 G3) is left as plain taps: its annihilator ``(1 - z^-1)(1 - 2 cos(2 pi h / T)
z^-1 + z^-2)`` has three roots within ``2 pi h / T`` of ``z = 1``, ``R`` is then ``(2 pi h / T)^2`` smaller
than the taps, and the block propagation of that recursion lost 1e-7 of the loop's signals (measured,
seed 000 loop with DcZV).

``D = (1 - z^-1)^p`` is run in its difference form (``p`` cascaded running sums:
``Delta^p q_j = (R xs)_j``, ``Delta^m q_j = Delta^m q_{j-1} + Delta^{m+1} q_j``), whose
rounding grows like the block length, not its square as in the companion form
``q_j = 2 q_{j-1} - q_{j-2} + ..`` (measured 1e-9 of the loop's signals with a
decreasing kernel).  The roots on the unit circle would still let rounding
drift: the recursion's state is recomputed from the stored history at the start
of every block (:meth:`RunningSums.exact_state`), which bounds the drift to one block.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy import signal

from ..shapers.base import Shaper

__all__ = ["RunningSums", "running_sums"]

# an entry of R = D * taps below this fraction of the largest tap is rounding of an annihilated interior
_ZERO = 1e-13
# the recursion must reproduce the taps to this fraction of the largest tap (else it is not used)
_CHECK = 1e-11


class RunningSums(NamedTuple):
    """``D q = R xs`` for the delayed FIR output ``q_j = sum_i taps[i] xs[j - i]`` (``i >= 1``).

    Attributes
    ----------
    den : ndarray
        ``D`` in ascending powers of ``z^-1``, ``den[0] = 1`` (``[1.]``: no recursion).
    head : ndarray of int, head_coef : ndarray
        Delays ``1 .. deg D`` of ``R`` and their coefficients (act within the block).
    far : ndarray of int, far_coef : ndarray
        The other delays of ``R`` (each ``> deg D``) and their coefficients.
    taps : ndarray
        The delayed taps ``taps[i]``, ``i = 0 .. last`` (``taps[0] = 0``), for the exact recursion state.
    """

    den: np.ndarray
    head: np.ndarray
    head_coef: np.ndarray
    far: np.ndarray
    far_coef: np.ndarray
    taps: np.ndarray

    @property
    def order(self) -> int:
        return self.den.size - 1

    @property
    def block(self) -> int:
        """Longest block over which the far taps read only the past (0: no far taps)."""
        return int(self.far[0]) if self.far.size else 0

    def far_sum(self, hist: np.ndarray, start: int, stop: int) -> np.ndarray:
        """``sum_far R_i xs[j - i]`` for ``j = start .. stop - 1`` from ``hist`` (index ``j`` = sample ``j``)."""
        if self.far.size <= 16:
            out = np.zeros(stop - start)
            for i, c in zip(self.far, self.far_coef):
                out += c * hist[start - i: stop - i]
            return out
        lo, hi = int(self.far[0]), int(self.far[-1])
        dense = np.zeros(hi - lo + 1)
        dense[self.far - lo] = self.far_coef
        return signal.convolve(hist[start - hi: stop - lo], dense, mode="valid")

    def exact_state(self, hist: np.ndarray, start: int) -> np.ndarray:
        """The backward differences ``Delta^m q_{start-1}``, ``m = 0 .. deg D - 1``, of the outputs summed
        directly from the taps: the exact state of the recursion in its difference form."""
        last = self.taps.size - 1
        rev = self.taps[::-1]
        q = np.array([rev[:-1] @ hist[start - m - last: start - m] for m in range(1, self.order + 1)])
        out = np.empty(self.order)
        for m in range(self.order):  # q holds Delta^m q_{start-1}, Delta^m q_{start-2}, ...
            out[m] = q[0]
            q = q[:-1] - q[1:]
        return out


# the power of (1 - z^-1) that annihilates each kernel's taps (piecewise constant, piecewise linear)
_ORDER = {"uniform": 1, "triangular": 2, "decreasing": 2}


def _annihilator(S: Shaper) -> np.ndarray | None:
    """``(1 - z^-1)^p`` with ``p`` the largest order of a part (a part's order: its kernels' summed);
    None with a cosine kernel."""
    p = 0
    for part in S.distributed:
        if any(k.shape not in _ORDER for k in part.kernels):
            return None
        p = max(p, sum(_ORDER[k.shape] for k in part.kernels))
    den = np.ones(1)
    for _ in range(p):
        den = np.convolve(den, [1.0, -1.0])
    return den


def running_sums(S: Shaper, delayed: np.ndarray, first: int) -> RunningSums | None:
    """The recursion for the delayed taps ``delayed`` (taps ``first .. last``) of the discretised ``S``.

    None (the caller keeps the plain taps) when the shaper has no distributed part, has a cosine
    kernel, or the recursion does not reproduce the taps to ``1e-11`` of the largest.
    """
    if not S.distributed or delayed.size == 0:
        return None
    last = first + delayed.size - 1
    taps = np.zeros(last + 1)
    taps[first:] = delayed
    den = _annihilator(S)
    if den is None:
        return None
    R = np.convolve(den, taps)
    scale = float(np.max(np.abs(taps)))
    R[np.abs(R) <= _ZERO * scale] = 0.0
    nz = np.flatnonzero(R)
    p = den.size - 1
    head, far = nz[nz <= p], nz[nz > p]
    # the recursion must give back the taps, and nothing after them, over a block beyond the last
    probe = np.zeros(last + max(p, 1) + (int(far[0]) if far.size else 1) + 1)
    probe[0] = 1.0
    implied = signal.lfilter(R, den, probe)
    want = np.zeros(probe.size)
    want[: last + 1] = taps
    if not np.all(np.abs(implied - want) <= _CHECK * scale):
        return None
    return RunningSums(den, head, R[head], far, R[far], taps)
