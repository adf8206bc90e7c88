"""Optimal lumped shapers: specified insensitivity (SI) and the shortest shaper under a firmware's limits.

The problem (Singhose, Seering and Singer's specified-insensitivity shapers, 1996/1997, for
several modes at once): for modes ``m`` with bands of frequency ratios ``[lo_m, hi_m]`` and
damping ranges ``[z_lo, z_hi]``,

    minimise ``t_n``  subject to  ``V(omega, zeta) <= vtol`` on every band,
    ``sum A_i = 1``, ``A_i >= 0``, ``0 = t_1 <= ... <= t_n``,
    and optionally ``n <= max_impulses`` and every ``t_i`` a multiple of ``sample_period``.

``V`` is the residual vibration of :mod:`posicast.analysis.vibration` with its default
``reference="end"`` (seed 004 eq. 1-3): ``V = e^{-zeta omega t_n} |sum A_i e^{zeta omega t_i}
e^{-j omega_d t_i}|``.

Method
------
1. **LP at a fixed duration** ``D``: amplitudes on a time grid (48 points per period of the
   highest frequency), ``|z| <= vtol`` as an inscribed 12-gon at sampled frequencies; the
   least polygon vibration ``s*(D)`` is a linear program (HiGHS).  Bisection on ``D`` gives the
   shortest grid shaper.
2. **Polish**: its impulse clusters start an SLSQP in continuous times and amplitudes with the
   exact constraints ``V^2 <= vtol^2`` and analytic gradients; frequencies where ``V`` peaks
   above ``vtol`` on a dense grid are added and the problem re-solved (an exchange method).
3. **Certificate** (a duration lower bound valid for *any* number of impulses at any times):
   any positive shaper of duration ``<= D``, its times rounded to a grid of step ``h``, is
   ``sum_k A_k w_k + B_k w'_k`` up to ``omega^2 h^2 / 8`` with ``|B_k| <= A_k h / 2``
   (``w_k = e^{(zeta omega - j omega_d) t_k - zeta omega D}``, ``|w''| <= omega^2``).  If that LP
   relaxation (circumscribed polygon) cannot bring ``V`` below ``vtol + omega^2 h^2 / 8`` at the
   sampled frequencies, no shaper of duration ``<= D`` meets the band: ``D`` is a lower bound.
4. **KKT residual** of the polished solution: the least-squares multipliers (``>= 0`` for the
   inequalities) of the active constraints and how far they leave the gradient of ``t_n``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from itertools import product
from typing import Any, NamedTuple, Sequence

import numpy as np
from scipy.optimize import minimize

from .. import _validate as v
from ..modes import Mode
from .base import TIME_RESOLUTION, Shaper, check_resolution
from .optimal_solver import (
    _GRID_PER_PERIOD,
    _MAX_LP,
    _Problem,
    _closed_form_starts,
    _clusters,
    _exchange,
    _kkt,
    _lower_bound,
    _lp,
    _lp_shortest,
    _peaks,
    _point_arrays,
    _qs,
    _slsqp_minimax,
    _unpack,
)

__all__ = ["ActiveConstraint", "Optimality", "OptimalShaper", "shortest_shaper", "si_shaper"]

_MAX_GRID = 2500             # most LP time-grid points (a duration cap: ~50 periods of the highest frequency)
_BUDGET = 2.5                # seconds after which the polish and the searches stop with the best found
_MAX_MODES = 10


@dataclass(frozen=True)
class ActiveConstraint:
    """A frequency (and damping) where the residual vibration reaches the tolerance."""

    mode: int          #: index of the mode (in the order given)
    ratio: float       #: omega / omega_mode
    zeta: float        #: damping ratio
    vibration: float   #: V there


@dataclass(frozen=True)
class Optimality:
    """How good an optimal shaper is, and why.

    Attributes
    ----------
    feasible : bool
        True if ``V <= vtol`` on the dense verification grid of every band (1e-6 relative slack).
    status : str
        ``"optimal"`` (a KKT point of the continuous problem), ``"feasible"`` (meets the bands but is
        not a verified KKT point, e.g. rounded to a sample grid), ``"infeasible"`` (the limits do not
        allow the bands: the shaper returned is the least-vibration one found) or ``"exact"`` (a closed
        form's defining equations solved to rounding).
    vtol : float
    max_vibration : float
        Largest ``V`` over the bands (dense grid, peaks refined).
    duration : float
        ``t_n`` [s].
    lower_bound : float
        Certified lower bound on the duration of *any* positive shaper meeting the bands at the
        sampled frequencies (LP relaxation, see the module docstring); 0 when not computed.
    n_impulses : int
    active : tuple of ActiveConstraint
        The frequencies where ``V`` touches ``vtol`` (within 1e-5 relative).
    kkt_residual : float or None
        ``|grad t_n - J^T lambda| / |grad t_n|`` over the active constraints (None where not computed:
        an infeasible result, or times rounded to a sample grid).
    message : str
    """

    feasible: bool
    status: str
    vtol: float
    max_vibration: float
    duration: float
    lower_bound: float
    n_impulses: int
    active: tuple[ActiveConstraint, ...]
    kkt_residual: float | None
    message: str

    @property
    def gap(self) -> float:
        """``(duration - lower_bound) / duration``: how far from the certified bound (1 without a bound)."""
        return (self.duration - self.lower_bound) / self.duration if self.duration > 0 else 0.0

    def summary(self) -> str:
        """One paragraph for a report or a terminal."""
        lb = f", certified lower bound {self.lower_bound:.6g} s (gap {100 * self.gap:.2f} %)" \
            if self.lower_bound > 0 else ""
        kkt = "" if self.kkt_residual is None else f", KKT residual {self.kkt_residual:.2g}"
        return (f"{self.status}: {self.n_impulses} impulses, duration {self.duration:.6g} s{lb}; "
                f"max V {self.max_vibration:.4g} (vtol {self.vtol:g}), {len(self.active)} active constraints"
                f"{kkt}. {self.message}")


@dataclass(frozen=True, eq=False, repr=False)
class OptimalShaper(Shaper):
    """A :class:`~posicast.shapers.base.Shaper` with its :class:`Optimality` (``.optimality``)."""

    optimality: Optimality | None = None



# ----------------------------------------------------------------------------- limits: N impulses, sample grid


def _merge_to(u: np.ndarray, A: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    u, A = u.copy(), A.copy()
    while u.size > n:
        i = int(np.argmin(np.diff(u)))
        w = A[i] + A[i + 1]
        t = (A[i] * u[i] + A[i + 1] * u[i + 1]) / w
        u = np.concatenate([u[:i], [t], u[i + 2:]])
        A = np.concatenate([A[:i], [w], A[i + 2:]])
    return u - u[0], A


def _limited(prob: _Problem, u: np.ndarray, A: np.ndarray, n: int, u_lb: float,
             u_cap: float) -> tuple[np.ndarray, np.ndarray, bool]:
    """At most ``n`` impulses: minimax SLSQP at growing durations from two starts, then the shortest."""
    nu, ze, _, _ = prob.points(6, max(u[-1], u_lb), 11, 3)
    q, sig = _qs(nu, ze)
    starts = [_merge_to(u, A, n)]
    D0 = max(u_lb, 1e-3)
    starts.append((np.linspace(0.0, D0, n), np.full(n, 1.0 / n)))
    best: tuple[float, np.ndarray, np.ndarray] | None = None
    fallback = None
    for u0, A0 in starts:
        x = np.concatenate([u0[1:] * D0 / max(u0[-1], 1e-12), A0])
        D = D0
        while D <= u_cap * (1 + 1e-12) and not prob.late():
            x = _slsqp_minimax(x, n, q, sig, D, prob.late)
            pk = _peaks(prob, *_unpack(x, n), prob.vtol * 0.5)
            worst = max(p[3] for p in pk)
            if fallback is None or worst < fallback[0]:
                fallback = (worst, *_unpack(x, n))
            if worst <= prob.vtol * (1 - 1e-4):
                uu, AA, met = _exchange(prob, *_unpack(x, n))
                if met and (best is None or uu[-1] < best[0]):
                    best = (uu[-1], uu, AA)
                break
            over = [p for p in pk if p[3] > 0.8 * max(prob.vtol, worst)]
            qa, sa = _point_arrays(prob, over)
            q, sig = np.concatenate([q, qa]), np.concatenate([sig, sa])
            if D >= u_cap:
                break
            D = min(u_cap, D * 1.15)  # warm start: the times stay, the bound grows
    if best is None:
        assert fallback is not None
        return fallback[1], fallback[2], False
    return best[1], best[2], True


def _amplitudes_at(prob: _Problem, u: np.ndarray, A_start: np.ndarray | None = None,
                   exact: bool = True) -> tuple[float, np.ndarray]:
    """Least worst V over amplitudes at fixed times ``u``: an LP (circumscribed polygon, a lower value than
    the exact one), then if ``exact`` SLSQP on the exact ``V^2`` at dense frequencies from the better of
    the LP's amplitudes and ``A_start``.  Returns (worst V at those frequencies, amplitudes)."""
    if not exact:  # a screening value: fewer frequencies, still a lower bound of the exact worst V
        nu, ze, _, _ = prob.points(8, u[-1], 11, 3)
        return _lp(*_qs(nu, ze), u, u[-1], inner=False)
    nu, ze, _, _ = prob.points(24, u[-1], 41, 5)
    q, sig = _qs(nu, ze)
    _, A0 = _lp(q, sig, u, u[-1], inner=False)
    W = np.exp(np.multiply.outer(q, u) - sig[:, None] * u[-1])
    n = u.size

    def v2(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        z = W @ y[:n]
        return np.abs(z) ** 2, 2.0 * (np.conj(z)[:, None] * W).real

    if A_start is not None and A_start.size == n and np.max(v2(A_start)[0]) < np.max(v2(A0)[0]):
        A0 = A_start
    y0 = np.concatenate([A0, [float(np.max(v2(A0)[0]))]])
    cons = [{"type": "ineq", "fun": lambda y: y[-1] - v2(y)[0],
             "jac": lambda y: np.hstack([-v2(y)[1], np.ones((q.size, 1))])},
            {"type": "eq", "fun": lambda y: np.array([y[:n].sum() - 1.0]),
             "jac": lambda y: np.concatenate([np.ones(n), [0.0]])[None, :]}]
    e = np.zeros(n + 1)
    e[-1] = 1.0
    res = minimize(lambda y: y[-1], y0, jac=lambda y: e, method="SLSQP", bounds=[(0, 1)] * n + [(0, None)],
                   constraints=cons, options={"maxiter": 100, "ftol": 1e-15})
    A = np.clip(res.x[:n], 0.0, None)
    A = A / A.sum()
    if np.max(v2(A)[0]) > np.max(v2(A0)[0]):
        A = A0
    return float(np.sqrt(np.max(v2(A)[0]))), A


def _stretched_roundings(prob: _Problem, u: np.ndarray, step: float, D: float) -> list[np.ndarray]:
    """Grid indices of the times stretched to ``D``: the floor/ceil roundings (up to 64, else the nearest)
    that the LP screen passes, shortest first (then least LP vibration), at most 4."""
    k = u * (D / u[-1]) / step if u[-1] > 0 else u / step
    inner = k[1:]
    choices = [np.unique(np.array([np.floor(x), np.ceil(x)])) for x in inner]
    combos = list(product(*choices)) if np.prod([c.size for c in choices]) <= 64 else [tuple(np.round(inner))]
    screened = []
    for c in combos:
        kk = np.unique(np.concatenate([[0.0], np.array(c, dtype=float)]))
        s_lp, _ = _amplitudes_at(prob, kk * step, exact=False)
        if s_lp <= prob.vtol:  # the LP's value is a lower bound of the exact one
            screened.append((kk[-1], s_lp, kk))
    return [kk for _, _, kk in sorted(screened, key=lambda c: (c[0], c[1]))[:4]]


def _meets_on_grid(prob: _Problem, s_ex: float, uu: np.ndarray, AA: np.ndarray) -> bool:
    """The exact worst ``V`` within tolerance, confirmed at the peaks of the dense grid."""
    if s_ex > prob.vtol * (1 + 1e-9):
        return False
    pk = _peaks(prob, uu, AA, prob.vtol * 0.9)
    return max(p[3] for p in pk) <= prob.vtol * (1 + 1e-6)


def _on_grid(prob: _Problem, u: np.ndarray, A: np.ndarray, step: float,
             u_cap: float) -> tuple[np.ndarray, np.ndarray, bool]:
    """Times rounded to multiples of ``step`` (scaled units), amplitudes re-solved; stretched until feasible.

    Each stretch tries the floor/ceil roundings of the times (up to 64), screened by the LP, shortest first;
    the exact amplitude problem is solved for the screened candidates."""
    best = None
    for stretch in range(0, 40 if step > 1e-9 * u[-1] else 1):  # a grid finer than the resolution: round once
        D = u[-1] + stretch * step
        if D > u_cap + step or (stretch and prob.late()):
            break
        for kk in _stretched_roundings(prob, u, step, D):
            uu = kk * step
            s_ex, AA = _amplitudes_at(prob, uu, A if kk.size == A.size else None)
            if best is None or s_ex < best[0]:
                best = (s_ex, uu, AA)
            if _meets_on_grid(prob, s_ex, uu, AA):
                keep = AA > 1e-12
                return uu[keep], AA[keep] / AA[keep].sum(), True
    if best is None:
        kk = np.unique(np.round(u / step))
        s_ex, AA = _amplitudes_at(prob, kk * step, A if kk.size == A.size else None)
        best = (s_ex, kk * step, AA)
    return best[1], best[2], False


# ----------------------------------------------------------------------------- public entry points


def _as_modes(modes: Any) -> tuple[Mode, ...]:
    if isinstance(modes, Mode):
        return (modes,)
    items = v.sequence(modes, "modes", min_len=1)
    for i, m in enumerate(items):
        v.instance_of(m, Mode, f"modes[{i}]", "a posicast Mode")
    return tuple(items)


def _per_mode(value: Any, n: int, name: str, lo: float, hi: float, default: Any, **kw: Any) -> tuple[tuple[float, float], ...]:
    """One ``(low, high)`` pair for every mode, or a sequence of ``n`` pairs."""
    if value is None:
        return tuple(default)
    if isinstance(value, (list, tuple)) and len(value) == n and n > 1 and all(
            isinstance(x, (list, tuple, np.ndarray)) for x in value):
        return tuple(v.ordered_pair(x, f"{name}[{i}]", lo, hi, **kw) for i, x in enumerate(value))
    if isinstance(value, (list, tuple)) and value and isinstance(value[0], (list, tuple, np.ndarray)):
        raise ValueError(f"{name} must be one (low, high) pair or one pair per mode ({n}), got {len(value)} pairs")
    p = v.ordered_pair(value, name, lo, hi, **kw)
    return (p,) * n


class _Spec(NamedTuple):
    """The checked arguments of :func:`shortest_shaper`."""

    modes: tuple[Mode, ...]
    vtol: float
    bands: tuple[tuple[float, float], ...]
    damps: tuple[tuple[float, float], ...]
    n_max: int | None   # max_impulses
    ts: float | None    # sample_period [s]
    dmax: float | None  # max_duration [s]


class _Search(NamedTuple):
    """The duration search's grid and limits, in scaled time units."""

    h: float        # LP grid step
    k_cap: int      # most grid steps searched
    u_cap: float    # longest duration searched


def _shortest_spec(modes: Any, vtol: Any, band: Any, damping: Any, max_impulses: Any, sample_period: Any,
                   max_duration: Any, certify: Any, name: Any) -> _Spec:
    ms = _as_modes(modes)
    if len(ms) > _MAX_MODES:
        raise ValueError(f"modes must be at most {_MAX_MODES} modes (each adds a band to every LP), got {len(ms)}: "
                         "design for the modes that matter, or in groups")
    tol = v.real_in_range(vtol, "vtol", 1e-6, 1.0, hi_open=True, hint=" (below 1e-6 the constraints are rounding)")
    bands = _per_mode(band, len(ms), "band", 0.0, 1000.0, None, lo_open=True)
    damps = _per_mode(damping, len(ms), "damping", 0.0, 1.0, [(m.zeta, m.zeta) for m in ms], hi_open=True)
    n_max = None if max_impulses is None else v.integer_in_range(max_impulses, "max_impulses", 2, 1000)
    ts = None if sample_period is None else v.positive(v.finite_real(sample_period, "sample_period"), "sample_period")
    dmax = None if max_duration is None else v.positive(v.finite_real(max_duration, "max_duration"), "max_duration")
    v.instance_of(certify, bool, "certify", "True or False")
    v.instance_of(name, str, "name", "a string")
    return _Spec(ms, tol, bands, damps, n_max, ts, dmax)


def _search_limits(spec: _Spec, scale: float) -> _Search:
    h = 2 * math.pi / _GRID_PER_PERIOD
    dmax = spec.dmax
    k_cap = _MAX_GRID if dmax is None else max(2, min(_MAX_GRID, int(math.floor(dmax * scale / h))))
    u_cap = (dmax * scale) if dmax is not None else k_cap * h
    return _Search(h, k_cap, u_cap)


def _least_vibration(prob: _Problem, spec: _Spec, lim: _Search, A_grid: np.ndarray, s_cap: float, k_done: int,
                     notes: list[str]) -> tuple[np.ndarray, np.ndarray, bool]:
    """No positive shaper within the cap: the least-vibration grid shaper there, and why."""
    u, A = _clusters(np.arange(k_done + 1) * lim.h, A_grid)
    tol, scale = spec.vtol, prob.scale
    if prob.late():
        notes.append(f"the duration search stopped at the time budget ({_BUDGET:g} s) at {k_done * lim.h / scale:.6g} s "
                     f"(least polygon vibration there {s_cap:.4g} > vtol {tol:g})")
    elif k_done >= lim.k_cap:
        notes.append(f"no positive shaper of duration <= {lim.u_cap / scale:.6g} s keeps V <= {tol:g} on the "
                     f"bands (least polygon vibration there {s_cap:.4g})")
    else:
        notes.append(f"the search stopped at duration {k_done * lim.h / scale:.6g} s (least polygon vibration "
                     f"there {s_cap:.4g} > vtol {tol:g}): a longer LP would exceed {_MAX_LP:g} entries; "
                     "narrow the bands or raise vtol")
    if spec.n_max is not None and u.size > spec.n_max:
        u, A = _merge_to(u, A, spec.n_max)
    return u, A, False


def _polished(prob: _Problem, u: np.ndarray, A: np.ndarray, ok: bool) -> tuple[np.ndarray, np.ndarray, bool]:
    """The grid shaper's polish, replaced by a closed form's when that is shorter, then re-polished."""
    for u0, A0 in _closed_form_starts(prob):  # a closed form meeting the bands bounds the duration
        if not ok or u0[-1] < u[-1] * (1 - 1e-9):
            u1, A1, _ = _exchange(prob, u0, A0) if not prob.late() else (u0, A0, True)  # the start meets
            if not ok or u1[-1] < u[-1]:                                                 # the bands
                u, A, ok = u1, A1, True
    for _ in range(2):  # re-polish from the result while it is not a KKT point (SLSQP can stall near
        if not ok or prob.late() or _kkt(prob, u, A, _peaks(prob, u, A, prob.vtol * 0.5)) <= 1e-5:  # degenerate
            break
        u1, A1, ok1 = _exchange(prob, u, A)
        if not (ok1 and u1[-1] < u[-1] * (1 - 1e-12)):
            break
        u, A = u1, A1
    return u, A, ok


def _shortest_found(prob: _Problem, spec: _Spec, lim: _Search, K: int, A_grid: np.ndarray,
                    notes: list[str]) -> tuple[np.ndarray, np.ndarray, bool]:
    """A positive grid shaper of ``K`` steps meets the bands: polished, then limited to ``max_impulses``."""
    u, A, ok = _polished(prob, *_exchange(prob, *_clusters(np.arange(K + 1) * lim.h, A_grid)))
    if not ok:
        notes.append("the polish did not reach a shaper meeting the bands on the dense grid")
    n_max = spec.n_max
    if n_max is not None and u.size > n_max:
        search_cap = min(lim.u_cap, 4.0 * u[-1])  # fewer impulses: searched up to 4x the unlimited optimum
        u, A, ok = _limited(prob, u, A, n_max, K * lim.h * 0.9, search_cap)
        if not ok:
            notes.append(f"the search found no shaper of {n_max} impulses keeping V <= {spec.vtol:g} on the bands "
                         f"within {search_cap / prob.scale:.6g} s (4x the unlimited optimum; a local search, not a "
                         "proof); this is the least-vibration shaper found")
    return u, A, ok


def _on_sample_grid(prob: _Problem, spec: _Spec, u_cap: float, u: np.ndarray, A: np.ndarray, ok: bool,
                    notes: list[str]) -> tuple[np.ndarray, np.ndarray, bool]:
    """A feasible shaper's times moved to the ``sample_period`` grid (when one is asked and it can be)."""
    ts, scale = spec.ts, prob.scale
    if not ok or ts is None:
        return u, A, ok
    if ts * scale > u_cap:
        notes.append(f"sample_period={ts:g} s is longer than the longest shaper searched ({u_cap / scale:.6g} s)")
        return u, A, False
    if ts * scale < TIME_RESOLUTION * u[-1]:
        notes.append(f"sample_period={ts:g} s is below the time resolution ({TIME_RESOLUTION:g} x duration): "
                     "the times are left as designed")
        return u, A, ok
    u, A, ok = _on_grid(prob, u, A, ts * scale, u_cap)
    if not ok:
        notes.append(f"no shaper on the {ts:g} s sample grid within the limits keeps V <= {spec.vtol:g}; "
                     "this is the least-vibration one found")
    elif spec.n_max is not None and u.size > spec.n_max:  # pragma: no cover - rounding never adds impulses
        ok = False
    return u, A, ok


def _within_duration(prob: _Problem, spec: _Spec, u_cap: float, u: np.ndarray, ok: bool, notes: list[str]) -> bool:
    """``ok`` unless the shaper outlasts ``max_duration``; the time-budget note."""
    if ok and spec.dmax is not None and u[-1] > u_cap * (1 + 1e-9):
        ok = False
        notes.append(f"the shortest shaper lasts {u[-1] / prob.scale:.6g} s, more than max_duration={spec.dmax:g} s")
    if prob.late():
        notes.append(f"the searches stopped at the time budget ({_BUDGET:g} s) with the best shaper found")
    return ok


def _kkt_status(prob: _Problem, u: np.ndarray, A: np.ndarray, pk: Any, feasible: bool,
                ts: float | None) -> tuple[float | None, str]:
    """The KKT residual (off the sample grid; None when not finite) and the status it gives."""
    kkt = _kkt(prob, u, A, pk) if feasible and ts is None else None
    kkt = kkt if kkt is not None and math.isfinite(kkt) else None
    status = "infeasible" if not feasible else ("optimal" if kkt is not None and kkt <= 1e-5 else "feasible")
    return kkt, status


def _optimality(prob: _Problem, spec: _Spec, h: float, u: np.ndarray, A: np.ndarray, ok: bool, certify: bool,
                notes: list[str]) -> Optimality:
    """The certificate of the final shaper (``u`` in scaled units): peaks, KKT residual, lower bound."""
    tol, ts, scale = spec.vtol, spec.ts, prob.scale
    pk = _peaks(prob, u, A, tol * 0.5)
    worst = max(p[3] for p in pk)
    feasible = ok and worst <= tol * (1 + 1e-6)
    kkt, status = _kkt_status(prob, u, A, pk, feasible, ts)
    lb = _lower_bound(prob, int(math.floor(u[-1] / h))) / scale if certify and feasible else 0.0
    if feasible and status == "feasible" and ts is None:
        notes.append(f"the solver stopped at a feasible point whose KKT residual {kkt:.2g} is above 1e-5")
    active = tuple(ActiveConstraint(p[0], p[1], p[2], p[3]) for p in pk if p[3] >= tol * (1 - 1e-5))
    times = u / scale
    if times.size >= 2:  # a mode too fast for seconds as the time unit: refused as design() refuses it
        check_resolution(float(times[-1]), float(times[-1]),
                         f"an optimal shaper for omega up to {scale:g} rad/s")
    return Optimality(feasible, status, tol, worst, float(times[-1]), min(lb, float(times[-1])), int(times.size),
                      active, kkt, " ".join(notes))


def _shortest_params(spec: _Spec) -> dict[str, Any]:
    params = {"vtol": spec.vtol, "band": spec.bands[0] if len(spec.bands) == 1 else spec.bands,
              "damping": spec.damps[0] if len(spec.damps) == 1 else spec.damps}
    for key, val in (("max_impulses", spec.n_max), ("sample_period", spec.ts), ("max_duration", spec.dmax)):
        if val is not None:
            params[key] = val
    return params


def shortest_shaper(modes: Mode | Sequence[Mode], *, vtol: float = 0.05, band: Any = (0.9, 1.1),
                    damping: Any = None, max_impulses: int | None = None, sample_period: float | None = None,
                    max_duration: float | None = None, certify: bool = True, name: str = "optimal") -> OptimalShaper:
    """The shortest positive shaper keeping the residual vibration ``<= vtol`` over bands around modes.

    Parameters
    ----------
    modes : Mode or sequence of Mode
        The modes (one to three is the benchmarked range; more work, slower).
    vtol : float
        Tolerable residual vibration (``reference="end"``), in (0, 1).
    band : (low, high) or sequence of them
        Frequency ratios ``omega / omega_mode`` to protect, ``0 < low <= high <= 1000``; one pair for every
        mode or one per mode.  ``low == high`` is a single frequency.
    damping : (low, high) or sequence of them, optional
        Damping range of each mode (``0 <= low <= high < 1``); default each mode's own ``zeta``.
    max_impulses : int, optional
        At most this many impulses (a firmware's limit, e.g. RepRapFirmware's custom shaper), ``>= 2``.
    sample_period : float, optional
        Impulse times on multiples of this period [s] (a controller's step), ``> 0``.
    max_duration : float, optional
        Longest acceptable duration [s] (a smoothing bound), ``> 0``.
    certify : bool
        Compute the certified duration lower bound (a few more LPs).
    name : str
        The shaper's name.

    Returns
    -------
    OptimalShaper
        An ordinary :class:`~posicast.shapers.base.Shaper` with ``.optimality``.  When the limits do not
        allow the bands (too wide for ``max_impulses``, a too short ``max_duration``, a coarse
        ``sample_period``) the result says so: ``optimality.feasible`` is False, ``status`` is
        ``"infeasible"`` and the shaper is the least-vibration one found.

    Raises
    ------
    TypeError, ValueError
        Bad parameters (the message names them).

    Examples
    --------
    >>> S = shortest_shaper(Mode(2 * math.pi, 0.0), vtol=0.05, band=(0.9, 1.1))
    >>> S.optimality.feasible, S.n_impulses, round(S.duration, 4)
    (True, 3, 0.8877)
    >>> S.optimality.lower_bound <= S.duration
    True
    """
    spec = _shortest_spec(modes, vtol, band, damping, max_impulses, sample_period, max_duration, certify, name)
    scale = max(m.omega * b[1] for m, b in zip(spec.modes, spec.bands))
    prob = _Problem(spec.modes, spec.bands, spec.damps, spec.vtol, scale, time.perf_counter() + _BUDGET)
    lim = _search_limits(spec, scale)
    K, A_grid, _, s_cap, k_done = _lp_shortest(prob, lim.k_cap)
    notes: list[str] = []
    if K is None:
        u, A, ok = _least_vibration(prob, spec, lim, A_grid, s_cap, k_done, notes)
    else:
        u, A, ok = _shortest_found(prob, spec, lim, K, A_grid, notes)
    u, A, ok = _on_sample_grid(prob, spec, lim.u_cap, u, A, ok, notes)
    ok = _within_duration(prob, spec, lim.u_cap, u, ok, notes)
    opt = _optimality(prob, spec, lim.h, u, A, ok, certify, notes)
    return OptimalShaper(u / scale, A, name=name, modes=spec.modes, params=_shortest_params(spec), optimality=opt)


def si_shaper(mode: Mode | Sequence[Mode], vtol: float = 0.05, band: Any = (0.9, 1.1), damping: Any = None,
              max_impulses: int | None = None) -> OptimalShaper:
    """The specified-insensitivity shaper (``design("si", ...)``): :func:`shortest_shaper` named ``"si"``."""
    return shortest_shaper(mode, vtol=vtol, band=band, damping=damping, max_impulses=max_impulses, name="si")
