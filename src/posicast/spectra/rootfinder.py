"""Certified roots of quasi-polynomials in a rectangle.

``roots(h, region)`` returns every root of ``h(s) = sum_i p_i(s) exp(-s tau_i)``
in ``re_min <= Re s <= re_max``, ``im_min <= Im s <= im_max`` together with a
*certified* count.  The method, in four steps:

1. **Certified count.**  The argument principle on the rectangle's boundary.
   The boundary is sampled adaptively until every segment ``[a, b]`` of length
   ``L`` passes the test ``M L / 2 + e < min(|h(a)|, |h(b)|)``, where ``M`` is a
   rigorous bound of ``|h'|`` on the segment (absolute coefficients, the
   segment's largest ``|s|`` and smallest ``Re s``) and ``e`` bounds the
   rounding error of the evaluation (including the phase of ``exp(-s tau)``,
   rounded to ``eps |s| tau``, which dominates at high frequency).  Next to a
   root, where that bound of ``|h'|`` is too coarse (it ignores the cancellation
   of ``h`` near a multiple root), ``M`` comes from the Taylor coefficients of
   ``h`` about the segment's midpoint.  Under that test ``h`` has no zero on the
   segment and its argument changes by less than ``pi`` along it, so the sum
   of the principal increments is exactly ``2 pi`` times the number of roots
   inside.  A segment that cannot pass the test down to a tiny length means a
   root on (or within rounding of) the boundary: that edge is moved outward
   and the count is redone ("shift and recount"); the region actually used is
   returned.
2. **Candidates.**  As in QPmR (seed 000 ref. [22], Vyhlídal & Zítek 2009) the
   region is covered by a grid whose step follows the delays; the discrete
   winding of ``h`` around every grid cell flags the cells that hold roots.
3. **Refinement.**  Vectorised Newton from the flagged cells; converged points
   are merged, clusters (multiple roots) get their multiplicity from a small
   certified count around them and are polished by Newton on
   ``h^{(m-1)}``.  A cluster whose points are too scattered for that (Newton
   stalls ``(rounding)^(1/m)`` away from an ``m``-fold root) is centred on the
   root of ``h^{(k)}`` next to it; one member already taken for a simple root is
   taken back into it.  Every root is returned with its relative residual
   ``|h(r)| / sum_i |p_i(r)| |exp(-r tau_i)|``.
4. **Reconciliation.**  When the roots found do not add up to the certified
   count, the rectangle is split, each part is counted (certified) and searched
   on a finer grid, recursively, until they do.  If that fails within the
   budget a :class:`RootFindingError` says so: a silent miss is impossible.

Evaluation is scaled by the positive factor ``exp(min(0, Re s) tau_max)`` so
that no exponential overflows; a positive factor changes neither the argument
nor the roots.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
from numpy.polynomial import polynomial as P

from .. import _validate as v
from ..core.quasipoly import QuasiPolynomial
from ..core.transfer import TransferFunction

__all__ = [
    "roots",
    "Roots",
    "RootFindingError",
    "BudgetExceeded",
    "as_quasipolynomial",
    "check_region",
    "check_budget",
    "check_ignore",
    "check_range",
    "certified_radius",
]

_EPS = np.finfo(float).eps
_TWO_PI = 2.0 * math.pi
_MAX_GRID = 2e7  # grid points held at once (complex: 320 MB)


class RootFindingError(RuntimeError):
    """The roots could not be certified (count and roots found disagree, or no clean boundary)."""


class BudgetExceeded(RootFindingError):
    """The region needs more evaluations or time than the budget allows."""


# ---------------------------------------------------------------------------- input checks
def as_quasipolynomial(h: Any, name: str = "h") -> QuasiPolynomial:
    """Return ``h`` as a nonzero :class:`QuasiPolynomial` or raise a clear error."""
    if isinstance(h, QuasiPolynomial):
        q = h
    elif isinstance(h, TransferFunction) or hasattr(h, "transfer"):
        raise TypeError(
            f"{name} must be a QuasiPolynomial; for a transfer function pass its .num (zeros) "
            "or .den (poles), or use posicast.spectra.zeros / poles"
        )
    elif isinstance(h, tuple) and len(h) == 2:
        q = QuasiPolynomial(h[0], h[1])
    else:
        raise TypeError(f"{name} must be a QuasiPolynomial or a (coeffs, delays) pair, got {type(h).__name__}")
    if q.is_zero:
        raise ValueError(f"{name} is identically zero: every s is a root")
    return q


def check_region(region: Any) -> tuple[float, float, float, float]:
    """Validate ``(re_min, re_max, im_min, im_max)``: four finite reals, nonempty."""
    if isinstance(region, (str, bytes)) or not hasattr(region, "__len__"):
        raise TypeError("region must be four real numbers (re_min, re_max, im_min, im_max), "
                        f"got {type(region).__name__}")
    items = list(region)
    if len(items) != 4:
        raise ValueError(f"region must have 4 entries (re_min, re_max, im_min, im_max), got {len(items)}")
    names = ("re_min", "re_max", "im_min", "im_max")
    vals = [v.finite_real(x, f"region {n}") for x, n in zip(items, names)]
    a, b, c, d = vals
    if not a < b:
        raise ValueError(f"region: re_min must be < re_max, got re_min={a:g}, re_max={b:g}")
    if not c < d:
        raise ValueError(f"region: im_min must be < im_max, got im_min={c:g}, im_max={d:g}")
    return a, b, c, d


def check_budget(max_evaluations: Any, timeout: Any = 1.0) -> tuple[float, float]:
    """``max_evaluations`` and ``timeout`` as finite positive floats (TypeError/ValueError otherwise)."""
    m = v.positive(max_evaluations, "max_evaluations")
    if m < 1:
        raise ValueError(f"max_evaluations must be >= 1, got {m:g}")
    return m, v.positive(timeout, "timeout")


def check_ignore(ignore: Any) -> np.ndarray:
    """``ignore`` as a flat array of finite complex points (TypeError/ValueError naming ``ignore``)."""
    try:
        arr = v.complex_array(ignore, "ignore")
    except ValueError:
        raise ValueError("ignore must contain finite points (no NaN or inf)") from None
    return np.atleast_1d(arr).ravel()


def check_range(q: QuasiPolynomial, rect: tuple[float, float, float, float]) -> None:
    """Refuse a region where the polynomial terms leave the float range (with the size they reach).

    The exponentials are scaled to modulus <= 1 everywhere, but ``|c_j| |s|^j`` (and the
    derivative bounds, one power more) must stay far below 1e308.
    """
    a, b, c, d = rect
    R = max(abs(complex(x, y)) for x in (a, b) for y in (c, d))
    if R <= 1.0:
        return
    nz = np.abs(q.coeffs) > 0
    j = np.nonzero(nz)[1]
    logmag = float(np.max(np.log10(np.abs(q.coeffs[nz])) + (j + 1) * math.log10(R)))
    if logmag > 250.0:
        deg = int(j.max())
        lim = 10 ** ((250.0 - float(np.max(np.log10(np.abs(q.coeffs[nz]))))) / (deg + 1))
        raise ValueError(
            f"region {rect} reaches |s| = {R:.3g}, where the degree-{deg} terms of h grow to about 1e{logmag:.0f} "
            f"and leave the float range; keep the region within |s| < {lim:.3g}"
        )


# ---------------------------------------------------------------------------- scaled evaluation
class _Evaluator:
    """Scaled evaluation of ``h``, ``h'`` and the derivative bound, counting evaluations."""

    def __init__(self, q: QuasiPolynomial, budget: int, deadline: float) -> None:
        self.q = q
        self.dq = q.derivative()
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
        return self._taylor_rows

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
        l = np.arange(rows[0][1].shape[1])[:, None]
        j0 = K + 1 - l  # the tail: k = l + j > K
        for tau, pder, apder, E, aE in rows:
            e0 = np.exp(-c * tau + shift)
            pl = P.polyval(c, pder) * e0  # (d + 1, n): p^{(l)}(c) / l!, scaled
            pa = P.polyval(absc, apder) * np.abs(e0)
            A += E @ pl
            S += aE @ pa
            if tau > 0:
                # rho^(l-1) sum_{j >= j0} (l + j) x^j / j!, x = rho tau <= 1/2: ratio <= 2 x / (j0 + 1)
                x = rho[None, :] * tau
                t0 = (l + j0) * x**j0 * self._inv_fact[j0]
                tail += np.sum(pa * rho[None, :] ** (l - 1) * t0 / (1.0 - 2.0 * x / (j0 + 1)), axis=0)
        k = np.arange(1, K + 1)[:, None]
        err = self.round_factor(absc + rho) * (1.0 + K) * S[1:]
        return np.sum(k * (np.abs(A[1:]) + err) * rho[None, :] ** (k - 1), axis=0) + tail

    def round_factor(self, r: np.ndarray | float) -> np.ndarray | float:
        """Bound of the relative rounding error of a scaled evaluation at ``|s| = r``.

        ``8 eps`` per term (polynomial and exponential), plus the phase: ``s tau`` is rounded
        to ``eps |s| tau``, which is the relative error of ``exp(-s tau)`` (it dominates at
        high frequency, e.g. 1e-12 at ``|s| tau = 1e4``).
        """
        return _EPS * (8.0 * self.n_terms + 2.0 * np.asarray(r) * self.tau_max)

    def _charge(self, n: int) -> None:
        self.evaluations += n
        if self.evaluations > self.budget:
            raise BudgetExceeded(
                f"root finding needed more than max_evaluations={self.budget:.3g} evaluations; "
                "shrink the region or raise max_evaluations"
            )
        if time.monotonic() > self.deadline:
            raise BudgetExceeded("root finding exceeded its time budget (timeout); shrink the region or raise timeout")

    def _exps(self, s: np.ndarray) -> np.ndarray:
        # exp(-s tau_k) * rho(s) with rho(s) = exp(min(0, Re s) tau_max): every factor has modulus <= 1
        shift = np.minimum(s.real, 0.0) * self.tau_max
        return np.exp(-np.multiply.outer(self.tau, s) + shift)

    def value(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Scaled ``h(s) rho(s)`` and the scaled magnitude ``sum |terms| rho(s)``."""
        s = np.asarray(s, dtype=complex)
        self._charge(s.size)
        e = self._exps(s)
        polys = P.polyval(s, self.c.T)
        val = np.sum(polys * e, axis=0)
        mag = np.sum(P.polyval(np.abs(s), self.abs_c.T) * np.abs(e), axis=0)
        return val, mag

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
        f = _scaled_eval(q, s, shift)
        df = _scaled_eval(dq, s, shift)
        with np.errstate(divide="ignore", invalid="ignore"):
            return f / df

    def deriv_bound(self, za: np.ndarray, zb: np.ndarray) -> np.ndarray:
        """Bound of ``|h'| rho_seg`` on segments, ``rho_seg = exp(min(0, min Re) tau_max)``."""
        R = np.maximum(np.abs(za), np.abs(zb))
        a = np.minimum(za.real, zb.real)
        e = np.exp(-np.multiply.outer(self.tau, a) + np.minimum(a, 0.0) * self.tau_max)
        return np.sum(P.polyval(R, self.deriv_bound_coeffs.T) * e, axis=0)


def _scaled_eval(q: QuasiPolynomial, s: np.ndarray, shift: np.ndarray) -> np.ndarray:
    if q.is_zero:
        return np.zeros(s.shape, dtype=complex)
    e = np.exp(-np.multiply.outer(q.delays, s) + shift)
    return np.sum(P.polyval(s, q.coeffs.T) * e, axis=0)


# ---------------------------------------------------------------------------- certified winding
class _OnBoundary(Exception):
    def __init__(self, point: complex) -> None:
        super().__init__(point)
        self.point = point


def _winding(ev: _Evaluator, corners: Sequence[complex], step: float, min_len: float) -> int:
    """Certified winding number of ``h`` along the closed polygon ``corners``.

    Raises :class:`_OnBoundary` with the offending point when a segment cannot
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
        raise _OnBoundary(complex(za[np.argmax(small)]))
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
            raise _OnBoundary(complex(0.5 * (za[i] + zb[i])))
        zm = 0.5 * (za + zb)
        vm, mm = ev.value(zm)
        za, zb = np.concatenate([za, zm]), np.concatenate([zm, zb])
        va, vb = np.concatenate([va, vm]), np.concatenate([vm, vb])
        ma, mb = np.concatenate([ma, mm]), np.concatenate([mm, mb])
    w = total / _TWO_PI
    k = round(w)
    if abs(w - k) > 1e-6:  # cannot happen when every segment passed; kept as a guard
        raise RootFindingError(f"argument principle gave a non-integer winding {w:.6f}")
    return int(k)


def _rect_corners(r: tuple[float, float, float, float]) -> list[complex]:
    a, b, c, d = r
    return [complex(a, c), complex(b, c), complex(b, d), complex(a, d)]


def _count(ev: _Evaluator, rect: tuple[float, float, float, float], step: float) -> int:
    # a segment that must be shorter than 1e-7 of the rectangle means a root on
    # (or within rounding of) the edge: the caller moves the edge instead
    size = max(rect[1] - rect[0], rect[3] - rect[2])
    return _winding(ev, _rect_corners(rect), step, min_len=1e-7 * size)


def _count_with_shifts(
    ev: _Evaluator, rect: tuple[float, float, float, float], step: float, max_shifts: int = 8
) -> tuple[int, tuple[float, float, float, float], bool]:
    """Count roots in ``rect``; move an edge outward when a root sits on it."""
    a, b, c, d = rect
    shifted = False
    delta = 1e-4 * max(b - a, d - c)
    for _ in range(max_shifts + 1):
        try:
            return _count(ev, (a, b, c, d), step), (a, b, c, d), shifted
        except _OnBoundary as hit:
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


# ---------------------------------------------------------------------------- candidates and Newton
def _grid_step(q: QuasiPolynomial, rect: tuple[float, float, float, float]) -> float:
    w, h = rect[1] - rect[0], rect[3] - rect[2]
    step = max(w, h) / 16.0
    tau_max = float(q.delays[-1])
    if tau_max > 0:
        # roots of a chain are about 2 pi / tau apart: six grid steps per spacing
        step = min(step, math.pi / (3.0 * tau_max))
    return step


def _grid_shape(rect: tuple[float, float, float, float], step: float) -> tuple[int, int]:
    # at least 5 nodes a side: a thin rectangle gets elongated cells, not a finer grid
    nx = max(5, int(math.ceil((rect[1] - rect[0]) / step)) + 1)
    ny = max(5, int(math.ceil((rect[3] - rect[2]) / step)) + 1)
    return nx, ny


def _grid_candidates(ev: _Evaluator, rect: tuple[float, float, float, float], step: float) -> np.ndarray:
    a, b, c, d = rect
    nx, ny = _grid_shape(rect, step)
    x = np.linspace(a, b, nx)
    y = np.linspace(c, d, ny)
    S = x[None, :] + 1j * y[:, None]
    # evaluate in blocks of rows: the per-delay intermediates stay near 1e6 points
    H = np.empty(S.shape, dtype=complex)
    rows = max(1, int(1_000_000 // (nx * max(1, ev.q.coeffs.shape[0]))))
    for i in range(0, ny, rows):
        H[i : i + rows], _ = ev.value(S[i : i + rows])
    with np.errstate(divide="ignore", invalid="ignore"):
        dh = np.angle(H[:, 1:] / H[:, :-1])
        dv = np.angle(H[1:, :] / H[:-1, :])
    wind = (dh[:-1, :] + dv[:, 1:] - dh[1:, :] - dv[:, :-1]) / _TWO_PI
    wind = np.nan_to_num(wind, nan=1.0)
    iy, ix = np.nonzero(np.abs(wind) > 0.5)
    centers = 0.5 * (x[ix] + x[ix + 1]) + 0.5j * (y[iy] + y[iy + 1])
    # zero samples (a root exactly on a grid node) are candidates too
    zy, zx = np.nonzero(H == 0)
    return np.concatenate([centers, S[zy, zx]])


def _newton(
    ev: _Evaluator, z: np.ndarray, max_step: float | np.ndarray, q: QuasiPolynomial | None = None, iters: int = 60
) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised damped Newton (on ``h``, or on ``q``); returns points and a converged mask."""
    dq = None if q is None else q.derivative()
    max_step = np.broadcast_to(np.asarray(max_step, dtype=float), np.shape(z)).copy()
    z = np.array(z, dtype=complex)
    active = np.ones(z.shape, dtype=bool)
    conv = np.zeros(z.shape, dtype=bool)
    for _ in range(iters):
        if not np.any(active):
            break
        za = z[active]
        st = ev.newton_step(za, q, dq)
        bad = ~np.isfinite(st)
        st[bad] = 0.0
        lim = max_step[active]
        big = np.abs(st) > lim
        st[big] *= lim[big] / np.abs(st[big])
        za = za - st
        z[active] = za
        done = (np.abs(st) <= 4 * _EPS * np.maximum(np.abs(za), 1.0)) & ~bad
        idx = np.flatnonzero(active)
        conv[idx[done]] = True
        active[idx[done | bad]] = False
    # one more step for the stragglers that are close: accept small steps
    if np.any(active):
        za = z[active]
        st = ev.newton_step(za, q, dq)
        ok = np.isfinite(st) & (np.abs(st) <= 1e-9 * np.maximum(np.abs(za), 1.0))
        idx = np.flatnonzero(active)
        conv[idx[ok]] = True
    return z, conv


@dataclass
class _Found:
    point: complex
    mult: int
    radius: float = 0.0  # a Pellet disk |s - centre| < radius certified to hold exactly ``mult`` roots
    centre: complex = 0j


def _rel_residual(q: QuasiPolynomial, z: np.ndarray) -> np.ndarray:
    z = np.asarray(z, dtype=complex)
    if z.size == 0:
        return np.zeros(0)
    tau_max = float(q.delays[-1])
    shift = np.minimum(z.real, 0.0) * tau_max
    e = np.exp(-np.multiply.outer(q.delays, z) + shift)
    val = np.abs(np.sum(P.polyval(z, q.coeffs.T) * e, axis=0))
    mag = np.sum(P.polyval(np.abs(z), np.abs(q.coeffs).T) * np.abs(e), axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(mag > 0, val / mag, val)


def _inside(z: np.ndarray, rect: tuple[float, float, float, float]) -> np.ndarray:
    a, b, c, d = rect
    return (z.real >= a) & (z.real <= b) & (z.imag >= c) & (z.imag <= d)


def _taylor_and_tail(
    q: QuasiPolynomial, c: complex, order: int, R0: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Taylor coefficients ``a_k`` of ``h`` about ``c`` (k <= order), their rounding errors and a
    bound ``B`` of ``|h|`` on ``|s - c| = R0``, all times one positive factor ``exp(kappa)``.

    ``kappa = min(0, Re c - R0) tau_max`` keeps every exponential at most 1 (no overflow
    far left with long delays); a common positive factor changes no Pellet/Rouché test.
    The rounding error counts the sums and the phase of ``exp(-c tau)``, rounded to
    ``eps |c| tau`` (see :meth:`_Evaluator.round_factor`).
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
            pt[l] = P.polyval(c, prow) * inv_fact[l]
            pabs[l] = P.polyval(abs(c), np.abs(prow)) * inv_fact[l]
            prow = P.polyder(prow) if prow.size > 1 else np.zeros(1)
        et = (-tau) ** np.arange(K) * inv_fact
        e0 = np.exp(-c * tau + kappa)
        a += e0 * np.convolve(pt, et)[:K]
        scale += abs(e0) * np.convolve(pabs, np.abs(et))[:K]
        B += float(P.polyval(abs(c) + R0, np.abs(row))) * math.exp(-(c.real - R0) * tau + kappa)
    err = _EPS * (8.0 * (order + q.coeffs.size) + 2.0 * abs(c) * tau_max) * scale
    return a, err, np.abs(a), B


def _pellet(q: QuasiPolynomial, c: complex, rho_max: float, order: int = 16) -> tuple[int, float, float] | None:
    """Certified number of roots in a small disk about ``c`` (Rouché/Pellet test).

    With the Taylor coefficients ``a_k`` of ``h`` about ``c``, if for some
    radius ``rho`` one term dominates, ``|a_m| rho^m > sum_{k != m} |a_k| rho^k``
    plus rounding errors and a Cauchy bound of the tail beyond ``order``, then
    ``h`` has exactly ``m`` roots in ``|s - c| < rho``.

    Radii are tried from small to large.  Returns ``(m, rho, rho_iso)``: the
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
    for j in range(39, -1, -1):
        rho = rho_max * 10.0 ** (-j / 4.0)
        x = rho / R0
        tail = B * x ** (order + 1) / (1.0 - x)
        terms = (absa + err) * rho**k
        m = int(np.argmax(absa * rho**k))
        lhs = (absa[m] - err[m]) * rho**m
        rhs = float(np.sum(terms) - terms[m]) + tail
        if lhs > rhs:
            certified.append((rho, m))
    if not certified:
        return None
    first = next((i for i, (_, m) in enumerate(certified) if m >= 1), None)
    if first is None:
        return 0, certified[-1][0], certified[-1][0]
    m, rho = certified[first][1], certified[first][0]
    rho_iso = rho
    for r2, m2 in certified[first + 1 :]:
        if m2 != m:
            break
        rho_iso = r2
    return m, rho, rho_iso


def certified_radius(q: QuasiPolynomial, c: complex, m: int, rho_max: float, order: int = 16) -> float | None:
    """Smallest radius (within a factor 2) of a disk about ``c`` certified to hold exactly ``m`` roots.

    The Pellet/Rouché test of :func:`_pellet` for the term ``m``: with the
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
    est = max([((absa[k] + err[k]) / lead) ** (1.0 / (m - k)) for k in range(m)] + [1e-16 * rho_max])
    if est > rho_max:
        return None
    k = np.arange(order + 1)
    n = int(math.floor(4.0 * math.log2(rho_max / est))) + 1
    rho = est * 2.0 ** (np.arange(min(n, 400)) / 4.0)  # steps of 2^(1/4)
    x = rho / R0
    tail = B * x ** (order + 1) / (1.0 - x)
    terms = (absa + err)[None, :] * rho[:, None] ** k[None, :]
    ok = lead * rho**m > np.sum(terms, axis=1) - terms[:, m] + tail
    return float(rho[np.argmax(ok)]) if np.any(ok) else None


def _cluster_rho_max(simple_pts: np.ndarray, centre: complex, step: float) -> float:
    """Largest Pellet radius for a cluster: well short of the nearest simple root and of the grid step."""
    lim = [0.25 * step, 0.05 * max(1.0, abs(centre))]
    if simple_pts.size:
        lim.append(0.4 * float(np.min(np.abs(simple_pts - centre))))
    return min(lim)


class _Solver:
    def __init__(self, ev: _Evaluator, rect: tuple[float, float, float, float], step: float) -> None:
        self.ev = ev
        self.rect = rect
        self.step = step
        self.found: list[_Found] = []
        # a root of h has multiplicity at most sum_k (deg p_k + 1) - 1 (Polya-Szego bound)
        self.max_cluster = min(40, int(ev.q.coeffs.size))
        # roots of a chain are about 2 pi / tau apart (see _grid_step); a polynomial has no such scale
        self.delay_step = math.pi / (3.0 * ev.tau_max) if ev.tau_max > 0 else math.inf

    # merge newly converged points into the list of distinct roots
    def absorb(self, pts: np.ndarray) -> None:
        pts = pts[_inside(pts, self.rect)]
        if pts.size == 0:
            return
        q = self.ev.q
        # An exact root at s = 0 of an h whose every term vanishes there (a loop with an
        # integrator and a distributed shaper) is reached as z ~ 1e-32, where |h| and the
        # term scale are both rounding: snap it onto 0, where the residual is exact.
        if q(0.0) == 0:
            pts = np.where(np.abs(pts) <= 1e-13, 0.0 + 0.0j, pts)
        pts = pts[_rel_residual(q, pts) <= 1e-6]
        # cluster: points closer than tol are one root (or one cluster of roots)
        order = np.argsort(pts.real + 1e-3 * pts.imag)
        pts = pts[order]
        if pts.size == 0:
            return
        # vectorised against the roots already found (a search can hold thousands)
        known = np.array([f.point for f in self.found], dtype=complex)
        centres = np.array([f.centre for f in self.found], dtype=complex)
        radii = np.array([f.radius for f in self.found])
        tol_known = 1e-7 * np.maximum(1.0, np.abs(known))
        new = np.empty(pts.size, dtype=complex)
        n_new = 0
        for p in pts:
            tol = 1e-7 * max(1.0, abs(p))
            # a point inside a cluster's certified disk is one of the roots already counted there
            # (Newton stalls about sqrt(eps) away from a double root, farther than tol)
            if known.size and np.any((np.abs(p - known) <= np.maximum(tol, tol_known)) | (np.abs(p - centres) < radii)):
                continue
            if n_new and np.any(np.abs(p - new[:n_new]) <= np.maximum(tol, 1e-7 * np.maximum(1.0, np.abs(new[:n_new])))):
                continue
            new[n_new] = p
            n_new += 1
        self.found.extend(_Found(complex(p), 0) for p in new[:n_new])

    def classify(self) -> None:
        """Give every new root its multiplicity.

        A point where ``|h'|`` is well above its rounding scale is a simple
        root.  The others are grouped into clusters; a certified count on a
        small box around each cluster gives its multiplicity ``m`` (minus any
        simple root inside), and Newton on ``h^{(m-1)}`` polishes it.
        """
        ev = self.ev
        new = [f for f in self.found if f.mult == 0]
        if not new:
            return
        z = np.array([f.point for f in new])
        shift = np.minimum(z.real, 0.0) * ev.tau_max
        dval = np.abs(_scaled_eval(ev.dq, z, shift))
        dmag = ev.deriv_bound(z, z)
        simple = dval > 1e-5 * dmag
        for f, is_simple in zip(new, simple):
            if is_simple:
                f.mult = 1
        suspects = [f for f, is_simple in zip(new, simple) if not is_simple]
        polish: dict[int, list[tuple[complex, float, float]]] = {}
        if suspects:
            # arrays (not lists searched per suspect): a search can hold thousands of clusters
            sus_pts = np.array([g.point for g in suspects])
            sus_alive = np.ones(sus_pts.size, dtype=bool)
            known = [g for g in self.found if g.mult >= 1]
            known_pts = np.array([g.point for g in known], dtype=complex)
            known_simple = np.array([g.mult == 1 for g in known], dtype=bool)
            known_alive = np.ones(known_pts.size, dtype=bool)
        for i, f in enumerate(suspects):
            if not sus_alive[i]:
                continue
            sus_alive[i] = False
            rc = min(1e-3 * max(1.0, abs(f.point)), 0.25 * self.step)
            idx = np.flatnonzero(sus_alive & (np.abs(sus_pts - f.point) <= 2 * rc))
            sus_alive[idx] = False
            group = [f] + [suspects[j] for j in idx]
            centre = complex(np.mean([g.point for g in group]))
            sel = known_alive & known_simple
            rho_max = _cluster_rho_max(known_pts[sel], centre, self.step)
            got = _pellet(ev.q, centre, rho_max)
            if got is None:
                # A cluster split by rounding (e.g. the fourfold ZV^4 zeros high up, where the float
                # delays are no longer exactly commensurate) can have had one member taken for a
                # simple root by an earlier pass; that root then shrinks rho_max below the cluster.
                # Take the roots already found within the cluster scale into the cluster and retry.
                near = np.flatnonzero(known_alive & (np.abs(known_pts - centre) <= rc))
                if near.size:
                    centre = complex(np.mean(np.concatenate([[g.point for g in group], known_pts[near]])))
                    sel = known_alive & known_simple
                    sel[near] = False
                    rho_max = _cluster_rho_max(known_pts[sel], centre, self.step)
                    got = _pellet(ev.q, centre, rho_max)
                    if got is not None and got[0] >= 1:
                        for j in near:
                            known[j].mult = -1
                        known_alive[near] = False
            if got is None:
                # Newton stalls about (rounding)^(1/m) away from an m-fold root, scattered around it
                # (1e-2 for a sixfold root), so the mean of the points found can be too far off for a
                # Pellet disk.  The root of h^(k) next to them is the cluster's centre for k = m - 1.
                # The disk may also need to be wider than a small region's grid step (a sixfold
                # cluster is 0.05 wide at s = -3): bounded by the delays' step instead, and short of
                # every root already known (clusters included), so that no disk counts one twice.
                # (A sixfold cluster high up, where the phase of exp(-s tau) is rounded to 1e-12, is
                # 0.04 wide and needs a disk of 0.3: up to the delays' step, a sixth of a chain's spacing.)
                sel = known_alive.copy()
                wide = 4.0 * max(self.step, self.delay_step)
                rho_c = _cluster_rho_max(known_pts[sel], centre, wide)
                for kd in range(0, self.max_cluster):
                    dk = ev.q.derivative(kd)
                    if dk.is_zero:
                        break
                    if kd == 0:
                        c2 = centre  # first the mean itself, in the wider disk
                    else:
                        # a few steps suffice for a centre (Newton is linear on a multiple root of h^(k))
                        zc, _ = _newton(ev, np.array([centre]), rho_c, q=dk, iters=12)
                        if not np.isfinite(zc[0]) or abs(zc[0] - centre) > rho_c:
                            continue
                        c2 = complex(zc[0])
                    got = _pellet(ev.q, c2, _cluster_rho_max(known_pts[sel], c2, wide))
                    if got is not None and got[0] >= 1:
                        centre = c2
                        break
                    got = None
            if got is None:
                raise RootFindingError(f"could not isolate the root cluster near {centre:.6g}")
            m, r, r_iso = got
            for g in group:
                g.mult = -1  # replaced by one representative below
            if m <= 0:
                continue
            # other suspects in the isolation disk are among these m roots: one cluster, counted once
            inside = np.flatnonzero(sus_alive & (np.abs(sus_pts - centre) < r_iso))
            for j in inside:
                suspects[j].mult = -1
            sus_alive[inside] = False
            polish.setdefault(m, []).append((centre, r, r_iso))
        # polish every cluster of multiplicity m at once, on h^{(m-1)} where an m-fold root is simple
        for m, items in polish.items():
            centres = np.array([c for c, _, _ in items])
            radii = np.array([r for _, r, _ in items])
            z2, ok = _newton(ev, centres, radii, q=ev.q.derivative(m - 1) if m > 1 else None)
            good = ok & (np.abs(z2 - centres) < radii)
            for c, zz, g, (_, _, r_iso) in zip(centres, z2, good, items):
                self.found.append(_Found(complex(zz) if g else complex(c), m, float(r_iso), complex(c)))
        self.found = [f for f in self.found if f.mult > 0]

    def n_in(self, rect: tuple[float, float, float, float]) -> int:
        return sum(f.mult for f in self.found if _inside(np.array([f.point]), rect)[0])

    def search(self, rect: tuple[float, float, float, float], step: float) -> None:
        cand = _grid_candidates(self.ev, rect, step)
        if cand.size:
            z, ok = _newton(self.ev, cand, max_step=2.0 * step)
            # multiple roots stall Newton at rounding level: keep those points too
            # (the rounding level grows with |s| tau: the phase of exp(-s tau) is rounded)
            ok |= _rel_residual(self.ev.q, z) <= np.maximum(1e-12, 64.0 * self.ev.round_factor(np.abs(z)))
            self.absorb(z[ok])
            self.classify()

    def reconcile(self, rect: tuple[float, float, float, float], count: int, step: float, depth: int) -> None:
        have = self.n_in(rect)
        if have == count:
            return
        if depth > 24:
            raise RootFindingError(
                f"could not isolate the roots in {rect}: argument principle counts {count}, found {have}"
            )
        if have > count:
            raise RootFindingError(
                f"inconsistent roots in {rect}: argument principle counts {count} but {have} roots were "
                "refined there (clustered or ill-conditioned roots)"
            )
        a, b, c, d = rect
        # split off-centre (an arbitrary irrational fraction) along the longer side
        for frac in (0.5 + 0.0731, 0.5 - 0.1127, 0.5 + 0.2213, 0.3):
            try:
                if b - a >= d - c:
                    m = a + frac * (b - a)
                    kids = [(a, m, c, d), (m, b, c, d)]
                else:
                    m = c + frac * (d - c)
                    kids = [(a, b, c, m), (a, b, m, d)]
                sub = [min(step, 0.5 * max(k[1] - k[0], k[3] - k[2])) for k in kids]
                counts = [_count(self.ev, k, st) for k, st in zip(kids, sub)]
                break
            except _OnBoundary:
                continue
        else:
            raise RootFindingError(f"could not split {rect} away from its roots")
        if sum(counts) != count:
            raise RootFindingError(f"inconsistent counts in {rect}: {count} vs {counts}")
        for k, n in zip(kids, counts):
            if n and self.n_in(k) < n:
                fine = 0.5 * min(step, max(k[1] - k[0], k[3] - k[2]) / 4.0)
                self.search(k, fine)
                self.reconcile(k, n, fine, depth + 1)


# ---------------------------------------------------------------------------- result
@dataclass(frozen=True)
class Roots:
    """Roots of a quasi-polynomial in a rectangle, with a certified count.

    Attributes
    ----------
    roots : ndarray of complex
        Every root in :attr:`region`, repeated by multiplicity, sorted by
        decreasing real part (ties by imaginary part).
    count : int
        The number of roots in :attr:`region` by the argument principle (certified);
        always ``len(roots)``.
    distinct, multiplicities : ndarray
        The distinct roots and their multiplicities.  A multiple root is
        reported once, at the simple root of ``h^{(m-1)}`` inside a disk where
        a Rouché/Pellet test certifies exactly ``m`` roots; rounding of the
        coefficients splits an exact ``m``-fold root into a tight cluster
        (about ``eps^{1/m}`` wide, e.g. 7e-4 for the fourfold zeros of ZVD^3;
        higher up the rounded delays are no longer exactly commensurate and the
        cluster widens, 3e-3 at 7000 rad/s), and such a cluster is what this
        reports.
    residuals : ndarray of float
        Relative residual ``|h(r)| / sum_i |p_i(r) exp(-r tau_i)|`` of each distinct root.
    region : tuple
        The rectangle actually used: the requested one, with an edge moved
        outward when a root lay on it (:attr:`shifted`).
    requested_region : tuple
    evaluations : int
        Quasi-polynomial evaluations spent.
    """

    roots: np.ndarray
    count: int
    distinct: np.ndarray
    multiplicities: np.ndarray
    residuals: np.ndarray
    region: tuple[float, float, float, float]
    requested_region: tuple[float, float, float, float]
    shifted: bool
    evaluations: int
    removed: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=complex))

    def __len__(self) -> int:
        return int(self.roots.size)

    def __repr__(self) -> str:
        return (
            f"Roots(count={self.count}, distinct={self.distinct.size}, region={self.region}, "
            f"max_residual={self.residuals.max() if self.residuals.size else 0.0:.1e})"
        )

    @property
    def abscissa(self) -> float:
        """Largest real part among the roots (``-inf`` when there are none)."""
        return float(self.roots.real.max()) if self.roots.size else -math.inf


def _sort_key(z: np.ndarray) -> np.ndarray:
    return np.lexsort((z.imag, -z.real))


def roots(
    h: Any,
    region: Sequence[float],
    *,
    ignore: Any = None,
    max_evaluations: float = 5e7,
    timeout: float = 120.0,
) -> Roots:
    """All roots of a quasi-polynomial in a rectangle, with a certified count.

    Parameters
    ----------
    h : QuasiPolynomial
        ``h(s) = sum_i p_i(s) exp(-s tau_i)`` (or a ``(coeffs, delays)`` pair).
        For a transfer function pass ``.num`` (zeros) or ``.den`` (poles).
    region : (re_min, re_max, im_min, im_max)
        The closed rectangle to search.
    ignore : array_like of complex, optional
        Points that are known spurious roots (e.g. a distributed-delay shaper's
        removable point ``s = 0``); each listed point removes one multiplicity
        of a root within ``1e-7 |s|`` of it.  Removed roots are in ``.removed``.
    max_evaluations : float
        Budget of quasi-polynomial evaluations; :class:`BudgetExceeded` is
        raised before the machine is exhausted.  The grid alone is checked
        before it is allocated.
    timeout : float
        Seconds; :class:`BudgetExceeded` past it.

    Returns
    -------
    Roots

    Raises
    ------
    ValueError, TypeError
        Bad ``h`` (identically zero, not a quasi-polynomial), ``region`` (also one
        so far from the origin that the polynomial terms leave the float range: the
        message gives the size reached and the largest usable ``|s|``), or a
        ``max_evaluations``/``timeout`` that is not a finite number > 0.
    BudgetExceeded
        The region's grid is over the budget (refused up front, with the estimate),
        or the evaluations or time ran out.
    RootFindingError
        The roots found cannot be reconciled with the certified count.

    Examples
    --------
    The zeros of the ZV shaper ``0.6 + 0.4 exp(-s pi)`` (seed 000 eq. 3) lie on
    ``Re s = -ln(0.6 / 0.4) / pi`` at ``Im s = 1, 3, 5, ...``:

    >>> from posicast import QuasiPolynomial
    >>> r = roots(QuasiPolynomial([[0.6], [0.4]], [0.0, np.pi]), (-2, 2, 0, 10))
    >>> r.count
    5
    >>> np.allclose(r.roots.imag, [1, 3, 5, 7, 9]), np.allclose(r.roots.real, -np.log(1.5) / np.pi)
    (True, True)
    """
    q0 = as_quasipolynomial(h)
    rect = check_region(region)
    max_evaluations, timeout = check_budget(max_evaluations, timeout)
    ign = None if ignore is None else check_ignore(ignore)
    q, _ = q0.factor_min_delay()
    check_range(q, rect)
    ev = _Evaluator(q, int(max_evaluations), time.monotonic() + float(timeout))
    step = _grid_step(q, rect)
    nx, ny = _grid_shape(rect, step)
    n_grid = nx * ny
    if n_grid > min(max_evaluations / 2, _MAX_GRID):
        raise BudgetExceeded(
            f"region {rect} needs a {n_grid:.3g}-point grid (step {step:.3g} from the largest delay "
            f"{float(q.delays[-1]):.4g}), over the budget of {min(max_evaluations / 2, _MAX_GRID):.3g} points "
            "(half of max_evaluations, at most 2e7 for memory); split or shrink the region"
        )
    count, used, shifted = _count_with_shifts(ev, rect, step)
    solver = _Solver(ev, used, step)
    if count:
        if q.is_polynomial:
            desc = q.coeffs[0, ::-1]
            desc = np.trim_zeros(desc, "f")
            cand = np.roots(desc) if desc.size > 1 else np.zeros(0, complex)
            z, ok = _newton(ev, cand, max_step=step)
            solver.absorb(z[ok])
            solver.classify()
        if solver.n_in(used) != count:
            solver.search(used, step)
        solver.reconcile(used, count, step, 0)
    found = [f for f in solver.found if _inside(np.array([f.point]), used)[0]]
    pts = np.array([f.point for f in found], dtype=complex)
    mult = np.array([f.mult for f in found], dtype=int)
    # real quasi-polynomial: snap numerically real roots onto the axis
    near_real = np.abs(pts.imag) <= 1e-13 * np.maximum(np.abs(pts), 1.0)
    pts[near_real] = pts[near_real].real
    removed = []
    if ign is not None:
        for p in ign:
            if pts.size == 0:
                break
            dist = np.abs(pts - p)
            i = int(np.argmin(dist))
            if dist[i] <= 1e-7 * max(1.0, abs(p)) and mult[i] > 0:
                mult[i] -= 1
                removed.append(pts[i])
        keep = mult > 0
        pts, mult = pts[keep], mult[keep]
        count -= len(removed)
    order = _sort_key(pts)
    pts, mult = pts[order], mult[order]
    res = _rel_residual(q, pts)
    return Roots(
        roots=np.repeat(pts, mult),
        count=int(count),
        distinct=pts,
        multiplicities=mult,
        residuals=res,
        region=used,
        requested_region=rect,
        shifted=shifted,
        evaluations=ev.evaluations,
        removed=np.array(removed, dtype=complex),
    )
