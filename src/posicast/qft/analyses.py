"""Seed 003's analyses: percentage vibration over a plant set, shaper length vs vibration (Fig. 6) and vs
uncertainty (Fig. 7), closed-loop bandwidth with and without the inner loop (Fig. 8).

**Percentage vibration** (seed 003, section "Require shorter input shaper length"):
``V = e^{-zeta omega_n t_n (omega / omega_n)} |sum_i A_i e^{-t_i s_p (omega / omega_n)}|`` with
``s_p = -zeta omega_n - j omega_n sqrt(1 - zeta^2)``: the residual vibration of a mode whose
natural frequency is the plant's actual ``omega`` and whose damping is the **model's** ``zeta``
(``s_p omega / omega_n`` scales the model pole).  This reading reproduces the printed
numbers (43.53 % for ZV, 3.59 % for ZVD^3 over the 27 plants); taking each plant's own damping
(``damping="plant"``) gives 44.18 % and 3.81 %.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Sequence

import numpy as np

from .. import _validate as v
from ..analysis.vibration import residual_vibration
from ..cases import modes_of
from ..core.transfer import TransferFunction, as_transfer
from ..modes import Mode
from ..shapers.base import Shaper
from ..shapers.registry import design
from .plantset import PlantSet

__all__ = [
    "percent_vibration", "zvdk", "ShaperLengths", "length_vs_vibration", "ShortestShaper", "shortest_zvdk",
    "UncertaintyLengths", "length_vs_uncertainty", "Bandwidth", "bandwidth",
]

_DAMPING = ("model", "plant")


def _plant_list(plants: Any, name: str = "plants") -> tuple[TransferFunction, ...]:
    if isinstance(plants, PlantSet):
        return plants.plants
    items = v.sequence(plants, name)
    if not items:
        raise ValueError(f"{name} must be a non-empty set of transfer functions, got an empty set")
    return tuple(as_transfer(P, f"{name}[{i}]") for i, P in enumerate(items))


@v.renamed_keywords(shaper="S")
def percent_vibration(S: Shaper, plants: Any, *, per_plant: bool = False, damping: str = "model") -> Any:
    """Seed 003's percentage vibration of shaper ``S`` over a plant set: the worst case, or per plant.

    Parameters
    ----------
    S : Shaper
        Designed for the model mode (``S.modes[0]``).
    plants : PlantSet or sequence of plants
        Each plant's least-damped mode gives its actual ``omega`` (:func:`posicast.cases.modes_of`).
    per_plant : bool
        Return every plant's value (array, in the set's order) instead of the worst case.
    damping : {"model", "plant"}
        The damping of the evaluated pole: the shaper's design damping (seed 003's formula,
        the default) or each plant's own.

    Returns
    -------
    float or ndarray
        ``V`` in percent.

    Examples
    --------
    >>> from posicast import cases, design, Mode
    >>> round(percent_vibration(design("zv", Mode(3.2074, 0.0389)), cases.two_mass_plants()), 2)
    43.53
    """
    return _percent(S, plants, per_plant, damping, "plants")


def _percent(S: Shaper, plants: Any, per_plant: bool, damping: str, name: str) -> Any:
    """:func:`percent_vibration` with the plants' argument name for messages."""
    S = v.instance_of(S, Shaper, "S", "a shaper (a posicast Shaper, from posicast.design)")
    damping = v.choice(damping, "damping", _DAMPING)
    if not isinstance(per_plant, bool):
        raise TypeError(f"per_plant must be a bool, got {type(per_plant).__name__}")
    if not S.modes:
        raise ValueError(f"S must be designed for a mode (it has none), got {S.name!r}")
    zeta0 = S.modes[0].zeta
    out = []
    for i, P in enumerate(_plant_list(plants, name)):
        modes = modes_of(P, f"{name}[{i}]")
        if not modes:
            raise ValueError(f"{name}[{i}] must have an underdamped mode, got none")
        m = modes[0]
        out.append(100.0 * float(residual_vibration(S, m.omega, zeta0 if damping == "model" else m.zeta)))
    arr = np.array(out)
    return arr if per_plant else float(arr.max())


def zvdk(mode: Mode, k: int) -> Shaper:
    """Seed 003 eq. 4: ZVD^k (``k = 0`` is ZV), ``k + 2`` impulses over ``(k + 1) pi / omega_d``."""
    k = v.integer(k, "k", 0)
    return design("zv", mode) if k == 0 else design("zvdk", mode, k=k)


@dataclass(frozen=True)
class ShaperLengths:
    """Fig. 6: ZVD^k length vs worst-case percentage vibration, without and with the inner loop.

    Attributes
    ----------
    k : ndarray of int
    lengths : ndarray
        ``t_{k+2} = (k + 1) pi / omega_d`` [s].
    without, with_inner : ndarray
        Worst-case V [%] over the open plants and over the inner closed loops.
    """

    k: np.ndarray
    lengths: np.ndarray
    without: np.ndarray
    with_inner: np.ndarray

    def length_for(self, vtol: float, inner: bool = False) -> float:
        """The shortest length whose worst-case V is at most ``vtol`` percent (inf if none)."""
        vals = self.with_inner if inner else self.without
        ok = np.flatnonzero(vals <= v.positive(vtol, "vtol") * (1 + 1e-12))
        return float(self.lengths[ok[0]]) if ok.size else float("inf")

    def plot(self, ax: Any = None) -> Any:
        """Seed 003 Fig. 6: length [s] against worst-case V [%]; returns ``(fig, ax)``."""
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots() if ax is None else (v.axes(ax).figure, ax)
        ax.plot(self.without, self.lengths, "o--", label="without inner loop")
        ax.plot(np.maximum(self.with_inner, 1e-3), self.lengths[0] + 0 * self.lengths, "s-", label="with inner loop (ZV)")
        ax.set_xscale("log")
        ax.set_xlabel("worst-case percentage vibration V [%]")
        ax.set_ylabel("input shaper length [s]")
        ax.legend()
        return fig, ax


def length_vs_vibration(plants: Any, mode: Mode, inner: Any = None, ks: Sequence[int] = range(6)) -> ShaperLengths:
    """Seed 003 Fig. 6: the ZVD^k family designed for ``mode``, worst-case V over ``plants`` and ``inner``.

    ``inner`` is the set of inner closed loops ``P G F / (1 + P G)`` (default: the reference
    model alone, ``F_m`` with ``mode``: perfect matching).
    """
    mode = v.instance_of(mode, Mode, "mode", "a posicast.Mode")
    ks = [v.integer(k, "ks[]", 0) for k in v.sequence(ks, "ks", min_len=1)]
    inner_set = inner if inner is not None else [_second_order(mode)]
    shapers = [zvdk(mode, k) for k in ks]
    return ShaperLengths(
        np.array(ks), np.array([S.duration for S in shapers]),
        np.array([percent_vibration(S, plants) for S in shapers]),
        np.array([_percent(S, inner_set, False, "model", "inner") for S in shapers]),
    )


def _second_order(mode: Mode) -> TransferFunction:
    w, z = mode.omega, mode.zeta
    return TransferFunction.from_poly([w * w], [1.0, 2.0 * z * w, w * w])


@dataclass(frozen=True)
class ShortestShaper:
    """The shortest ZVD^k meeting a vibration limit over a plant set."""

    k: int
    length: float
    vibration: float

    @property
    def name(self) -> str:
        return "ZV" if self.k == 0 else f"ZVD^{self.k}"


def shortest_zvdk(plants: Any, mode: Mode, vtol: float = 10.0, kmax: int = 30) -> ShortestShaper:
    """The smallest ``k`` with worst-case V <= ``vtol`` percent (ValueError if none up to ``kmax``).

    >>> from posicast import cases, Mode
    >>> shortest_zvdk(cases.two_mass_plants(), Mode(3.2074, 0.0389)).name
    'ZVD^2'
    """
    vtol = v.positive(vtol, "vtol")
    kmax = v.integer(kmax, "kmax", 0)
    for k in range(kmax + 1):
        S = zvdk(mode, k)
        V = percent_vibration(S, plants)
        if V <= vtol:
            return ShortestShaper(k, float(S.duration), V)
    raise ValueError(f"vtol = {vtol:g} % is met by no ZVD^k with k <= kmax = {kmax} over the plant set; "
                     "raise kmax or vtol")


@dataclass(frozen=True)
class UncertaintyLengths:
    """Fig. 7: the shortest ZVD^k for each uncertainty level, without the inner loop (with it: ZV)."""

    uncertainty: np.ndarray
    k: np.ndarray
    lengths: np.ndarray
    with_inner: float

    def plot(self, ax: Any = None) -> Any:
        """Seed 003 Fig. 7: length [s] against uncertainty [%]; returns ``(fig, ax)``."""
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots() if ax is None else (v.axes(ax).figure, ax)
        ax.step(self.uncertainty, self.lengths, "o--", where="post", label="without inner loop")
        ax.plot(self.uncertainty, self.with_inner + 0 * self.uncertainty, "s-", label="with inner loop")
        ax.set_xlabel("uncertainty in c1, c2, k2 [%]")
        ax.set_ylabel("input shaper length [s]")
        ax.legend()
        return fig, ax


def length_vs_uncertainty(
    levels: Sequence[float] = (0, 10, 20, 30, 40, 50, 60, 70),
    mode: Mode = Mode(3.2074, 0.0389),
    vtol: float = 10.0,
    plant_set: Callable[[float], Any] = PlantSet.two_mass,
) -> UncertaintyLengths:
    """Seed 003 Fig. 7: for each uncertainty level the shortest ZVD^k over ``plant_set(level)``.

    With the inner loop the shaper is designed for the exact reference model, so the
    ZV suffices at every level (its length is ``with_inner``).
    """
    lv = [v.real_in_range(x, "levels[]", 0.0, 100.0, hi_open=True) for x in v.sequence(levels, "levels", min_len=1)]
    best = [shortest_zvdk(plant_set(x), mode, vtol) for x in lv]
    zv = shortest_zvdk([_second_order(mode)], mode, vtol)
    return UncertaintyLengths(np.array(lv), np.array([b.k for b in best]), np.array([b.length for b in best]),
                              zv.length)


@dataclass(frozen=True)
class Bandwidth:
    """Closed-loop bandwidth: the first frequency where ``|T(j omega)|`` falls 3 dB below ``|T(0)|``.

    Attributes
    ----------
    omega : float
        The -3 dB bandwidth [rad/s].
    peak, peak_omega : float
        The largest ``|T(j omega)|`` below the bandwidth and where it is.
    """

    omega: float
    peak: float
    peak_omega: float


def bandwidth(T: Any, omega: Any = None) -> Bandwidth:
    """The -3 dB bandwidth of a closed loop ``T`` (refined between grid points by bisection).

    >>> round(bandwidth((1.0, [1.0, 1.0])).omega, 6)      # 1 / (s + 1)
    1.0
    """
    tf = as_transfer(T, "T")
    w = np.logspace(-4, 4, 8001) if omega is None else np.unique(v.strict_real_array(omega, "omega"))
    g0 = abs(complex(tf(0.0)))
    if not np.isfinite(g0) or g0 == 0:
        raise ValueError(f"T must have a finite, nonzero DC gain for a -3 dB bandwidth, got {g0:g}")
    m = np.abs(tf.freqresp(w))
    below = np.flatnonzero(m < g0 / np.sqrt(2))
    if below.size == 0:
        return Bandwidth(float("inf"), float(m.max()), float(w[m.argmax()]))
    i = below[0]
    lo, hi = (w[i - 1], w[i]) if i > 0 else (0.0, w[0])
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if abs(complex(tf(1j * mid))) >= g0 / np.sqrt(2) else (lo, mid)
    j = int(np.argmax(m[: i + 1]))
    return Bandwidth(float(0.5 * (lo + hi)), float(m[j]), float(w[j]))
