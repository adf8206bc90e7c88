"""The nonlinear method: actuator saturation and/or rate limit, the ring walked sample by sample."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy import signal

from ..loops.loop import Loop
from ..shapers.base import Shaper
from .discrete import discretize_ss
from .layout import RingLayout, Signals
from .shaped_loop import load_response
from .streaming import discretize

__all__ = ["run_nonlinear", "Limits"]


class Limits(NamedTuple):
    """Actuator limits on the ring's node ``u``: range ``[low, high]`` and largest change per step."""

    low: float
    high: float
    step: float


def _taps(S: Shaper | None, h: float) -> np.ndarray:
    if S is None:
        return np.ones(1)
    D = discretize(S, 1.0 / h, "linear")
    if D.b is not None:
        raise ValueError("saturation/rate_limit: shapers with an IIR part (notch) are not supported here")
    return D.taps


def _limited_node(layout: RingLayout) -> int:
    """The node the limits act on: ``u`` (the actuator command), else the controller's output."""
    i = layout.nodes.index("u") if "u" in layout.nodes else layout.controller
    if not layout.controller <= i < layout.plant:
        raise ValueError(f"saturation/rate_limit: the {layout.ring.nodes[i]!r} node of the ring must lie between the "
                         "controller and the plant")
    return i


def run_nonlinear(loop: Loop, layout: RingLayout, S: Shaper | None, sig: Signals, h: float, cm: str,
                  sat: tuple[float, float] | None, rate: float | None) -> Signals:
    """Sample-by-sample simulation with actuator saturation and/or rate limit on ``u``.

    Same discretisation as the sampled mode (controller by ``cm``, plant exact
    ZOH, shaper taps with fractional delays; the inverse shaper as the
    recursion of seed 000 eq. 19/20), run as an explicit loop because the
    limits make the loop nonlinear.  Each step walks the ring from the plant's
    output round to its input: ``node = block(previous) + inputs added there``.
    Its cyclomatic complexity (27) is on purpose: the per-sample ring walk stays
    inline, see the comment at the loop.
    """
    N = sig["w"].size
    Ac, Bc, Cc, Dc = discretize_ss(loop.C, h, cm)
    Ag, Bg, Cg, Dg = discretize_ss(loop.G, h, "zoh")
    if Dg != 0:
        raise ValueError("G must be strictly proper for simulation (a held input feeds straight through)")
    taps = _taps(S, h)
    nz = np.flatnonzero(taps)
    nz_past = nz[nz > 0]
    w_past = taps[nz_past]
    r = sig["w"]
    if layout.reference_shaper and S is not None:
        r = signal.lfilter(taps, [1.0], r)
    lo, hi = sat if sat is not None else (-np.inf, np.inf)
    limits = Limits(lo, hi, rate * h if rate is not None else np.inf)
    n = len(layout.nodes)
    c, g, s, lim = layout.controller, layout.plant, layout.shaper, _limited_node(layout)
    added = [_added(layout, sig, r, i) for i in range(n)]
    order = list(range(g, n)) + list(range(0, g))  # from the plant's output round to its input
    xs_node = -1 if s is None else (s if layout.inverse else s - 1)
    xc = np.zeros(Ac.shape[0])
    xg = np.zeros(Ag.shape[0])
    pad = int(nz.max()) + 1 if nz.size else 1
    hist = np.zeros(N + pad)  # the shaper input's history, offset by pad so index k - j >= 0
    vals = np.zeros((n, N))
    val = [0.0] * n
    u_prev = 0.0
    cg, cc = Cg[0], (Cc[0] if Ac.size else None)
    bc, bg = Bc[:, 0], Bg[:, 0]
    # One explicit step per sample: the limits make the loop nonlinear.  The ring walk stays inline (a branch
    # per block kind, CC above 20): a call per node and step would double the cost of this Python loop.
    for k in range(N):
        for i in order:
            prev = val[i - 1]
            if i == g:
                x = float(cg @ xg)
            elif i == 0:
                x = -prev
            elif i == c:
                x = float(cc @ xc) + Dc * prev if Ac.size else Dc * prev
            elif i == s and layout.inverse:
                x = (prev - float(np.dot(w_past, hist[pad + k - nz_past]))) / taps[0]
            elif i == s:
                x = taps[0] * prev + float(np.dot(w_past, hist[pad + k - nz_past]))
            else:
                x = prev
            a = added[i]
            if a is not None:
                x = a[k] + x if i == 0 else x + a[k]
            if i == lim:
                x = min(max(x, limits.low), limits.high)
                x = min(max(x, u_prev - limits.step), u_prev + limits.step)
                u_prev = x
            val[i] = x
            if i == xs_node:
                hist[pad + k] = x
        if Ac.size:
            xc = Ac @ xc + bc * val[c - 1]
        xg = Ag @ xg + bg * val[g - 1]
        vals[:, k] = val
    nodes = {name: vals[i] for i, name in enumerate(layout.nodes)}
    d = layout.injected(sig, g)
    y = load_response(loop, vals[g - 1], np.zeros(N) if d is None else d, h)
    return layout.outputs(nodes, y, r)


def _added(layout: RingLayout, sig: Signals, r: np.ndarray, node: int) -> np.ndarray | None:
    """The inputs added at ``node``, the reference ``w`` as ``r`` (shaped outside the loop)."""
    out = None
    for name in layout.ring.injected(node):
        x = r if name == "w" else sig[name]
        out = x if out is None else out + x
    return out
