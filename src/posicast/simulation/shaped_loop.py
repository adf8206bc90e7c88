"""A loop with its shaper inside, on a fixed step, as one state space built by walking the loop's ring.

Used by the stepped (continuous, shaper in the loop) and the sampled methods.
Every rational block is kept as a balanced state space and the loop is run as
one (:mod:`posicast.simulation.discrete`), never as a product of ``z^-1``
polynomials: at small steps the poles of such a polynomial are lost near
``z = 1`` (stable high-order loops diverged at 0.5 ms).
"""

from __future__ import annotations

import numpy as np
from ..core.transfer import TransferFunction
from ..loops.loop import Loop
from ..shapers.base import Shaper
from .discrete import BLOCK, HeldFilter, PowerPropagator, balance, block_length, discretize_ss
from .layout import RingLayout
from .running_sums import RunningSums, running_sums
from .streaming import discretize, prewarped_step

__all__ = ["ShapedLoop", "load_response", "cancel_origin"]

INPUTS = ("w", "d", "di", "n")
# ShapedLoop: below this block length (the nearest far tap) a step-by-step update beats blocks
_BLOCK_MIN = 16
# a state this large has diverged beyond any divergence limit: the simulation stops
_HUGE = 1e150


class _NodeEquations:
    """``sig = P sig + Qx x + Qu u`` for the ring's nodes (inputs ``u``: ``w, d, di, n`` and ``q``),
    and the state update's input selection ``Bsel`` (``x+ = A x + Bsel sig``)."""

    def __init__(self, n_nodes: int, nx: int) -> None:
        self.P = np.zeros((n_nodes, n_nodes))
        self.Qx = np.zeros((n_nodes, nx))
        self.Qu = np.zeros((n_nodes, 5))
        self.Bsel = np.zeros((nx, n_nodes))


class ShapedLoop:
    """A loop with its shaper inside on step ``h``, as a state space.

    ``C`` and ``G`` are discretised from their balanced continuous state
    spaces (:func:`~posicast.simulation.discrete.discretize_ss`), the shaper's
    IIR part likewise (Tustin prewarped as in
    :func:`~posicast.simulation.streaming.discretize`), and the shaper's FIR taps
    act through the stored history of the shaper's input ``xs`` (the node
    before ``S``, or the output of ``1/S``: ``S m = (its input)``).
    Within a step only the undelayed tap ``s0`` (plus the IIR direct term)
    acts, so the ring's node equations are solved once for the signals as
    functions of the state and the inputs, and each step is one state update
    of a low-order, balanced closed loop.

    Why not the loop algebra on ``z^-1`` polynomials: the closed-loop
    characteristic polynomial of a ninth-order plant (and, with a
    distributed-delay shaper, of degree #taps + 10, thousands) run by
    ``lfilter`` has coefficients that do not determine its roots at small
    steps; stable loops diverged at 0.5 ms, the notch loop at 1 ms.

    Parameters
    ----------
    loop : Loop
        A loop whose ring holds the shaper (:class:`~posicast.simulation.layout.RingLayout`).
    layout : RingLayout
    S : Shaper
        The loop's shaper.
    h : float
        Step [s].
    plant, controller : {'zoh', 'foh', 'bilinear'}
        Discretisation of ``G`` and of ``C``.
    """

    def __init__(self, loop: Loop, layout: RingLayout, S: Shaper, h: float, plant: str, controller: str) -> None:
        if layout.shaper is None:
            raise ValueError(f"the {loop.architecture} loop has no shaper inside its ring")
        if loop.G.has_delays or loop.C.has_delays or loop.F.has_delays:
            raise ValueError("simulation supports delay-free G, C and F (the shaper carries the delays)")
        if loop.G.num.degree >= loop.G.den.degree and plant == "zoh":
            raise ValueError("G must be strictly proper for a sampled simulation (a held input feeds straight through)")
        self.loop, self.layout, self.h = loop, layout, h
        Ac, Bc, Cc, Dc = discretize_ss(loop.C, h, controller)
        Ag, Bg, Cg, Dg = discretize_ss(loop.G, h, plant)
        D = discretize(S, 1.0 / h, "linear")
        taps = np.asarray(D.taps, dtype=float)
        Ar, Br, Cr, Dr = (np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), 0.0)
        if S.continuous is not None:
            Ar, Br, Cr, Dr = discretize_ss(S.continuous, prewarped_step(S, h), "bilinear")
        s0 = float(taps[0]) + Dr  # the shaper's undelayed gain
        if layout.inverse and abs(s0) < 1e-12 * (np.abs(taps).sum() + abs(Dr)):
            raise ValueError("the inverse shaper needs a nonzero undelayed term (1/S is not causal)")
        # delayed taps i = first .. last (those at i >= 1 only see the past of xs)
        late = np.flatnonzero(taps[1:]) + 1
        self.first = int(late[0]) if late.size else 0
        self.last = int(late[-1]) if late.size else 0
        self.delayed = taps[self.first: self.last + 1].copy() if late.size else np.zeros(0)

        nc, ng, nr = Ac.shape[0], Ag.shape[0], Ar.shape[0]
        nx = nc + ng + nr
        ic, ig, ir = slice(0, nc), slice(nc, nc + ng), slice(nc + ng, nx)
        n_nodes = len(layout.nodes)
        eq, self.ixs = _ring_equations(layout, nx, (ic, Ac, Bc, Cc, Dc), (ig, Ag, Bg, Cg, Dg), (ir, Cr), s0)
        eq.Bsel[ir, self.ixs] = Br[:, 0]
        I_P = np.eye(n_nodes) - eq.P
        if np.linalg.cond(I_P) > 1e12:
            raise ValueError("the discretised loop is not well posed (its instantaneous loop gain is -1)")
        Sx = np.linalg.solve(I_P, eq.Qx)
        Su = np.linalg.solve(I_P, eq.Qu)
        # x+ = blockdiag(Ac, Ag, Ar) x + Bsel sig
        A = np.zeros((nx, nx))
        A[ic, ic], A[ig, ig], A[ir, ir] = Ac, Ag, Ar
        # one diagonal similarity for the whole loop: its blocks are balanced, their coupling need not be
        self.A, self.B, self.Sx = balance(A + eq.Bsel @ Sx, eq.Bsel @ Su, Sx)
        self.Su = Su
        self._recursion(S)
        self.reset()

    def _recursion(self, S: Shaper) -> None:
        """The delayed taps as a recursion plus far taps (:mod:`.running_sums`), and the loop around it as
        one state space ``z+ = Aa z + Ba [w, d, di, n, far]`` over blocks of the nearest far tap.

        ``z`` holds the loop's state ``x``, the last ``Lh`` shaper inputs ``xs`` (the recursion's head)
        and the recursion's state, the differences ``Delta^m q_{j-1}``, ``m < deg D``.
        """
        plan = running_sums(S, self.delayed, self.first) if self.delayed.size else None
        if plan is None:  # the taps themselves are the far taps (lumped shapers), or there are none
            taps = np.zeros(self.last + 1)
            if self.delayed.size:
                taps[self.first:] = self.delayed
            far = np.flatnonzero(taps)
            plan = RunningSums(np.ones(1), far[:0], taps[:0], far, taps[far], taps)
        self.plan = plan
        nx, p = self.A.shape[0], plan.order
        lh = int(plan.head[-1]) if plan.head.size else 0
        nz = nx + lh + p
        ixs = self.ixs
        cx, dq, bq = self.Sx[ixs], self.Su[ixs, 4], self.B[:, 4]
        cr = np.zeros(nz)  # Delta^p q_j = cr z_j + far_j (the head of R)
        cr[nx + plan.head - 1] = plan.head_coef
        cq = cr.copy()  # q_j = sum_m Delta^m q_{j-1} + Delta^p q_j = cq z_j + far_j
        cq[nx + lh: nz] = 1.0
        cs = dq * cq  # xs_j = cs z_j + (known_j + dq far_j)
        cs[:nx] += cx
        Aa = np.zeros((nz, nz))
        Ba = np.zeros((nz, 5))
        Aa[:nx, :nx] = self.A
        Aa[:nx] += np.outer(bq, cq)
        Ba[:nx] = self.B
        if lh:
            Aa[nx] = cs
            Aa[nx + 1: nx + lh, nx: nx + lh - 1] = np.eye(lh - 1)
            Ba[nx, :4] = self.Su[ixs, :4]
            Ba[nx, 4] = dq
        if p:  # Delta^m q_j = sum_{l >= m} Delta^l q_{j-1} + Delta^p q_j
            Aa[nx + lh: nz] = cr
            Aa[nx + lh: nz, nx + lh: nz] += np.triu(np.ones((p, p)))
            Ba[nx + lh: nz, 4] = 1.0
        self.Aa, self.Ba, self.cq, self.lh = Aa, Ba, cq, lh
        self.block = plan.block if plan.far.size else BLOCK
        self.tail_length = self.last + p
        self._props: dict[tuple[tuple[int, ...], int], PowerPropagator] = {}

    def reset(self) -> None:
        """Start again from rest (zero state and history)."""
        self._x = np.zeros(self.A.shape[0])
        self._z = np.zeros(self.Aa.shape[0])
        self._tail = np.zeros(self.tail_length)
        if getattr(self, "_load", None) is None:
            self._load = HeldFilter(cancel_origin(self.loop.F * self.loop.G), self.h)
        self._load.reset()
        if getattr(self, "_load_d", None) is not None:
            self._load_d.reset()
        else:
            self._load_d: HeldFilter | None = None  # F on the output disturbance, made when one acts
        self._diverged = False

    def response(self, inputs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """All loop signals for the inputs ``w, d, di, n`` on the step ``h`` (``y`` for held plant input), from rest."""
        self.reset()
        return self.advance(inputs)

    def advance(self, inputs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The loop signals for the next samples of the inputs, continuing from the previous call."""
        ext = np.ascontiguousarray(np.vstack([inputs[name] for name in INPUTS]))
        run = self._blocks if self.block >= _BLOCK_MIN else self._steps
        with np.errstate(over="ignore", invalid="ignore"):  # a diverging loop is reported by _finish
            if self._diverged:
                X, q = np.full((self.A.shape[0], ext.shape[1]), np.nan), np.full(ext.shape[1], np.nan)
            else:
                X, q = run(ext)
            sig = self.Sx @ X + self.Su[:, :4] @ ext + np.outer(self.Su[:, 4], q)
        lay = self.layout
        nodes = {name: sig[i] for i, name in enumerate(lay.nodes)}
        d = lay.injected(inputs, lay.plant)
        y = self._load.run(sig[lay.plant - 1])
        if self._load_d is None and d is not None and np.any(d):
            self._load_d = HeldFilter(self.loop.F, self.h)
        if self._load_d is not None:
            y = y + self._load_d.run(np.zeros(ext.shape[1]) if d is None else d)
        return lay.outputs(nodes, y, None)

    def _propagator(self, active: tuple[int, ...], K: int) -> PowerPropagator:
        """The block propagator of the loop with the recursion for the input columns ``active`` (cached)."""
        key = (active, K)
        if key not in self._props:
            rows = np.vstack([np.eye(self.A.shape[0], self.Aa.shape[0]), self.cq])
            self._props[key] = PowerPropagator(self.Aa, self.Ba[:, list(active)], K, rows)
        return self._props[key]

    def _xs_known(self, ext: np.ndarray) -> np.ndarray:
        """The part of the shaper input ``xs`` set by the inputs ``w, d, di, n`` (not by the state or ``q``)."""
        return self.Su[self.ixs, :4] @ ext

    def _history(self, N: int) -> tuple[np.ndarray, int]:
        """The stored shaper inputs before this call followed by room for ``N`` more, and the offset of the first."""
        hist = np.zeros(self._tail.size + N)
        hist[: self._tail.size] = self._tail
        return hist, self._tail.size

    def _keep_tail(self, hist: np.ndarray) -> None:
        if self._tail.size:
            self._tail = hist[-self._tail.size:].copy()

    def _steps(self, ext: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """States (columns) and delayed FIR output ``q``, one explicit state update per step.

        For shapers whose taps near ``t = 0`` are not a kernel's running sum
        (:mod:`.running_sums`): the history enters every step.
        """
        N = ext.shape[1]
        A, B, ixs = self.A, self.B, self.ixs
        drive = np.ascontiguousarray((B[:, :4] @ ext).T)  # the known part of the update, row j for step j
        xs_known = self._xs_known(ext)
        cx, dq, bq = self.Sx[ixs], self.Su[ixs, 4], B[:, 4]
        X = np.zeros((N, A.shape[0]))
        q = np.zeros(N)
        x = self._x
        taps, last = self.delayed[::-1], self.last
        span = taps.size  # last - first + 1, or 0 without delayed taps
        hist, o = self._history(N)  # hist[o + j] = xs[j]
        for j in range(N):
            qj = float(taps @ hist[o + j - last: o + j - last + span]) if span else 0.0  # sum_i taps[i] xs[j - i]
            X[j] = x
            q[j] = qj
            hist[o + j] = cx @ x + xs_known[j] + dq * qj
            x = A @ x + drive[j] + bq * qj
            if j % 4096 == 4095 and not np.all(np.abs(x) < _HUGE):
                X[j + 1:] = np.nan  # diverged far beyond any divergence limit: stop here
                q[j + 1:] = np.nan
                self._diverged = True
                break
        self._x = x
        self._keep_tail(hist)
        return X.T, q

    def _blocks(self, ext: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """States (columns) and delayed FIR output ``q`` by the method of steps over blocks of the nearest far tap.

        Over a block the far taps read only the shaper input before it, so
        they are summed for the whole block at once; the loop with the
        recursion of :mod:`.running_sums` is then a linear system with a
        known input, run over the block by
        :class:`~posicast.simulation.discrete.PowerPropagator` (as accurate as
        :meth:`_steps`, 1e-13).  The recursion's state is summed exactly from
        the history at the start of each block, so its rounding never drifts.
        """
        N = ext.shape[1]
        plan, nx, lh, p = self.plan, self.A.shape[0], self.lh, self.plan.order
        K = max(1, min(self.block, block_length(self.Aa.shape[0], N)))
        # only the inputs that act in this chunk enter the propagator (one per set of inputs, kept)
        active = [i for i in range(4) if np.any(ext[i])] + ([4] if plan.far.size else [])
        prop = self._propagator(tuple(active), K)
        ext_active = ext[[i for i in active if i < 4]]
        xs_known = self._xs_known(ext)
        cx, dq = self.Sx[self.ixs], self.Su[self.ixs, 4]
        X = np.zeros((nx, N))
        q = np.zeros(N)
        hist, o = self._history(N)  # hist[o + j] = xs[j]
        z = self._z
        for k in range(0, N, K):
            kk = min(N, k + K)
            far = plan.far_sum(hist, o + k, o + kk) if plan.far.size else np.zeros(kk - k)
            if lh:
                z[nx: nx + lh] = hist[o + k - lh: o + k][::-1]  # xs[k - 1], .., xs[k - lh]
            if p:
                z[nx + lh:] = plan.exact_state(hist, o + k)  # Delta^m q[k - 1]
            Y, z = prop.block(z, np.vstack([ext_active[:, k:kk], far]) if plan.far.size else ext_active[:, k:kk])
            X[:, k:kk] = Y[:nx]
            q[k:kk] = Y[nx] + far
            hist[o + k: o + kk] = cx @ X[:, k:kk] + xs_known[k:kk] + dq * q[k:kk]
            if not np.all(np.abs(z) < _HUGE):
                X[:, kk:] = np.nan  # diverged far beyond any divergence limit: stop here
                q[kk:] = np.nan
                self._diverged = True
                break
        self._z = z
        self._keep_tail(hist)
        return X, q


def _ring_equations(layout: RingLayout, nx: int, C: tuple, G: tuple, R: tuple, s0: float) -> tuple[_NodeEquations, int]:
    """Walk the ring: ``node i = block i (node i - 1) + inputs added at i``; returns the equations and the
    node whose history the shaper's delayed taps read (``xs``).

    ``C``, ``G``: ``(state slice, A, B, C, D)`` of the discretised controller and plant; ``R``: ``(state slice,
    C)`` of the shaper's rational part; ``s0`` the shaper's undelayed gain.
    """
    ic, Ac, Bc, Cc, Dc = C
    ig, Ag, Bg, Cg, Dg = G
    ir, Cr = R
    ring = layout.ring
    n_nodes = len(ring.nodes)
    ixs = -1
    eq = _NodeEquations(n_nodes, nx)
    iq = 4  # the delayed FIR output q, after the inputs w, d, di, n
    for i, blk in enumerate(ring.blocks):  # node i = block i (node i - 1) + inputs added at i
        prev = (i - 1) % n_nodes
        for name in ring.injected(i):
            eq.Qu[i, INPUTS.index(name)] += 1.0
        if i == 0:
            eq.P[0, prev] = -1.0                 # the comparator: e = (inputs) - nodes[-1]
        elif i == layout.controller:
            eq.P[i, prev] = Dc                   # v = Cc xc + Dc e
            eq.Qx[i, ic] = Cc[0]
            eq.Bsel[ic, prev] = Bc[:, 0]
        elif i == layout.plant:
            eq.P[i, prev] = Dg                   # z = Cg xg + Dg up (+ d)
            eq.Qx[i, ig] = Cg[0]
            eq.Bsel[ig, prev] = Bg[:, 0]
        elif i == layout.shaper and layout.inverse:
            eq.P[i, prev] = 1.0 / s0             # s0 m + Cr xr + q = (input of 1/S)
            eq.Qx[i, ir] = -Cr[0] / s0
            eq.Qu[i, iq] = -1.0 / s0
            ixs = i
        elif i == layout.shaper:
            eq.P[i, prev] = s0                   # u = s0 v + Cr xr + q
            eq.Qx[i, ir] = Cr[0]
            eq.Qu[i, iq] = 1.0
            ixs = prev
        else:
            eq.P[i, prev] = 1.0                  # a plain connection
    return eq, ixs


def load_response(loop: Loop, up: np.ndarray, d: np.ndarray, h: float) -> np.ndarray:
    """``y = (F G) up + F d`` for held ``up`` and ``d``, exact at the samples.

    The cascade ``F G`` is one block (its common ``s`` factors cancelled), run
    as a balanced state space (:class:`~posicast.simulation.discrete.HeldFilter`):
    a high-order transfer polynomial at a small step loses about 1e-8 here.
    """
    y = HeldFilter(cancel_origin(loop.F * loop.G), h).run(up)
    if np.any(d):
        y = y + HeldFilter(loop.F, h).run(d)
    return y


def cancel_origin(tf: TransferFunction) -> TransferFunction:
    """Cancel common factors ``s^k`` of a rational transfer function (exact zero coefficients)."""
    num, den = tf.num.coeffs[0], tf.den.coeffs[0]
    k = 0
    while k < min(num.size, den.size) - 1 and num[k] == 0 and den[k] == 0:
        k += 1
    if k == 0 or tf.has_delays:
        return tf
    return TransferFunction.from_poly(num[k:][::-1], den[k:][::-1])
