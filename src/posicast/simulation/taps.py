"""Discrete taps of a shaper's parts at a sample period (the arithmetic behind :func:`~posicast.simulation.streaming.discretize`).

Lumped impulses become one tap, or fractional-delay taps split between samples;
a distributed part becomes the exact integrals of its delay density against the
interpolation kernel (module docstring of :mod:`posicast.simulation.streaming`);
an IIR remainder is discretised by the prewarped Tustin transform.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import signal

from posicast.shapers.base import DistributedPart, Shaper

__all__ = ["impulse_taps", "part_taps", "part_pieces", "prewarped_step", "iir_section", "GRID_TOL"]

_GL_X, _GL_W = np.polynomial.legendre.leggauss(16)
GRID_TOL = 1e-9  # a delay within this fraction of a sample of the grid sits on the grid


def _split(x: float) -> tuple[int, float]:
    """``x = n + f`` with integer ``n`` and ``0 <= f < 1`` (``f`` snapped to 0 near the grid)."""
    n = math.floor(x)
    f = x - n
    if f > 1.0 - GRID_TOL:
        return n + 1, 0.0
    if f < GRID_TOL:
        return n, 0.0
    return n, f


def impulse_taps(x: float, amp: float, fractional: str) -> list[tuple[int, float]]:
    if fractional == "round":
        return [(int(math.floor(x + 0.5)), amp)]
    n, f = _split(x)
    if f == 0.0:
        return [(n, amp)]
    if fractional == "linear":
        return [(n, amp * (1.0 - f)), (n + 1, amp * f)]
    # cubic Lagrange interpolation through the nodes n-1, n, n+1, n+2 evaluated at n + f
    h = (
        -f * (f - 1.0) * (f - 2.0) / 6.0,
        (f + 1.0) * (f - 1.0) * (f - 2.0) / 2.0,
        -(f + 1.0) * f * (f - 2.0) / 2.0,
        (f + 1.0) * f * (f - 1.0) / 6.0,
    )
    if n - 1 < 0:  # unreachable after _check_rate (delays >= one sample)
        raise ValueError("lagrange3 needs every delay between samples to be >= one sample")
    return [(n - 1 + j, amp * hj) for j, hj in enumerate(h)]


def part_pieces(p: DistributedPart) -> list[float]:
    pts = [p.delay, p.end]
    if len(p.kernels) == 1 and p.kernels[0].shape == "triangular":
        pts.append(p.delay + p.kernels[0].T / 2.0)
    return pts


def part_taps(p: DistributedPart, Ts: float, fractional: str) -> tuple[int, np.ndarray]:
    """``(k0, w)``: taps ``w[j]`` at sample ``k0 + j`` for one distributed part."""
    if len(p.kernels) > 1:
        # A convolution of kernels (from S1 * S2): the product of the discretised factors (each
        # kernel integrated exactly, the delay as a fractional-delay impulse), which keeps each
        # factor's accuracy at the pole instead of that of a numerically convolved density.
        start, w = 0, np.array([1.0])
        for k in p.kernels:
            k0_i, w_i = part_taps(DistributedPart(1.0, 0.0, (k,)), Ts, fractional)
            start += k0_i
            w = np.convolve(w, w_i)
        imp = impulse_taps(p.delay / Ts, p.weight, fractional)
        i0 = min(i for i, _ in imp)
        d = np.zeros(max(i for i, _ in imp) - i0 + 1)
        for i, a in imp:
            d[i - i0] += a
        return start + i0, np.convolve(w, d)
    a, b = p.delay / Ts, p.end / Ts  # support in samples
    if fractional == "round":  # box [k - 1/2, k + 1/2)
        k0 = int(math.floor(a + 0.5))
        k1 = int(math.floor(b + 0.5))
        edges = np.arange(k0, k1 + 2) - 0.5
    else:  # hat on [k - 1, k + 1]
        k0 = int(math.floor(a))
        k1 = int(math.ceil(b))
        edges = np.arange(k0, k1 + 1, dtype=float)
    inner = [x / Ts for x in part_pieces(p)]
    knots = np.unique(np.clip(np.concatenate([edges, inner]), a, b))
    lo, hi = knots[:-1], knots[1:]
    keep = hi > lo
    lo, hi = lo[keep], hi[keep]
    mid, half = (lo + hi) / 2.0, (hi - lo) / 2.0
    xs = mid[:, None] + half[:, None] * _GL_X[None, :]  # nodes (in samples)
    ws = half[:, None] * _GL_W[None, :]
    dens = p.density(xs * Ts) * Ts  # density per sample
    n_taps = (k1 - k0 + 2) if fractional == "round" else (k1 - k0 + 1)
    w = np.zeros(n_taps)
    if fractional == "round":
        idx = np.floor(xs + 0.5).astype(int) - k0
        np.add.at(w, idx.ravel(), (dens * ws).ravel())
    elif fractional == "linear":
        # every sub-interval lies within one grid cell: use the cell of its midpoint
        left = np.broadcast_to(np.floor(mid).astype(int)[:, None], xs.shape)
        frac = xs - left
        np.add.at(w, (left - k0).ravel(), (dens * ws * (1.0 - frac)).ravel())
        np.add.at(w, (left + 1 - k0).ravel(), (dens * ws * frac).ravel())
    else:  # lagrange3: the density against the cubic Lagrange interpolation kernel
        cell = np.broadcast_to(np.floor(mid).astype(int)[:, None], xs.shape)
        first = np.maximum(cell - 1, 0)  # nodes first .. first + 3 (one-sided at the start: causal)
        w = np.zeros(n_taps + 3)
        base = (dens * ws).ravel()
        x_loc = (xs - first).ravel()
        for j in range(4):
            lj = np.ones_like(x_loc)
            for m in range(4):
                if m != j:
                    lj *= (x_loc - m) / (j - m)
            np.add.at(w, (first + j - k0).ravel() + 1, base * lj)
        k0 -= 1  # w[0] is sample k0 - 1 (zero unless the part starts past one sample)
        if k0 < 0:
            w, k0 = w[1:], 0
    total = w.sum()
    if total != 0.0:  # remove quadrature / numerical-convolution error: taps sum to the weight
        w *= p.weight / total
    return k0, w


def prewarped_step(S: Shaper, Ts: float) -> float:
    """The step of the plain bilinear transform that is Tustin prewarped at the shaper's (first) mode.

    ``s = (w0 / tan(w0 Ts / 2)) (z - 1) / (z + 1)`` is the bilinear transform with
    the step ``2 tan(w0 Ts / 2) / w0``; ``Ts`` itself for a shaper without modes.
    """
    if not S.modes:
        return Ts
    w0 = S.modes[0].omega
    return 2.0 * math.tan(w0 * Ts / 2.0) / w0


def iir_section(S: Shaper, Ts: float) -> tuple[np.ndarray, np.ndarray] | tuple[None, None]:
    if S.continuous is None:
        return None, None
    try:
        ct = S.continuous.to_scipy()
    except ValueError as exc:
        raise ValueError(
            "S.continuous contains delays (e.g. a product of a delay shaper and an IIR notch); only a "
            "delay-free IIR part can be discretised"
        ) from exc
    bz, az, _ = signal.cont2discrete((ct.num, ct.den), prewarped_step(S, Ts), method="bilinear")
    bz = np.atleast_1d(np.asarray(bz, dtype=float).ravel())
    az = np.atleast_1d(np.asarray(az, dtype=float).ravel())
    return bz / az[0], az / az[0]
