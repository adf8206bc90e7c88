"""The loop as it runs on the controller: poles and stability at the sample rate (z domain).

A continuous analysis of a loop with a shaper (:mod:`posicast.spectra`) treats the
shaper's delays as exact.  On the controller every block runs at the sample period
``Ts``: the controller ``C`` discretised (Tustin by default), the shaper as its taps
on the sample grid (a delay between samples split over two taps, distributed delays
integrated, :func:`~posicast.simulation.streaming.discretize`), the inverse shaper as
the recursion ``m[n] = (z[n] - sum_{k>=1} w_k m[n-k]) / w_0`` (seed 000 eq. 19-20),
the plant ``G`` held by a zero-order hold and sampled exactly, and optionally a
computation delay of whole samples between the controller and the actuator.

The result is one autonomous linear recursion ``x[n+1] = A x[n]`` whose state holds
the blocks' states and the shaper's delay line; the loop is stable iff the spectral
radius ``max |eig(A)| < 1``.  Its poles map to ``s = ln(z) / Ts`` for comparison with
the continuous spectrum.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
from scipy.sparse import lil_matrix
from scipy.sparse.linalg import eigs

from .. import _validate as v
from ..loops.loop import Loop
from ..shapers.base import Shaper
from .discrete import discretize_ss
from .streaming import discretize

__all__ = ["SampledLoop", "sampled_loop", "CONTROLLER_METHODS", "MAX_STATES"]

CONTROLLER_METHODS = ("bilinear", "zoh", "foh")
MAX_STATES = 200_000  #: most states (shaper taps + computation delay + blocks) a sampled loop may have
_DENSE_MAX = 1500  # up to this many states every pole by a dense eigensolver; above: the largest few
_MARGINAL = 1e-9


class _Blocks(NamedTuple):
    """The loop's blocks at the sample period: controller and held plant state spaces, the shaper's taps."""

    Ac: np.ndarray
    Bc: np.ndarray
    Cc: np.ndarray
    Dc: Any
    Ag: np.ndarray
    Bg: np.ndarray
    Cg: np.ndarray
    w: np.ndarray     # the shaper's taps ([1.0] without a shaper in the loop)
    in_loop: bool     # a shaper inside the loop
    inverse: bool     # ... run as 1/S


class _Layout(NamedTuple):
    """Where each block's states sit in ``x``: controller, plant, the shaper's delay line, the computation delay."""

    ic: int
    ig: int
    ih: int
    idl: int
    nc: int
    ng: int
    K: int   # the shaper's delay line
    d: int   # computation delay [samples]
    n: int


class _Rows(NamedTuple):
    """The loop's signals as rows over the state (sparse: ``{column: coefficient}``)."""

    e: dict[int, float]        # the controller's input
    u: dict[int, float]        # the command
    u_plant: dict[int, float]  # the command applied (after the computation delay)
    line_in: dict[int, float]  # what enters the shaper's delay line


def _checked(loop: Any, sample_rate: Any, computation_delay: Any, controller_method: Any) -> tuple[float, int, bool]:
    """``(fs, d, in_loop)``; the loop's architecture and blocks checked."""
    v.instance_of(loop, Loop, "loop", "a posicast Loop")
    fs = v.positive(sample_rate, "sample_rate")
    if not math.isfinite(1.0 / fs):
        raise ValueError(f"sample_rate must be > {1.0 / MAX_STATES:g} Hz (its period must be finite), got {fs:g}")
    d = v.integer_in_range(computation_delay, "computation_delay", 0, MAX_STATES)
    v.choice(controller_method, "controller_method", CONTROLLER_METHODS)
    arch = loop.architecture
    if arch not in ("feedforward", "control_action", "inverse_shaper"):
        raise ValueError(f"the sampled loop is built for the seed architectures, got {arch!r}")
    if loop.G.has_delays or loop.C.has_delays:
        raise ValueError("G and C must be delay-free (the shaper carries the delays)")
    if loop.G.num.degree >= loop.G.den.degree:
        raise ValueError("G must be strictly proper (a held input would feed straight through)")
    S = loop.shaper
    in_loop = S is not None and arch != "feedforward"
    if in_loop and not isinstance(S, Shaper):
        raise TypeError(f"the loop's shaper must be a posicast Shaper, got {type(S).__name__}")
    return fs, d, in_loop


def _blocks(loop: Loop, fs: float, in_loop: bool, controller_method: str, fractional: str) -> _Blocks:
    h = 1.0 / fs
    Ac, Bc, Cc, Dc = discretize_ss(loop.C, h, controller_method)
    Ag, Bg, Cg, _ = discretize_ss(loop.G, h, "zoh")
    w = np.array([1.0])
    if in_loop:
        D = discretize(loop.shaper, fs, fractional)
        if D.b is not None:
            raise ValueError("a shaper with an IIR part is not supported in the sampled loop")
        w = np.asarray(D.taps, dtype=float)
    inverse = in_loop and loop.architecture == "inverse_shaper"
    if inverse and w[0] == 0.0:
        raise ValueError("the inverse shaper needs a nonzero undelayed tap (1/S is not causal)")
    return _Blocks(Ac, Bc, Cc, Dc, Ag, Bg, Cg, w, in_loop, inverse)


def _layout(b: _Blocks, d: int, fs: float) -> _Layout:
    K = b.w.size - 1
    nc, ng = b.Ac.shape[0], b.Ag.shape[0]
    n = nc + ng + K + d
    if n > MAX_STATES:
        raise ValueError(f"the loop at sample_rate = {fs:g} Hz would have {n} states (the shaper's taps plus "
                         f"computation_delay = {d}); at most {MAX_STATES}: use a lower sample_rate")
    return _Layout(0, nc, nc + ng, nc + ng + K, nc, ng, K, d, n)


def _row(pairs: list[tuple[int, np.ndarray]]) -> dict[int, float]:
    out: dict[int, float] = {}
    for start, vals in pairs:
        for j, val in enumerate(np.atleast_1d(vals)):
            if val != 0.0:
                out[start + j] = out.get(start + j, 0.0) + float(val)
    return out


def _scale(r: dict[int, float], c: float) -> dict[int, float]:
    return {j: c * val for j, val in r.items()}


def _add(*rs: dict[int, float]) -> dict[int, float]:
    out: dict[int, float] = {}
    for r in rs:
        for j, val in r.items():
            out[j] = out.get(j, 0.0) + val
    return out


def _signal_rows(b: _Blocks, lay: _Layout) -> _Rows:
    w, K, d = b.w, lay.K, lay.d
    z_row = _row([(lay.ig, b.Cg[0])])                                    # z = Cg xg (w = d = n = 0)
    hist = _row([(lay.ih + k - 1, w[k]) for k in range(1, K + 1)])       # sum_{k>=1} w_k (delay line)[k]
    m_row: dict[int, float] = {}
    if b.inverse:
        m_row = _scale(_add(z_row, _scale(hist, -1.0)), 1.0 / w[0])  # seed 000 eq. 19-20 on the grid
        e_row = _scale(m_row, -1.0)
    else:
        e_row = _scale(z_row, -1.0)
    v_row = _add(_row([(lay.ic, b.Cc[0])]) if lay.nc else {}, _scale(e_row, b.Dc))
    u_row = _add(_scale(v_row, w[0]), hist) if b.in_loop and not b.inverse else v_row
    up_row = _row([(lay.idl + d - 1, np.array([1.0]))]) if d else u_row
    line_in = m_row if b.inverse else v_row                             # what enters the shaper's delay line
    return _Rows(e_row, u_row, up_row, line_in)


def _state_matrix(b: _Blocks, lay: _Layout, rows: _Rows) -> Any:
    """``A`` of ``x[n+1] = A x[n]`` (CSR)."""
    ic, ig, ih, idl = lay.ic, lay.ig, lay.ih, lay.idl
    A = lil_matrix((lay.n, lay.n))

    def put(i: int, r: dict[int, float]) -> None:
        for j, val in r.items():
            A[i, j] = A[i, j] + val

    for i in range(lay.nc):
        put(ic + i, _add(_row([(ic, b.Ac[i])]), _scale(rows.e, b.Bc[i, 0])))
    for i in range(lay.ng):
        put(ig + i, _add(_row([(ig, b.Ag[i])]), _scale(rows.u_plant, b.Bg[i, 0])))
    if lay.K:
        put(ih, rows.line_in)
        for k in range(1, lay.K):
            A[ih + k, ih + k - 1] = 1.0
    if lay.d:
        put(idl, rows.u)
        for j in range(1, lay.d):
            A[idl + j, idl + j - 1] = 1.0
    return A.tocsr()


class SampledLoop:
    """A loop of :mod:`posicast.loops` run at ``sample_rate``: its z-domain state matrix and poles.

    Parameters
    ----------
    loop : Loop
        ``feedforward``, ``control_action`` or ``inverse_shaper`` (the shaper, if any,
        must be a posicast Shaper).
    sample_rate : float
        Controller rate [Hz].
    computation_delay : int
        Whole samples between the controller's output and the actuator (0: the
        command computed from sample ``n`` is applied at sample ``n``).
    controller_method : {"bilinear", "zoh", "foh"}
        Discretisation of ``C`` (the simulator's default is Tustin).
    fractional : {"linear", "lagrange3", "round"}
        How the shaper's delays between samples are realised.

    Examples
    --------
    >>> import posicast as pc
    >>> case = pc.cases.flexible_link()
    >>> L = SampledLoop(case.loop("inverse_shaper", pc.design("dzv", case.mode)), 200.0)
    >>> L.stability(), round(L.spectral_radius, 4)
    ('stable', 0.981)
    """

    def __init__(self, loop: Loop, sample_rate: float, computation_delay: int = 0,
                 controller_method: str = "bilinear", fractional: str = "linear") -> None:
        fs, d, in_loop = _checked(loop, sample_rate, computation_delay, controller_method)
        blocks = _blocks(loop, fs, in_loop, controller_method, fractional)
        lay = _layout(blocks, d, fs)
        self.A = _state_matrix(blocks, lay, _signal_rows(blocks, lay))
        self.sample_rate = fs
        self.computation_delay = d
        self.architecture = loop.architecture
        self.n_states = lay.n

    def poles(self, count: int | None = None) -> np.ndarray:
        """Eigenvalues of ``A`` (z-domain poles), largest modulus first.

        All of them up to 1500 states; above, the ``count`` (default 12) of largest modulus.
        """
        if self.n_states <= _DENSE_MAX:
            z = np.linalg.eigvals(self.A.toarray()) if self.n_states else np.zeros(0, complex)
        else:
            k = min(count or 12, self.n_states - 2)
            z = eigs(self.A, k=k, which="LM", return_eigenvectors=False, tol=1e-12, maxiter=20 * self.n_states)
        z = z[np.argsort(-np.abs(z), kind="stable")]
        return z if count is None else z[:count]

    @property
    def spectral_radius(self) -> float:
        """``max |z|`` over the poles: the loop is stable iff it is below 1."""
        z = self.poles(1 if self.n_states > _DENSE_MAX else None)
        return float(np.abs(z[0])) if z.size else 0.0

    def stability(self) -> str:
        """``"stable"``, ``"marginal"`` (radius 1 to 1e-9) or ``"unstable"``."""
        r = self.spectral_radius
        return "marginal" if abs(r - 1.0) <= _MARGINAL else ("stable" if r < 1.0 else "unstable")

    def s_poles(self, count: int | None = None) -> np.ndarray:
        """The poles as ``s = ln(z) fs`` (principal branch, |Im| <= pi fs), for comparison with the continuous spectrum."""
        z = self.poles(count)
        with np.errstate(divide="ignore"):
            return np.log(z.astype(complex)) * self.sample_rate

    def __repr__(self) -> str:
        return (f"SampledLoop({self.architecture}, {self.sample_rate:g} Hz, delay {self.computation_delay} samples, "
                f"{self.n_states} states)")


def sampled_loop(loop: Loop, sample_rate: float, **options: Any) -> SampledLoop:
    """:class:`SampledLoop` ``(loop, sample_rate, **options)``.

    >>> import posicast as pc
    >>> case = pc.cases.flexible_link()
    >>> sampled_loop(case.loop("control_action"), 200.0).stability()
    'stable'
    """
    return SampledLoop(loop, sample_rate, **options)
