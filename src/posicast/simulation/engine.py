"""Time-domain simulation of the three shaper architectures (issue #4).

Two modes:

* **sampled** (``sample_rate`` given): the controller and the shaper run at
  the sample rate, as on a real controller: ``C`` by Tustin (or ZOH/FOH),
  the shaper as FIR taps with fractional delays split between samples (seed
  000 eq. 19 for the inverse ZV and eq. 20 for the inverse DZV are the IIR
  recursions ``1 / S(z)``).  The plant ``G`` and the flexible part ``F`` see
  the held control signal and are discretised exactly (zero-order hold), so
  their outputs are exact at every sample.
* **continuous** (``sample_rate=None``): when the loop's channels have
  delay-free denominators (feedforward shaper, or no shaper) every channel is
  simulated *exactly* for held inputs, fractional delays included
  (:func:`exact_delayed_response`).  With the shaper inside the loop an
  internal step ``h = dt / substeps`` is used, every block is discretised for
  piecewise-linear signals (FOH), delays are fractional; the response
  carries ``accuracy``, the difference to a run at ``2 h`` (an error
  estimate of the ``2 h`` run, and a bound of about three times that of this
  one); with an odd number of substeps the comparison run is at ``h / 2``.

Every rational block is kept as a balanced state space and every loop is run
as one (:mod:`posicast.simulation.discrete`), never as a product of ``z^-1``
polynomials: at small steps the poles of such a polynomial are lost near
``z = 1`` (stable high-order loops diverged at 0.5 ms).

External inputs ``w``, ``d``, ``di``, ``n`` are held between the samples of
``t`` (zero-order hold), the natural reading of steps and of sampled data.
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np
from scipy import signal

from .. import _validate as v
from ..core.transfer import TransferFunction
from ..loops.loop import Loop
from ..shapers.base import Shaper
from .discrete import (
    PowerPropagator,
    _shift,
    balance,
    block_length,
    discretize_ss,
    exact_delayed_response,
    poly_add,
    poly_mul,
    propagate,
    state_space,
)
from .streaming import discretize, prewarped_step
from .response import SimulationResponse

__all__ = ["simulate", "DivergenceWarning"]

INPUTS = ("w", "d", "di", "n")

# Up-front work limits (issue #13): a simulation is refused, with the estimate and the parameter to
# change, before it allocates anything large.  Costs measured on the reference machine (2 cores):
# about 350 MB peak per 10^6 samples of t in the exact and sampled modes; 3.6 us and 25 us per internal
# step for the fine-step (shaper in the loop) and the sample-by-sample (saturation/rate limit) runs.
MAX_BYTES = 2e9
MAX_SECONDS = 60.0
_BYTES_PER_SAMPLE = 350.0
_BYTES_PER_FINE_STEP = 8.0 * 40  # repeated inputs, states and outputs of the fine run and its comparison
_SECONDS_PER_FINE_STEP = 3.6e-6
_SECONDS_PER_NONLINEAR_STEP = 25e-6
MAX_SUBSTEPS = 1_000_000


class DivergenceWarning(UserWarning):
    """A simulated loop diverged; the response stops where it did."""


def _as_signal(x: Any, name: str, n: int) -> np.ndarray:
    if x is None:
        return np.zeros(n)
    if np.isscalar(x):
        raise TypeError(f"{name} must be an array on t (or None), got a scalar")
    arr = v.strict_real_array(x, name, allow_empty=True)
    if arr.ndim != 1 or arr.size != n:
        raise ValueError(f"{name} must have the length of t ({n}), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains NaN or inf")
    return arr


def _check_time(t: Any) -> tuple[np.ndarray, float]:
    if isinstance(t, (str, bytes)) or np.isscalar(t) or t is None:
        raise TypeError(f"t must be an array of times, got {type(t).__name__}")
    n = int(np.size(t)) if isinstance(t, np.ndarray) else None
    if n is not None:  # before any copy of a large grid
        _refuse_samples(n)
    t = v.strict_real_array(t, "t", allow_empty=True)
    if t.ndim != 1 or t.size < 2:
        raise ValueError("t must be a 1-D array of at least 2 times")
    _refuse_samples(t.size)
    dt = (t[-1] - t[0]) / (t.size - 1)
    if dt <= 0 or not np.allclose(np.diff(t), dt, rtol=1e-9, atol=1e-12 * max(1.0, abs(t[-1]))):
        raise ValueError("t must be uniform and increasing")
    return t, float(dt)


def _refuse_samples(n: int) -> None:
    v.refuse_large(_BYTES_PER_SAMPLE * n, MAX_BYTES, f"simulating {n:.3g} samples", f"use fewer samples in t "
                   f"(at most about {MAX_BYTES / _BYTES_PER_SAMPLE:.3g}: a coarser step or a shorter time)", "bytes")


def _refuse_work(loop: Loop, S: Shaper | None, n: int, dt: float, sample_rate: Any, substeps: int | None,
                 nonlinear: bool) -> None:
    """Estimate the internal steps of the run chosen by ``simulate`` and refuse it if too large."""
    in_loop = S is not None and loop.architecture != "feedforward"
    if sample_rate is not None:
        steps, fine = float(n), False  # the controller runs at most once per step of t
    elif nonlinear or in_loop:
        sub = substeps if substeps is not None else max(1, int(math.ceil(dt / 1e-3 - 1e-9)))
        steps, fine = float(n) * sub * (1.0 if nonlinear else 3.0), True  # + the comparison run
    else:
        return  # exact continuous mode: covered by the per-sample estimate
    change = ("use fewer samples in t" + (", fewer substeps" if sample_rate is None else "")
              + (" or sample_rate (the sampled mode runs at the controller rate)" if sample_rate is None else ""))
    if fine:
        v.refuse_large(_BYTES_PER_FINE_STEP * steps, MAX_BYTES, f"the simulation's {steps:.3g} internal steps",
                       change, "bytes")
    per = _SECONDS_PER_NONLINEAR_STEP if nonlinear else _SECONDS_PER_FINE_STEP
    v.refuse_large(per * steps, MAX_SECONDS, f"the simulation's {steps:.3g} internal steps", change, "s")


def _shaper_object(loop: Loop) -> Shaper | None:
    S = loop.shaper
    if S is None:
        return None
    if not isinstance(S, Shaper):
        raise TypeError(
            "simulation needs the loop's shaper as a posicast Shaper (impulses and kernels), "
            f"got {type(S).__name__}"
        )
    return S


def _check_rates(S: Shaper | None, h: float, name: str, rate: float) -> None:
    if S is None:
        return
    times = S.impulses[0]
    pos = times[times > 0]
    first = [float(pos.min())] if pos.size else []
    first += [p.delay + (0 if p.delay > 0 else p.length) for p in S.distributed]
    if first and min(first) < h * (1 - 1e-9):
        raise ValueError(
            f"{name} = {rate:g} Hz is too low: the shaper's shortest delay {min(first):.4g} s is below one "
            f"sample ({h:.4g} s); use {name} >= {1.0 / min(first):.4g} Hz"
        )
    for m in S.modes:
        if m.omega / (2 * math.pi) >= 0.5 * rate:
            raise ValueError(
                f"{name} = {rate:g} Hz is too low: the shaper's mode {m.freq_hz:.4g} Hz is at or above "
                f"the Nyquist frequency {0.5 * rate:.4g} Hz"
            )


def _discrete_shaper(S: Shaper, h: float) -> tuple[np.ndarray, np.ndarray]:
    """``(b, a)`` of the shaper on step ``h``: FIR taps (fractional delays split linearly,
    distributed delays integrated exactly) plus its rational part in parallel."""
    D = discretize(S, 1.0 / h, "linear")
    b, a = D.taps, np.ones(1)
    if D.b is not None:
        b = poly_add(poly_mul(b, D.a), D.b)
        a = D.a
    return b, a


# the loop signals of a shaped loop, in the order of the node equations of _ShapedLoop
_NODES = ("e", "v", "u", "up", "z", "m", "xs")
# _ShapedLoop: below this first delayed tap a step-by-step update beats blocks of that many steps
_BLOCK_MIN = 16
# a state this large has diverged beyond any divergence limit: the simulation stops
_HUGE = 1e150


class _ShapedLoop:
    """A loop with its shaper inside (control action or inverse shaper) on step ``h``, as a state space.

    ``C`` and ``G`` are discretised from their balanced continuous state
    spaces (:func:`~posicast.simulation.discrete.discretize_ss`), the shaper's
    IIR part likewise (Tustin prewarped as in
    :func:`~posicast.simulation.streaming.discretize`), and the shaper's FIR taps
    act through the stored history of the shaper's input ``xs`` (``v`` for the
    control-action shaper, ``m`` for the inverse shaper, ``S m = z + n``).
    Within a step only the undelayed tap ``s0`` (plus the IIR direct term)
    acts, so the node equations are solved once for the signals as functions
    of the state and the inputs, and each step is one state update of a
    low-order, balanced closed loop.

    Why not the loop algebra on ``z^-1`` polynomials: the closed-loop
    characteristic polynomial of a ninth-order plant (and, with a
    distributed-delay shaper, of degree #taps + 10, thousands) run by
    ``lfilter`` has coefficients that do not determine its roots at small
    steps; stable loops diverged at 0.5 ms, the notch loop at 1 ms.

    Parameters
    ----------
    loop : Loop
        Control-action or inverse-shaper architecture.
    S : Shaper
        The loop's shaper.
    h : float
        Step [s].
    plant, controller : {'zoh', 'foh', 'bilinear'}
        Discretisation of ``G`` and of ``C``.
    """

    def __init__(self, loop: Loop, S: Shaper, h: float, plant: str, controller: str) -> None:
        if loop.architecture not in ("control_action", "inverse_shaper"):
            raise ValueError(f"a shaper inside the loop needs the control_action or inverse_shaper loop, "
                             f"got {loop.architecture!r}")
        if loop.G.has_delays or loop.C.has_delays or loop.F.has_delays:
            raise ValueError("simulation supports delay-free G, C and F (the shaper carries the delays)")
        if loop.G.num.degree >= loop.G.den.degree and plant == "zoh":
            raise ValueError("G must be strictly proper for a sampled simulation (a held input feeds straight through)")
        self.loop, self.h = loop, h
        Ac, Bc, Cc, Dc = discretize_ss(loop.C, h, controller)
        Ag, Bg, Cg, Dg = discretize_ss(loop.G, h, plant)
        D = discretize(S, 1.0 / h, "linear")
        taps = np.asarray(D.taps, dtype=float)
        Ar, Br, Cr, Dr = (np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), 0.0)
        if S.continuous is not None:
            Ar, Br, Cr, Dr = discretize_ss(S.continuous, prewarped_step(S, h), "bilinear")
        s0 = float(taps[0]) + Dr  # the shaper's undelayed gain
        inverse = loop.architecture == "inverse_shaper"
        if inverse and abs(s0) < 1e-12 * (np.abs(taps).sum() + abs(Dr)):
            raise ValueError("the inverse shaper needs a nonzero undelayed term (1/S is not causal)")
        # delayed taps i = first .. last (those at i >= 1 only see the past of xs)
        late = np.flatnonzero(taps[1:]) + 1
        self.first = int(late[0]) if late.size else 0
        self.last = int(late[-1]) if late.size else 0
        self.delayed = taps[self.first: self.last + 1].copy() if late.size else np.zeros(0)

        nc, ng, nr = Ac.shape[0], Ag.shape[0], Ar.shape[0]
        nx = nc + ng + nr
        ic, ig, ir = slice(0, nc), slice(nc, nc + ng), slice(nc + ng, nx)
        k = {name: i for i, name in enumerate(_NODES)}
        iw, id_, idi, in_, iq = range(5)  # inputs: w, d, di, n and the delayed FIR output q
        # node equations  sig = P sig + Qx x + Qu u
        P = np.zeros((7, 7))
        Qx = np.zeros((7, nx))
        Qu = np.zeros((7, 5))
        P[k["z"], k["up"]] = Dg              # z = Cg xg + Dg up + d
        Qx[k["z"], ig] = Cg[0]
        Qu[k["z"], id_] = 1.0
        P[k["v"], k["e"]] = Dc               # v = Cc xc + Dc e
        Qx[k["v"], ic] = Cc[0]
        P[k["up"], k["u"]] = 1.0             # up = u + di
        Qu[k["up"], idi] = 1.0
        if inverse:
            P[k["e"], k["m"]] = -1.0         # e = w - m
            Qu[k["e"], iw] = 1.0
            P[k["u"], k["v"]] = 1.0          # u = v
            P[k["m"], k["z"]] = 1.0 / s0     # s0 m + Cr xr + q = z + n
            Qu[k["m"], in_] = 1.0 / s0
            Qx[k["m"], ir] = -Cr[0] / s0
            Qu[k["m"], iq] = -1.0 / s0
            P[k["xs"], k["m"]] = 1.0
        else:
            P[k["e"], k["z"]] = -1.0         # e = w - z - n
            Qu[k["e"], iw] = 1.0
            Qu[k["e"], in_] = -1.0
            P[k["u"], k["v"]] = s0           # u = s0 v + Cr xr + q
            Qx[k["u"], ir] = Cr[0]
            Qu[k["u"], iq] = 1.0
            P[k["xs"], k["v"]] = 1.0
        I_P = np.eye(7) - P
        if np.linalg.cond(I_P) > 1e12:
            raise ValueError("the discretised loop is not well posed (its instantaneous loop gain is -1)")
        Sx = np.linalg.solve(I_P, Qx)
        Su = np.linalg.solve(I_P, Qu)
        # x+ = blockdiag(Ac, Ag, Ar) x + Bsel sig
        A = np.zeros((nx, nx))
        A[ic, ic], A[ig, ig], A[ir, ir] = Ac, Ag, Ar
        Bsel = np.zeros((nx, 7))
        Bsel[ic, k["e"]] = Bc[:, 0]
        Bsel[ig, k["up"]] = Bg[:, 0]
        Bsel[ir, k["xs"]] = Br[:, 0]
        # one diagonal similarity for the whole loop: its blocks are balanced, their coupling need not be
        self.A, self.B, self.Sx = balance(A + Bsel @ Sx, Bsel @ Su, Sx)
        self.Su = Su
        self.index = k

    def response(self, inputs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """All loop signals for the inputs ``w, d, di, n`` on the step ``h`` (``y`` for held ``up``)."""
        ext = np.ascontiguousarray(np.vstack([inputs["w"], inputs["d"], inputs["di"], inputs["n"]]))
        run = self._blocks if self.first >= _BLOCK_MIN else self._steps
        with np.errstate(over="ignore", invalid="ignore"):  # a diverging loop is reported by _finish
            X, q = run(ext)
            sig = self.Sx @ X + self.Su[:, :4] @ ext + np.outer(self.Su[:, 4], q)
        out = {name: sig[i] for name, i in self.index.items() if name != "xs"}
        if self.loop.architecture != "inverse_shaper":
            del out["m"]
        out["y"] = _load_response(self.loop, out["up"], inputs["d"], self.h)
        return out

    def _xs_known(self, ext: np.ndarray) -> np.ndarray:
        """The part of the shaper input ``xs`` set by the inputs ``w, d, di, n`` (not by the state or ``q``)."""
        return self.Su[self.index["xs"], :4] @ ext

    def _steps(self, ext: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """States (columns) and delayed FIR output ``q``, one explicit state update per step.

        For shapers whose first delayed tap is within a few steps (a kernel
        starting at ``t = 0``: the history enters every step) or without
        delayed taps (the notch).
        """
        N = ext.shape[1]
        A, B, ixs = self.A, self.B, self.index["xs"]
        drive = np.ascontiguousarray((B[:, :4] @ ext).T)  # the known part of the update, row j for step j
        xs_known = self._xs_known(ext)
        cx, dq, bq = self.Sx[ixs], self.Su[ixs, 4], B[:, 4]
        X = np.zeros((N, A.shape[0]))
        q = np.zeros(N)
        x = np.zeros(A.shape[0])
        taps, last = self.delayed[::-1], self.last
        span = taps.size  # last - first + 1, or 0 without delayed taps
        hist = np.zeros(N + last)  # hist[j + last] = xs[j] (zero before the start)
        for j in range(N):
            qj = float(taps @ hist[j: j + span]) if span else 0.0  # sum_i taps[i] xs[j - i], i = first .. last
            X[j] = x
            q[j] = qj
            hist[j + last] = cx @ x + xs_known[j] + dq * qj
            x = A @ x + drive[j] + bq * qj
            if j % 4096 == 4095 and not np.all(np.abs(x) < _HUGE):
                X[j + 1:] = np.nan  # diverged far beyond any divergence limit: stop here
                q[j + 1:] = np.nan
                break
        return X.T, q

    def _blocks(self, ext: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """States (columns) and delayed FIR output ``q`` by the method of steps (needs ``first >= 1``).

        Over ``first`` steps (the first delayed tap) ``q`` depends only on the
        shaper input before the block, so it is computed for the whole block
        by one convolution; the loop is then a delay-free linear system with a
        known input, run over the block by
        :class:`~posicast.simulation.discrete.PowerPropagator` (as accurate as
        :meth:`_steps`, 1e-13, and about three times faster).
        """
        N = ext.shape[1]
        ixs = self.index["xs"]
        first, last = self.first, self.last
        K = max(1, min(first, block_length(self.A.shape[0], N)))  # q over a block needs only xs before it
        prop = PowerPropagator(self.A, self.B, K)
        xs_known = self._xs_known(ext)
        cx, dq = self.Sx[ixs], self.Su[ixs, 4]
        X = np.zeros((self.A.shape[0], N))
        q = np.zeros(N)
        hist = np.zeros(N + last)  # hist[j + last] = xs[j] (zero before the start)
        x0 = np.zeros(self.A.shape[0])
        for k in range(0, N, K):
            kk = min(N, k + K)
            # q[j] = sum_{i = first}^{last} taps[i] xs[j - i], j = k .. kk - 1: xs[k - last .. kk - 1 - first]
            q[k:kk] = signal.convolve(hist[k: kk + last - first], self.delayed, mode="valid")
            X[:, k:kk], x0 = prop.block(x0, np.vstack([ext[:, k:kk], q[k:kk]]))
            hist[k + last: kk + last] = cx @ X[:, k:kk] + xs_known[k:kk] + dq * q[k:kk]
            if not np.all(np.abs(x0) < _HUGE):
                X[:, kk:] = np.nan  # diverged far beyond any divergence limit: stop here
                q[kk:] = np.nan
                break
        return X, q


def _load_response(loop: Loop, up: np.ndarray, d: np.ndarray, h: float) -> np.ndarray:
    """``y = (F G) up + F d`` for held ``up`` and ``d``, exact at the samples.

    The cascade ``F G`` is one block (its common ``s`` factors cancelled), run
    as a balanced state space (:func:`exact_delayed_response`): a high-order
    transfer polynomial at a small step loses about 1e-8 here.
    """
    y = exact_delayed_response(_cancel_origin(loop.F * loop.G), up, h)
    if np.any(d):
        y = y + exact_delayed_response(loop.F, d, h)
    return y


def _cancel_origin(tf: TransferFunction) -> TransferFunction:
    """Cancel common factors ``s^k`` of a rational transfer function (exact zero coefficients)."""
    num, den = tf.num.coeffs[0], tf.den.coeffs[0]
    k = 0
    while k < min(num.size, den.size) - 1 and num[k] == 0 and den[k] == 0:
        k += 1
    if k == 0 or tf.has_delays:
        return tf
    return TransferFunction.from_poly(num[k:][::-1], den[k:][::-1])


def _delay_free_loop(loop: Loop, sig: dict[str, np.ndarray], r: np.ndarray, h: float, cm: str) -> dict[str, np.ndarray]:
    """The loop without a shaper inside, as one discrete state-space system (:func:`propagate`).

    ``C`` is discretised by ``cm``; the plant and the load, ``G`` with ``F``
    on its output, are discretised together, exactly for held ``up`` and
    ``d`` (one zero-order hold of the cascade ``x_g' = A_g x_g + B_g up``,
    ``x_f' = A_f x_f + B_f (C_g x_g + d)``); ``r`` is the (already shaped)
    reference.  Every signal, ``y`` included, comes from one propagation of
    the closed-loop state, so nothing passes through a high-order
    transfer-function polynomial.
    """
    from .discrete import _zoh

    Ac, Bc, Cc, Dc = discretize_ss(loop.C, h, cm)
    Ag, Bg, Cg, Dg = state_space(loop.G)
    if Dg != 0:
        raise ValueError("G must be strictly proper for simulation (a held input feeds straight through)")
    Af, Bf, Cf, Df = state_space(loop.F)
    nc, ng, nf = Ac.shape[0], Ag.shape[0], Af.shape[0]
    npl = ng + nf
    # the continuous cascade G -> F, inputs (up, d), outputs (G xg, y - Df d), held over each step
    Ap = np.zeros((npl, npl))
    Ap[:ng, :ng] = Ag
    Ap[ng:, :ng] = Bf @ Cg
    Ap[ng:, ng:] = Af
    Bp = np.zeros((npl, 2))
    Bp[:ng, 0] = Bg[:, 0]
    Bp[ng:, 1] = Bf[:, 0]
    Rp = np.zeros((2, npl))
    Rp[0, :ng] = Cg[0]
    Rp[1, :ng] = Df * Cg[0]
    Rp[1, ng:] = Cf[0]
    Ap, Bp, Rp = balance(Ap, Bp, Rp)
    Phi, Gam = _zoh(Ap, Bp, h)
    gz, gy = Rp
    n = nc + npl
    # e = ext - G xg with ext = r - n - d;  v = Cc xc + Dc e;  up = v + di
    ext = r - sig["n"] - sig["d"]
    A = np.zeros((n, n))
    ic, ip = slice(0, nc), slice(nc, n)
    A[ic, ic] = Ac
    A[ic, ip] = -np.outer(Bc[:, 0], gz)
    A[ip, ic] = np.outer(Gam[:, 0], Cc[0]) if nc else np.zeros((npl, 0))
    A[ip, ip] = Phi - Dc * np.outer(Gam[:, 0], gz)
    b_ext = np.concatenate([Bc[:, 0], Dc * Gam[:, 0]])
    b_di = np.concatenate([np.zeros(nc), Gam[:, 0]])
    b_d = np.concatenate([np.zeros(nc), Gam[:, 1]])
    rows = np.array([
        np.concatenate([np.zeros(nc), gz]),                                   # G xg
        np.concatenate([Cc[0] if nc else np.zeros(0), -Dc * gz]),             # v - Dc ext
        np.concatenate([np.zeros(nc), gy]),                                   # y - Df d
    ])
    # the coupling terms are not balanced by the blocks' own scaling: balance the loop
    A, Bcols, rows = balance(A, np.column_stack([b_ext, b_di, b_d]), rows)
    inputs = [(Bcols[:, 0], ext)]
    if np.any(sig["di"]):
        inputs.append((Bcols[:, 1], sig["di"]))
    if np.any(sig["d"]):
        inputs.append((Bcols[:, 2], sig["d"]))
    gx, v_state, y_state = propagate(A, inputs, rows)
    out: dict[str, np.ndarray] = {}
    out["z"] = gx + sig["d"]
    out["e"] = r - out["z"] - sig["n"]
    out["v"] = v_state + Dc * ext
    out["u"] = out["v"]
    out["up"] = out["v"] + sig["di"]
    out["y"] = y_state + Df * sig["d"]
    if loop.architecture == "feedforward":
        out["r"] = r
    elif loop.architecture == "inverse_shaper":
        out["m"] = out["z"] + sig["n"]
    return out


def _nonlinear(loop: Loop, S: Shaper | None, sig: dict[str, np.ndarray], h: float, cm: str,
               sat: tuple[float, float] | None, rate: float | None) -> dict[str, np.ndarray]:
    """Sample-by-sample simulation with actuator saturation and/or rate limit on ``u``.

    Same discretisation as the sampled mode (controller by ``cm``, plant exact
    ZOH, shaper taps with fractional delays; the inverse shaper as the
    recursion of seed 000 eq. 19/20), run as an explicit loop because the
    limits make the loop nonlinear.
    """
    N = sig["w"].size
    Ac, Bc, Cc, Dc = discretize_ss(loop.C, h, cm)
    Ag, Bg, Cg, Dg = discretize_ss(loop.G, h, "zoh")
    if Dg != 0:
        raise ValueError("G must be strictly proper for simulation (a held input feeds straight through)")
    taps = np.ones(1)
    if S is not None:
        D = discretize(S, 1.0 / h, "linear")
        if D.b is not None:
            raise ValueError("saturation/rate_limit: shapers with an IIR part (notch) are not supported here")
        taps = D.taps
    nz = np.flatnonzero(taps)
    nz_past = nz[nz > 0]
    w_past = taps[nz_past]
    r = sig["w"]
    if loop.architecture == "feedforward" and S is not None:
        r = signal.lfilter(taps, [1.0], r)
    lo, hi = sat if sat is not None else (-np.inf, np.inf)
    du = rate * h if rate is not None else np.inf
    xc = np.zeros(Ac.shape[0])
    xg = np.zeros(Ag.shape[0])
    pad = int(nz.max()) + 1 if nz.size else 1
    vh = np.zeros(N + pad)  # histories, offset by pad so index k - j >= 0
    mh = np.zeros(N + pad)
    out = {k: np.zeros(N) for k in ("e", "v", "u", "up", "z")}
    if loop.architecture == "inverse_shaper":
        out["m"] = np.zeros(N)
    u_prev = 0.0
    cg, cc = Cg[0], (Cc[0] if Ac.size else None)
    bc, bg = Bc[:, 0], Bg[:, 0]
    ca, inv = loop.architecture == "control_action", loop.architecture == "inverse_shaper"
    for k in range(N):
        z = float(cg @ xg) + sig["d"][k]
        zn = z + sig["n"][k]
        if inv:
            m = (zn - float(np.dot(w_past, mh[pad + k - nz_past]))) / taps[0]
            mh[pad + k] = m
            out["m"][k] = m
        else:
            m = zn
        e = r[k] - m
        v = float(cc @ xc) + Dc * e if Ac.size else Dc * e
        vh[pad + k] = v
        u = taps[0] * v + float(np.dot(w_past, vh[pad + k - nz_past])) if ca else v
        u = min(max(u, lo), hi)
        u = min(max(u, u_prev - du), u_prev + du)
        u_prev = u
        up = u + sig["di"][k]
        if Ac.size:
            xc = Ac @ xc + bc * e
        xg = Ag @ xg + bg * up
        out["e"][k], out["v"][k], out["u"][k], out["up"][k], out["z"][k] = e, v, u, up, z
    out["y"] = _load_response(loop, out["up"], sig["d"], h)
    if loop.architecture == "feedforward":
        out["r"] = r
    return out


def _exact_closed_loop(loop: Loop, S: Shaper | None, sig: dict[str, np.ndarray], h: float) -> dict[str, np.ndarray]:
    """Exact sampled solution of the continuous loop for held inputs (lumped feedforward shaper or none).

    The closed loop (C, G and F in continuous time) is one state-space system;
    each impulse ``A_i`` at ``t_i = (n_i + f_i) h`` of the feedforward shaper
    feeds the held reference in two parts, before and after the instant
    ``f_i h`` inside a step (modified z-transform), so fractional delays are
    exact.  One propagation (:func:`~posicast.simulation.discrete.propagate`) gives every signal.
    """
    from scipy.linalg import expm

    Ac, Bc, Cc, Dc = state_space(loop.C)
    Ag, Bg, Cg, Dg = state_space(loop.G)
    Af, Bf, Cf, Df = state_space(loop.F)
    if Dg != 0:
        raise ValueError("G must be strictly proper for simulation")
    nc, ng, nf = Ac.shape[0], Ag.shape[0], Af.shape[0]
    n = nc + ng + nf
    ic, ig, iff = slice(0, nc), slice(nc, nc + ng), slice(nc + ng, n)
    A = np.zeros((n, n))
    A[ic, ic] = Ac
    A[ic, ig] = -Bc @ Cg
    A[ig, ic] = Bg @ Cc
    A[ig, ig] = Ag - Dc * Bg @ Cg
    A[iff, ig] = Bf @ Cg
    A[iff, iff] = Af
    b_ext = np.concatenate([Bc[:, 0], Dc * Bg[:, 0], np.zeros(nf)])  # ext = r - n - d
    b_di = np.concatenate([np.zeros(nc), Bg[:, 0], np.zeros(nf)])
    b_d = np.concatenate([np.zeros(nc + ng), Bf[:, 0]])  # d enters F through z = G up + d
    rows = np.array([
        np.concatenate([np.zeros(nc), Cg[0], np.zeros(nf)]),                                # G xg
        np.concatenate([Cc[0] if nc else np.zeros(0), -Dc * Cg[0], np.zeros(nf)]),          # v - Dc ext
        np.concatenate([np.zeros(nc), Df * Cg[0], Cf[0] if nf else np.zeros(0)]),           # y - Df d
    ])
    # one diagonal similarity for the loop (the coupling of the balanced blocks can still span 1e12)
    A, Bcols, rows = balance(A, np.column_stack([b_ext, b_di, b_d]), rows)
    b_ext, b_di, b_d = Bcols[:, 0], Bcols[:, 1], Bcols[:, 2]

    def zoh(b: np.ndarray, T: float) -> np.ndarray:
        M = np.zeros((n + 1, n + 1))
        M[:n, :n] = A * T
        M[:n, n] = b * T
        E = expm(M)
        return E[:n, n]

    # e^{Ah} and the held-input integrals of the three input columns from one exponential
    M = np.zeros((n + 3, n + 3))
    M[:n, :n] = A * h
    M[:n, n:] = np.column_stack([b_ext, b_di, b_d]) * h
    E = expm(M)
    Phi = E[:n, :n]
    full = {"ext": E[:n, n], "di": E[:n, n + 1], "d": E[:n, n + 2]}
    N = sig["w"].size
    w = sig["w"]
    times, amps = (np.zeros(1), np.ones(1)) if S is None else S.impulses
    inputs: list[tuple[np.ndarray, np.ndarray]] = []
    r_now = np.zeros(N)  # r(t_k), for the direct terms
    for ti, ai in zip(times, amps):
        x = ti / h
        k0 = int(np.floor(x + 1e-12))
        f = x - k0 if x - k0 > 1e-12 else 0.0
        if f == 0.0:
            inputs.append((ai * full["ext"], _shift(w, k0)))
            r_now += ai * _shift(w, k0)
        else:
            delta = f * h
            late = zoh(b_ext, h - delta)
            early = expm(A * (h - delta)) @ zoh(b_ext, delta)
            inputs.append((ai * late, _shift(w, k0)))
            inputs.append((ai * early, _shift(w, k0 + 1)))
            r_now += ai * _shift(w, k0 + 1)
    held = -sig["n"] - sig["d"]
    if np.any(held):
        inputs.append((full["ext"], held))
    if np.any(sig["di"]):
        inputs.append((full["di"], sig["di"]))
    if np.any(sig["d"]):
        inputs.append((full["d"], sig["d"]))
    gx, v0, y0 = propagate(Phi, inputs, rows)
    ext_now = r_now + held
    out: dict[str, np.ndarray] = {}
    out["z"] = gx + sig["d"]
    out["e"] = r_now - out["z"] - sig["n"]
    out["v"] = v0 + Dc * ext_now
    out["u"] = out["v"]
    out["up"] = out["u"] + sig["di"]
    out["y"] = y0 + Df * sig["d"]
    if loop.architecture == "feedforward":
        out["r"] = r_now
    elif loop.architecture == "inverse_shaper":
        out["m"] = out["z"] + sig["n"]
    return out


def _exact_feedforward(loop: Loop, inputs: dict[str, np.ndarray], h: float) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    dsts = [d for d in loop.outputs]
    for dst in dsts:
        acc = np.zeros(inputs["w"].size)
        for src, x in inputs.items():
            if not np.any(x):
                continue
            tf: TransferFunction = loop.transfer(src, dst)
            if tf.num.is_zero:
                continue
            acc += exact_delayed_response(tf, x, h)
        out[dst] = acc
    out["up"] = out["u"] + inputs["di"]
    return out


def simulate(
    loop: Loop,
    t: Any,
    w: Any = None,
    d: Any = None,
    n: Any = None,
    sample_rate: float | None = None,
    *,
    di: Any = None,
    substeps: int | None = None,
    controller_method: str = "bilinear",
    saturation: float | tuple[float, float] | None = None,
    rate_limit: float | None = None,
    divergence_limit: float = 1e6,
) -> SimulationResponse:
    """Simulate a loop of :mod:`posicast.loops` for reference, disturbance and noise signals.

    Parameters
    ----------
    loop : Loop
        From :func:`posicast.feedforward`, :func:`~posicast.control_action` or
        :func:`~posicast.inverse_shaper`; its shaper must be a posicast Shaper.
    t : array_like
        Uniform, increasing time grid [s].
    w, d, n : array_like or None
        Reference, output disturbance (added to ``z``) and measurement noise on
        ``t``, held between samples.  ``di`` is an input disturbance (added to
        the plant input).
    sample_rate : float or None
        Controller/shaper rate [Hz] for the sampled mode; ``1 / sample_rate``
        must be an integer multiple of the step of ``t``.  None: continuous mode.
    substeps : int, optional
        Continuous mode with the shaper in the loop: internal steps per step of
        ``t`` (default: enough for ``h <= 1 ms`` and at least 1).
    controller_method : {'bilinear', 'zoh', 'foh'}
        Sampled mode: the controller's discretisation.
    saturation : float or (float, float), optional
        Actuator limits on ``u``: ``(u_min, u_max)``, or ``u_max`` for ``±u_max``.
    rate_limit : float, optional
        Largest ``|du/dt|`` of the actuator command [units/s].  With either
        limit the loop is run sample by sample (sampled mode at
        ``sample_rate``; continuous mode at the internal step, ZOH plant and
        Tustin controller).
    divergence_limit : float
        A signal whose magnitude exceeds ``divergence_limit`` times the largest
        input magnitude (or 1) has diverged: the response stops at that time
        and :attr:`SimulationResponse.diverged` says when and which signal.

    Returns
    -------
    SimulationResponse

    Raises
    ------
    ValueError, TypeError
        A bad argument (named in the message), or work estimated up front beyond
        :data:`MAX_BYTES` of memory or :data:`MAX_SECONDS` of computation: the
        message gives the estimate and what to change (fewer samples, fewer
        ``substeps``, a ``sample_rate``), before anything large is allocated.

    Examples
    --------
    Feedforward ZV shaping of a unit step: the load ``y`` settles without
    residual vibration.

    >>> import numpy as np, posicast
    >>> S = posicast.design("zv", posicast.Mode(10.0, 0.03))
    >>> loop = posicast.feedforward(G=(1, [1, 1, 0]), F=([1, 0], [1, 0.6, 100]),
    ...                             C=([10, 10], [0.01, 1]), S=S)     # seed 000 eq. 25-27
    >>> t = np.arange(0, 30, 1e-3)
    >>> r = posicast.simulate(loop, t, w=np.ones_like(t))
    >>> bool(r.residual_vibration(after=15.0) < 1e-10)
    True
    """
    if not isinstance(loop, Loop):
        raise TypeError(f"loop must be a posicast Loop (feedforward/control_action/inverse_shaper), got {type(loop).__name__}")
    t, dt = _check_time(t)
    N = t.size
    # every argument is checked, and the work estimated, before anything large is allocated or run
    if isinstance(divergence_limit, (bool, np.bool_)) or not isinstance(divergence_limit, (int, float, np.integer,
                                                                                           np.floating)):
        raise TypeError(f"divergence_limit must be a number > 1, got {type(divergence_limit).__name__}")
    if not (divergence_limit > 1):
        raise ValueError(f"divergence_limit must be a number > 1, got {divergence_limit!r}")
    v.choice(controller_method, "controller_method", ("bilinear", "zoh", "foh"))
    S = _shaper_object(loop)
    sat = _check_saturation(saturation)
    if rate_limit is not None:
        if isinstance(rate_limit, bool) or not isinstance(rate_limit, (int, float, np.integer, np.floating)) \
                or not rate_limit > 0:
            raise ValueError(f"rate_limit must be a positive number of units per second, got {rate_limit!r}")
        rate_limit = float(rate_limit)
    if substeps is not None:
        substeps = v.integer_in_range(substeps, "substeps", 1, MAX_SUBSTEPS)
    if sample_rate is not None:
        _controller_period(sample_rate, dt, N)
    nonlinear = sat is not None or rate_limit is not None
    _refuse_work(loop, S, N, dt, sample_rate, substeps, nonlinear)
    sig = {"w": _as_signal(w, "w", N), "d": _as_signal(d, "d", N), "di": _as_signal(di, "di", N),
           "n": _as_signal(n, "n", N)}
    accuracy = 0.0
    if nonlinear:
        if sample_rate is None:
            if substeps is None:
                substeps = max(1, int(math.ceil(dt / 1e-3 - 1e-9)))
            h = dt / substeps
            _check_rates(S, h, "the internal rate (1/t step x substeps)", 1.0 / h)
            fine = {k: np.repeat(v, substeps) for k, v in sig.items()}
            res = _nonlinear(loop, S, fine, h, "bilinear", sat, rate_limit)
            out = {k: v[::substeps] for k, v in res.items()}
            mode = "continuous (nonlinear, fine step)"
        else:
            Ts, m = _controller_period(sample_rate, dt, N)
            _check_rates(S, Ts, "sample_rate", float(sample_rate))
            for lp in (loop.F, loop.G):
                _check_mode_nyquist(lp, float(sample_rate))
            coarse = {k: v[::m] for k, v in sig.items()} if m > 1 else sig
            res = _nonlinear(loop, S, coarse, Ts, controller_method, sat, rate_limit)
            out = _plant_on_fine_grid(loop, res, sig, Ts, m) if m > 1 else res
            mode = "sampled"
        return _finish(loop, t, sig, out, mode, sample_rate, accuracy, divergence_limit)
    if sample_rate is not None:
        Ts, m = _controller_period(sample_rate, dt, N)
        _check_rates(S, Ts, "sample_rate", float(sample_rate))
        for lp in (loop.F, loop.G):
            _check_mode_nyquist(lp, float(sample_rate))
        out = _sampled(loop, S, sig, Ts, m, controller_method)
        mode = "sampled"
    else:
        exact = loop.architecture == "feedforward" or S is None
        if exact:
            if S is None or (not S.distributed and S.continuous is None):
                out = _exact_closed_loop(loop, S, sig, dt)
            else:
                out = _exact_feedforward(loop, sig, dt)
            mode = "continuous (exact)"
        else:
            if substeps is None:
                substeps = max(1, int(math.ceil(dt / 1e-3 - 1e-9)))
            h = dt / substeps
            _check_rates(S, 2 * h, "the internal rate (1/t step x substeps)", 1.0 / (2 * h))
            out = _fine(loop, S, sig, h, substeps)
            coarse = _fine(loop, S, sig, 2 * h, substeps // 2) if substeps % 2 == 0 else \
                _fine_coarse(loop, S, sig, h, substeps)
            accuracy = float(np.max(np.abs(out["y"] - coarse["y"]))) if N else 0.0
            mode = "continuous"
    return _finish(loop, t, sig, out, mode, sample_rate, accuracy, divergence_limit)


def _check_saturation(saturation: Any) -> tuple[float, float] | None:
    if saturation is None:
        return None
    if isinstance(saturation, (int, float)) and not isinstance(saturation, bool):
        if not saturation > 0:
            raise ValueError(f"saturation must be > 0 (symmetric limit) or (u_min, u_max), got {saturation!r}")
        return -float(saturation), float(saturation)
    try:
        lo, hi = (float(x) for x in saturation)
    except (TypeError, ValueError) as exc:
        raise TypeError("saturation must be a number or a pair (u_min, u_max)") from exc
    if not lo < hi:
        raise ValueError(f"saturation needs u_min < u_max, got ({lo:g}, {hi:g})")
    return lo, hi


def _controller_period(sample_rate: Any, dt: float, n: int) -> tuple[float, int]:
    if isinstance(sample_rate, bool) or not isinstance(sample_rate, (int, float, np.integer, np.floating)) \
            or not sample_rate > 0 or not math.isfinite(sample_rate):
        raise ValueError(f"sample_rate must be a positive number of Hz (or None), got {sample_rate!r}")
    Ts = 1.0 / float(sample_rate)
    if not Ts <= dt * (n - 1):
        raise ValueError(f"sample_rate = {float(sample_rate):g} Hz: the controller period {Ts:.6g} s is longer than "
                         f"the simulated time {dt * (n - 1):.6g} s")
    ratio = Ts / dt
    m = int(round(ratio))
    if m < 1 or abs(ratio - m) > 1e-6 * ratio:
        raise ValueError(
            f"sample_rate: the controller period {Ts:.6g} s must be an integer multiple of the step of t "
            f"({dt:.6g} s)"
        )
    return Ts, m


def _plant_on_fine_grid(loop: Loop, c_out: dict[str, np.ndarray], sig: dict[str, np.ndarray], Ts: float,
                        m: int) -> dict[str, np.ndarray]:
    """Hold the controller's outputs over ``m`` steps of ``t`` and run the plant exactly on ``t``."""
    N = sig["w"].size
    out: dict[str, np.ndarray] = {}
    for k in ("e", "v", "u", "m", "r"):
        if k in c_out:
            out[k] = np.repeat(c_out[k], m)[:N]
    up = out["u"] + sig["di"]
    out["up"] = up
    out["z"] = exact_delayed_response(loop.G, up, Ts / m) + sig["d"]
    out["y"] = _load_response(loop, up, sig["d"], Ts / m)
    return out


def _check_mode_nyquist(tf: TransferFunction, rate: float) -> None:
    if tf.den.degree < 1:
        return
    poles = np.roots(tf.den.coeffs[0, ::-1])
    if poles.size and np.max(np.abs(poles)) / (2 * math.pi) >= 0.5 * rate:
        f = float(np.max(np.abs(poles)) / (2 * math.pi))
        raise ValueError(
            f"sample_rate = {rate:g} Hz is too low: a plant mode at {f:.4g} Hz is at or above the Nyquist "
            f"frequency {0.5 * rate:.4g} Hz"
        )


def _sampled(loop: Loop, S: Shaper | None, sig: dict[str, np.ndarray], Ts: float, m: int, cm: str) -> dict[str, np.ndarray]:
    coarse = {k: v[::m] for k, v in sig.items()} if m > 1 else sig
    if S is None or loop.architecture == "feedforward":
        r = coarse["w"]
        if S is not None:
            b, a = _discrete_shaper(S, Ts)
            r = signal.lfilter(b, a, r)
        c_out = _delay_free_loop(loop, coarse, r, Ts, cm)
    else:
        c_out = _ShapedLoop(loop, S, Ts, "zoh", cm).response(coarse)
    if m == 1:
        return c_out
    return _plant_on_fine_grid(loop, c_out, sig, Ts, m)


def _fine(loop: Loop, S: Shaper | None, sig: dict[str, np.ndarray], h: float, sub: int) -> dict[str, np.ndarray]:
    fine = {k: np.repeat(v, sub) for k, v in sig.items()}
    out = _ShapedLoop(loop, S, h, "foh", "foh").response(fine)
    return {k: v[::sub] for k, v in out.items()}


def _fine_coarse(loop: Loop, S: Shaper | None, sig: dict[str, np.ndarray], h: float, sub: int) -> dict[str, np.ndarray]:
    # odd substeps: the comparison run uses twice as many steps (h / 2) instead of 2 h
    return _fine(loop, S, sig, h / 2, 2 * sub)


def _finish(loop: Loop, t: np.ndarray, sig: dict[str, np.ndarray], out: dict[str, np.ndarray], mode: str,
            sample_rate: float | None, accuracy: float, limit: float) -> SimulationResponse:
    signals = dict(sig)
    signals.update({name: values for name, values in out.items() if name != "zn"})
    scale = max(1.0, max(float(np.max(np.abs(values))) for values in sig.values()))
    diverged = None
    which = None
    first = t.size
    for k in ("y", "z", "u", "v", "e", "m", "r"):
        if k not in signals:
            continue
        bad = np.flatnonzero(~np.isfinite(signals[k]) | (np.abs(signals[k]) > limit * scale))
        if bad.size and bad[0] < first:
            first, which = int(bad[0]), k
    if which is not None:
        diverged = float(t[first])
        warnings.warn(
            f"the {loop.architecture} loop diverged: |{which}| exceeded {limit:g} x the input scale at "
            f"t = {diverged:.4g} s; the response stops there",
            DivergenceWarning,
            stacklevel=3,
        )
        t = t[:first]
        signals = {k: v[:first] for k, v in signals.items()}
    return SimulationResponse(
        time=t, signals=signals, mode=mode, sample_rate=sample_rate, accuracy=accuracy,
        diverged=diverged, diverged_signal=which, architecture=loop.architecture,
    )
