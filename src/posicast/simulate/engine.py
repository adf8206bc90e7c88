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
  estimate of the ``2 h`` run, and a bound of about three times that of this one).

External inputs ``w``, ``d``, ``di``, ``n`` are held between the samples of
``t`` (zero-order hold), the natural reading of steps and of sampled data.
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np
from scipy import signal

from ..core.transfer import TransferFunction
from ..loops.loop import Loop
from ..shapers.base import Shaper
from .discrete import discretize_rational, exact_delayed_response, poly_add, poly_mul
from .streaming import discretize
from .response import SimulationResponse

__all__ = ["simulate", "DivergenceWarning"]

INPUTS = ("w", "d", "di", "n")


class DivergenceWarning(UserWarning):
    """A simulated loop diverged; the response stops where it did."""


def _as_signal(x: Any, name: str, n: int) -> np.ndarray:
    if x is None:
        return np.zeros(n)
    if np.isscalar(x):
        raise TypeError(f"{name} must be an array on t (or None), got a scalar")
    try:
        arr = np.asarray(x, dtype=float)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be an array of real numbers on t") from exc
    if arr.ndim != 1 or arr.size != n:
        raise ValueError(f"{name} must have the length of t ({n}), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains NaN or inf")
    return arr


def _check_time(t: Any) -> tuple[np.ndarray, float]:
    try:
        t = np.asarray(t, dtype=float)
    except (TypeError, ValueError) as exc:
        raise TypeError("t must be an array of times") from exc
    if t.ndim != 1 or t.size < 2:
        raise ValueError("t must be a 1-D array of at least 2 times")
    if not np.all(np.isfinite(t)):
        raise ValueError("t contains NaN or inf")
    dt = (t[-1] - t[0]) / (t.size - 1)
    if dt <= 0 or not np.allclose(np.diff(t), dt, rtol=1e-9, atol=1e-12 * max(1.0, abs(t[-1]))):
        raise ValueError("t must be uniform and increasing")
    return t, float(dt)


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


class _DiscreteLoop:
    """The loop's blocks as ``z^-1`` polynomials and its channels by the loop algebra."""

    def __init__(self, loop: Loop, S: Shaper | None, h: float, plant: str, controller: str) -> None:
        self.loop = loop
        if loop.G.has_delays or loop.C.has_delays or loop.F.has_delays:
            raise ValueError("simulation supports delay-free G, C and F (the shaper carries the delays)")
        if loop.G.num.degree >= loop.G.den.degree and plant == "zoh":
            raise ValueError("G must be strictly proper for a sampled simulation (a held input feeds straight through)")
        self.G = discretize_rational(loop.G, h, plant)
        self.C = discretize_rational(loop.C, h, controller)
        self.h = h
        one = (np.ones(1), np.ones(1))
        Sd = _discrete_shaper(S, h) if S is not None else one
        if loop.architecture == "feedforward":
            blocks = [one, self.C, one, one, self.G, one]
            self.pre = Sd
        elif loop.architecture == "control_action":
            blocks = [one, self.C, Sd, one, self.G, one]
            self.pre = one
        else:
            if S is not None and abs(Sd[0][0]) < 1e-12 * np.abs(Sd[0]).sum():
                raise ValueError("the inverse shaper needs a nonzero undelayed term (1/S is not causal)")
            blocks = [one, self.C, one, one, self.G, one, (Sd[1], Sd[0])]
            self.pre = one
        self.blocks = blocks
        nodes = len(blocks)
        self.nodes = nodes
        self.char = poly_add(poly_mul(*[b[1] for b in blocks]), poly_mul(*[b[0] for b in blocks]))
        names = ("e", "v", "u", "up", "z", "zn", "m")
        self.idx = {nm: i for i, nm in enumerate(names[:nodes])}
        self.inputs = {"w": 0, "d": self.idx["z"], "di": self.idx["up"], "n": self.idx["zn"]}

    def channel(self, src: str, dst_node: int) -> tuple[np.ndarray, np.ndarray]:
        a = self.inputs[src]
        b = dst_node
        n = self.nodes
        length = (b - a) % n
        path = {(a + k) % n for k in range(1, length + 1)}
        sign = -1.0 if 0 in path else 1.0
        num = poly_mul(*[blk[0] if i in path else blk[1] for i, blk in enumerate(self.blocks)])
        pre = self.pre if src == "w" else (np.ones(1), np.ones(1))
        return sign * poly_mul(num, pre[0]), poly_mul(self.char, pre[1])

    def response(self, inputs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """All loop signals: ``e`` through the closed loop, the rest forward from ``e``."""
        N = inputs["w"].size
        e = np.zeros(N)
        for src, x in inputs.items():
            if np.any(x):
                b, a = self.channel(src, 0)
                e += signal.lfilter(b, a, x)
        names = list(self.idx)
        out = {"e": e}
        added = {self.inputs[k]: inputs[k] for k in ("d", "di", "n")}
        prev = e
        for i in range(1, self.nodes):
            b, a = self.blocks[i]
            cur = prev * b[0] if (a.size == 1 and b.size == 1 and a[0] == 1) else signal.lfilter(b, a, prev)
            if i in added:
                cur = cur + added[i]
            out[names[i]] = cur
            prev = cur
        out.pop("zn", None)
        out["y"] = _load_response(self.loop, out["up"], inputs["d"], self.h)
        if self.loop.architecture == "feedforward":
            b, a = self.pre
            out["r"] = signal.lfilter(b, a, inputs["w"])
        return out


def _ss(bd: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """State space of a discrete ``(b, a)`` (powers of ``z^-1``, equal lengths)."""
    b, a = bd
    n = max(a.size, b.size)
    b = np.concatenate([b, np.zeros(n - b.size)])
    a = np.concatenate([a, np.zeros(n - a.size)])
    if n == 1:
        return np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), float(b[0] / a[0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", signal.BadCoefficients)
        A, B, C, D = signal.tf2ss(b, a)
    return A, B, C, float(D[0, 0])


def _load_response(loop: Loop, up: np.ndarray, d: np.ndarray, h: float) -> np.ndarray:
    """``y = (F G) up + F d`` for held ``up`` and ``d``, exact at the samples.

    The cascade ``F G`` is one block (its common ``s`` factors cancelled), run
    mode by mode (:func:`exact_delayed_response`): a high-order transfer
    polynomial at a small step loses about 1e-8 here.
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
    """The loop without a shaper inside, as one discrete state-space system run in its Schur basis.

    ``C`` is discretised by ``cm``, ``G`` and ``F G`` exactly for a held
    plant input; ``r`` is the (already shaped) reference.  Every signal is
    computed from the closed-loop state, so nothing passes through a
    high-order transfer-function polynomial.
    """
    from .discrete import schur_propagate

    Ac, Bc, Cc, Dc = _ss(discretize_rational(loop.C, h, cm))
    Ag, Bg, Cg, Dg = _ss(discretize_rational(loop.G, h, "zoh"))
    if Dg != 0:
        raise ValueError("G must be strictly proper for simulation (a held input feeds straight through)")
    nc, ng = Ac.shape[0], Ag.shape[0]
    n = nc + ng
    # e = r - n - d - Cg xg ; v = Cc xc + Dc e ; up = v + di
    ext = r - sig["n"] - sig["d"]
    A = np.zeros((n, n))
    ic, ig = slice(0, nc), slice(nc, n)
    A[ic, ic] = Ac
    A[ic, ig] = -Bc @ Cg
    A[ig, ic] = Bg @ Cc
    A[ig, ig] = Ag - Dc * Bg @ Cg
    inputs = [(np.concatenate([Bc[:, 0], Dc * Bg[:, 0]]), ext)]
    if np.any(sig["di"]):
        inputs.append((np.concatenate([np.zeros(nc), Bg[:, 0]]), sig["di"]))
    rows = np.array([
        np.concatenate([np.zeros(nc), Cg[0]]),
        np.concatenate([Cc[0] if nc else np.zeros(0), -Dc * Cg[0]]),
    ])
    xg_out, v_state = schur_propagate(A, inputs, rows)
    xs = {"xg": xg_out, "v": v_state}
    out: dict[str, np.ndarray] = {}
    out["z"] = xs["xg"] + sig["d"]
    out["e"] = r - out["z"] - sig["n"]
    out["v"] = xs["v"] + Dc * ext
    out["u"] = out["v"]
    out["up"] = out["v"] + sig["di"]
    out["y"] = _load_response(loop, out["up"], sig["d"], h)
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
    Ac, Bc, Cc, Dc = _ss(discretize_rational(loop.C, h, cm))
    Ag, Bg, Cg, Dg = _ss(discretize_rational(loop.G, h, "zoh"))
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


def _continuous_ss(tf: TransferFunction) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    num = np.trim_zeros(tf.num.coeffs[0][::-1], "f") if not tf.num.is_zero else np.zeros(1)
    den = np.trim_zeros(tf.den.coeffs[0][::-1], "f")
    if num.size > den.size:
        raise ValueError("an improper block (more zeros than poles) cannot be simulated")
    if den.size == 1:
        return np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), float(num[-1] / den[0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", signal.BadCoefficients)
        A, B, Cm, D = signal.tf2ss(num, den)
    return A, B, Cm, float(D[0, 0])


def _exact_closed_loop(loop: Loop, S: Shaper | None, sig: dict[str, np.ndarray], h: float) -> dict[str, np.ndarray]:
    """Exact sampled solution of the continuous loop for held inputs (lumped feedforward shaper or none).

    The closed loop (C, G and F in continuous time) is one state-space system;
    each impulse ``A_i`` at ``t_i = (n_i + f_i) h`` of the feedforward shaper
    feeds the held reference in two parts, before and after the instant
    ``f_i h`` inside a step (modified z-transform), so fractional delays are
    exact.  One propagation (:func:`schur_propagate`) gives every signal.
    """
    from scipy.linalg import expm

    from .discrete import _shift, schur_propagate

    Ac, Bc, Cc, Dc = _continuous_ss(loop.C)
    Ag, Bg, Cg, Dg = _continuous_ss(loop.G)
    Af, Bf, Cf, Df = _continuous_ss(loop.F)
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
    rows = np.array([
        np.concatenate([np.zeros(nc), Cg[0], np.zeros(nf)]),                                # G xg
        np.concatenate([Cc[0] if nc else np.zeros(0), -Dc * Cg[0], np.zeros(nf)]),          # v - Dc ext
        np.concatenate([np.zeros(nc), Df * Cg[0], Cf[0] if nf else np.zeros(0)]),           # y - Df d
    ])
    gx, v0, y0 = schur_propagate(Phi, inputs, rows)
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
    sig = {"w": _as_signal(w, "w", N), "d": _as_signal(d, "d", N), "di": _as_signal(di, "di", N),
           "n": _as_signal(n, "n", N)}
    if not (isinstance(divergence_limit, (int, float)) and divergence_limit > 1):
        raise ValueError(f"divergence_limit must be a number > 1, got {divergence_limit!r}")
    if controller_method not in ("bilinear", "zoh", "foh"):
        raise ValueError(f"controller_method must be 'bilinear', 'zoh' or 'foh', got {controller_method!r}")
    S = _shaper_object(loop)
    sat = _check_saturation(saturation)
    if rate_limit is not None:
        if isinstance(rate_limit, bool) or not isinstance(rate_limit, (int, float)) or not rate_limit > 0:
            raise ValueError(f"rate_limit must be a positive number of units per second, got {rate_limit!r}")
        rate_limit = float(rate_limit)
    nonlinear = sat is not None or rate_limit is not None
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
            Ts, m = _controller_period(sample_rate, dt)
            _check_rates(S, Ts, "sample_rate", float(sample_rate))
            for lp in (loop.F, loop.G):
                _check_mode_nyquist(lp, float(sample_rate))
            coarse = {k: v[::m] for k, v in sig.items()} if m > 1 else sig
            res = _nonlinear(loop, S, coarse, Ts, controller_method, sat, rate_limit)
            out = _plant_on_fine_grid(loop, res, sig, Ts, m) if m > 1 else res
            mode = "sampled"
        return _finish(loop, t, sig, out, mode, sample_rate, accuracy, divergence_limit)
    if sample_rate is not None:
        Ts, m = _controller_period(sample_rate, dt)
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
            if not isinstance(substeps, (int, np.integer)) or substeps < 1:
                raise ValueError(f"substeps must be an integer >= 1, got {substeps!r}")
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


def _controller_period(sample_rate: Any, dt: float) -> tuple[float, int]:
    if isinstance(sample_rate, bool) or not isinstance(sample_rate, (int, float)) or not sample_rate > 0 \
            or not math.isfinite(sample_rate):
        raise ValueError(f"sample_rate must be a positive number of Hz (or None), got {sample_rate!r}")
    Ts = 1.0 / float(sample_rate)
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
        c_out = _DiscreteLoop(loop, S, Ts, "zoh", cm).response(coarse)
    if m == 1:
        return c_out
    return _plant_on_fine_grid(loop, c_out, sig, Ts, m)


def _fine(loop: Loop, S: Shaper | None, sig: dict[str, np.ndarray], h: float, sub: int) -> dict[str, np.ndarray]:
    fine = {k: np.repeat(v, sub) for k, v in sig.items()}
    out = _DiscreteLoop(loop, S, h, "foh", "foh").response(fine)
    return {k: v[::sub] for k, v in out.items()}


def _fine_coarse(loop: Loop, S: Shaper | None, sig: dict[str, np.ndarray], h: float, sub: int) -> dict[str, np.ndarray]:
    # odd substeps: the comparison run uses twice as many steps (h / 2) instead of 2 h
    return _fine(loop, S, sig, h / 2, 2 * sub)


def _finish(loop: Loop, t: np.ndarray, sig: dict[str, np.ndarray], out: dict[str, np.ndarray], mode: str,
            sample_rate: float | None, accuracy: float, limit: float) -> SimulationResponse:
    signals = {k: v for k, v in sig.items()}
    for k, v in out.items():
        if k == "zn":
            continue
        signals[k] = v
    scale = max(1.0, max(float(np.max(np.abs(v))) for v in sig.values()))
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
