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
from .evaluation import EPS, TWO_PI, Evaluator

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
    return np.concatenate([centers, S[zy, zx]])


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
    return z, conv
