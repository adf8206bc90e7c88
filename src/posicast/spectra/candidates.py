"""Candidates and Newton (steps 2 and 3 of :func:`posicast.roots`).

As in QPmR (seed 000 ref. [22], Vyhlídal & Zítek 2009) the region is covered by a grid
whose step follows the delays (:func:`grid_step`); the discrete winding of ``h`` around
every grid cell flags the cells that hold roots (:func:`grid_candidates`).  A vectorised
damped Newton (:func:`newton`) refines them.
"""

from __future__ import annotations

import math

import numpy as np

from ..core.quasipoly import QuasiPolynomial
from .checks import BudgetExceeded
from .evaluation import EPS, TWO_PI, Evaluator, relative_residual

__all__ = ["grid_step", "grid_shape", "grid_candidates", "newton"]


def grid_step(q: QuasiPolynomial, rect: tuple[float, float, float, float]) -> float:
    """The candidate grid's step: a sixteenth of the longer side, at most a sixth of a chain's spacing."""
    w, h = rect[1] - rect[0], rect[3] - rect[2]
    step = max(w, h) / 16.0
    tau_max = float(q.delays[-1])
    if tau_max > 0:
        # roots of a chain are about 2 pi / tau apart: six grid steps per spacing
        step = min(step, math.pi / (3.0 * tau_max))
    return step


MAX_GRID = 2e7  # grid points held at once (complex: 320 MB)


def _fmt_rect(rect: tuple[float, float, float, float]) -> str:
    return "(" + ", ".join(f"{float(x):.6g}" for x in rect) + ")"


def grid_shape(rect: tuple[float, float, float, float], step: float) -> tuple[int, int]:
    """Grid nodes ``(nx, ny)`` of ``rect`` at ``step``."""
    # at least 5 nodes a side: a thin rectangle gets elongated cells, not a finer grid
    nx = max(5, int(math.ceil((rect[1] - rect[0]) / step)) + 1)
    ny = max(5, int(math.ceil((rect[3] - rect[2]) / step)) + 1)
    return nx, ny


def grid_candidates(ev: Evaluator, rect: tuple[float, float, float, float], step: float) -> np.ndarray:
    """Centres of the grid cells around which ``h`` winds, and grid nodes where ``h`` is exactly 0."""
    a, b, c, d = rect
    nx, ny = grid_shape(rect, step)
    # refused before it is allocated: a refinement halves the step, so a large region's grid grows 4x a level
    left = ev.budget - ev.evaluations
    if nx * ny > min(left, MAX_GRID):
        raise BudgetExceeded(
            f"the search of {_fmt_rect(rect)} needs a {nx * ny:.3g}-point grid (step {step:.3g}), over the "
            f"{min(left, MAX_GRID):.3g} evaluations left of max_evaluations={ev.budget:.3g} (at most {MAX_GRID:.0e} "
            "held at once); shrink the region or raise max_evaluations"
        )
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
    wind = (dh[:-1, :] + dv[:, 1:] - dh[1:, :] - dv[:, :-1]) / TWO_PI
    wind = np.nan_to_num(wind, nan=1.0)
    iy, ix = np.nonzero(np.abs(wind) > 0.5)
    centers = 0.5 * (x[ix] + x[ix + 1]) + 0.5j * (y[iy] + y[iy + 1])
    # zero samples (a root exactly on a grid node) are candidates too
    zy, zx = np.nonzero(H == 0)
    # and the nodes where |h| is below its four neighbours: h rho is analytic times a factor of modulus
    # 1 (rho = exp(min(0, Re s) tau_max)), so |h rho| has local minima only at roots, and a node's
    # discrete minimum is next to one.  The cells' winding misses roots where the cells are long
    # against their distance to the root (a thin strip right of a root chain: 0.25 x 8 cells); the
    # minima catch them without the splits of reconciliation (issue #15).  Square cells need them not.
    dx, dy = (b - a) / (nx - 1), (d - c) / (ny - 1)
    if not max(dx, dy) > 2.0 * min(dx, dy):
        return np.concatenate([centers, S[zy, zx]])
    A = np.abs(H)
    P = np.pad(A, 1, constant_values=np.inf)
    lm = (A < P[:-2, 1:-1]) & (A < P[2:, 1:-1]) & (A < P[1:-1, :-2]) & (A < P[1:-1, 2:])
    my, mx = np.nonzero(lm)
    return np.concatenate([centers, S[zy, zx], S[my, mx]])


def newton(
    ev: Evaluator, z: np.ndarray, max_step: float | np.ndarray, q: QuasiPolynomial | None = None, iters: int = 60
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
        done = (np.abs(st) <= 4 * EPS * np.maximum(np.abs(za), 1.0)) & ~bad
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
    # A root next to s = 0 much closer than 1 (-1e-300 for a loop with a gain of 1e-300) passes the
    # absolute test above one step early, at a point where h is all rounding: one more step, kept
    # where it lowers the relative residual.
    small = conv & (np.abs(z) < 1e-3)
    if np.any(small):
        zs = z[small]
        st = ev.newton_step(zs, q, dq)
        zn = zs - np.where(np.isfinite(st), st, 0.0)
        qq = ev.q if q is None else q
        better = relative_residual(qq, zn) < relative_residual(qq, zs)
        z[np.flatnonzero(small)[better]] = zn[better]
    return z, conv
