"""Certified root counts by the argument principle (step 1 of :func:`posicast.roots`).

The boundary is sampled adaptively until every segment ``[a, b]`` of length ``L``
passes the test ``M L / 2 + e < min(|h(a)|, |h(b)|)``, where ``M`` is a rigorous bound
of ``|h'|`` on the segment (:meth:`Evaluator.deriv_bound`, or next to a root the Taylor
bound :meth:`Evaluator.taylor_deriv_bound`) and ``e`` bounds the rounding error of the
evaluation.  Under that test ``h`` has no zero on the segment and its argument changes
by less than ``pi`` along it, so the sum of the principal increments is exactly
``2 pi`` times the number of roots inside.  A segment that cannot pass the test down to
a tiny length means a root on (or within rounding of) the boundary
(:class:`OnBoundary`); :func:`count_with_shifts` then moves that edge outward and
counts again ("shift and recount").
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from .checks import RootFindingError
from .evaluation import TWO_PI, Evaluator

__all__ = ["OnBoundary", "winding", "rect_corners", "count_in_rect", "count_with_shifts"]


class OnBoundary(Exception):
    """A root on (or within rounding of) a counting path, next to :attr:`point`."""

    def __init__(self, point: complex) -> None:
        super().__init__(point)
        self.point = point


def winding(ev: Evaluator, corners: Sequence[complex], step: float, min_len: float) -> int:
    """Certified winding number of ``h`` along the closed polygon ``corners``.

    Raises :class:`OnBoundary` with the offending point when a segment cannot
    be certified down to ``min_len`` (a root on or next to the path).
    """
    pts = []
    n_c = len(corners)
    for i in range(n_c):
        a, b = corners[i], corners[(i + 1) % n_c]
        n = max(2, int(math.ceil(abs(b - a) / step)))
        pts.append(a + (b - a) * np.arange(n) / n)
    z = np.concatenate(pts)
    za, zb = z, np.roll(z, -1)
    va, ma = ev.value(za)
    # (1e-10: a root that close is moved off at once; high up, the rounding level can be higher)
    small = np.abs(va) <= np.maximum(1e-10, 4.0 * ev.round_factor(np.abs(za))) * ma
    if np.any(small):  # a sample (numerically) on a root
        raise OnBoundary(complex(za[np.argmax(small)]))
    vb, mb = np.roll(va, -1), np.roll(ma, -1)
    total = 0.0
    # the Taylor bound (below) for segments that bisection alone has not settled in 8 rounds
    sharp_len = float(np.max(np.abs(zb - za))) / 256.0
    while za.size:
        L = np.abs(zb - za)
        # bring the endpoint values to the segment's scaling rho_seg <= rho(endpoint)
        a_min = np.minimum(za.real, zb.real)
        rho_seg = np.minimum(a_min, 0.0) * ev.tau_max
        fa = np.exp(rho_seg - np.minimum(za.real, 0.0) * ev.tau_max)
        fb = np.exp(rho_seg - np.minimum(zb.real, 0.0) * ev.tau_max)
        ha, hb = np.abs(va) * fa, np.abs(vb) * fb
        err = ev.round_factor(np.maximum(np.abs(za), np.abs(zb))) * np.maximum(ma * fa, mb * fb)
        M = ev.deriv_bound(za, zb)
        ok = 0.5 * M * L + err < np.minimum(ha, hb)
        # Segments failing the coarse bound next to a root: the Taylor bound keeps the cancellation
        # of h (decisive next to a multiple root), on segments short against the delays.
        # Only where bisection would still need many rounds: the coarse bound asks for segments
        # 16 times shorter (it is costly, and a simple root next to the path is settled in a few).
        i_s = np.flatnonzero(~ok & (L <= sharp_len))
        if i_s.size:
            hmin = np.minimum(ha[i_s], hb[i_s])
            Ls = L[i_s]
            keep = (Ls * ev.tau_max <= 1.0) & (hmin > err[i_s]) & (32.0 * (hmin - err[i_s]) < Ls * M[i_s])
            i_s = i_s[keep]
            if i_s.size:
                M2 = ev.taylor_deriv_bound(0.5 * (za[i_s] + zb[i_s]), 0.5 * L[i_s], rho_seg[i_s])
                ok[i_s] = 0.5 * M2 * L[i_s] + err[i_s] < np.minimum(ha[i_s], hb[i_s])
        if np.any(ok):
            total += float(np.sum(np.angle(vb[ok] / va[ok])))
        bad = ~ok
        if not np.any(bad):
            break
        za, zb, va, vb, ma, mb, L = za[bad], zb[bad], va[bad], vb[bad], ma[bad], mb[bad], L[bad]
        if np.any(L < min_len):
            i = int(np.argmin(L))
            raise OnBoundary(complex(0.5 * (za[i] + zb[i])))
        zm = 0.5 * (za + zb)
        vm, mm = ev.value(zm)
        za, zb = np.concatenate([za, zm]), np.concatenate([zm, zb])
        va, vb = np.concatenate([va, vm]), np.concatenate([vm, vb])
        ma, mb = np.concatenate([ma, mm]), np.concatenate([mm, mb])
    w = total / TWO_PI
    k = round(w)
    if abs(w - k) > 1e-6:  # cannot happen when every segment passed; kept as a guard
        raise RootFindingError(f"argument principle gave a non-integer winding {w:.6f}")
    return int(k)


def rect_corners(r: tuple[float, float, float, float]) -> list[complex]:
    """The corners of ``(re_min, re_max, im_min, im_max)``, counter-clockwise from the lower left."""
    a, b, c, d = r
    return [complex(a, c), complex(b, c), complex(b, d), complex(a, d)]


def count_in_rect(ev: Evaluator, rect: tuple[float, float, float, float], step: float) -> int:
    """Certified number of roots in ``rect`` (:class:`OnBoundary` when one lies on its edge)."""
    # a segment that must be shorter than 1e-7 of the rectangle means a root on
    # (or within rounding of) the edge: the caller moves the edge instead
    size = max(rect[1] - rect[0], rect[3] - rect[2])
    return winding(ev, rect_corners(rect), step, min_len=1e-7 * size)


def count_with_shifts(
    ev: Evaluator, rect: tuple[float, float, float, float], step: float, max_shifts: int = 8
) -> tuple[int, tuple[float, float, float, float], bool]:
    """Count roots in ``rect``; move an edge outward when a root sits on it."""
    a, b, c, d = rect
    shifted = False
    delta = 1e-4 * max(b - a, d - c)
    for _ in range(max_shifts + 1):
        try:
            return count_in_rect(ev, (a, b, c, d), step), (a, b, c, d), shifted
        except OnBoundary as hit:
            p = hit.point
            dist = {"a": abs(p.real - a), "b": abs(p.real - b), "c": abs(p.imag - c), "d": abs(p.imag - d)}
            nearest = min(dist, key=dist.__getitem__)
            # the nearest edge, and at a corner the other one too (a root next to a corner blocks both)
            for edge in [e for e in dist if e == nearest or dist[e] <= delta]:
                if edge == "a":
                    a -= delta
                elif edge == "b":
                    b += delta
                elif edge == "c":
                    c -= delta
                else:
                    d += delta
            shifted = True
            delta *= 2.0
    raise RootFindingError(
        f"could not find a root-free boundary near region {rect}: roots on every shifted edge"
    )
