"""Solving an EI family at one ``(zeta, vtol)``: Newton / MINPACK at fixed ``zeta``, continuation in ``zeta``.

For one family (:mod:`posicast.shapers.ei_families`) and one ``vtol`` the solutions
form a curve starting at the undamped closed form; it is traced by pseudo-arclength
continuation and cached (:data:`traces`) as a warm start only: :func:`solve` answers
every request by solving the square system at exactly the given ``zeta``
(residuals < 1e-12), from the first stretch of the curve that reaches it.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
from scipy.optimize import root

from ..modes import Mode
from .ei_families import FAMILIES, R_MAX, ShaperFamily, invalid_reason

__all__ = ["solve", "to_seconds", "sigma_of", "traces"]

# ---------------------------------------------------------------------------
# the solver: Newton / hybrj at fixed zeta, pseudo-arclength continuation in zeta
# ---------------------------------------------------------------------------

_TOL = 1e-12  # residual tolerance (dimensionless)
_H_MAX = 0.08  # largest arclength step along a solution curve
_H_MIN = 1e-7
_MAX_POINTS = 600
_CACHE_SIZE = 64  # traced curves kept (one per family and vtol)


def _complex_step(residual, y):
    """``residual(y)`` and its complex-step Jacobian: one evaluation at ``y`` and at ``y + i h e_k`` for every ``k``."""
    n = y.size
    h = 1e-30
    yy = np.empty((n + 1, n), dtype=complex)
    yy[:] = y
    yy[1:] += 1j * h * np.eye(n)
    rr = residual(yy)
    return rr[0].real, (rr[1:].imag / h).T


def _fun_jac(prob: ShaperFamily, sigma: float, vtol: float):
    """Residual and complex-step Jacobian in ``x`` at fixed ``sigma``."""
    return lambda x: _complex_step(lambda xx: prob.residual(xx, sigma, vtol), x)


def _aug_fun_jac(prob: ShaperFamily, vtol: float):
    """Residual and complex-step Jacobian in ``y = (x, sigma)`` (n x (n + 1))."""
    return lambda y: _complex_step(lambda yy: prob.residual(yy[:, :-1], yy[:, -1][:, None, None], vtol), y)


def _newton(fj, x: np.ndarray, maxit: int) -> tuple[np.ndarray, np.ndarray]:
    """Newton's method with step halving; stops when the residual stops decreasing."""
    f, jac = fj(x)
    for _ in range(maxit):
        norm = np.max(np.abs(f))
        if not np.isfinite(norm) or norm < 1e-15:
            break
        try:
            dx = np.linalg.solve(jac, -f)
        except np.linalg.LinAlgError:
            break
        step = 1.0
        while step > 0.1:
            xn = x + step * dx
            fn, jn = fj(xn)
            if np.max(np.abs(fn)) < norm:  # False for NaN
                break
            step *= 0.5
        else:
            break
        x, f, jac = xn, fn, jn
    return x, f


def _solve_at(prob: ShaperFamily, x0: np.ndarray, sigma: float, vtol: float
              ) -> tuple[np.ndarray | None, str | None]:
    """Solve the square system at fixed ``(sigma, vtol)`` from ``x0``.

    Damped Newton first (cheap from a point on the traced curve); if it
    stalls, MINPACK's hybrj (``scipy.optimize.root``, method "hybr") from
    ``x0``, polished by Newton.  Accepts only residuals below ``_TOL`` and
    admissible shapers.
    """
    fj = _fun_jac(prob, sigma, vtol)
    with np.errstate(all="ignore"):
        x, f = _newton(fj, x0, 8)
        if not np.max(np.abs(f)) < _TOL:
            try:
                sol = root(fj, x0, jac=True, method="hybr", options={"xtol": 1e-14, "maxfev": 40})
            except (np.linalg.LinAlgError, ValueError):
                return None, "the solver failed"
            x, f = _newton(fj, sol.x, 4)
    if not np.max(np.abs(f)) < _TOL:
        return None, "the solver failed to converge"
    reason = invalid_reason(prob, x, sigma, vtol)
    return (None, reason) if reason else (x, None)


# --- pseudo-arclength continuation of the solution curve from zeta = 0 -------------
#
# For one family and one vtol the solutions form a curve y(s) = (x(s), sigma(s))
# starting at the undamped closed form (sigma = 0).  The curve is traced by
# arclength (so it is followed through turning points), and a request for
# sigma is answered on the *first* stretch of the curve that reaches sigma:
# the answer is the solution connected to the undamped closed form, whatever
# was asked before.  (Some curves have a small S-bend, e.g. the 2-hump EI with
# vtol = 0.1 near zeta = 0.29, where three solutions coexist for a 3e-4 wide
# range of zeta; there the first one along the curve is returned.)


@dataclass
class _Trace:
    sig: list[float]
    xs: list[np.ndarray]
    tau: np.ndarray  # unit tangent at the last point, oriented along the curve
    h: float
    end: str | None = None  # why the curve ends (None: not reached yet)


traces: OrderedDict[tuple[str, float], _Trace] = OrderedDict()


def _tangent(jac: np.ndarray, tau_prev: np.ndarray) -> np.ndarray:
    a = np.vstack([jac, tau_prev])
    b = np.zeros(len(tau_prev))
    b[-1] = 1.0
    t = np.linalg.solve(a, b)
    return t / np.linalg.norm(t)


def _correct(fj, yp: np.ndarray, tau: np.ndarray) -> np.ndarray | None:
    """Newton on ``F(y) = 0, tau . (y - yp) = 0``; None unless it converges fast."""
    found = _correct_with_jacobian(fj, yp, tau)
    return None if found is None else found[0]


def _correct_with_jacobian(fj, yp: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """:func:`_correct`, and the Jacobian at the point it returns (the next tangent's: not evaluated again,
    issue #15)."""
    y = yp.copy()
    for _ in range(7):
        f, jac = fj(y)
        if not np.all(np.isfinite(f)):
            return None
        g = np.append(f, tau @ (y - yp))
        if np.max(np.abs(f)) < _TOL and abs(g[-1]) < 1e-12:
            return y, jac
        dy = np.linalg.solve(np.vstack([jac, tau]), -g)
        if np.max(np.abs(dy)) > 0.25:
            return None
        y = y + dy
    f, jac = fj(y)
    return (y, jac) if np.max(np.abs(f)) < _TOL else None


def _end_reason(prob: ShaperFamily, x: np.ndarray, why: str | None) -> str:
    _, amps = prob.unpack(x)
    top = float(np.max(prob.zeros(x)))
    if top > 0.5 * R_MAX:
        return "the outermost zero of V runs off to infinite frequency"
    if np.min(amps) < 1e-3:
        return "an impulse amplitude reaches 0 (it would go negative)"
    if why is None or "failed" in why:
        return "the solution curve ends"
    return why


def _extend(prob: ShaperFamily, tr: _Trace, vtol: float, sigma: float) -> None:
    """Trace the curve further until it reaches ``sigma`` or ends."""
    fj = _aug_fun_jac(prob, vtol)
    y = np.append(tr.xs[-1], tr.sig[-1])
    with np.errstate(all="ignore"):
        while tr.end is None and max(tr.sig) < sigma:
            h, why = tr.h, None
            while True:
                try:
                    found = _correct_with_jacobian(fj, y + h * tr.tau, tr.tau)
                    if found is None:
                        why = "the solver failed to converge"
                    elif found[0][-1] < 0:
                        why = "the solution curve turns back (a fold)"
                    else:
                        why = invalid_reason(prob, found[0][:-1], found[0][-1], vtol)
                    if why is None:
                        ynew = found[0]
                        tnew = _tangent(found[1], tr.tau)
                        if tnew @ tr.tau < 0.9:  # too sharp a turn: smaller step
                            why = "the solver failed to converge"
                except np.linalg.LinAlgError:
                    why = "the solver failed"
                if why is None:
                    break
                h *= 0.5
                if h < _H_MIN:
                    tr.end = _end_reason(prob, y[:-1], why)
                    return
            grow = h == tr.h
            y, tr.tau = ynew, tnew
            tr.sig.append(float(y[-1]))
            tr.xs.append(y[:-1].copy())
            tr.h = min(_H_MAX, h * 1.6) if grow else h
            smax = max(tr.sig)
            if y[-1] < smax - max(0.05, 0.25 * smax):
                tr.end = "the solution curve turns back (a fold)"
            elif len(tr.sig) > _MAX_POINTS:
                tr.end = "the solution curve could not be followed further"


def _trace(key: str, vtol: float) -> _Trace:
    k = (key, vtol)
    tr = traces.get(k)
    if tr is None:
        prob = FAMILIES[key]
        x0 = prob.initial(vtol)
        y0 = np.append(x0, 0.0)
        fj = _aug_fun_jac(prob, vtol)
        tau0 = np.zeros(len(y0))
        tau0[-1] = 1.0
        try:
            with np.errstate(all="ignore"):
                t0 = _tangent(fj(y0)[1], tau0)
        except np.linalg.LinAlgError:
            t0 = None
        if t0 is None or not np.all(np.isfinite(t0)):
            raise ValueError(f"vtol={vtol:g} is too close to 0 or 1 for the damped {prob.name} shaper: its solution "
                             "curve is singular at zeta = 0 (the undamped closed form has coinciding zeros or a "
                             "vanishing impulse); use a vtol further inside (0, 1)")
        tr = _Trace([0.0], [x0], t0, 0.02)
        traces[k] = tr
        while len(traces) > _CACHE_SIZE:
            traces.popitem(last=False)
    traces.move_to_end(k)
    return tr


def sigma_of(zeta: float) -> float:
    """``sigma = zeta / sqrt(1 - zeta^2)``: the designs depend on ``zeta`` only through it."""
    return zeta / math.sqrt(1.0 - zeta * zeta)


def _range_error(prob: ShaperFamily, zeta: float, vtol: float, sig_max: float, reason: str | None
                 ) -> ValueError:
    z_ok = sig_max / math.sqrt(1.0 + sig_max * sig_max)
    return ValueError(
        f"zeta={zeta:g} is outside the range where the damped {prob.name} shaper exists "
        f"for vtol={vtol:g}: it works for 0 <= zeta <= {math.floor(z_ok * 1e4) / 1e4:.4f} "
        f"(beyond that {reason}; a smaller vtol widens the range)")


def solve(key: str, zeta: float, vtol: float) -> np.ndarray:
    """Solution vector for ``(zeta, vtol)``, solved for exactly these inputs.

    The cached traced curve only supplies the starting point (and tells where
    the family ends); the returned solution is solved at the given ``zeta``.
    """
    prob = FAMILIES[key]
    sigma = sigma_of(zeta)
    tr = _trace(key, vtol)
    if max(tr.sig) < sigma:
        _extend(prob, tr, vtol, sigma)
    if max(tr.sig) < sigma:
        raise _range_error(prob, zeta, vtol, max(tr.sig), tr.end)
    if sigma == 0.0:
        x, _ = _solve_at(prob, tr.xs[0], 0.0, vtol)
        if x is None:  # pragma: no cover - the closed form is exact
            raise ValueError(f"{prob.name}: the undamped closed form is not admissible for vtol={vtol:g}; "
                             "use a vtol further inside (0, 1)")
        return x
    for _ in range(40):
        sig = np.array(tr.sig)
        i = int(np.argmax(sig >= sigma)) - 1  # the first crossing of sigma along the curve
        s0, s1 = sig[i], sig[i + 1]
        w = (sigma - s0) / (s1 - s0)
        x0 = tr.xs[i] + w * (tr.xs[i + 1] - tr.xs[i])
        x, _ = _solve_at(prob, x0, sigma, vtol)
        if x is not None and (np.max(np.abs(x - x0)) < 2 * np.max(np.abs(tr.xs[i + 1] - tr.xs[i]))):
            return x
        # refine the segment: a curve point half way along it, then retry
        ya, yb = np.append(tr.xs[i], s0), np.append(tr.xs[i + 1], s1)
        tau = (yb - ya) / np.linalg.norm(yb - ya)
        try:
            with np.errstate(all="ignore"):
                ym = _correct(_aug_fun_jac(prob, vtol), 0.5 * (ya + yb), tau)
        except np.linalg.LinAlgError:
            ym = None
        if ym is None:
            break
        tr.sig.insert(i + 1, float(ym[-1]))
        tr.xs.insert(i + 1, ym[:-1].copy())
    raise ValueError(f"{prob.name}: the solver did not converge at zeta={zeta:g}, vtol={vtol:g} (near the end "
                     "of the family's range); a smaller zeta or vtol is solvable")


def to_seconds(prob: ShaperFamily, x: np.ndarray, mode: Mode) -> tuple[np.ndarray, np.ndarray]:
    """Impulse times (s, scaled by ``mode``'s damped period) and amplitudes of a solution ``x`` (copies)."""
    times, amps = prob.unpack(x)
    times = np.asarray(times, dtype=float) * mode.damped_period
    times[0] = 0.0
    return times, np.asarray(amps, dtype=float).copy()
