"""The exact method: the continuous loop without a shaper inside, exact at the samples for held inputs.

Two cases: a lumped shaper outside the loop (or none), one state space whose
reference enters at the impulses' fractional delays (:func:`exact_lumped`);
a shaper with distributed or rational parts outside the loop, every channel
run exactly (:func:`exact_channels`, fractional delays included).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from ..core.transfer import TransferFunction
from ..loops.loop import Loop
from ..shapers.base import Shaper
from .discrete import _shift, balance, exact_delayed_response, propagate, state_space
from .layout import RingLayout, Signals

__all__ = ["exact_lumped", "exact_channels", "delay_free_signals"]


def exact_lumped(loop: Loop, layout: RingLayout, S: Shaper | None, sig: Signals, h: float) -> Signals:
    """Exact sampled solution of the continuous loop for held inputs (lumped feedforward shaper or none).

    The closed loop (C, G and F in continuous time) is one state-space system;
    each impulse ``A_i`` at ``t_i = (n_i + f_i) h`` of the feedforward shaper
    feeds the held reference in two parts, before and after the instant
    ``f_i h`` inside a step (modified z-transform), so fractional delays are
    exact.  One propagation (:func:`~posicast.simulation.discrete.propagate`) gives every signal.
    """
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
    held = layout.controller_input(sig, np.zeros(N))  # -n - d: the inputs the controller sees but w
    plant_in, plant_out = layout.held_sum(sig, "plant input"), layout.held_sum(sig, "plant output")
    if np.any(held):
        inputs.append((full["ext"], held))
    if plant_in is not None and np.any(plant_in):
        inputs.append((full["di"], plant_in))
    if plant_out is not None and np.any(plant_out):
        inputs.append((full["d"], plant_out))
    gx, v0, y0 = propagate(Phi, inputs, rows)
    return delay_free_signals(layout, sig, r_now, r_now + held, (gx, v0, y0), Dc, Df)


def delay_free_signals(layout: RingLayout, sig: Signals, r: np.ndarray, ext: np.ndarray,
                       states: tuple[np.ndarray, np.ndarray, np.ndarray], Dc: float, Df: float) -> Signals:
    """Every signal of a loop without a shaper inside from its state outputs ``(G xg, v - Dc ext, y - Df d)``.

    ``ext`` is the controller's input less ``G xg``; the other nodes follow by walking the ring.
    """
    gx, v0, y0 = states
    d = layout.held_sum(sig, "plant output")
    d = np.zeros(r.size) if d is None else d
    known = {layout.nodes[layout.plant]: gx + d, layout.nodes[layout.controller]: v0 + Dc * ext}
    nodes = layout.walk(known, sig, r)
    return layout.outputs(nodes, y0 + Df * d, r)


def exact_channels(loop: Loop, layout: RingLayout, inputs: Signals, h: float) -> Signals:
    """Every output as the sum of its exact channels from the inputs (:func:`exact_delayed_response`)."""
    out: Signals = {}
    for dst in loop.outputs:
        acc = np.zeros(inputs["w"].size)
        for src, x in inputs.items():
            if not np.any(x):
                continue
            tf: TransferFunction = loop.transfer(src, dst)
            if tf.num.is_zero:
                continue
            acc += exact_delayed_response(tf, x, h)
        out[dst] = acc
    known = {name: out[name] for name in layout.nodes if name in out}
    nodes = layout.walk(known, inputs)
    for name, values in nodes.items():
        out.setdefault(name, values)
    return out
