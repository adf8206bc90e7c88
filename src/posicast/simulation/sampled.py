"""The sampled method: the controller and the shaper at the sample rate, the plant exact between samples.

As on a real controller: ``C`` by Tustin (or ZOH/FOH), the shaper as FIR taps
with fractional delays split between samples (seed 000 eq. 19 for the inverse
ZV and eq. 20 for the inverse DZV are the IIR recursions ``1 / S(z)``).  The
plant ``G`` and the flexible part ``F`` see the held control signal and are
discretised exactly (zero-order hold), so their outputs are exact at every
sample.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from ..loops.loop import Loop
from ..shapers.base import Shaper
from .discrete import _zoh, balance, discretize_ss, exact_delayed_response, poly_add, poly_mul, propagate, state_space
from .exact import delay_free_signals
from .layout import RingLayout, Signals
from .shaped_loop import ShapedLoop, load_response
from .streaming import discretize

__all__ = ["run_sampled", "delay_free_loop", "plant_on_fine_grid", "discrete_shaper"]


def run_sampled(loop: Loop, layout: RingLayout, S: Shaper | None, sig: Signals, Ts: float, m: int,
                cm: str) -> Signals:
    """The sampled run: every step of ``t`` (``m`` per controller period ``Ts``), controller by ``cm``."""
    coarse = {k: v[::m] for k, v in sig.items()} if m > 1 else sig
    if S is None or layout.shaper is None:
        r = coarse["w"]
        if S is not None and layout.reference_shaper:
            b, a = discrete_shaper(S, Ts)
            r = signal.lfilter(b, a, r)
        c_out = delay_free_loop(loop, layout, coarse, r, Ts, cm)
    else:
        c_out = ShapedLoop(loop, layout, S, Ts, "zoh", cm).response(coarse)
    if m == 1:
        return c_out
    return plant_on_fine_grid(loop, layout, c_out, sig, Ts, m)


def plant_on_fine_grid(loop: Loop, layout: RingLayout, c_out: Signals, sig: Signals, Ts: float, m: int) -> Signals:
    """Hold the controller's signals over ``m`` steps of ``t`` and run the plant exactly on ``t``.

    The plant's input node is its held predecessor plus the inputs added there (``up = u + di``).
    """
    N = sig["w"].size
    g_in, g_out = layout.nodes[layout.plant - 1], layout.nodes[layout.plant]
    out: Signals = {k: np.repeat(x, m)[:N] for k, x in c_out.items() if k not in (g_in, g_out, "y")}
    gi = layout.plant - 1
    if layout.ring.blocks[gi].identity and gi > layout.controller:
        added = layout.injected(sig, gi)
        held = out[layout.nodes[gi - 1]]
        up = held if added is None else held + added
    else:
        up = np.repeat(c_out[g_in], m)[:N]
    out[g_in] = up
    d = layout.injected(sig, layout.plant)
    d = np.zeros(N) if d is None else d
    out[g_out] = exact_delayed_response(loop.G, up, Ts / m) + d
    out["y"] = load_response(loop, up, d, Ts / m)
    for name, tap in layout.ring.outputs.items():  # outputs reading the plant's nodes
        if tap.block.identity and layout.nodes[tap.node] in (g_in, g_out):
            out[name] = out[layout.nodes[tap.node]]
    return out


def discrete_shaper(S: Shaper, h: float) -> tuple[np.ndarray, np.ndarray]:
    """``(b, a)`` of the shaper on step ``h``: FIR taps (fractional delays split linearly,
    distributed delays integrated exactly) plus its rational part in parallel."""
    D = discretize(S, 1.0 / h, "linear")
    b, a = D.taps, np.ones(1)
    if D.b is not None:
        b = poly_add(poly_mul(b, D.a), D.b)
        a = D.a
    return b, a


def delay_free_loop(loop: Loop, layout: RingLayout, sig: Signals, r: np.ndarray, h: float, cm: str) -> Signals:
    """The loop without a shaper inside, as one discrete state-space system (:func:`propagate`).

    ``C`` is discretised by ``cm``; the plant and the load, ``G`` with ``F``
    on its output, are discretised together, exactly for held ``up`` and
    ``d`` (one zero-order hold of the cascade ``x_g' = A_g x_g + B_g up``,
    ``x_f' = A_f x_f + B_f (C_g x_g + d)``); ``r`` is the (already shaped)
    reference.  Every signal, ``y`` included, comes from one propagation of
    the closed-loop state, so nothing passes through a high-order
    transfer-function polynomial.
    """
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
    ext = layout.controller_input(sig, r)
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
    plant_in, plant_out = layout.held_sum(sig, "plant input"), layout.held_sum(sig, "plant output")
    if plant_in is not None and np.any(plant_in):
        inputs.append((Bcols[:, 1], plant_in))
    if plant_out is not None and np.any(plant_out):
        inputs.append((Bcols[:, 2], plant_out))
    return delay_free_signals(layout, sig, r, ext, propagate(A, inputs, rows), Dc, Df)
