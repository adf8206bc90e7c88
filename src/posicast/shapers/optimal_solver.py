"""The solver behind :mod:`posicast.shapers.optimal`: the sampled problem, the duration LP and its certificate,
the SLSQP polish with exchanged frequencies, the closed-form starts and the KKT residual.

Times are handled in units of ``1 / scale`` (``scale`` the highest band frequency, so its period is ``2 pi``);
the method is described in :mod:`posicast.shapers.optimal`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import linprog, lsq_linear, minimize, minimize_scalar

from ..modes import Mode
from .ei import ei_exact, ei_multi_hump
from .lumped import mzv_impulses, zvdk_impulses

_N_DIR = 12                  # polygon directions of the LP
_COS = math.cos(math.pi / _N_DIR)
_GRID_PER_PERIOD = 48        # LP time grid: points per period of the highest frequency
_MAX_LP = 4e5                # most LP matrix entries (~0.3 s of HiGHS); beyond, the search stops and says so
_REL = 1e-7                  # relative slack: the NLP aims at vtol (1 - _REL); "active" within 1e-5


# ----------------------------------------------------------------------------- the problem


@dataclass(frozen=True)
class _Problem:
    modes: tuple[Mode, ...]
    bands: tuple[tuple[float, float], ...]
    dampings: tuple[tuple[float, float], ...]
    vtol: float
    scale: float  # times are handled in units of 1 / scale (scale = highest band frequency)
    deadline: float = math.inf  # time.perf_counter() after which loops stop with their best so far

    def late(self) -> bool:
        return time.perf_counter() > self.deadline

    def points(self, per_cycle: float, duration: float, n_min: int, n_zeta: int) -> tuple[np.ndarray, ...]:
        """Sample frequencies ``(nu, zeta, mode index, ratio)``: ``per_cycle`` points per oscillation of V."""
        nu, ze, idx, rat = [], [], [], []
        for i, (m, (lo, hi), (z0, z1)) in enumerate(zip(self.modes, self.bands, self.dampings)):
            width = (hi - lo) * m.omega / self.scale
            n = 1 if hi == lo else int(min(4000, max(n_min, math.ceil(per_cycle * width * duration / (2 * math.pi)) + 1)))
            r = np.linspace(lo, hi, n)
            zs = np.array([z0]) if z1 == z0 else np.linspace(z0, z1, n_zeta)
            for z in zs:
                nu.append(r * m.omega / self.scale)
                ze.append(np.full(n, z))
                idx.append(np.full(n, i))
                rat.append(r)
        return tuple(np.concatenate(x) for x in (nu, ze, idx, rat))


def _qs(nu: np.ndarray, zeta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``q = nu (zeta - j sqrt(1 - zeta^2))`` (so ``e^{q t}`` is a term of S(p) e^{...}) and the decay ``nu zeta``."""
    return nu * (zeta - 1j * np.sqrt((1.0 - zeta) * (1.0 + zeta))), nu * zeta


def _z(u: np.ndarray, A: np.ndarray, q: np.ndarray, sig: np.ndarray, u_end: float) -> np.ndarray:
    """``e^{-sigma u_end} sum_i A_i e^{q u_i}``: the residual phasor at each sample (|z| = V)."""
    return np.exp(np.multiply.outer(q, u) - sig[:, None] * u_end) @ A


# ----------------------------------------------------------------------------- step 1: LP


def _lp(q: np.ndarray, sig: np.ndarray, u: np.ndarray, u_end: float, first_order_h: float = 0.0,
        inner: bool = True) -> tuple[float, np.ndarray]:
    """Least polygon vibration ``s*`` over amplitudes on the grid ``u`` (and ``B`` if ``first_order_h``)."""
    W = np.exp(np.multiply.outer(q, u) - sig[:, None] * u_end)
    rot = np.exp(-1j * 2 * math.pi * np.arange(_N_DIR) / _N_DIR)
    K = u.size
    blocks = [(rot[:, None, None] * W[None]).real.reshape(-1, K)]
    if first_order_h:
        blocks.append((rot[:, None, None] * (q[:, None] * W)[None]).real.reshape(-1, K))
    nv = K * len(blocks)
    A_ub = np.hstack(blocks + [-np.ones((blocks[0].shape[0], 1))])
    b_ub = np.zeros(A_ub.shape[0])
    if first_order_h:  # |B_k| <= h/2 A_k
        eye = np.eye(K)
        lim = np.hstack([np.vstack([-0.5 * first_order_h * eye, -0.5 * first_order_h * eye]),
                         np.vstack([eye, -eye]), np.zeros((2 * K, 1))])
        A_ub = np.vstack([A_ub, lim])
        b_ub = np.concatenate([b_ub, np.zeros(2 * K)])
    A_eq = np.zeros((1, nv + 1))
    A_eq[0, :K] = 1.0
    c = np.zeros(nv + 1)
    c[-1] = 1.0
    bounds = [(0, None)] * K + [(None, None)] * (nv - K) + [(None, None)]
    res = linprog(c, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=[1.0], bounds=bounds, method="highs")
    if res.status != 0:  # pragma: no cover - the LP is always feasible and bounded
        raise RuntimeError(f"the shaper LP failed: {res.message}")
    s = float(res.x[-1])
    return (s / _COS if inner else s), res.x[:K]


def _lp_size(prob: _Problem, K: int) -> float:
    h = 2 * math.pi / _GRID_PER_PERIOD
    return float(prob.points(8, K * h, 11, 3)[0].size * _N_DIR) * (2 * K + 4)


def _lp_shortest(prob: _Problem, k_cap: int) -> tuple[int | None, np.ndarray, float, float, int]:
    """Bisection on the grid length: (shortest K or None, its amplitudes, grid step h, s* at the largest K
    solved, that K).  None when no K up to ``k_cap`` (or up to the LP size limit) meets the bands."""
    h = 2 * math.pi / _GRID_PER_PERIOD  # scale = the highest frequency: its period is 2 pi

    def solve(K: int) -> tuple[float, np.ndarray]:
        u = np.arange(K + 1) * h
        nu, ze, _, _ = prob.points(8, u[-1], 11, 3)
        q, sig = _qs(nu, ze)
        return _lp(q, sig, u, u[-1], inner=False)  # circumscribed: a start just outside, the polish fixes it

    nu_min = min(m.omega * b[0] for m, b in zip(prob.modes, prob.bands)) / prob.scale
    k = max(2, min(k_cap, int(math.ceil(math.pi / nu_min / h))))  # ZV's duration at the lowest frequency
    while k > 2 and _lp_size(prob, k) > _MAX_LP:
        k //= 2
    lo, s_lo = 0, 1.0
    while True:
        s, A = solve(k)
        if s <= prob.vtol:
            break
        nxt = min(k_cap, 2 * k)
        if k >= k_cap or _lp_size(prob, nxt) > _MAX_LP or prob.late():
            return None, A, h, s, k
        lo, s_lo, k = k, s, nxt
    best, hi, s_hi = (k, A), k, s
    last = 0
    while hi - lo > 1 and not prob.late():  # regula falsi on s*(K) = vtol, bisection when an end stays
        mid = lo + (hi - lo) * (s_lo - prob.vtol) / (s_lo - s_hi) if last != 2 else 0.5 * (lo + hi)
        mid = int(min(hi - 1, max(lo + 1, round(mid))))
        s, A = solve(mid)
        if s <= prob.vtol:
            hi, s_hi, best = mid, s, (mid, A)
            last = 2 if last == -1 else 1
        else:
            lo, s_lo = mid, s
            last = 2 if last == 1 else -1
    return best[0], best[1], h, 0.0, best[0]


def _lower_bound(prob: _Problem, k_hi: int) -> float:
    """A duration (scaled units) proven infeasible by the first-order LP relaxation (module docstring):
    tried at 97 % and then 94 %, 88 %, ... of ``k_hi`` grid steps, the first proven is returned."""
    h = 2 * math.pi / _GRID_PER_PERIOD
    slack = h * h / 8.0  # nu <= 1: omega^2 h^2 / 8 in scaled units

    def infeasible(K: int) -> bool:
        if _lp_size(prob, K) > _MAX_LP:
            return False  # not tried: no bound from it
        u = np.arange(K + 1) * h
        nu, ze, _, _ = prob.points(8, u[-1], 11, 3)
        q, sig = _qs(nu, ze)
        s, _ = _lp(q, sig, u, u[-1], first_order_h=h, inner=False)
        return s > prob.vtol + slack

    frac = 0.97
    while frac > 0.3:
        K = int(math.floor(frac * k_hi))
        if K < 1:
            break
        if infeasible(K):
            return K * h
        frac = 1.0 - 2.0 * (1.0 - frac)
    return 0.0


def _clusters(u: np.ndarray, A: np.ndarray, gap: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Impulse clusters of a grid solution: runs of nonzero amplitudes -> (weighted time, total amplitude)."""
    nz = np.flatnonzero(A > 1e-9 * A.max())
    groups: list[list[int]] = [[int(nz[0])]]
    for i in nz[1:]:
        if i - groups[-1][-1] <= gap:
            groups[-1].append(int(i))
        else:
            groups.append([int(i)])
    amps = np.array([A[g].sum() for g in groups])
    times = np.array([np.dot(A[g], u[g]) / A[g].sum() for g in groups])
    times -= times[0]
    return times, amps / amps.sum()


# ----------------------------------------------------------------------------- step 2: NLP polish


def _unpack(x: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    return np.concatenate([[0.0], x[: n - 1]]), x[n - 1: 2 * n - 1]


def _v2_and_grad(x: np.ndarray, n: int, q: np.ndarray, sig: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``|z_j|^2`` and its gradient in ``x = (u_2..u_n, A_1..A_n)``."""
    u, A = _unpack(x, n)
    with np.errstate(over="ignore", invalid="ignore"):  # far iterates of a failing SLSQP: nan, then refused
        W = np.exp(np.multiply.outer(q, u) - sig[:, None] * u[-1])
        z = W @ A
        dz_du = q[:, None] * W * A[None, :]
        dz_du[:, -1] -= sig * z
        dz = np.hstack([dz_du[:, 1:], W])
        return np.abs(z) ** 2, 2.0 * (np.conj(z)[:, None] * dz).real


def _linear_constraints(n: int, u_max: float | None) -> list[dict[str, Any]]:
    D = np.zeros((n - 1, 2 * n - 1))  # u_{i+1} - u_i >= 0 (u_1 = 0)
    for i in range(n - 1):
        D[i, i] = 1.0
        if i:
            D[i, i - 1] = -1.0
    cons = [{"type": "ineq", "fun": lambda x, D=D: D @ x, "jac": lambda x, D=D: D},
            {"type": "eq", "fun": lambda x: np.array([x[n - 1:].sum() - 1.0]),
             "jac": lambda x: np.concatenate([np.zeros(n - 1), np.ones(n)])[None, :]}]
    if u_max is not None:
        e = np.zeros(2 * n - 1)
        e[n - 2] = -1.0
        cons.append({"type": "ineq", "fun": lambda x: np.array([u_max - x[n - 2]]), "jac": lambda x: e[None, :]})
    return cons


def _stop_when(late: Any) -> Any:
    """An optimiser callback that ends the run (StopIteration, scipy >= 1.11) once ``late()``."""
    def callback(*_: Any) -> None:
        if late():
            raise StopIteration
    return callback


def _slsqp_shortest(x0: np.ndarray, n: int, q: np.ndarray, sig: np.ndarray, vtol: float,
                    late: Any = lambda: False) -> np.ndarray:
    """Shortest shaper from ``x0`` with ``V_j <= vtol``, as ``1 - V_j / target >= 0`` (scaled by the target,
    so that a small vtol is as well conditioned as a large one)."""
    target = vtol * (1 - _REL)
    grad = np.zeros(2 * n - 1)
    grad[n - 2] = 1.0

    def con(x: np.ndarray) -> np.ndarray:
        return 1.0 - np.sqrt(_v2_and_grad(x, n, q, sig)[0]) / target

    def jac(x: np.ndarray) -> np.ndarray:
        v2, g = _v2_and_grad(x, n, q, sig)
        return -g / (2.0 * np.maximum(np.sqrt(v2), 1e-300)[:, None] * target)

    cons = _linear_constraints(n, None) + [{"type": "ineq", "fun": con, "jac": jac}]
    bounds = [(0, None)] * (n - 1) + [(0, 1)] * n
    best, last = None, x0
    for shrink in (1.0, 0.99):  # a start at a degenerate point (ZVD: V = 0 twice) can stall SLSQP's line
        y0 = x0.copy()          # search; slightly shorter times get past it.  Keep the shortest.
        y0[: n - 1] *= shrink
        res = minimize(lambda x: x[n - 2], y0, jac=lambda x: grad, method="SLSQP", bounds=bounds,
                       constraints=cons, options={"maxiter": 120, "ftol": 1e-14}, callback=_stop_when(late))
        last = res.x
        ok = res.success and np.min(con(res.x)) >= -1e-6
        if ok and (best is None or res.x[n - 2] < best[n - 2]):
            best = res.x
        if ok and res.x[n - 2] < x0[n - 2] * (1 - 1e-6):  # progress from the start: no retry needed
            break
    return last if best is None else best


def _slsqp_minimax(x0: np.ndarray, n: int, q: np.ndarray, sig: np.ndarray, u_max: float,
                   late: Any = lambda: False) -> np.ndarray:
    """Least worst ``V^2`` with ``n`` impulses within ``[0, u_max]`` (variables x and the level s)."""
    y0 = np.concatenate([x0, [float(np.max(_v2_and_grad(x0, n, q, sig)[0]))]])
    cons = [{"type": c["type"], "fun": (lambda y, f=c["fun"]: f(y[:-1])),
             "jac": (lambda y, j=c["jac"]: np.hstack([np.atleast_2d(j(y[:-1])), np.zeros((np.atleast_2d(j(y[:-1])).shape[0], 1))]))}
            for c in _linear_constraints(n, u_max)]
    cons.append({"type": "ineq", "fun": lambda y: y[-1] - _v2_and_grad(y[:-1], n, q, sig)[0],
                 "jac": lambda y: np.hstack([-_v2_and_grad(y[:-1], n, q, sig)[1], np.ones((q.size, 1))])})
    e = np.zeros(y0.size)
    e[-1] = 1.0
    bounds = [(0, u_max)] * (n - 1) + [(0, 1)] * n + [(0, None)]
    res = minimize(lambda y: y[-1], y0, jac=lambda y: e, method="SLSQP", bounds=bounds, constraints=cons,
                   options={"maxiter": 300, "ftol": 1e-14}, callback=_stop_when(late))
    return res.x[:-1]


def _peaks(prob: _Problem, u: np.ndarray, A: np.ndarray, refine_above: float) -> list[tuple[int, float, float, float]]:
    """Local maxima of V on a dense grid of every band (refined when above ``refine_above``):
    ``(mode index, ratio, zeta, V)``, band ends included."""
    out = []
    for i, (m, (lo, hi), (z0, z1)) in enumerate(zip(prob.modes, prob.bands, prob.dampings)):
        nu_per = m.omega / prob.scale
        n = 1 if hi == lo else int(min(20000, max(101, math.ceil(40 * (hi - lo) * nu_per * u[-1] / (2 * math.pi)) + 101)))
        r = np.linspace(lo, hi, n)
        for z in (np.array([z0]) if z1 == z0 else np.linspace(z0, z1, 5)):
            q, sig = _qs(r * nu_per, np.full(n, z))
            V = np.abs(_z(u, A, q, sig, u[-1]))
            if n == 1:
                out.append((i, float(r[0]), float(z), float(V[0])))
                continue
            inner = np.flatnonzero((V[1:-1] >= V[:-2]) & (V[1:-1] >= V[2:])) + 1
            tall = set(inner[np.argsort(V[inner])[-25:]].tolist())  # refine the 25 tallest peaks at most
            for k in [0, n - 1] + inner.tolist():
                rk, vk = float(r[k]), float(V[k])
                if k in tall and vk > refine_above:
                    def f(x: float, z: float = float(z)) -> float:
                        qq, ss = _qs(np.array([x * nu_per]), np.array([z]))
                        return -float(np.abs(_z(u, A, qq, ss, u[-1]))[0])
                    res = minimize_scalar(f, bounds=(r[k - 1], r[k + 1]), method="bounded", options={"xatol": 1e-12})
                    if -res.fun > vk:
                        rk, vk = float(res.x), float(-res.fun)
                out.append((i, rk, float(z), vk))
    return out


def _point_arrays(prob: _Problem, pk: list[tuple[int, float, float, float]]) -> tuple[np.ndarray, np.ndarray]:
    nu = np.array([p[1] * prob.modes[p[0]].omega / prob.scale for p in pk])
    return _qs(nu, np.array([p[2] for p in pk]))


def _meets(prob: _Problem, u: np.ndarray, A: np.ndarray) -> bool:
    return max(p[3] for p in _peaks(prob, u, A, prob.vtol * 0.9)) <= prob.vtol * (1 + 1e-6)


def _exchange(prob: _Problem, u: np.ndarray, A: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
    """Step 2: SLSQP on an exchanged set of frequencies until the dense grid is within vtol.

    Returns the shortest iterate meeting the bands (or the start if it does and nothing shorter
    does), else the last iterate, and whether it meets them."""
    nu, ze, _, _ = prob.points(6, u[-1], 11, 3)
    q, sig = _qs(nu, ze)
    best = (u, A) if _meets(prob, u, A) else None
    for rnd in range(8):
        if rnd and prob.late():
            break
        n = u.size
        x = _slsqp_shortest(np.concatenate([u[1:], A]), n, q, sig, prob.vtol, prob.late)
        u_new, A_new = _unpack(x, n)
        keep = A_new > 1e-10  # drop vanished impulses
        u_new, A_new = u_new[keep] - u_new[keep][0], A_new[keep] / A_new[keep].sum()
        pk = _peaks(prob, u_new, A_new, prob.vtol * 0.9)
        ordered = bool(np.all(np.diff(u_new) > 1e-9 * max(u_new[-1], 1.0)))
        if ordered and max(p[3] for p in pk) <= prob.vtol * (1 + 1e-6):
            if best is None or u_new[-1] <= best[0][-1]:
                best = (u_new, A_new)
            return best[0], best[1], True
        over = [p for p in pk if p[3] > prob.vtol * (1 - 1e-3)]
        qa, sa = _point_arrays(prob, over)
        q, sig = np.concatenate([q, qa]), np.concatenate([sig, sa])
        if ordered:
            u, A = u_new, A_new
    if best is not None:
        return best[0], best[1], True
    return u, A, False


def _closed_form_starts(prob: _Problem) -> list[tuple[np.ndarray, np.ndarray]]:
    """Single mode: the closed-form families (ZV ... ZVDDD, MZV, EI, 2- and 3-hump EI) that meet the bands,
    in scaled time units; polishing them makes the result no longer than any of them."""
    if len(prob.modes) != 1:
        return []
    m = prob.modes[0]
    builders = [lambda k=k: zvdk_impulses(m, k) for k in range(4)] + [lambda: mzv_impulses(m)]
    if prob.vtol >= 1e-6:
        builders += [lambda: ei_exact(m, prob.vtol), lambda: ei_multi_hump(m, prob.vtol, 2),
                     lambda: ei_multi_hump(m, prob.vtol, 3)]
    out = []
    for build in builders:
        if prob.late():
            break
        try:
            t, a = build()
        except (ValueError, RuntimeError):  # a family without a solution at this (zeta, vtol)
            continue
        u = np.asarray(t, dtype=float) * prob.scale
        a = np.asarray(a, dtype=float)
        if max(p[3] for p in _peaks(prob, u, a, prob.vtol * 0.9)) <= prob.vtol * (1 + 1e-9):
            out.append((u, a))
    return out


# ----------------------------------------------------------------------------- step 4: KKT


def _kkt(prob: _Problem, u: np.ndarray, A: np.ndarray, pk: list[tuple[int, float, float, float]]) -> float:
    n = u.size
    if n < 2:
        return math.inf
    act = [p for p in pk if p[3] >= prob.vtol * (1 - 1e-5)]
    cols = []
    if act:
        q, sig = _point_arrays(prob, act)
        cols.append(-_v2_and_grad(np.concatenate([u[1:], A]), n, q, sig)[1])  # grad of vtol^2 - V^2
    m = 2 * n - 1
    for i in range(n):  # A_i >= 0 active
        if A[i] < 1e-9:
            e = np.zeros((1, m))
            e[0, n - 1 + i] = 1.0
            cols.append(e)
    for i in range(n - 1):  # u_{i+1} - u_i >= 0 active
        if u[i + 1] - u[i] < 1e-9:
            e = np.zeros((1, m))
            e[0, i] = 1.0
            if i:
                e[0, i - 1] = -1.0
            cols.append(e)
    G = np.vstack(cols) if cols else np.zeros((0, m))
    eq = np.concatenate([np.zeros(n - 1), np.ones(n)])[None, :]
    M = np.vstack([G, eq]).T
    g = np.zeros(m)
    g[n - 2] = 1.0
    lb = np.concatenate([np.zeros(G.shape[0]), [-np.inf]])
    res = lsq_linear(M, g, bounds=(lb, np.full(M.shape[1], np.inf)))
    return float(np.linalg.norm(M @ res.x - g) / np.linalg.norm(g))
