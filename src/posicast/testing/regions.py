"""Check a computed region against brute force: sample gains, compute ``||S||_inf`` and stability directly.

Independent of the region machinery: the peak sensitivity of each sampled
controller is ``max 1 / |1 + C(j omega) P(j omega)|`` on a dense uniform grid
plus a log grid (refined by a 1-D search near the bound), and stability is a
certified spectrum check of that controller's loop (:meth:`Loop.stability`).
A point the region classifies differently is *explained* when the brute-force
classification at the same ``ky`` on the nearest scan line agrees with the
region: the boundary then lies between the point and that line, at most half a
line spacing (in ``kx``) away.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from .. import _validate as v
from ..spectra.rootfinder import RootFindingError
from ..tune.design import TuningResult

# Work bounds of sample_check: the brute force evaluates n x n_uniform loop frequency responses (about
# 10 ns each) and one certified spectrum check per candidate point (about 10 ms each).
MAX_SAMPLES = 20_000
MAX_UNIFORM = 1_000_000
MAX_EVALUATIONS = 5e9

__all__ = ["RegionCheck", "sample_check", "brute_force_sensitivity"]


@dataclass(frozen=True)
class RegionCheck:
    """Outcome of :func:`sample_check`.

    Attributes
    ----------
    points : ndarray, shape (n, 2)
        Sampled ``(kx, ky)``.
    ms : ndarray
        Brute-force ``||S||_inf`` per point.
    stable : ndarray of bool or None-like
        Certified stability (checked only where ``ms < Ms``; False elsewhere).
    brute, region : ndarray of bool
        Admissible by brute force / by the region.
    misclassified : ndarray of int
        Indices where the two disagree.
    explained : ndarray of bool
        For each misclassified point: the boundary lies within half a line spacing in ``kx``.
    unexplained : int
    failures : int
        Spectrum checks that could not be certified (those points are left out).
    seconds : float
        Brute-force time.
    """

    points: np.ndarray
    ms: np.ndarray
    stable: np.ndarray
    brute: np.ndarray
    region: np.ndarray
    misclassified: np.ndarray
    explained: np.ndarray
    failures: int
    seconds: float

    @property
    def unexplained(self) -> int:
        return int(np.count_nonzero(~self.explained))


def _dense_grid(result: TuningResult, n_uniform: int) -> np.ndarray:
    eng = result.region.problem
    fd = eng.fd
    w = fd.omega[: fd.n_grid]
    ext = result.region.extent() or (0.0, 1.0, 0.0, 1.0)
    X = max(abs(ext[0]), abs(ext[1])) * 1.5
    Y = max(abs(v) for v in ext[2:] if math.isfinite(v)) * 1.5 if any(math.isfinite(v) for v in ext[2:]) else 1.0
    L = X * np.abs(eng.columns.a[: fd.n_grid]) + Y * np.abs(eng.columns.b[: fd.n_grid]) + np.abs(eng.columns.u[: fd.n_grid] - 1)
    sig = np.flatnonzero(np.isfinite(L) & (L > 1e-3))
    w_max = float(w[sig[-1]]) * 2.0 if sig.size else float(w[-1])
    w_pos = w[w > 0]
    return np.unique(np.concatenate([np.linspace(w_max / n_uniform, w_max, n_uniform),
                                     np.geomspace(w_pos[0], w_pos[-1], 4000)]))


def brute_force_sensitivity(result: TuningResult, points: np.ndarray, n_uniform: int = 40000,
                            refine_within: float = 0.02) -> np.ndarray:
    """``||S||_inf`` of the family's controller at each ``(kx, ky)`` of ``points`` (direct evaluation)."""
    fam = result.family
    loop0 = result.region.problem.loop_factory(0.0, 0.0)
    P = loop0.plant_gain
    w = _dense_grid(result, n_uniform)
    s = 1j * w
    p = np.asarray(P(s))
    den = np.polyval(fam.dC, s)
    c0 = np.polyval(fam.n0, s) / den
    cx = np.polyval(fam.nx, s) / den
    cy = np.polyval(fam.ny, s) / den
    out = np.empty(len(points))
    gamma = next((c.gamma for c in result.constraints if c.kind == "S" and c.weight is None), None)
    for k0 in range(0, len(points), 64):
        blk = points[k0 : k0 + 64]
        C = c0[None, :] + blk[:, :1] * cx[None, :] + blk[:, 1:2] * cy[None, :]
        mag = 1.0 / np.abs(1.0 + C * p[None, :])
        mag = np.where(np.isfinite(mag), mag, 0.0)
        out[k0 : k0 + 64] = mag.max(axis=1)
        if gamma is None:
            continue
        for r, (kx, ky) in enumerate(blk):
            val = out[k0 + r]
            if abs(val - gamma) > refine_within * gamma:
                continue
            i = int(np.argmax(mag[r]))
            lo, hi = w[max(i - 1, 0)], w[min(i + 1, w.size - 1)]
            num = np.poly1d(fam.numerator(kx, ky))
            dC = np.poly1d(fam.dC)
            f = lambda x: -1.0 / abs(1.0 + num(1j * x) / dC(1j * x) * complex(P(1j * x)))  # noqa: E731
            res = minimize_scalar(f, bounds=(lo, hi), method="bounded", options={"xatol": 1e-12 * max(hi, 1)})
            out[k0 + r] = max(val, -res.fun)
    return out


def _stable(result: TuningResult, kx: float, ky: float) -> bool | None:
    try:
        return bool(result.region.problem.loop_factory(kx, ky).stability(max_evaluations=2e7, timeout=20.0).stable)
    except (RootFindingError, ValueError):
        return None


def sample_check(result: TuningResult, n: int = 2000, seed: int = 0, margin: float = 0.3,
                 n_uniform: int = 40000) -> RegionCheck:
    """Sample ``n`` gains uniformly in the region's box (enlarged by ``margin``) and classify them directly.

    Only the ``||S||_inf < Ms`` constraint is checked (the seed 001 case); the
    result must have exactly one unweighted ``'S'`` constraint.
    """
    n = v.integer_in_range(n, "n", 1, MAX_SAMPLES)
    seed = v.integer_in_range(seed, "seed", 0, 2**63 - 1)
    n_uniform = v.integer_in_range(n_uniform, "n_uniform", 100, MAX_UNIFORM)
    margin = v.real_in_range(margin, "margin", 0.0, 100.0)
    v.refuse_large(float(n) * n_uniform, MAX_EVALUATIONS, f"sample_check with n = {n} and n_uniform = {n_uniform} "
                   f"(n x n_uniform frequency-response evaluations)", "use fewer samples n or a smaller n_uniform",
                   "evaluations")
    if not isinstance(result, TuningResult):
        raise TypeError(f"result must be a TuningResult, got {type(result).__name__}")
    if len(result.constraints) != 1 or result.constraints[0].kind != "S" or result.constraints[0].weight is not None:
        raise ValueError("sample_check handles a single unweighted ||S||inf < Ms constraint")
    region = result.region
    ext = region.extent()
    if ext is None:
        raise ValueError("the region is empty: nothing to sample")
    x0, x1 = region.x[0], region.x[-1]
    y0, y1 = ext[2], ext[3]
    dy = (y1 - y0) * margin
    rng = np.random.default_rng(seed)
    pts = np.column_stack([rng.uniform(x0, x1, n), rng.uniform(y0 - dy, y1 + dy, n)])
    Ms = result.constraints[0].gamma
    t0 = time.perf_counter()
    ms = brute_force_sensitivity(result, pts, n_uniform)
    stable = np.zeros(n, dtype=bool)
    failures = 0
    cand = np.flatnonzero(ms < Ms)
    for k in cand:
        st = _stable(result, *pts[k])
        if st is None:
            failures += 1
        stable[k] = bool(st)
    seconds = time.perf_counter() - t0
    brute = (ms < Ms) & stable
    inside = region.contains(pts[:, 0], pts[:, 1])
    mis = np.flatnonzero(brute != inside)
    explained = np.zeros(mis.size, dtype=bool)
    if mis.size:
        idx = np.abs(region.x[None, :] - pts[mis, :1]).argmin(axis=1)
        on_line = np.column_stack([region.x[idx], pts[mis, 1]])
        ms_line = brute_force_sensitivity(result, on_line, n_uniform)
        for r, (k, q) in enumerate(zip(mis, on_line)):
            st = _stable(result, *q) if ms_line[r] < Ms else False
            explained[r] = bool((ms_line[r] < Ms) and bool(st)) == bool(inside[k])
    return RegionCheck(pts, ms, stable, brute, inside, mis, explained, failures, seconds)
