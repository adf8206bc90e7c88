"""Feedback loops with a signal shaper: the three architectures of seed 001 Fig. 1-3.

Every loop has the actuator-side plant ``G``, the flexible load ``F`` (outside the
loop, ``y = F z``), the controller ``C`` and a shaper ``S``.  Four external
inputs act on it:

* ``w`` reference, ``d`` output disturbance (added to the actuator output ``z``),
* ``di`` input disturbance (added to the plant input),
* ``n`` measurement noise (added to the measured ``z``).

=================  =================================================================
architecture       signal equations
=================  =================================================================
feedforward        ``r = S w``; ``e = r - (z + n)``; ``v = C e``; ``u = v``;
(seed 001 Fig. 1)  ``z = G (u + di) + d``; ``y = F z``
control_action     ``e = w - (z + n)``; ``v = C e``; ``u = S v``;
(Fig. 2, "CLSS")   ``z = G (u + di) + d``; ``y = F z``
inverse_shaper     ``e = w - m``, ``m = (z + n) / S``; ``v = C e``; ``u = v``;
(Fig. 3)           ``z = G (u + di) + d``; ``y = F z``
=================  =================================================================

Every channel is an exact :class:`~posicast.core.transfer.TransferFunction` over
one **common** denominator.  With each loop block written ``X = N_X / D_X`` and
``D_L``, ``N_L`` the products of the loop blocks' denominators and numerators
(``1/S`` contributes ``N = S.den``, ``D = S.num``), the loop gain is
``L = N_L / D_L`` and the characteristic quasi-polynomial is
``D_L + N_L``; a channel from an input injected at one loop signal to another
loop signal is ``(+/-) (numerators on the path) (denominators off the path) /
(D_L + N_L)``, times the blocks outside the loop (the prefilter ``S`` of the
feedforward architecture, ``F`` for ``y``).  Nothing is cancelled, so the
channels share their denominator and a distributed-delay shaper's removable
singularities show up as common roots: :attr:`Loop.cancelled` lists them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
from numpy.polynomial import polynomial as P

from .. import _validate as v
from ..core.quasipoly import QuasiPolynomial
from ..core.transfer import TransferFunction, as_transfer

__all__ = [
    "Loop",
    "feedforward",
    "control_action",
    "inverse_shaper",
    "Margins",
    "NyquistResponse",
    "ARCHITECTURES",
    "INPUTS",
    "removable_points",
    "feature_frequencies",
]

ARCHITECTURES = ("feedforward", "control_action", "inverse_shaper")
INPUTS = ("w", "d", "di", "n")
_COMMON_OUTPUTS = ("e", "v", "u", "z", "y")

# A Taylor coefficient below this fraction of its magnitude scale counts as zero
# when the vanishing order of a shaper's numerator/denominator is counted.
_VANISH_RTOL = 1e-9
# Polynomial roots closer than this (relative) are one multiple root.
_CLUSTER_RTOL = 1e-6


# ---------------------------------------------------------------------- internals
@dataclass(frozen=True)
class _Block:
    """One block ``N / D`` of the loop; ``num = den = None`` is the identity."""

    name: str
    num: QuasiPolynomial | None = None
    den: QuasiPolynomial | None = None

    @property
    def identity(self) -> bool:
        return self.num is None


_ONE = _Block("1")


def _product(factors: Sequence[QuasiPolynomial | None]) -> QuasiPolynomial:
    out = QuasiPolynomial.constant(1.0)
    for f in factors:
        if f is not None:
            out = out * f
    return out


def _checked_block(obj: Any, name: str) -> TransferFunction:
    """``as_transfer`` with every error message naming the argument."""
    try:
        return as_transfer(obj, name)
    except TypeError as exc:
        msg = str(exc)
        raise TypeError(msg if msg.startswith(name) else f"{name}: {msg}") from exc
    except ValueError as exc:
        msg = str(exc)
        raise ValueError(msg if msg.startswith(name) else f"{name}: {msg}") from exc


def feature_frequencies(tfs: Sequence[TransferFunction]) -> list[float]:
    """Frequencies [rad/s] where the blocks ``tfs`` change: ``|root|`` of every polynomial row of their
    numerators and denominators (nonzero roots) and ``2 pi / tau`` of every delay.

    >>> feature_frequencies([TransferFunction.from_poly([1.0], [1.0, 3.0, 2.0])])   # poles -1, -2
    [1.0, 2.0]
    """
    out: list[float] = []
    for i, tf in enumerate(v.sequence(tfs, "tfs")):
        if not isinstance(tf, TransferFunction):
            raise TypeError(f"tfs[{i}] must be a TransferFunction, got {type(tf).__name__}")
        for q in (tf.num, tf.den):
            if q.is_zero:
                continue
            for row in q.coeffs:
                nz = np.flatnonzero(row)
                if nz.size and nz[-1] > nz[0]:
                    r = P.polyroots(row[nz[0] : nz[-1] + 1])
                    out += sorted(float(abs(x)) for x in r if abs(x) > 0 and np.isfinite(abs(x)))
            out += [2.0 * math.pi / t for t in q.delays if t > 0]
    return out


def _vanishing_order(h: QuasiPolynomial, s0: complex, max_order: int = 24) -> int:
    """Number of leading Taylor coefficients of ``h`` about ``s0`` that vanish (relative to their scale)."""
    if h.is_zero:
        return max_order
    c, scale = h.taylor(s0, max_order)
    k = 0
    while k <= max_order and abs(c[k]) <= _VANISH_RTOL * scale[k]:
        k += 1
    return k


def removable_points(num: QuasiPolynomial, den: QuasiPolynomial) -> np.ndarray:
    """Common roots of ``num`` and ``den`` when ``den`` is a polynomial (times at most one delay).

    A distributed-delay shaper ``N / D`` has ``D = p(s)`` a polynomial whose roots
    are also roots of ``N`` (``s = 0`` for every kernel, ``s = +/- 2 pi j / T`` for
    the cosine kernel): removable singularities of ``N / D``.  Each root of ``p``
    at which ``num`` also vanishes is returned ``min(m_num, m_den)`` times, the
    vanishing orders being counted with exact Taylor coefficients.  An empty
    array when ``den`` carries several delays (its roots are not computed here).

    Examples
    --------
    >>> import posicast
    >>> S = posicast.design("dzv", posicast.Mode(10.0, 0.03))
    >>> removable_points(S.num, S.den)
    array([0.+0.j])
    >>> removable_points(QuasiPolynomial.from_poly([1.0, 2.0]), QuasiPolynomial.from_poly([1.0, 1.0])).size
    0
    """
    for name, q in (("num", num), ("den", den)):
        if not isinstance(q, QuasiPolynomial):
            raise TypeError(f"{name} must be a QuasiPolynomial, got {type(q).__name__}")
    if num.is_zero or den.is_zero or not den.is_polynomial or den.degree < 1:
        return np.zeros(0, dtype=complex)
    row = den.coeffs[0]
    roots = P.polyroots(row)
    # Cluster numerically repeated roots, then count multiplicities exactly.
    centres: list[complex] = []
    members: list[list[complex]] = []
    for r in sorted(roots, key=lambda z: (round(z.real, 6), round(z.imag, 6))):
        r = complex(r)
        for i, c in enumerate(centres):
            if abs(r - c) <= _CLUSTER_RTOL * max(1.0, abs(c)):
                members[i].append(r)
                centres[i] = complex(np.mean(members[i]))
                break
        else:
            centres.append(r)
            members.append([r])
    out: list[complex] = []
    for c in centres:
        if abs(c.imag) <= 1e-14 * max(1.0, abs(c)):
            c = complex(c.real, 0.0)
        if abs(c) <= 1e-14:
            c = 0j
        m = min(_vanishing_order(num, c), _vanishing_order(den, c))
        out += [c] * m
    return np.array(out, dtype=complex)


@dataclass(frozen=True)
class _Topology:
    nodes: tuple[str, ...]  # loop signals in order; node 0 is the comparator output e
    blocks: tuple[_Block, ...]  # blocks[i] maps node i-1 to node i (blocks[0]: the comparator, sign -1)
    inputs: dict[str, tuple[int, _Block]]  # src -> (node where it is added, prefilter)
    outputs: dict[str, tuple[int, _Block]]  # dst -> (loop node, postfilter)


# ---------------------------------------------------------------------- data objects
@dataclass(frozen=True)
class NyquistResponse:
    """Loop-gain frequency response ``L(j omega)`` (the data behind a Nyquist plot).

    Attributes
    ----------
    omega : ndarray
        Frequencies [rad/s].
    response : ndarray of complex
        ``L(j omega)``.
    name : str
        A label (the loop's architecture and shaper).
    """

    omega: np.ndarray
    response: np.ndarray
    name: str = ""

    @property
    def min_distance(self) -> float:
        """``min |1 + L(j omega)|`` over the grid (the inverse of the grid's peak sensitivity)."""
        return float(np.min(np.abs(1.0 + self.response)))


@dataclass(frozen=True)
class Margins:
    """Robustness margins of a loop, read from its loop gain on the imaginary axis.

    Attributes
    ----------
    ms, omega_ms : float
        Peak sensitivity ``Ms = max |1 / (1 + L(j omega))|`` and where it occurs.
    mt, omega_mt : float
        Peak complementary sensitivity ``Mt = max |L / (1 + L)|`` and where.
    sm : float
        Stability margin ``1 / Ms``: the least distance of the Nyquist curve to -1.
    gm, omega_gm : float
        Gain margin ``1 / |L|`` at a phase crossover (``L`` real negative);
        of several crossovers, the one closest to 1 in ``|log gm|`` (as MATLAB and
        python-control report it).  ``inf``/``nan`` when there is none.
    pm, omega_pm : float
        Phase margin [deg] at a gain crossover (``|L| = 1``), the smallest in
        absolute value.  ``inf``/``nan`` when there is none.

    The margins say nothing about stability by themselves: check
    :meth:`Loop.is_stable` (a loop with delays has infinitely many poles).
    """

    ms: float
    omega_ms: float
    mt: float
    omega_mt: float
    sm: float
    gm: float
    omega_gm: float
    pm: float
    omega_pm: float


# ---------------------------------------------------------------------- the loop
class Loop:
    """A feedback loop with a signal shaper, with every channel as an exact transfer function.

    Build one with :func:`feedforward`, :func:`control_action` or
    :func:`inverse_shaper` (or ``Loop(architecture, G=..., C=..., F=..., S=...)``).

    Parameters
    ----------
    architecture : {'feedforward', 'control_action', 'inverse_shaper'}
        Where the shaper sits (seed 001 Fig. 1, 2, 3).
    G : plant-like
        Actuator-side plant (input: actuator command, output ``z``).
    C : plant-like
        Controller.
    F : plant-like or None
        Flexible load, ``y = F z``; ``None`` means ``F = 1``.
    S : Shaper, plant-like or None
        The shaper; ``None`` means no shaper (``S = 1``).

    "plant-like" is anything :func:`posicast.as_transfer` accepts: a
    TransferFunction, a Shaper, a number, ``(num, den)`` (descending powers), a
    scipy ``lti`` or a python-control SISO system.

    Attributes
    ----------
    architecture : str
    G, C, F : TransferFunction
    S : TransferFunction or None
    shaper : object
        ``S`` as passed (e.g. the :class:`~posicast.Shaper`), or None.
    inputs, outputs : tuple of str
        Allowed ``src`` and ``dst`` names.
    characteristic : QuasiPolynomial
        ``D_L + N_L``; its roots, less :attr:`cancelled`, are the closed-loop poles.
    cancelled : ndarray of complex
        Spurious roots of :attr:`characteristic`: the shaper's removable
        singularities (see :func:`removable_points`), repeated by multiplicity.
        Empty for the feedforward architecture (the shaper is outside the loop).
        Only the shaper's points are listed: a common root of another block's
        numerator and denominator (e.g. ``G`` given as ``(s, s^2 + s)``) is a
        genuine hidden mode of the loop and stays a pole.

    Examples
    --------
    Seed 000's simulation example (eq. 25-27) with the inverse DZV shaper:

    >>> import posicast
    >>> S = posicast.design("dzv", posicast.Mode(10.0, 0.03))
    >>> loop = posicast.inverse_shaper(G=(1, [1, 1, 0]), F=([1, 0], [1, 0.6, 100]),
    ...                                C=([10, 10], [0.01, 1]), S=S)
    >>> loop.characteristic.kind
    'retarded'
    >>> loop.cancelled                      # S = N/D with N(0) = D(0) = 0
    array([0.+0.j])
    >>> abs(loop.transfer("w", "z")(0.0) - 1.0) < 1e-12   # integrator: unit DC gain
    True
    """

    architecture: str
    G: TransferFunction
    C: TransferFunction
    F: TransferFunction
    S: TransferFunction | None

    def __init__(self, architecture: str, *, G: Any, C: Any, F: Any = None, S: Any = None) -> None:
        if not isinstance(architecture, str):
            raise TypeError(f"architecture must be a string, got {type(architecture).__name__}")
        if architecture not in ARCHITECTURES:
            raise ValueError(f"architecture must be one of {ARCHITECTURES}, got {architecture!r}")
        if G is None:
            raise TypeError("G must be a plant (TransferFunction, (num, den), number, scipy/python-control system), got None")
        if C is None:
            raise TypeError("C must be a controller (TransferFunction, (num, den), number, scipy/python-control system), got None")
        self.architecture = architecture
        self.G = _checked_block(G, "G")
        self.C = _checked_block(C, "C")
        self.F = _checked_block(1.0 if F is None else F, "F")
        self.shaper = S
        self.S = None if S is None else _checked_block(S, "S")
        if self.S is not None and self.S.num.is_zero:
            raise ValueError("S is identically zero: no signal passes the shaper, so no loop can be formed")
        self._topology = self._build_topology()
        self.inputs: tuple[str, ...] = tuple(self._topology.inputs)
        self.outputs: tuple[str, ...] = tuple(self._topology.outputs) + (("r",) if architecture == "feedforward" else ())
        blocks = self._topology.blocks
        self._D_L = _product([b.den for b in blocks])
        self._N_L = _product([b.num for b in blocks])
        char = self._D_L + self._N_L
        if char.is_zero:
            raise ValueError("the loop is ill-posed: 1 + C G (S) is identically zero")
        self.characteristic: QuasiPolynomial = char
        self._shaper_removable = (
            removable_points(self.S.num, self.S.den) if self.S is not None else np.zeros(0, dtype=complex)
        )
        in_loop = architecture != "feedforward"
        self.cancelled: np.ndarray = self._shaper_removable.copy() if in_loop else np.zeros(0, dtype=complex)
        self.cancelled.flags.writeable = False
        self._channels: dict[tuple[str, str], TransferFunction] = {}

    # ------------------------------------------------------------------ structure
    def _build_topology(self) -> _Topology:
        G = _Block("G", self.G.num, self.G.den)
        C = _Block("C", self.C.num, self.C.den)
        F = _Block("F", self.F.num, self.F.den)
        S = _ONE if self.S is None else _Block("S", self.S.num, self.S.den)
        S_inv = _ONE if self.S is None else _Block("1/S", self.S.den, self.S.num)
        if self.architecture == "feedforward":
            #        e      v    u     up     z    zn
            nodes = ("e", "v", "u", "up", "z", "zn")
            blocks = (_ONE, C, _ONE, _ONE, G, _ONE)
            w_pre = S
        elif self.architecture == "control_action":
            nodes = ("e", "v", "u", "up", "z", "zn")
            blocks = (_ONE, C, S, _ONE, G, _ONE)
            w_pre = _ONE
        else:  # inverse_shaper
            nodes = ("e", "v", "u", "up", "z", "zn", "m")
            blocks = (_ONE, C, _ONE, _ONE, G, _ONE, S_inv)
            w_pre = _ONE
        idx = {name: i for i, name in enumerate(nodes)}
        inputs = {"w": (0, w_pre), "d": (idx["z"], _ONE), "di": (idx["up"], _ONE), "n": (idx["zn"], _ONE)}
        outputs = {name: (idx[name], _ONE) for name in ("e", "v", "u", "z")}
        outputs["y"] = (idx["z"], F)
        if "m" in idx:
            outputs["m"] = (idx["m"], _ONE)
        return _Topology(nodes, blocks, inputs, outputs)

    def _check_pair(self, src: Any, dst: Any) -> tuple[str, str]:
        if not isinstance(src, str) or src not in self.inputs:
            raise ValueError(f"src must be one of {self.inputs}, got {src!r}")
        if not isinstance(dst, str) or dst not in self.outputs:
            raise ValueError(f"dst must be one of {self.outputs} for the {self.architecture} loop, got {dst!r}")
        return src, dst

    def _shaper_in_channel(self, src: str, dst: str) -> bool:
        """True if the channel's numerator and denominator both carry the shaper's removable factor."""
        if self.S is None:
            return False
        if self.architecture == "feedforward":
            return src == "w"
        return True

    # ------------------------------------------------------------------ channels
    def transfer(self, src: str, dst: str) -> TransferFunction:
        """The exact transfer function from input ``src`` to output ``dst``.

        Parameters
        ----------
        src : {'w', 'd', 'di', 'n'}
        dst : {'e', 'v', 'u', 'z', 'y'}, plus ``'r'`` (feedforward) or ``'m'`` (inverse shaper)

        Returns
        -------
        TransferFunction
            Over the loop's common denominator (``characteristic`` times the
            denominators of the blocks outside the loop).

        Examples
        --------
        >>> loop = control_action(G=(1, [1, 1, 0]), C=2.0)
        >>> T = loop.transfer("d", "z")        # 1 / (1 + 2 / (s^2 + s))
        >>> abs(T(1.0) - 1 / (1 + 2 / 2)) < 1e-15
        True
        """
        src, dst = self._check_pair(src, dst)
        key = (src, dst)
        if key not in self._channels:
            self._channels[key] = self._channel(src, dst)
        return self._channels[key]

    def _path(self, src: str, dst: str) -> tuple[_Block, _Block, set[int], float]:
        """The loop's blocks on the way from input ``src`` to output ``dst``.

        Returns the input's and the output's own blocks, the set of ring nodes
        passed, and the sign (-1 when the path crosses the comparator
        ``e = (...) - (...)``).
        """
        topo = self._topology
        n_nodes = len(topo.nodes)
        a, pre = topo.inputs[src]
        b, post = topo.outputs[dst]
        length = (b - a) % n_nodes
        path = {(a + k) % n_nodes for k in range(1, length + 1)}
        return pre, post, path, -1.0 if 0 in path else 1.0

    def _channel(self, src: str, dst: str) -> TransferFunction:
        if dst == "r":  # feedforward prefilter output: outside the loop
            if src != "w":
                return TransferFunction(QuasiPolynomial.zero(), QuasiPolynomial.constant(1.0))
            return self.S if self.S is not None else TransferFunction.constant(1.0)
        topo = self._topology
        pre, post, path, sign = self._path(src, dst)
        factors = [blk.num if i in path else blk.den for i, blk in enumerate(topo.blocks)]
        num = _product(factors + [pre.num, post.num])
        den = _product([self.characteristic, pre.den, post.den])
        return TransferFunction(num.scaled(sign), den)

    def channels(self) -> dict[tuple[str, str], TransferFunction]:
        """All channels ``{(src, dst): TransferFunction}``.

        >>> len(feedforward(G=(1, [1, 0]), C=1.0).channels())   # 4 inputs x 6 outputs
        24
        """
        return {(s, d): self.transfer(s, d) for s in self.inputs for d in self.outputs}

    @property
    def plant_gain(self) -> TransferFunction:
        """``P``: the loop gain without the controller, ``L = C P`` (seed 001 eq. 5).

        ``G`` (feedforward), ``S G`` (control action, ``P_1``), ``G / S`` (inverse
        shaper, ``P_2``), as one exact transfer function.

        >>> loop = inverse_shaper(G=(1, [1, 0]), C=3.0, S=0.5)
        >>> complex(loop.plant_gain(1j))          # (1 / j) / 0.5
        -2j
        """
        blocks = [b for b in self._topology.blocks if b.name != "C"]
        return TransferFunction(_product([b.num for b in blocks]), _product([b.den for b in blocks]))

    def controller_factor(self, src: str, dst: str) -> tuple[TransferFunction, bool]:
        """Split channel ``src -> dst`` as ``R C / (1 + L)`` or ``R / (1 + L)``.

        Returns ``(R, through_controller)``: ``R`` is exact and independent of
        ``C``, and ``through_controller`` says whether the path passes the
        controller.  Every channel has this form because ``C`` enters the loop
        once; the tuning module (:mod:`posicast.tune`) uses it to write each
        H-infinity constraint as a quadratic in the controller gains.

        Examples
        --------
        >>> loop = control_action(G=(1, [1, 1, 0]), C=2.0, S=0.5)
        >>> R, through = loop.controller_factor("n", "u")    # -C S / (1 + C S G)
        >>> through, complex(R(1j)).real
        (True, -0.5)
        >>> loop.controller_factor("d", "z")[1]                # 1 / (1 + L)
        False
        """
        src, dst = self._check_pair(src, dst)
        if dst == "r":
            raise ValueError("channel w -> r (the feedforward prefilter) is outside the loop: it has no controller factor")
        topo = self._topology
        pre, post, path, sign = self._path(src, dst)
        through = False
        nums, dens = [pre.num, post.num], [pre.den, post.den]
        for i, blk in enumerate(topo.blocks):
            if blk.name == "C":
                through = i in path
                continue
            nums.append(blk.num if i in path else blk.den)
            dens.append(blk.den)
        return TransferFunction(_product(nums).scaled(sign), _product(dens)), through

    @property
    def loop_gain(self) -> TransferFunction:
        """``L = N_L / D_L``: ``C G`` (feedforward), ``C S G`` (control action), ``C G / S`` (inverse shaper)."""
        return TransferFunction(self._N_L, self._D_L)

    @property
    def sensitivity(self) -> TransferFunction:
        """``1 / (1 + L) = D_L / characteristic`` (seed 001 eq. 15)."""
        return TransferFunction(self._D_L, self.characteristic)

    @property
    def complementary_sensitivity(self) -> TransferFunction:
        """``L / (1 + L) = N_L / characteristic``."""
        return TransferFunction(self._N_L, self.characteristic)

    def channel_cancelled(self, src: str, dst: str) -> np.ndarray:
        """Spurious common roots of a channel's numerator and denominator (the shaper's removable points).

        Empty when the channel does not contain the shaper (feedforward, inputs
        other than ``w``).
        """
        src, dst = self._check_pair(src, dst)
        if not self._shaper_in_channel(src, dst) or self._shaper_removable.size == 0:
            return np.zeros(0, dtype=complex)
        tf = self.transfer(src, dst)
        out: list[complex] = []
        for r in np.unique(self._shaper_removable):
            m = int(np.count_nonzero(self._shaper_removable == r))
            m = min(m, _vanishing_order(tf.num, r), _vanishing_order(tf.den, r))
            out += [complex(r)] * m
        return np.array(out, dtype=complex)

    # ------------------------------------------------------------------ spectra
    def poles(self, region: Any) -> Any:
        """Closed-loop poles in ``region``: roots of :attr:`characteristic` less :attr:`cancelled`.

        Delegates to :func:`posicast.spectra.roots`; returns its result
        (``.roots`` repeated by multiplicity, ``.count``, ``.region``).
        """
        from ..spectra import roots

        return roots(self.characteristic, region, ignore=self.cancelled)

    def zeros(self, src: str, dst: str, region: Any) -> Any:
        """Zeros of channel ``src -> dst`` in ``region`` (its numerator's roots less the spurious ones).

        The shaper's removable points are roots of the numerator too; they are
        removed (:meth:`channel_cancelled`).  Delegates to :func:`posicast.spectra.roots`.
        """
        tf = self.transfer(src, dst)
        if tf.num.is_zero:
            raise ValueError(f"channel {src} -> {dst} is identically zero: it has no zeros to compute")
        from ..spectra import roots

        return roots(tf.num, region, ignore=self.channel_cancelled(src, dst))

    def spectral_abscissa(self) -> float:
        """Largest real part of the closed-loop poles (:func:`posicast.spectra.spectral_abscissa`)."""
        from ..spectra import spectral_abscissa

        return spectral_abscissa(self.characteristic, ignore=self.cancelled)

    def stability(self, *, max_evaluations: float = 5e7, timeout: float = 120.0) -> Any:
        """Full stability report of the closed loop (:func:`posicast.spectra.stability`).

        ``.stable``, ``.marginal`` (roots on the imaginary axis within the certificate),
        ``.kind`` ('retarded', 'neutral', 'polynomial'), ``.unstable_roots``, ``.reason``,
        ``.difference`` (neutral loops: the difference operator's ``abscissa`` and
        ``strongly_stable``; None otherwise); the abscissa of the loop itself is
        :meth:`spectral_abscissa`.  ``max_evaluations`` and ``timeout``
        bound each root search (:class:`~posicast.spectra.BudgetExceeded` past them).
        """
        from ..spectra import stability

        return stability(self.characteristic, ignore=self.cancelled, max_evaluations=max_evaluations,
                         timeout=timeout)

    def is_stable(self) -> bool:
        """True if every closed-loop pole has a negative real part (see :meth:`stability`)."""
        return bool(self.stability().stable)

    # ------------------------------------------------------------------ frequency domain
    def frequency_response(self, src: str, dst: str, omega: Any) -> np.ndarray:
        """Channel ``src -> dst`` at ``s = j omega`` (complex array, ``omega`` in rad/s).

        >>> loop = feedforward(G=(1, [1, 0]), C=1.0)
        >>> complex(loop.frequency_response("w", "z", [1.0])[0])   # 1 / (j + 1)
        (0.5-0.5j)
        """
        w = v.strict_real_array(omega, "omega", allow_empty=True)
        return self.transfer(src, dst).freqresp(w)

    def default_omega(self) -> np.ndarray:
        """A frequency grid [rad/s] covering the loop's dynamics.

        Log-spaced over a decade beyond the smallest and largest pole/zero
        magnitudes and ``2 pi / tau`` of the loop's delays, merged with a
        linear grid fine enough (40 points per ``2 pi / tau_max``) to resolve the
        ripple that the delays put on ``L(j omega)``.
        """
        blocks = [self.G, self.C] + ([self.S] if self.S is not None and self.architecture != "feedforward" else [])
        feats = feature_frequencies(blocks)
        if not feats:
            feats = [1.0]
        lo = 10.0 ** (math.floor(math.log10(min(feats))) - 1)
        hi = 10.0 ** (math.ceil(math.log10(max(feats))) + 1)
        grid = np.logspace(math.log10(lo), math.log10(hi), 2000)
        tau = self.loop_gain.max_delay
        if tau > 0:
            n_lin = int(min(200_000, math.ceil((hi - lo) / (2 * math.pi / tau / 40.0)) + 1))
            grid = np.union1d(grid, np.linspace(lo, hi, n_lin))
        return grid

    def nyquist(self, omega: Any = None) -> NyquistResponse:
        """The loop gain on the imaginary axis: ``L(j omega)`` (data; draw it with :func:`nyquist_plot`).

        >>> data = feedforward(G=(1, [1, 0]), C=1.0).nyquist([1.0])
        >>> complex(data.response[0])
        -1j
        """
        w = self.default_omega() if omega is None else v.strict_real_array(omega, "omega").reshape(-1)
        return NyquistResponse(w, self.loop_gain.freqresp(w), self.label)

    def margins(self, omega: Any = None) -> Margins:
        """Peak sensitivities and gain/phase margins from ``L(j omega)``.

        Parameters
        ----------
        omega : array_like, optional
            Frequency grid [rad/s], default :meth:`default_omega`.  Peaks and
            crossovers found on the grid are refined by a 1-D search between the
            neighbouring grid points.

        Returns
        -------
        Margins

        Examples
        --------
        >>> m = feedforward(G=(1, [1, 1, 0]), C=1.0).margins()
        >>> round(m.pm, 2), m.gm                      # 1 / (s^2 + s): PM 51.83 deg, no phase crossover
        (51.83, inf)
        """
        from scipy.optimize import brentq, minimize_scalar

        w = self.default_omega() if omega is None else np.unique(v.strict_real_array(omega, "omega").reshape(-1))
        if w.size < 2:
            raise ValueError("omega must contain at least 2 frequencies")
        if np.any(w < 0):
            raise ValueError("omega must be >= 0")
        Ltf = self.loop_gain
        S_tf = self.sensitivity
        T_tf = self.complementary_sensitivity

        def peak(tf: TransferFunction) -> tuple[float, float]:
            mag = np.abs(tf.freqresp(w))
            mag = np.where(np.isfinite(mag), mag, np.inf)
            i = int(np.argmax(mag))
            if not np.isfinite(mag[i]):
                return math.inf, float(w[i])
            lo, hi = w[max(i - 1, 0)], w[min(i + 1, w.size - 1)]
            res = minimize_scalar(
                lambda x: -abs(tf(1j * x)), bounds=(lo, hi), method="bounded", options={"xatol": 1e-10 * max(hi, 1e-300)}
            )
            if -res.fun > mag[i]:
                return float(-res.fun), float(res.x)
            return float(mag[i]), float(w[i])

        ms, w_ms = peak(S_tf)
        mt, w_mt = peak(T_tf)
        L = Ltf.freqresp(w)
        fin = np.isfinite(L)

        def L_at(x: float) -> complex:
            return complex(Ltf(1j * x))

        # gain crossovers |L| = 1
        pm, w_pm = math.inf, math.nan
        g = np.abs(L) - 1.0
        for i in np.flatnonzero(fin[:-1] & fin[1:] & (np.sign(g[:-1]) != np.sign(g[1:]))):
            x = brentq(lambda t: abs(L_at(t)) - 1.0, w[i], w[i + 1], xtol=1e-14 * w[i + 1])
            p = math.degrees(np.angle(-L_at(x)))
            if abs(p) < abs(pm):
                pm, w_pm = p, x
        # phase crossovers: L real negative
        gm, w_gm = math.inf, math.nan
        im = L.imag
        cand = fin[:-1] & fin[1:] & (np.sign(im[:-1]) != np.sign(im[1:])) & (L.real[:-1] + L.real[1:] < 0)
        for i in np.flatnonzero(cand):
            x = brentq(lambda t: L_at(t).imag, w[i], w[i + 1], xtol=1e-14 * w[i + 1])
            lx = L_at(x)
            if lx.real >= 0 or x <= 0:
                continue
            gmi = -1.0 / lx.real
            if abs(math.log(gmi)) < abs(math.log(gm)):
                gm, w_gm = gmi, x
        return Margins(ms, w_ms, mt, w_mt, 1.0 / ms if ms > 0 else math.inf, gm, w_gm, pm, w_pm)

    # ------------------------------------------------------------------ display
    @property
    def label(self) -> str:
        """Short description: architecture and shaper name."""
        return f"{self.architecture} ({self._shaper_name()})"

    def _shaper_name(self) -> str:
        if self.S is None:
            return "no shaper"
        name = getattr(self.shaper, "name", None)
        return str(name) if isinstance(name, str) else "S"

    def __repr__(self) -> str:
        ch = self.characteristic
        kind = ch.kind
        canc = ", ".join(f"{c:.4g}" for c in self.cancelled) if self.cancelled.size else "none"
        return (
            f"Loop({self.architecture!r}, S={self._shaper_name()}, characteristic: {kind}, "
            f"degree {ch.degree}, max delay {ch.delays.max():.6g}, "
            f"cancelled: {canc})"
        )


# ---------------------------------------------------------------------- constructors
def feedforward(*, G: Any, C: Any, F: Any = None, S: Any = None) -> Loop:
    """Shaper outside the loop, on the reference (seed 001 Fig. 1, eq. 1-2).

    ``r = S w``, ``e = r - (z + n)``, ``v = C e``, ``u = v``, ``z = G (u + di) + d``,
    ``y = F z``.  Loop gain ``L = C G``; the shaper does not change stability.

    Examples
    --------
    >>> import posicast
    >>> S = posicast.design("zv", posicast.Mode(10.0, 0.03))
    >>> loop = feedforward(G=(1, [1, 1, 0]), C=([10, 10], [0.01, 1]), F=([1, 0], [1, 0.6, 100]), S=S)
    >>> p = S.modes[0].pole                        # F's pole, a zero of S
    >>> bool(np.isfinite(loop.transfer("w", "y")(p)))   # cancelled in w -> y ...
    True
    >>> bool(abs(loop.transfer("d", "y")(p)) > 1e12)    # ... but not in d -> y (seed 001 eq. 2)
    True
    """
    return Loop("feedforward", G=G, C=C, F=F, S=S)


def control_action(*, G: Any, C: Any, F: Any = None, S: Any = None) -> Loop:
    """Shaper in the loop between controller and plant ("CLSS", seed 001 Fig. 2, eq. 3).

    ``e = w - (z + n)``, ``v = C e``, ``u = S v``, ``z = G (u + di) + d``,
    ``y = F z``.  Loop gain ``L = C S G``; characteristic
    ``Q N D_S + P M N_S`` in seed 000's notation (eq. 11-12 with ``D_S = 1``).

    >>> import posicast
    >>> S = posicast.design("zv", posicast.Mode(10.0, 0.03))
    >>> loop = control_action(G=(1, [1, 1, 0]), C=([10, 10], [0.01, 1]), S=S)
    >>> loop.characteristic.kind
    'retarded'
    """
    return Loop("control_action", G=G, C=C, F=F, S=S)


def inverse_shaper(*, G: Any, C: Any, F: Any = None, S: Any = None) -> Loop:
    """Inverse shaper ``1/S`` in the feedback path (seed 000 Fig. 3, eq. 15-16; seed 001 Fig. 3).

    ``e = w - m``, ``m = (z + n) / S``, ``v = C e``, ``u = v``,
    ``z = G (u + di) + d``, ``y = F z``.  Loop gain ``L = C G / S``;
    characteristic ``S.num D_C D_G + N_C N_G S.den`` (seed 000 eq. 23,
    ``S Q N + P M``, when ``S.den = 1``).  The shaper's zeros are zeros of both
    ``w -> z`` and ``d -> z`` (seed 000 eq. 21-22).

    **Seed 001 eq. 4 is misprinted**: its denominators read ``S + C S G``; the
    block diagram (its Fig. 3) gives ``S + C G``, e.g.
    ``T_wy = F C S G / (S + C G)``, as in seed 000 eq. 15-16.  The channels here
    follow the diagram (checked in the test suite against both seeds and a
    direct solution of the signal equations).

    >>> import posicast
    >>> S = posicast.design("zv", posicast.Mode(10.0, 0.03))
    >>> loop = inverse_shaper(G=(1, [1, 1, 0]), C=([10, 10], [0.01, 1]), S=S)
    >>> loop.characteristic.kind                 # inverse ZV: neutral (seed 000 Sec. IV-B)
    'neutral'
    >>> abs(loop.transfer("d", "z")(S.modes[0].pole)) < 1e-12
    True
    """
    return Loop("inverse_shaper", G=G, C=C, F=F, S=S)
