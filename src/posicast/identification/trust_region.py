"""Bounded nonlinear least squares for the output-error search: scipy's trust-region reflective method, lean.

:func:`trust_region_reflective` is the algorithm of ``scipy.optimize.least_squares(method="trf",
x_scale="jac", tr_solver="exact")`` (Branch, Coleman and Li 1999; scipy's ``_lsq/trf.py`` and
``_lsq/common.py``, BSD-3-Clause, followed step by step), for the few parameters of an OE fit
(2 per mode) and a long residual.  Two things differ, neither the iterates beyond rounding:

* the SVD of the augmented Jacobian ``[J D; diag(C)^1/2]`` ((m + n) x n, every inner iteration) is
  taken of the n x n triangle of one QR of ``[J, f]`` per Jacobian stacked on ``diag(C)^1/2``
  (2n x n): the same singular values, right vectors and ``U^T f``;
* the quadratic models use ``J^T J`` (n x n) instead of products with ``J`` (m x n).

Why: on the records of 20-2000 samples the demo's identification fits (issue #15), scipy's
bookkeeping around the call (argument checks, the function wrappers, an (m + n) x n SVD per inner
iteration) cost about 2.5 ms per fit, more than the model itself.
"""

from __future__ import annotations

import math
from typing import Callable, NamedTuple

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


def trust_region_reflective(fun: Callable[[np.ndarray], np.ndarray], jac: Callable[[np.ndarray], np.ndarray],
                            x0: np.ndarray, lb: np.ndarray, ub: np.ndarray, *, ftol: float, xtol: float,
                            gtol: float, max_nfev: int) -> TRFResult:
    """Minimise ``0.5 |fun(x)|^2`` over ``lb <= x <= ub`` (scipy's ``trf_bounds``; ``x0`` is moved strictly
    inside first, as scipy does).  Everything after one QR per Jacobian is n x n."""
    x = _strictly_feasible(np.array(x0, dtype=float), lb, ub, rstep=1e-10)
    f = fun(x)
    nfev = 1
    cost = 0.5 * float(f @ f)
    R, qf = _triangle(jac(x), f)
    g, G = R.T @ qf, R.T @ R  # J^T f and J^T J
    scale_inv = np.sqrt(np.diag(G))  # x_scale="jac": the column norms of J
    scale_inv = np.where(scale_inv == 0, 1.0, scale_inv)
    v, dv = _cl_scaling(x, g, lb, ub)
    Delta = _norm(x * scale_inv / np.sqrt(np.where(dv != 0, v * scale_inv, v))) or 1.0
    alpha = 0.0
    while True:
        v, dv = _cl_scaling(x, g, lb, ub)
        g_norm = float(np.max(np.abs(g * v)))
        if g_norm < gtol or nfev == max_nfev:
            break
        scale = 1.0 / scale_inv
        d = np.sqrt(np.where(dv != 0, v * scale_inv, v)) * scale
        diag_h = g * dv * scale
        g_h = d * g
        G_h = G * np.outer(d, d)  # J_h^T J_h with J_h = J diag(d)
        # the SVD of the augmented Jacobian [J_h; diag(diag_h)^1/2] from that of [R d; diag(diag_h)^1/2]
        U, s, Vt, info = lapack.dgesdd(np.vstack([R * d, np.diag(np.sqrt(diag_h))]), compute_uv=1,
                                       full_matrices=0)
        if info != 0:
            U, s, Vt = np.linalg.svd(np.vstack([R * d, np.diag(np.sqrt(diag_h))]), full_matrices=False)
        V = Vt.T
        uf = qf @ U[: qf.size]
        theta = max(0.995, 1.0 - g_norm)
        actual_reduction = -1.0
        done = False
        while actual_reduction <= 0 and nfev < max_nfev:
            p_h, alpha = _solve_lsq_trust_region(x.size, f.size, uf, s, V, Delta, alpha)
            p = d * p_h
            step, step_h, predicted = _select_step(x, G_h, diag_h, g_h, p, p_h, d, Delta, lb, ub, theta)
            x_new = _strictly_feasible(x + step, lb, ub)
            f_new = fun(x_new)
            nfev += 1
            step_h_norm = _norm(step_h)
            if not np.all(np.isfinite(f_new)):
                Delta = 0.25 * step_h_norm
                continue
            cost_new = 0.5 * float(f_new @ f_new)
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
            R, qf = _triangle(jac(x), f)
            g, G = R.T @ qf, R.T @ R
            scale_inv = np.maximum(np.sqrt(np.diag(G)), scale_inv)
        elif done:
            break
    return TRFResult(x, cost, f, nfev)


def _norm(a: np.ndarray) -> float:
    return math.sqrt(float(a @ a))


def _triangle(J: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``R`` and ``Q^T f`` of the QR factorisation ``J = Q R`` (one QR of ``[J, f]``, Q not formed)."""
    m, n = J.shape
    a = np.empty((m, n + 1), order="F")
    a[:, :n] = J
    a[:, n] = f
    qr, _, _, info = lapack.dgeqrf(a, overwrite_a=1)
    if info != 0:  # pragma: no cover - LAPACK argument error
        raise np.linalg.LinAlgError(f"dgeqrf failed (info {info})")
    if m > n:
        return np.triu(qr[:n, :n]), qr[:n, n].copy()
    R, qf = np.zeros((n, n)), np.zeros(n)  # fewer samples than parameters: J = Q R[:m]
    R[:m] = np.triu(qr[:m, :n])
    qf[:m] = qr[:m, n]
    return R, qf


def _cl_scaling(x: np.ndarray, g: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Coleman and Li's scaling vector and its derivative (scipy ``CL_scaling_vector``, finite bounds)."""
    return np.where(g < 0, ub - x, np.where(g > 0, x - lb, 1.0)), np.sign(g)


def _strictly_feasible(x: np.ndarray, lb: np.ndarray, ub: np.ndarray, rstep: float = 0.0) -> np.ndarray:
    """``x`` with a coordinate on (or within ``rstep`` of) a bound moved inside: one ulp when ``rstep`` is 0,
    else ``rstep`` relative (scipy ``make_strictly_feasible``)."""
    if rstep == 0 and not ((x <= lb) | (x >= ub)).any():
        return x
    out = x.copy()
    if rstep == 0:
        lo, hi = x <= lb, x >= ub
        out[lo] = np.nextafter(lb[lo], ub[lo])
        out[hi] = np.nextafter(ub[hi], lb[hi])
    else:
        tol_lo, tol_hi = rstep * np.maximum(1.0, np.abs(lb)), rstep * np.maximum(1.0, np.abs(ub))
        lo = x - lb <= np.minimum(ub - x, tol_lo)
        hi = (ub - x <= np.minimum(x - lb, tol_hi)) & ~lo
        out[lo] = lb[lo] + tol_lo[lo]
        out[hi] = ub[hi] - tol_hi[hi]
    tight = (out < lb) | (out > ub)
    out[tight] = 0.5 * (lb[tight] + ub[tight])
    return out


def _solve_lsq_trust_region(n: int, m: int, uf: np.ndarray, s: np.ndarray, V: np.ndarray, Delta: float,
                            alpha0: float, rtol: float = 0.01, max_iter: int = 10) -> tuple[np.ndarray, float]:
    """The trust-region step from the SVD (Moré's iteration on the Levenberg-Marquardt parameter; scipy's)."""
    suf = s * uf

    def phi_and_derivative(alpha: float) -> tuple[float, float]:
        denom = s ** 2 + alpha
        p_norm = float(np.linalg.norm(suf / denom))
        return p_norm - Delta, -float(np.sum(suf ** 2 / denom ** 3)) / p_norm

    full_rank = m >= n and s[-1] > _EPS * m * s[0]
    if full_rank:
        p = -V @ (uf / s)
        if np.linalg.norm(p) <= Delta:
            return p, 0.0
    alpha_upper = float(np.linalg.norm(suf)) / Delta
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
    p = -V @ (suf / (s ** 2 + alpha))
    p *= Delta / np.linalg.norm(p)
    return p, alpha


def _quadratic(G: np.ndarray, g: np.ndarray, s: np.ndarray, diag: np.ndarray) -> float:
    """``0.5 s^T (J^T J + diag) s + g^T s`` (scipy ``evaluate_quadratic``, with ``G = J^T J``)."""
    return 0.5 * float(s @ G @ s + (s * diag) @ s) + float(s @ g)


def _step_to_bound(x: np.ndarray, s: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> tuple[float, np.ndarray]:
    """The largest step along ``s`` within the bounds and which coordinates hit them (scipy's)."""
    nz = s != 0
    steps = np.full(x.shape, np.inf)
    with np.errstate(over="ignore"):
        steps[nz] = np.maximum((lb - x)[nz] / s[nz], (ub - x)[nz] / s[nz])
    t = float(np.min(steps))
    return t, (steps == t) * np.sign(s)


def _select_step(x: np.ndarray, G_h: np.ndarray, diag_h: np.ndarray, g_h: np.ndarray, p: np.ndarray,
                 p_h: np.ndarray, d: np.ndarray, Delta: float, lb: np.ndarray, ub: np.ndarray,
                 theta: float) -> tuple[np.ndarray, np.ndarray, float]:
    """The best of the trust-region step (cut at a bound), its reflection and the scaled gradient (scipy's)."""
    if np.all((x + p >= lb) & (x + p <= ub)):
        return p, p_h, -_quadratic(G_h, g_h, p_h, diag_h)
    p_stride, hits = _step_to_bound(x, p, lb, ub)
    r_h = p_h.copy()
    r_h[hits.astype(bool)] *= -1
    r = d * r_h
    p *= p_stride
    p_h *= p_stride
    x_on_bound = x + p
    # the reflected direction leaves the feasible box or the trust region first
    a2, b2, c2 = float(r_h @ r_h), float(p_h @ r_h), float(p_h @ p_h) - Delta ** 2
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
        a = 0.5 * float(r_h @ G_h @ r_h + (r_h * diag_h) @ r_h)
        b = float(r_h @ g_h) + float(p_h @ G_h @ r_h) + float((p_h * diag_h) @ r_h)
        c = 0.5 * float(p_h @ G_h @ p_h) + float(g_h @ p_h) + 0.5 * float((p_h * diag_h) @ p_h)
        r_stride, r_value = _minimize_1d(a, b, r_stride_l, r_stride_u, c)
        r_h *= r_stride
        r_h += p_h
        r = r_h * d
    else:
        r_value = math.inf
    p *= theta
    p_h *= theta
    p_value = _quadratic(G_h, g_h, p_h, diag_h)
    ag_h = -g_h
    ag = d * ag_h
    to_tr = Delta / float(np.linalg.norm(ag_h))
    to_bound, _ = _step_to_bound(x, ag, lb, ub)
    ag_stride = theta * to_bound if to_bound < to_tr else to_tr
    a = 0.5 * float(ag_h @ G_h @ ag_h + (ag_h * diag_h) @ ag_h)
    b = float(g_h @ ag_h)
    ag_stride, ag_value = _minimize_1d(a, b, 0.0, ag_stride, 0.0)
    ag_h *= ag_stride
    ag *= ag_stride
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
