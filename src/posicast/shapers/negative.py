"""Unity-magnitude (negative) input shapers: UM-ZV and UM-ZVD, solved exactly for damped modes.

A unity-magnitude shaper has impulses ``+1, -1, +1, ...`` (sum 1).  Its running sum
(the shaped response to a unit step) is only ever 0 or 1, so a step command that uses
the full actuator range stays within it; that is the amplitude bound these shapers are
built around (Singhose, Seering and Singer, "Time-optimal negative input shapers",
ASME J. Dyn. Syst. Meas. Control 119(2), 1997).  For any other bounded input ``|u| <= U``
the shaped command is bounded by ``sum |A_i| U``: ``3 U`` for UM-ZV, ``5 U`` for UM-ZVD.

* UM-ZV: ``A = [1, -1, 1]`` at ``[0, t2, t3]`` with ``S(p) = 0`` at the mode's pole.
  For ``zeta = 0`` the three phasors form an equilateral triangle: ``t2 = T/6``,
  ``t3 = T/3`` (duration ``T / 3`` against ZV's ``T / 2``).
* UM-ZVD: ``A = [1, -1, 1, -1, 1]`` at ``[0, t2, t3, t4, t5]`` with ``S(p) = S'(p) = 0``.

Singhose et al. publish cubic curve fits in ``zeta`` of the times (in units of the
undamped period ``T_n``); here the times are solved from the definitions by Newton's
method started from those fits, with continuation in ``zeta`` when the fit is too far off
(the fits are stated for ``zeta <= 0.3``).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import minimize, root

from ..modes import Mode
from .. import _validate as v
from .base import check_decay, check_mode, check_resolution
from .optimal import ActiveConstraint, OptimalShaper, Optimality
from .optimal_solver import _peaks, _point_arrays, _Problem, _qs

__all__ = ["um_zv_impulses", "um_zvd_impulses", "um_shaper", "um_si_shaper", "UM_FIT", "um_fit_times"]

#: Singhose, Seering & Singer (1997) curve fits ``t_i / T_n = M0 + M1 z + M2 z^2 + M3 z^3``
#: (``T_n = 2 pi / omega``, undamped period), as printed in their Table (UM-ZV, UM-ZVD).
UM_FIT = {
    "um_zv": ((0.16724, 0.27242, 0.20345, 0.0), (0.33323, 0.00533, 0.17914, 0.20125)),
    "um_zvd": ((0.08945, 0.28411, 0.23013, 0.16401), (0.36613, -0.08833, 0.24048, 0.17001),
               (0.64277, 0.29103, 0.23262, 0.43784), (0.73228, 0.00992, 0.49385, 0.38633)),
}


def um_fit_times(kind: str, mode: Mode) -> np.ndarray:
    """The published curve-fit times (s) of ``kind`` ("um_zv" or "um_zvd"), first impulse at 0."""
    Tn = 2.0 * math.pi / mode.omega
    z = mode.zeta
    return np.array([0.0] + [Tn * (c[0] + c[1] * z + c[2] * z * z + c[3] * z ** 3) for c in UM_FIT[kind]])


def _undamped(n_deriv: int) -> np.ndarray:
    """Times (in damped periods) of the undamped UM shaper: exact for UM-ZV, solved for UM-ZVD."""
    if n_deriv == 0:
        return np.array([0.0, 1.0 / 6.0, 1.0 / 3.0])
    # symmetric UM-ZVD at zeta = 0: times 0, a, c, 2c - a, 2c (in periods, x = 2 pi t):
    # S(j) e^{j 2pi c} = 2 cos(2pi c) - 2 cos(2pi (c - a)) + 1 = 0 and its derivative
    # d/dw: -2 c sin(2pi c) + 2 (c - a) sin(2pi (c - a)) = 0 (the phase factor's term vanishes with S)
    def f(x: np.ndarray) -> np.ndarray:
        a, c = x
        return np.array([2 * math.cos(2 * math.pi * c) - 2 * math.cos(2 * math.pi * (c - a)) + 1,
                         -2 * c * math.sin(2 * math.pi * c) + 2 * (c - a) * math.sin(2 * math.pi * (c - a))])

    sol = root(f, [0.08945, 0.36613], tol=1e-15)
    a, c = sol.x
    return np.array([0.0, a, c, 2 * c - a, 2 * c])


def _solve(mode: Mode, amps: np.ndarray, n_deriv: int, start: np.ndarray) -> np.ndarray | None:
    """Times (s, first 0) with ``S^(k)(p) = 0`` for ``k <= n_deriv``; None if Newton fails."""
    p = mode.pole
    scale = mode.damped_omega  # work in radians of the damped oscillation

    def F(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t = np.concatenate([[0.0], x])
        e = amps * np.exp(-p / scale * t)
        res, jac = [], []
        for k in range(n_deriv + 1):
            tk = t ** k
            val = np.sum(tk * e)
            # d/dt_i of t_i^k A_i e^{-q t_i} = (k t_i^{k-1} - q t_i^k) A_i e^{-q t_i}
            d = ((k * t ** (k - 1) if k else 0.0) - p / scale * tk) * e
            res += [val.real, val.imag]
            jac += [d[1:].real, d[1:].imag]
        return np.array(res), np.array(jac)

    with np.errstate(over="ignore", invalid="ignore"):
        sol = root(F, start[1:] * scale, jac=True, method="hybr", tol=1e-14)
        x = sol.x
        t = np.concatenate([[0.0], x]) / scale
        r, _ = F(x)
    if not (np.all(np.isfinite(r)) and np.all(np.diff(t) > 0) and np.max(np.abs(r)) < 1e-9):
        return None
    return t


def _um(mode: Mode, n_deriv: int, kind: str) -> tuple[np.ndarray, np.ndarray]:
    check_mode(mode)
    n = 3 if n_deriv == 0 else 5
    amps = np.array([(-1.0) ** i for i in range(n)])
    check_decay(mode, 0.5 if n_deriv == 0 else 1.0, f"a {kind.upper()} shaper")
    Td = mode.damped_period
    for start in (um_fit_times(kind, mode), _undamped(n_deriv) * Td):
        t = _solve(mode, amps, n_deriv, start)
        if t is not None:
            return t, amps
    # continuation in zeta from the undamped solution (beyond the fits' range)
    t = _undamped(n_deriv) * Mode(mode.omega, 0.0).damped_period
    for z in np.linspace(0.0, mode.zeta, 41)[1:]:
        m = Mode(mode.omega, float(z))
        t_new = _solve(m, amps, n_deriv, t)
        if t_new is None:
            raise ValueError(f"zeta={mode.zeta:g}: the {kind.upper()} equations have no solution with ordered "
                             f"times beyond zeta={float(z):.3g}; use a positive shaper (zvd, ei, si)")
        t = t_new
    return t, amps


def um_zv_impulses(mode: Mode) -> tuple[np.ndarray, np.ndarray]:
    """UM-ZV: ``[1, -1, 1]`` with ``S(p) = 0`` (Singhose, Seering, Singer 1997).

    Examples
    --------
    >>> t, a = um_zv_impulses(Mode(2 * math.pi, 0.0))      # 1 Hz: T = 1 s
    >>> np.round(t, 12).tolist(), a.tolist()
    ([0.0, 0.166666666667, 0.333333333333], [1.0, -1.0, 1.0])
    """
    return _um(mode, 0, "um_zv")


def um_zvd_impulses(mode: Mode) -> tuple[np.ndarray, np.ndarray]:
    """UM-ZVD: ``[1, -1, 1, -1, 1]`` with ``S(p) = S'(p) = 0`` (Singhose, Seering, Singer 1997).

    Examples
    --------
    >>> t, a = um_zvd_impulses(Mode(2 * math.pi, 0.0))     # fit: 0.08945, 0.36613, 0.64277, 0.73228
    >>> np.round(t, 4).tolist()
    [0.0, 0.0895, 0.3662, 0.643, 0.7325]
    """
    return _um(mode, 1, "um_zvd")


def um_shaper(mode: Mode, kind: str) -> OptimalShaper:
    """``design("um_zv" | "um_zvd", mode)``: the shaper with its :class:`~posicast.shapers.optimal.Optimality`.

    ``status="exact"``: the defining equations hold to rounding (``kkt_residual`` is the largest of
    ``|S(p)|`` and, for UM-ZVD, ``|S'(p)| / T_d``).  ``params`` state the amplitude bound: the running
    sum of the impulses stays in ``[0, 1]`` (``amplitude_bound = 1``: a step within the actuator range
    stays within it) and ``l1_norm = sum |A_i|`` (3 or 5) bounds the shaped command for any input.

    Examples
    --------
    >>> S = um_shaper(Mode(2 * math.pi, 0.0), "um_zv")
    >>> round(S.duration, 12), S.params["amplitude_bound"], S.params["l1_norm"]
    (0.333333333333, 1.0, 3.0)
    """
    check_mode(mode)
    t, a = (um_zv_impulses if kind == "um_zv" else um_zvd_impulses)(mode)
    check_resolution(float(np.min(np.diff(t))), float(t[-1]), f"a {kind} shaper for omega={mode.omega:g} rad/s")
    p = mode.pole
    e = a * np.exp(-p * t)
    res = abs(e.sum())
    if kind == "um_zvd":
        res = max(res, abs(np.sum(-t * e)) / mode.damped_period)
    v_model = res * math.exp(-mode.decay * t[-1]) if kind == "um_zv" else abs(e.sum()) * math.exp(-mode.decay * t[-1])
    run = np.cumsum(a)
    opt = Optimality(True, "exact", 0.0, float(v_model), float(t[-1]), 0.0, int(t.size), (), float(res),
                     f"impulses +-1: running sum in [{run.min():g}, {run.max():g}], sum |A_i| = {np.abs(a).sum():g}")
    return OptimalShaper(t, a, name=kind, modes=(mode,),
                         params={"amplitude_bound": float(np.abs(run).max()), "l1_norm": float(np.abs(a).sum())},
                         optimality=opt)


def um_si_shaper(mode: Mode, vtol: float = 0.05, band: tuple[float, float] = (0.9, 1.1)) -> OptimalShaper:
    """``design("um_si", mode, vtol=, band=)``: the shortest unity-magnitude shaper (3 or 5 impulses +-1)
    keeping ``V <= vtol`` over the band of frequency ratios (the SI variant of Singhose et al. 1997).

    The times are polished by SLSQP with the amplitudes fixed, from UM-ZV (3 impulses) and UM-ZVD
    (5 impulses), on frequencies exchanged until a dense grid is within ``vtol``; the shorter feasible
    one is returned.  A band too wide for 5 unity-magnitude impulses is a result that says so
    (``optimality.feasible`` False: UM-ZVD, with its worst vibration on the band).

    Examples
    --------
    >>> S = um_si_shaper(Mode(2 * math.pi, 0.0), 0.05, (1.0, 1.0))   # one frequency, 5 % left there
    >>> S.optimality.feasible, S.n_impulses, S.duration < 1 / 3        # shorter than UM-ZV's T/3
    (True, 3, True)
    """
    check_mode(mode)
    vtol = v.real_in_range(vtol, "vtol", 1e-6, 1.0, hi_open=True)
    lo, hi = v.ordered_pair(band, "band", 0.0, 1000.0, lo_open=True)
    prob = _Problem((mode,), ((lo, hi),), ((mode.zeta, mode.zeta),), vtol, mode.omega * hi)
    best = None
    for kind in ("um_zv", "um_zvd"):
        t0, amps = _um(mode, 0 if kind == "um_zv" else 1, kind)
        u = t0 * prob.scale
        nu, ze, _, _ = prob.points(6, u[-1], 11, 1)
        q, sig = _qs(nu, ze)
        for _ in range(6):
            u = _times_shortest(u, amps, q, sig, vtol)
            pk = _peaks(prob, u, amps, vtol * 0.9)
            if max(p[3] for p in pk) <= vtol * (1 + 1e-6) and np.all(np.diff(u) > 0):
                if best is None or u[-1] < best[0][-1]:
                    best = (u, amps, pk)
                break
            qa, sa = _point_arrays(prob, [p for p in pk if p[3] > vtol * (1 - 1e-3)])
            q, sig = np.concatenate([q, qa]), np.concatenate([sig, sa])
    if best is None:
        t0, amps = _um(mode, 1, "um_zvd")
        u = t0 * prob.scale
        pk = _peaks(prob, u, amps, vtol * 0.5)
        best, ok, note = (u, amps, pk), False, "5 unity-magnitude impulses cannot keep V <= vtol on this band (local search)"
    else:
        ok, note = True, "impulses +-1: running sum in [0, 1]"
    u, amps, pk = best
    t = u / prob.scale
    worst = max(p[3] for p in pk)
    active = tuple(ActiveConstraint(p[0], p[1], p[2], p[3]) for p in pk if p[3] >= vtol * (1 - 1e-5))
    opt = Optimality(ok, "feasible" if ok else "infeasible", vtol, worst, float(t[-1]), 0.0, int(t.size), active,
                     None, note)
    return OptimalShaper(t, amps, name="um_si", modes=(mode,),
                         params={"vtol": vtol, "band": (lo, hi), "amplitude_bound": 1.0,
                                 "l1_norm": float(np.abs(amps).sum())}, optimality=opt)


def _times_shortest(u0: np.ndarray, amps: np.ndarray, q: np.ndarray, sig: np.ndarray, vtol: float) -> np.ndarray:
    """SLSQP on the times (first at 0) of fixed amplitudes: min t_n with ``V_j <= vtol (1 - 1e-7)``."""
    n = u0.size
    target = vtol * (1 - 1e-7)

    def parts(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        u = np.concatenate([[0.0], x])
        with np.errstate(over="ignore", invalid="ignore"):
            W = np.exp(np.multiply.outer(q, u) - sig[:, None] * u[-1])
            z = W @ amps
            dz = q[:, None] * W * amps[None, :]
            dz[:, -1] -= sig * z
        V = np.abs(z)
        g = (np.conj(z)[:, None] * dz[:, 1:]).real / np.maximum(V, 1e-300)[:, None]
        return V, g

    D = np.eye(n - 1) - np.eye(n - 1, k=-1)
    grad = np.zeros(n - 1)
    grad[-1] = 1.0
    cons = [{"type": "ineq", "fun": lambda x: 1.0 - parts(x)[0] / target, "jac": lambda x: -parts(x)[1] / target},
            {"type": "ineq", "fun": lambda x: D @ x, "jac": lambda x: D}]
    best = None
    for shrink in (1.0, 0.99):
        res = minimize(lambda x: x[-1], u0[1:] * shrink, jac=lambda x: grad, method="SLSQP", constraints=cons,
                       bounds=[(0, None)] * (n - 1), options={"maxiter": 150, "ftol": 1e-14})
        ok = res.success and np.min(1.0 - parts(res.x)[0] / target) >= -1e-6
        if ok and (best is None or res.x[-1] < best[-1]):
            best = res.x
        if ok and res.x[-1] < u0[-1] * (1 - 1e-6):
            break
    return np.concatenate([[0.0], best if best is not None else res.x])
