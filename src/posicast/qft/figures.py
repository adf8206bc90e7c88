"""Seed 003 Fig. 9 (root locus without the inner loop) and Fig. 11 (control effort of the inner controller).

>>> from posicast import cases
>>> c = cases.ALL["two_mass"]
>>> rl = root_locus(cases.two_mass_plants(), c.C, [0.5, 1.0, 2.0])
>>> int((rl.crossing <= 1.0).sum())        # plants the printed PI destabilises without a shaper
4
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from scipy import signal

from .. import _validate as v
from ..core.transfer import TransferFunction, as_transfer
from ..shapers.base import Shaper
from ..simulation.engine import simulate
from .analyses import _plant_list
from .architecture import model_matching

__all__ = ["RootLocus", "root_locus", "ControlEffort", "control_effort"]


def _rational(tf: TransferFunction, name: str) -> tuple[np.ndarray, np.ndarray]:
    if tf.has_delays:
        raise ValueError(f"{name} must be delay-free (rational), got delay {tf.max_delay:g} s")
    sc = tf.to_scipy()
    return np.asarray(sc.num, float), np.asarray(sc.den, float)


@dataclass(frozen=True)
class RootLocus:
    """Closed-loop poles of ``1 + k C P_i = 0`` for every plant and gain.

    Attributes
    ----------
    gains : ndarray
    poles : ndarray of complex, shape ``(plants, gains, n)``
    crossing : ndarray
        Per plant, the smallest gain of the grid with a pole at ``Re s >= 0`` (inf if none).
    """

    gains: np.ndarray
    poles: np.ndarray
    crossing: np.ndarray

    def plot(self, ax: Any = None) -> Any:
        """Seed 003 Fig. 9: the loci of all plants; returns ``(fig, ax)``."""
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots() if ax is None else (v.axes(ax).figure, ax)
        for i in range(self.poles.shape[0]):
            p = self.poles[i].ravel()
            ax.plot(p.real, p.imag, ".", ms=1.5, color="tab:red" if np.isfinite(self.crossing[i]) else "tab:blue")
        ax.axvline(0.0, color="k", lw=0.8)
        ax.set_xlabel("Re s")
        ax.set_ylabel("Im s")
        ax.set_title("root locus of 1 + k C P over the plant set (red: crosses into Re s > 0)")
        return fig, ax


def root_locus(plants: Any, C: Any, gains: Any = None) -> RootLocus:
    """The root locus of ``1 + k C P`` for every plant (delay-free loops; seed 003 Fig. 9).

    Parameters
    ----------
    plants : PlantSet or sequence of plants
    C : plant-like
        The controller (seed 003: ``0.396 (1 + 24 s) / s``, the PI without the inner loop).
    gains : array_like, optional
        Multipliers ``k > 0`` of ``C`` (default: 400 from 0.01 to 100, log-spaced).
    """
    items = _plant_list(plants)
    num_c, den_c = _rational(as_transfer(C, "C"), "C")
    k = np.geomspace(0.01, 100.0, 400) if gains is None else np.atleast_1d(v.strict_real_array(gains, "gains"))
    if k.ndim != 1 or k.size == 0 or np.any(k <= 0) or k.size > 100_000:
        raise ValueError(f"gains must be 1 to 100000 values > 0, got {k.size} values")
    rows, cross = [], []
    for i, P in enumerate(items):
        num_p, den_p = _rational(P, f"plants[{i}]")
        a, b = np.convolve(den_p, den_c), np.convolve(num_p, num_c)
        n = max(a.size, b.size)
        a, b = np.pad(a, (n - a.size, 0)), np.pad(b, (n - b.size, 0))
        with np.errstate(all="ignore"):
            if not np.all(np.isfinite(np.outer(k, b) + a)):
                raise ValueError(f"C and plants[{i}] give non-finite loop coefficients at these gains; rescale them")
            row = [np.roots(a + g * b) for g in k]
        deg = max(len(r) for r in row)
        row = [np.pad(r, (0, deg - len(r)), constant_values=np.nan) for r in row]
        rows.append(np.array(row))
        unstable = np.flatnonzero([np.nanmax(r.real) >= 0 if np.any(np.isfinite(r)) else False for r in row])
        cross.append(float(k[unstable[0]]) if unstable.size else float("inf"))
    deg = max(r.shape[1] for r in rows)
    poles = np.array([np.pad(r, ((0, 0), (0, deg - r.shape[1])), constant_values=np.nan) for r in rows])
    return RootLocus(k, poles, np.array(cross))


class ControlEffort(NamedTuple):
    """Seed 003 Fig. 11: the output ``y``, the shaped inner reference ``r_s`` and the effort ``u`` of ``G``."""

    t: np.ndarray
    y: np.ndarray
    rs: np.ndarray
    u: np.ndarray


def control_effort(*, P: Any, G: Any, F: Any, C: Any, S: Any, t: Any, w: Any = None) -> ControlEffort:
    """Simulate seed 003's Fig. 1 loop and the inner controller's output ``u = G F r_s / (1 + P G)``.

    The outer loop is simulated by :func:`posicast.simulate` (``r_s`` is its ``u``); ``u`` follows
    from ``r_s`` through the rational ``G F / (1 + P G)``, which must be proper (the printed
    polynomial ``G`` of seed 003 is not: its effort for a step is an impulse).
    """
    Pt, Gt, Ft = as_transfer(P, "P"), as_transfer(G, "G"), as_transfer(F, "F")
    (nP, dP), (nG, dG), (nF, dF) = _rational(Pt, "P"), _rational(Gt, "G"), _rational(Ft, "F")
    num = np.convolve(np.convolve(nG, nF), dP)
    den = np.convolve(dF, np.polyadd(np.convolve(dP, dG), np.convolve(nP, nG)))
    num, den = np.trim_zeros(num, "f"), np.trim_zeros(den, "f")
    if num.size > den.size:
        raise ValueError("G must make G F / (1 + P G) proper for a control effort (an improper G, such as the "
                         "printed polynomial of seed 003, gives impulses)")
    nC, dC = _rational(as_transfer(C, "C"), "C")
    if np.trim_zeros(nC, "f").size > np.trim_zeros(dC, "f").size:
        raise ValueError("C must be proper (no more zeros than poles) to be simulated")
    if S is not None:
        v.instance_of(S, Shaper, "S", "a posicast Shaper (from posicast.design) or None")
    tt = v.strict_real_array(t, "t")
    loop = model_matching(P=Pt, G=Gt, F=Ft, C=C, S=S)
    try:
        resp = simulate(loop, tt, w=np.ones_like(tt) if w is None else w)
    except ValueError as exc:  # the simulator's refusal, for the loop these arguments make
        raise ValueError(f"the loop of P, G, F, C and S cannot be simulated: {exc}") from None
    rs = resp.u
    _, u, _ = signal.lsim((num, den), rs, tt[: rs.size])
    return ControlEffort(tt[: rs.size], resp.y, rs, np.asarray(u, float))
