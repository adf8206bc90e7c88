"""Feedback loops with a signal shaper: the loop of any registered architecture (seed 001 Fig. 1-3).

The loop's blocks ``G`` (actuator-side plant), ``C`` (controller), ``F``
(flexible load, ``y = F z``) and ``S`` (shaper) are arranged in a
:class:`~posicast.loops.ring.Ring` by its architecture
(:mod:`posicast.loops.architectures`: the signal equations of the three seed
architectures, and :func:`~posicast.loops.architectures.register_architecture`).

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
import warnings
from typing import Any, Sequence

import numpy as np

from .. import _validate as v
from .. import spectra
from ..spectra.rootfinder import Roots
from ..core.quasipoly import QuasiPolynomial
from ..core.transfer import TransferFunction, as_transfer
from ..core.verbs import SystemVerbs
from .architectures import ARCHITECTURES, INPUTS, build_ring
from .margins import Margins, NyquistResponse, margins_on_grid
from ..core.removable import removable_points, vanishing_order
from .points import feature_frequencies
from .ring import IDENTITY, INVERSE_SHAPER, SHAPER, Block, LoopBlocks, Ring

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


# ---------------------------------------------------------------------- internals
def _product(factors: Sequence[QuasiPolynomial | None]) -> QuasiPolynomial:
    out = QuasiPolynomial.constant(1.0)
    for f in factors:
        if f is not None:
            out = out * f
    return out


# ---------------------------------------------------------------------- the loop
class Loop(SystemVerbs):
    """A feedback loop with a signal shaper, with every channel as an exact transfer function.

    Build one with :func:`feedforward`, :func:`control_action` or
    :func:`inverse_shaper` (or ``Loop(architecture, G=..., C=..., F=..., S=...)``).

    Parameters
    ----------
    architecture : str
        Where the shaper sits: ``'feedforward'``, ``'control_action'``,
        ``'inverse_shaper'`` (seed 001 Fig. 1, 2, 3) or a name added by
        :func:`~posicast.loops.register_architecture` (:data:`ARCHITECTURES`).
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
    ring : Ring
        The loop's blocks and how they connect (:class:`~posicast.loops.ring.Ring`),
        built by its architecture; the channels and the simulator read it.
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
        v.choice(architecture, "architecture", ARCHITECTURES)
        if G is None:
            raise TypeError("G must be a plant (TransferFunction, (num, den), number, scipy/python-control system), got None")
        if C is None:
            raise TypeError("C must be a controller (TransferFunction, (num, den), number, scipy/python-control system), got None")
        self.architecture = architecture
        self.G = as_transfer(G, "G")
        self.C = as_transfer(C, "C")
        self.F = as_transfer(1.0 if F is None else F, "F")
        self.shaper = S
        self.S = None if S is None else as_transfer(S, "S")
        if self.S is not None and self.S.num.is_zero:
            raise ValueError("S is identically zero: no signal passes the shaper, so no loop can be formed")
        self.ring: Ring = build_ring(architecture, self._blocks())
        self.inputs: tuple[str, ...] = tuple(self.ring.inputs)
        self.outputs: tuple[str, ...] = tuple(self.ring.outputs) + tuple(self.ring.external)
        blocks = self.ring.blocks
        self._D_L = _product([b.den for b in blocks])
        self._N_L = _product([b.num for b in blocks])
        char = self._D_L + self._N_L
        if char.is_zero:
            raise ValueError("the loop is ill-posed: 1 + C G (S) is identically zero")
        self.characteristic: QuasiPolynomial = char
        self._shaper_removable = (
            removable_points(self.S.num, self.S.den) if self.S is not None else np.zeros(0, dtype=complex)
        )
        in_loop = self.ring.has_shaper()
        self.cancelled: np.ndarray = self._shaper_removable.copy() if in_loop else np.zeros(0, dtype=complex)
        self.cancelled.flags.writeable = False
        self._channels: dict[tuple[str, str], TransferFunction] = {}

    # ------------------------------------------------------------------ structure
    def _blocks(self) -> LoopBlocks:
        """The loop's blocks, for its architecture to arrange in a ring."""
        S = IDENTITY if self.S is None else Block.of(SHAPER, self.S)
        S_inverse = IDENTITY if self.S is None else Block.inverse_of(INVERSE_SHAPER, self.S)
        return LoopBlocks(Block.of("G", self.G), Block.of("C", self.C), Block.of("F", self.F), S, S_inverse)

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
        if self.ring.has_shaper():
            return True
        shaped = (SHAPER, INVERSE_SHAPER)
        pre = self.ring.inputs[src].block
        post = self.ring.outputs[dst].block if dst in self.ring.outputs else pre  # external: the input's prefilter
        return pre.name in shaped or post.name in shaped

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

    def _channel(self, src: str, dst: str) -> TransferFunction:
        if dst in self.ring.external:  # an input's prefiltered signal (feedforward r = S w): outside the loop
            if src != self.ring.external[dst]:
                return TransferFunction(QuasiPolynomial.zero(), QuasiPolynomial.constant(1.0))
            pre = self.ring.inputs[src].block
            return TransferFunction.constant(1.0) if pre.identity else TransferFunction(pre.num, pre.den)
        pre, post, path, sign = self.ring.path(src, dst)
        factors = [blk.num if i in path else blk.den for i, blk in enumerate(self.ring.blocks)]
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
        blocks = [b for b in self.ring.blocks if b.name != "C"]
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
        if dst in self.ring.external:
            raise ValueError(f"channel {self.ring.external[dst]} -> {dst} (the feedforward prefilter) is outside the "
                             "loop: it has no controller factor")
        pre, post, path, sign = self.ring.path(src, dst)
        through = False
        nums, dens = [pre.num, post.num], [pre.den, post.den]
        for i, blk in enumerate(self.ring.blocks):
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
            m = min(m, vanishing_order(tf.num, r), vanishing_order(tf.den, r))
            out += [complex(r)] * m
        return np.array(out, dtype=complex)

    # ------------------------------------------------------------------ spectra
    # poles, stability, spectral_abscissa and rightmost come from SystemVerbs (posicast.spectra.systems):
    # the roots of :attr:`characteristic` less :attr:`cancelled`.
    def zeros(self, region: Any = None, *args: Any, channel: Sequence[str] | None = None,
              max_evaluations: float = 5e7, timeout: float = 120.0) -> Roots:
        """Zeros of the channel ``channel=(src, dst)`` in ``region`` (its numerator's roots less the spurious ones).

        The shaper's removable points are roots of the numerator too; they are
        removed (:meth:`channel_cancelled`).  The old call ``zeros(src, dst, region)``
        still works, with a FutureWarning.

        >>> loop = control_action(G=(1, [1, 1, 0]), C=([1.0, 2.0], [1.0]))
        >>> loop.zeros((-5, 5, -5, 5), channel=("w", "z")).roots        # C G / (1 + C G): the zero of C
        array([-2.+0.j])
        """
        if isinstance(region, str):  # the 0.1 signature zeros(src, dst, region)
            if len(args) != 2 or channel is not None:
                raise TypeError("zeros takes (region, channel=(src, dst)); the old form is zeros(src, dst, region)")
            warnings.warn("Loop.zeros(src, dst, region) is now zeros(region, channel=(src, dst))", FutureWarning,
                          stacklevel=2)
            channel, region = (region, args[0]), args[1]
        elif args:
            raise TypeError("zeros takes (region, channel=(src, dst))")
        return spectra.zeros(self, region, channel=channel, max_evaluations=max_evaluations, timeout=timeout)

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
        blocks = [self.G, self.C] + ([self.S] if self.S is not None and self.ring.has_shaper() else [])
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
        w = self.default_omega() if omega is None else np.unique(v.strict_real_array(omega, "omega").reshape(-1))
        if w.size < 2:
            raise ValueError("omega must contain at least 2 frequencies")
        if np.any(w < 0):
            raise ValueError("omega must be >= 0")
        return margins_on_grid(self.loop_gain, self.sensitivity, self.complementary_sensitivity, w)

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
