"""Bounded nonlinear least squares for the output-error search: scipy's trust-region reflective method, lean.

:func:`trust_region_reflective` is the algorithm of ``scipy.optimize.least_squares(method="trf",
x_scale="jac", tr_solver="exact")`` (Branch, Coleman and Li 1999; scipy's ``_lsq/trf.py`` and
``_lsq/common.py``, BSD-3-Clause, followed step by step), for the few parameters of an OE fit
(2 per mode) and a long residual.  Two things differ, neither the iterates beyond rounding:

* the SVD of the augmented Jacobian ``[J D; diag(C)^1/2]`` ((m + n) x n, every inner iteration) is
  taken of the n x n triangle of one QR of ``[J, f]`` per Jacobian stacked on ``diag(C)^1/2``
  (2n x n): the same singular values, right vectors and ``U^T f``;
* the quadratic models use ``J^T J`` (n x n) instead of products with ``J`` (m x n);
* the n-vectors are Python floats (lists): numpy's call overhead on 2-element arrays was most of
  the search's own cost.

Why: on the records of 20-2000 samples the demo's identification fits (issue #15), scipy's
bookkeeping around the call (argument checks, the function wrappers, an (m + n) x n SVD per inner
iteration) cost about 2.5 ms per fit, more than the model itself.
"""

# This module follows SciPy's scipy/optimize/_lsq/trf.py and _lsq/common.py step by step; their
# copyright notice, conditions and disclaimer (BSD-3-Clause) are retained here:
#
# Copyright (c) 2001-2002 Enthought, Inc. 2003, SciPy Developers.
# All rights reserved.
#
# Redistribution and use in source and binary forms, with or without
# modification, are permitted provided that the following conditions
# are met:
#
# 1. Redistributions of source code must retain the above copyright
#    notice, this list of conditions and the following disclaimer.
#
# 2. Redistributions in binary form must reproduce the above
#    copyright notice, this list of conditions and the following
#    disclaimer in the documentation and/or other materials provided
#    with the distribution.
#
# 3. Neither the name of the copyright holder nor the names of its
#    contributors may be used to endorse or promote products derived
#    from this software without specific prior written permission.
#
# THIS SOFTWARE IS PROVIDED BY THE COPYRIGHT HOLDERS AND CONTRIBUTORS
# "AS IS" AND ANY EXPRESS OR IMPLIED WARRANTIES, INCLUDING, BUT NOT
# LIMITED TO, THE IMPLIED WARRANTIES OF MERCHANTABILITY AND FITNESS FOR
# A PARTICULAR PURPOSE ARE DISCLAIMED. IN NO EVENT SHALL THE COPYRIGHT
# OWNER OR CONTRIBUTORS BE LIABLE FOR ANY DIRECT, INDIRECT, INCIDENTAL,
# SPECIAL, EXEMPLARY, OR CONSEQUENTIAL DAMAGES (INCLUDING, BUT NOT
# LIMITED TO, PROCUREMENT OF SUBSTITUTE GOODS OR SERVICES; LOSS OF USE,
# DATA, OR PROFITS; OR BUSINESS INTERRUPTION) HOWEVER CAUSED AND ON ANY
# THEORY OF LIABILITY, WHETHER IN CONTRACT, STRICT LIABILITY, OR TORT
# (INCLUDING NEGLIGENCE OR OTHERWISE) ARISING IN ANY WAY OUT OF THE USE
# OF THIS SOFTWARE, EVEN IF ADVISED OF THE POSSIBILITY OF SUCH DAMAGE.

from __future__ import annotations

import math
from typing import Callable, List, NamedTuple

import numpy as np
from scipy.linalg import lapack

__all__ = ["TRFResult", "trust_region_reflective"]

_EPS = float(np.finfo(float).eps)


class TRFResult(NamedTuple):
    """The end of a search: the parameters, half the residual sum of squares, the residual, evaluations."""

    x: np.ndarray
    cost: float
    fun: np.ndarray
    nfev: int


Vec = List[float]


def trust_region_reflective(fun: Callable[[np.ndarray], np.ndarray], jac: Callable[[np.ndarray], np.ndarray],
                            x0: np.ndarray, lb: np.ndarray, ub: np.ndarray, *, ftol: float, xtol: float,
                            gtol: float, max_nfev: int) -> TRFResult:
    """Minimise ``0.5 |fun(x)|^2`` over ``lb <= x <= ub`` (scipy's ``trf_bounds``; ``x0`` is moved strictly
    inside first, as scipy does).  Everything after one QR per Jacobian is n x n.

    Parameters
    ----------
    fun, jac : callable
        The residual (m,) and its Jacobian (m, n) at ``x``.
    x0, lb, ub : ndarray (n,)
        Start and finite bounds, ``lb < ub``, ``lb <= x0 <= ub``.
    ftol, xtol, gtol : float
        scipy's tolerances (relative cost change with a good step, relative step, scaled gradient).
    max_nfev : int
        Most evaluations of ``fun``.

    Returns
    -------
    TRFResult
        ``x``, ``cost`` (half the sum of squares), ``fun`` (the residual at ``x``), ``nfev``.

    Examples
    --------
    Rosenbrock's valley with its minimum (1, 1) cut off by ``x[1] >= 1.5`` (scipy's documentation):

    >>> import numpy as np
    >>> fun = lambda x: np.array([10 * (x[1] - x[0] ** 2), 1 - x[0]])
    >>> jac = lambda x: np.array([[-20 * x[0], 10.0], [-1.0, 0.0]])
    >>> r = trust_region_reflective(fun, jac, np.array([2.0, 2.0]), np.array([-3.0, 1.5]),
    ...                             np.array([3.0, 3.0]), ftol=1e-12, xtol=1e-10, gtol=1e-12, max_nfev=200)
    >>> np.round(r.x, 8).tolist()
    [1.22437075, 1.5]
    """
    n = int(np.size(x0))
    if np.shape(lb) != (n,) or np.shape(ub) != (n,) or not np.all(np.asarray(lb) < np.asarray(ub)):
        raise ValueError(f"lb and ub must be {n} finite bounds with lb < ub, got {lb!r} and {ub!r}")
    if not np.all((np.asarray(x0) >= lb) & (np.asarray(x0) <= ub)):
        raise ValueError(f"x0 must lie within the bounds [lb, ub], got {x0!r}")
    lo, hi = [float(a) for a in lb], [float(a) for a in ub]
    x = _strictly_feasible([float(a) for a in x0], lo, hi, rstep=1e-10)
    f = fun(np.array(x))
    m = f.size
    nfev = 1
    cost = 0.5 * float(f @ f)
    R, qf = _triangle(jac(np.array(x)), f)
    g, G = _normal(R, qf)
    scale_inv = [math.sqrt(G[i][i]) or 1.0 for i in range(n)]  # x_scale="jac": the column norms of J
    v, dv = _cl_scaling(x, g, lo, hi)
    Delta = _norm([x[i] * scale_inv[i] / math.sqrt(v[i] * scale_inv[i] if dv[i] else v[i]) for i in range(n)]) or 1.0
    alpha = 0.0
    while True:
        v, dv = _cl_scaling(x, g, lo, hi)
        g_norm = max(abs(g[i] * v[i]) for i in range(n))
        if g_norm < gtol or nfev == max_nfev:
            break
        scale = [1.0 / si for si in scale_inv]
        d = [math.sqrt(v[i] * scale_inv[i] if dv[i] else v[i]) * scale[i] for i in range(n)]
        diag_h = [g[i] * dv[i] * scale[i] for i in range(n)]
        g_h = [d[i] * g[i] for i in range(n)]
        G_h = [[G[i][j] * d[i] * d[j] for j in range(n)] for i in range(n)]  # J_h^T J_h, J_h = J diag(d)
        # the SVD of the augmented Jacobian [J_h; diag(diag_h)^1/2] from that of [R d; diag(diag_h)^1/2]
        M = np.array([[R[i][j] * d[j] for j in range(n)] for i in range(n)]
                     + [[math.sqrt(diag_h[i]) if i == j else 0.0 for j in range(n)] for i in range(n)])
        U, sv, Vt, info = lapack.dgesdd(M, 1, 0)  # (compute_uv, full_matrices)
        if info != 0:
            U, sv, Vt = np.linalg.svd(M, full_matrices=False)
        s, V, uf = sv.tolist(), Vt.T.tolist(), (np.array(qf) @ U[:n]).tolist()
        theta = max(0.995, 1.0 - g_norm)
        actual_reduction = -1.0
        done = False
        while actual_reduction <= 0 and nfev < max_nfev:
            p_h, alpha = _solve_lsq_trust_region(n, m, uf, s, V, Delta, alpha)
            p = [d[i] * p_h[i] for i in range(n)]
            step, step_h, predicted = _select_step(x, G_h, diag_h, g_h, p, p_h, d, Delta, lo, hi, theta)
            x_new = _strictly_feasible([x[i] + step[i] for i in range(n)], lo, hi)
            f_new = fun(np.array(x_new))
            nfev += 1
            step_h_norm = _norm(step_h)
            cost_new = 0.5 * float(f_new @ f_new)
            if not math.isfinite(cost_new) and not np.all(np.isfinite(f_new)):
                Delta = 0.25 * step_h_norm
                continue
            actual_reduction = cost - cost_new
            Delta_new, ratio = _update_radius(Delta, actual_reduction, predicted, step_h_norm,
                                              step_h_norm > 0.95 * Delta)
            # scipy's check_termination: ftol (with a good step) or xtol
            if (actual_reduction < ftol * cost and ratio > 0.25) or _norm(step) < xtol * (xtol + _norm(x)):
                done = True
                break
            alpha *= Delta / Delta_new
            Delta = Delta_new
        if actual_reduction > 0:
            x, f, cost = x_new, f_new, cost_new
            if done:
                break  # (scipy evaluates the Jacobian here once more, for its result only)
            R, qf = _triangle(jac(np.array(x)), f)
            g, G = _normal(R, qf)
            scale_inv = [max(math.sqrt(G[i][i]), scale_inv[i]) for i in range(n)]
        elif done:
            break
    return TRFResult(np.array(x), cost, f, nfev)


# The small sums below are plain loops from 0.0, in index order: the same additions as the built-in sum() of
# Python 3.11 over a generator (which starts from 0 and adds in order), at a third of its cost (issue #15).


def _norm(a: Vec) -> float:
    acc = 0.0
    for t in a:
        acc += t * t
    return math.sqrt(acc)


def _dot(a: Vec, b: Vec) -> float:
    acc = 0.0
    for s, t in zip(a, b):
        acc += s * t
    return acc


def _diag_quad(a: Vec, diag: Vec) -> float:
    """``a^T diag(diag) a``, each term ``(a_i diag_i) a_i``."""
    acc = 0.0
    for t, di in zip(a, diag):
        acc += t * di * t
    return acc


def _quad(G: list[Vec], a: Vec, b: Vec) -> float:
    """``a^T G b``."""
    acc = 0.0
    for ai, Gi in zip(a, G):
        acc += ai * _dot(Gi, b)
    return acc


def _triangle(J: np.ndarray, f: np.ndarray) -> tuple[list[Vec], Vec]:
    """``R`` and ``Q^T f`` of the QR factorisation ``J = Q R`` (one QR of ``[J, f]``, Q not formed)."""
    m, n = J.shape
    a = np.empty((m, n + 1), order="F")
    a[:, :n] = J
    a[:, n] = f
    qr, _, _, info = lapack.dgeqrf(a, overwrite_a=1)
    if info != 0:  # pragma: no cover - LAPACK argument error
        raise np.linalg.LinAlgError(f"dgeqrf failed (info {info})")
    top = qr[: min(m, n)].tolist()  # fewer samples than parameters: J = Q R[:m], the other rows 0
    top += [[0.0] * (n + 1)] * (n - len(top))
    return [[row[j] if j >= i else 0.0 for j in range(n)] for i, row in enumerate(top)], [row[n] for row in top]


def _normal(R: list[Vec], qf: Vec) -> tuple[Vec, list[Vec]]:
    """``J^T f = R^T Q^T f`` and ``J^T J = R^T R``."""
    n = len(qf)
    g = [0.0] * n
    G = [[0.0] * n for _ in range(n)]
    for k in range(n):
        Rk, fk = R[k], qf[k]
        for i in range(n):
            g[i] += Rk[i] * fk
            Gi, rki = G[i], Rk[i]
            for j in range(n):
                Gi[j] += rki * Rk[j]
    return g, G


def _cl_scaling(x: Vec, g: Vec, lb: Vec, ub: Vec) -> tuple[Vec, Vec]:
    """Coleman and Li's scaling vector and its derivative (scipy ``CL_scaling_vector``, finite bounds)."""
    v = [ub[i] - x[i] if g[i] < 0 else (x[i] - lb[i] if g[i] > 0 else 1.0) for i in range(len(x))]
    return v, [-1.0 if gi < 0 else (1.0 if gi > 0 else 0.0) for gi in g]


def _strictly_feasible(x: Vec, lb: Vec, ub: Vec, rstep: float = 0.0) -> Vec:
    """``x`` with a coordinate on (or within ``rstep`` of) a bound moved inside: one ulp when ``rstep`` is 0,
    else ``rstep`` relative (scipy ``make_strictly_feasible``)."""
    out = list(x)
    for i, (xi, a, b) in enumerate(zip(x, lb, ub)):
        if rstep == 0:
            if xi <= a:
                out[i] = math.nextafter(a, b)
            elif xi >= b:
                out[i] = math.nextafter(b, a)
        else:
            ta, tb = rstep * max(1.0, abs(a)), rstep * max(1.0, abs(b))
            if xi - a <= min(b - xi, ta):
                out[i] = a + ta
            elif b - xi <= min(xi - a, tb):
                out[i] = b - tb
        if out[i] < a or out[i] > b:
            out[i] = 0.5 * (a + b)
    return out


def _solve_lsq_trust_region(n: int, m: int, uf: Vec, s: Vec, V: list[Vec], Delta: float, alpha0: float,
                            rtol: float = 0.01, max_iter: int = 10) -> tuple[Vec, float]:
    """The trust-region step from the SVD (Moré's iteration on the Levenberg-Marquardt parameter; scipy's)."""
    suf = [si * ui for si, ui in zip(s, uf)]

    def phi_and_derivative(alpha: float) -> tuple[float, float]:
        denom = [si * si + alpha for si in s]
        p_norm = _norm([a / b for a, b in zip(suf, denom)])
        acc = 0.0
        for a, b in zip(suf, denom):
            acc += a * a / b ** 3
        return p_norm - Delta, -acc / p_norm

    def along(c: Vec) -> Vec:  # -V c
        return [-_dot(V[i], c) for i in range(n)]

    full_rank = m >= n and s[-1] > _EPS * m * s[0]
    if full_rank:
        p = along([a / b for a, b in zip(uf, s)])
        if _norm(p) <= Delta:
            return p, 0.0
    alpha_upper = _norm(suf) / Delta
    alpha_lower = 0.0
    if full_rank:
        phi, phi_prime = phi_and_derivative(0.0)
        alpha_lower = -phi / phi_prime
    if not full_rank and alpha0 == 0:
        alpha = max(0.001 * alpha_upper, math.sqrt(alpha_lower * alpha_upper))
    else:
        alpha = alpha0
    for _ in range(max_iter):
        if alpha < alpha_lower or alpha > alpha_upper:
            alpha = max(0.001 * alpha_upper, math.sqrt(alpha_lower * alpha_upper))
        phi, phi_prime = phi_and_derivative(alpha)
        if phi < 0:
            alpha_upper = alpha
        ratio = phi / phi_prime
        alpha_lower = max(alpha_lower, alpha - ratio)
        alpha -= (phi + Delta) * ratio / Delta
        if abs(phi) < rtol * Delta:
            break
    p = along([a / (si * si + alpha) for a, si in zip(suf, s)])
    k = Delta / _norm(p)
    return [k * t for t in p], alpha


def _quadratic(G: list[Vec], g: Vec, s: Vec, diag: Vec) -> float:
    """``0.5 s^T (J^T J + diag) s + g^T s`` (scipy ``evaluate_quadratic``, with ``G = J^T J``)."""
    return 0.5 * (_quad(G, s, s) + _diag_quad(s, diag)) + _dot(s, g)


def _step_to_bound(x: Vec, s: Vec, lb: Vec, ub: Vec) -> tuple[float, Vec]:
    """The largest step along ``s`` within the bounds and which coordinates hit them (scipy's)."""
    steps = [max((a - xi) / si, (b - xi) / si) if si != 0 else math.inf for xi, si, a, b in zip(x, s, lb, ub)]
    t = min(steps)
    return t, [(1.0 if si > 0 else -1.0) if (st == t and si != 0) else 0.0 for st, si in zip(steps, s)]


def _select_step(x: Vec, G_h: list[Vec], diag_h: Vec, g_h: Vec, p: Vec, p_h: Vec, d: Vec, Delta: float,
                 lb: Vec, ub: Vec, theta: float) -> tuple[Vec, Vec, float]:
    """The best of the trust-region step (cut at a bound), its reflection and the scaled gradient (scipy's)."""
    n = len(x)
    if all(a <= xi + pi <= b for xi, pi, a, b in zip(x, p, lb, ub)):
        return p, p_h, -_quadratic(G_h, g_h, p_h, diag_h)
    p_stride, hits = _step_to_bound(x, p, lb, ub)
    r_h = [-t if hit else t for t, hit in zip(p_h, hits)]
    r = [d[i] * r_h[i] for i in range(n)]
    p = [t * p_stride for t in p]
    p_h = [t * p_stride for t in p_h]
    x_on_bound = [x[i] + p[i] for i in range(n)]
    # the reflected direction leaves the feasible box or the trust region first
    a2, b2, c2 = _dot(r_h, r_h), _dot(p_h, r_h), _dot(p_h, p_h) - Delta ** 2
    q = -(b2 + math.copysign(math.sqrt(b2 * b2 - a2 * c2), b2))
    to_tr = max(q / a2, c2 / q)
    to_bound, _ = _step_to_bound(x_on_bound, r, lb, ub)
    r_stride = min(to_bound, to_tr)
    if r_stride > 0:
        r_stride_l = (1 - theta) * p_stride / r_stride
        r_stride_u = theta * to_bound if r_stride == to_bound else to_tr
    else:
        r_stride_l, r_stride_u = 0.0, -1.0
    if r_stride_l <= r_stride_u:
        pd = [p_h[i] * diag_h[i] for i in range(n)]
        a = 0.5 * (_quad(G_h, r_h, r_h) + _diag_quad(r_h, diag_h))
        b = _dot(r_h, g_h) + _quad(G_h, p_h, r_h) + _dot(pd, r_h)
        c = 0.5 * _quad(G_h, p_h, p_h) + _dot(g_h, p_h) + 0.5 * _dot(pd, p_h)
        r_stride, r_value = _minimize_1d(a, b, r_stride_l, r_stride_u, c)
        r_h = [r_h[i] * r_stride + p_h[i] for i in range(n)]
        r = [r_h[i] * d[i] for i in range(n)]
    else:
        r_value = math.inf
    p = [t * theta for t in p]
    p_h = [t * theta for t in p_h]
    p_value = _quadratic(G_h, g_h, p_h, diag_h)
    ag_h = [-t for t in g_h]
    ag = [d[i] * ag_h[i] for i in range(n)]
    to_tr = Delta / _norm(ag_h)
    to_bound, _ = _step_to_bound(x, ag, lb, ub)
    ag_stride = theta * to_bound if to_bound < to_tr else to_tr
    a = 0.5 * (_quad(G_h, ag_h, ag_h) + _diag_quad(ag_h, diag_h))
    b = _dot(g_h, ag_h)
    ag_stride, ag_value = _minimize_1d(a, b, 0.0, ag_stride, 0.0)
    ag_h = [t * ag_stride for t in ag_h]
    ag = [t * ag_stride for t in ag]
    if p_value < r_value and p_value < ag_value:
        return p, p_h, -p_value
    if r_value < p_value and r_value < ag_value:
        return r, r_h, -r_value
    return ag, ag_h, -ag_value


def _minimize_1d(a: float, b: float, lb: float, ub: float, c: float) -> tuple[float, float]:
    """Minimum of ``a t^2 + b t + c`` over ``[lb, ub]`` (scipy ``minimize_quadratic_1d``)."""
    t = [lb, ub]
    if a != 0:
        ext = -0.5 * b / a
        if lb < ext < ub:
            t.append(ext)
    vals = [ti * (a * ti + b) + c for ti in t]
    i = int(np.argmin(vals))
    return t[i], vals[i]


def _update_radius(Delta: float, actual: float, predicted: float, step_norm: float,
                   bound_hit: bool) -> tuple[float, float]:
    """The trust radius after a step and the step's quality ratio (scipy ``update_tr_radius``)."""
    if predicted > 0:
        ratio = actual / predicted
    elif predicted == actual == 0:
        ratio = 1.0
    else:
        ratio = 0.0
    if ratio < 0.25:
        Delta = 0.25 * step_norm
    elif ratio > 0.75 and bound_hit:
        Delta *= 2.0
    return Delta, ratio
