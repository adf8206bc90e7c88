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
from typing import NamedTuple, Sequence

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

    The first samples are ``3 step`` apart.  A segment that fails the test is
    cut into as many equal pieces as the test asks for (``2 (min |h| - e) / M``
    long) when that is at most 8, rather than halved: the same test on every
    final segment, with fewer evaluations and rounds.
    """
    pts = []
    n_c = len(corners)
    for i in range(n_c):
        a, b = corners[i], corners[(i + 1) % n_c]
        n = max(2, int(math.ceil(abs(b - a) / (_FIRST_STEP * step))))
        pts.append(a + (b - a) * np.arange(n) / n)
    z = np.concatenate(pts)
    v, m, az, sh = ev.value_parts(z)
    # (1e-10: a root that close is moved off at once; high up, the rounding level can be higher)
    av = np.abs(v)
    small = av <= np.maximum(1e-10, 4.0 * ev.round_factor(az)) * m
    if small.any():  # a sample (numerically) on a root
        raise OnBoundary(complex(z[np.argmax(small)]))
    # per segment: the end points, their values, |values|, magnitudes, |z| and scaling exponents
    ca, fa = np.array([z, v]), np.array([av, m, az, sh])
    seg = _Segments(ca, np.roll(ca, -1, axis=1), fa, np.roll(fa, -1, axis=1))
    total = 0.0
    tau_max = ev.tau_max
    # the Taylor bound (below) for segments that bisection alone would not have settled in 8 rounds
    sharp_len = float(np.max(np.abs(seg.zb - seg.za))) / 256.0
    while True:
        za, zb = seg.za, seg.zb
        L = np.abs(zb - za)
        # bring the endpoint values to the segment's scaling rho_seg <= rho(endpoint)
        rho_seg = np.minimum(seg.sa, seg.sb)  # = min(0, min Re) tau_max
        fa = np.exp(rho_seg - seg.sa)
        fb = np.exp(rho_seg - seg.sb)
        ha, hb = seg.aa * fa, seg.ab * fb
        R = np.maximum(seg.za_abs, seg.zb_abs)
        err = ev.round_factor(R) * np.maximum(seg.ma * fa, seg.mb * fb)
        M = ev.deriv_bound_at(R, np.minimum(za.real, zb.real))
        hmin = np.minimum(ha, hb)
        ok = 0.5 * M * L + err < hmin
        # Segments failing the coarse bound next to a root: the Taylor bound keeps the cancellation
        # of h (decisive next to a multiple root), on segments short against the delays.
        # Only where bisection would still need many rounds: the coarse bound asks for segments
        # 16 times shorter (it is costly, and a simple root next to the path is settled in a few).
        bad = ~ok
        i_s = np.flatnonzero(bad & (L <= sharp_len))
        if i_s.size:
            hs, es, Ls = hmin[i_s], err[i_s], L[i_s]
            keep = (Ls * tau_max <= 1.0) & (hs > es) & (32.0 * (hs - es) < Ls * M[i_s])
            i_s = i_s[keep]
            if i_s.size:
                M2 = ev.taylor_deriv_bound(0.5 * (za[i_s] + zb[i_s]), 0.5 * L[i_s], rho_seg[i_s])
                ok[i_s] = 0.5 * M2 * L[i_s] + err[i_s] < hmin[i_s]
                bad = ~ok
        i_bad = np.flatnonzero(bad)
        if i_bad.size < ok.size:
            total += float(np.add.reduce(np.angle(seg.vb[ok] / seg.va[ok])))
        if not i_bad.size:
            break
        Lb = L[i_bad]
        if Lb.min() < min_len:
            i = int(np.argmin(Lb))
            raise OnBoundary(complex(0.5 * (za[i_bad[i]] + zb[i_bad[i]])))
        # pieces the test asks for: 0.5 M l + err < min |h| at the ends needs l < 2 (min |h| - err) / M
        # (an estimate: the pieces are tested again), from 2 to 8; where it asks for more (or for no
        # length at all: an end at rounding level), |h| is small at an end, next to a root, and
        # halving keeps the extra points where they are needed
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            want = np.ceil(Lb * M[i_bad] / (2.0 * (hmin[i_bad] - err[i_bad])))
        want[~(want <= _MAX_PIECES)] = 2.0
        seg = seg.cut(i_bad, np.maximum(want, 2.0).astype(np.intp), ev)
    w = total / TWO_PI
    k = round(w)
    if abs(w - k) > 1e-6:  # cannot happen when every segment passed; kept as a guard
        raise RootFindingError(f"argument principle gave a non-integer winding {w:.6f}")
    return int(k)


# the first samples are 3 steps apart (the cuts refine where the test asks: 3x fewer evaluations for the
# tuner's unstable_count on the crane, where far from the roots a segment of many steps passes)
_FIRST_STEP = 3.0
_MAX_PIECES = 8.0  # a failing segment is cut into at most this many pieces (else halved)


class _Segments(NamedTuple):
    """The segments of a boundary walk not yet certified.  At the end points ``a`` and ``b``:
    ``c*`` holds rows ``z, h rho``; ``f*`` holds rows ``|h rho|``, the scaled magnitude, ``|z|`` and
    the scaling exponent (few arrays: a walk's rounds are small, numpy calls dominate)."""

    ca: np.ndarray
    cb: np.ndarray
    fa: np.ndarray
    fb: np.ndarray

    za = property(lambda self: self.ca[0])
    zb = property(lambda self: self.cb[0])
    va = property(lambda self: self.ca[1])
    vb = property(lambda self: self.cb[1])
    aa = property(lambda self: self.fa[0])
    ab = property(lambda self: self.fb[0])
    ma = property(lambda self: self.fa[1])
    mb = property(lambda self: self.fb[1])
    za_abs = property(lambda self: self.fa[2])
    zb_abs = property(lambda self: self.fb[2])
    sa = property(lambda self: self.fa[3])
    sb = property(lambda self: self.fb[3])

    def cut(self, idx: np.ndarray, n: np.ndarray, ev: Evaluator) -> "_Segments":
        """Segments ``idx``, segment ``idx[i]`` cut into ``n[i]`` equal pieces (new points evaluated)."""
        ca, cb, fa, fb = self.ca[:, idx], self.cb[:, idx], self.fa[:, idx], self.fb[:, idx]
        za, zb = ca[0], cb[0]
        total = int(n.sum())
        owner = np.repeat(np.arange(idx.size), n)
        first = np.cumsum(n) - n  # where each segment's pieces start
        last = first + n - 1
        j = np.arange(total) - first[owner]
        inner = j > 0
        o = owner[inner]
        zi = za[o] + (zb[o] - za[o]) * (j[inner] / n[o])
        vi, mi, azi, shi = ev.value_parts(zi)
        out = []
        for a_old, b_old, new in ((ca, cb, np.array([zi, vi])), (fa, fb, np.array([np.abs(vi), mi, azi, shi]))):
            a = np.empty((a_old.shape[0], total), dtype=a_old.dtype)
            a[:, first] = a_old
            a[:, inner] = new
            b = np.empty_like(a)
            b[:, :-1] = a[:, 1:]
            b[:, last] = b_old
            out += [a, b]
        return _Segments(out[0], out[1], out[2], out[3])


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
