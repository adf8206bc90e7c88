"""Seed 003 Fig. 1: closed-loop signal shaping around an inner model-matching loop.

``r_b -> (+) -> C -> v -> IS -> r_s -> F -> (+) -> G -> u -> P -> y``, with ``y`` fed back to
both comparators.  The inner loop is ``T_i = P G F / (1 + P G)`` from ``r_s`` to ``y``; seen
from the outer PI ``C`` it is the plant of a control-action loop (the shaper between ``C`` and
the inner loop), the registered architecture ``"model_matching"``.  :func:`model_matching`
builds that loop (every channel, stability and :func:`posicast.simulate` as for the other
architectures: ``u`` there is ``r_s``); :func:`inner_loop` is the inner loop itself
(``feedforward`` with the prefilter ``F`` outside the loop), whose ``w -> u`` channel is the
control effort of ``G`` (seed 003 Fig. 11) and whose ``d``, ``di`` channels are the physical
disturbances at the plant.

>>> import posicast
>>> from posicast import cases
>>> c = cases.ALL["two_mass"]
>>> S = posicast.design("zv", posicast.Mode(3.2074, 0.0389))
>>> loop = model_matching(P=c.G, G=c.extras["G_qft"], F=c.extras["F_m"], C=c.extras["C_inner"], S=S)
>>> loop.architecture, loop.is_stable()
('model_matching', True)
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .. import _validate as v
from ..cases import two_mass_plant
from ..core.transfer import TransferFunction, as_transfer
from ..loops.loop import Loop, feedforward

__all__ = ["model_matching", "inner_loop", "inner_closed_loop", "deviated_two_mass"]


def inner_loop(*, P: Any, G: Any, F: Any) -> Loop:
    """The inner loop ``e = F r_s - y``, ``u = G e``, ``y = P u`` as a feedforward loop (``w = r_s``).

    >>> from posicast import cases
    >>> c = cases.ALL["two_mass"]
    >>> L = inner_loop(P=c.G, G=c.extras["G_qft"], F=c.extras["F_m"])
    >>> round(abs(complex(L.transfer("w", "z")(1e-6j))), 6)       # T_i(0) = F(0) = 1
    1.0
    """
    return feedforward(G=as_transfer(P, "P"), C=as_transfer(G, "G"), S=as_transfer(F, "F"))


def model_matching(*, P: Any, G: Any, F: Any, C: Any, S: Any = None, load: Any = None) -> Loop:
    """Seed 003 Fig. 1: the outer loop of ``C`` and the shaper ``S`` around the inner loop ``(P, G, F)``.

    Parameters
    ----------
    P : plant-like
        The flexible plant.
    G, F : plant-like
        The inner controller and prefilter (e.g. from :func:`posicast.qft_design`).
    C : plant-like
        The outer controller (seed 003 eq. 5: ``C = 1.742 (1 + 0.19 s) / s``).
    S : Shaper, optional
        The input shaper ``IS`` (designed for the reference model).
    load : plant-like, optional
        A flexible part outside both loops, ``y = load z`` (the robot's link ``P2``, whose
        motor position ``z = x1`` is fed back); default 1.

    Returns
    -------
    Loop
        Architecture ``"model_matching"``; its ``G`` is the inner closed loop ``P G F / (1 + P G)``.
    """
    return Loop("model_matching", G=inner_closed_loop(P, G, F), C=C, S=S, F=load)


def inner_closed_loop(P: Any, G: Any, F: Any) -> TransferFunction:
    """``T_i = P G F / (1 + P G) = N_P N_G N_F / (D_F (D_P D_G + N_P N_G))``, the blocks' own poles cancelled.

    (The algebra of :class:`~posicast.TransferFunction` cancels nothing, so ``(P G F) / (1 + P G)``
    would keep the plant's integrator as a spurious pole at 0.)
    """
    polys = []
    for x, name in ((P, "P"), (G, "G"), (F, "F")):
        tf = as_transfer(x, name)
        if tf.has_delays:
            raise ValueError(f"{name} must be delay-free (rational) for the inner loop, got delay {tf.max_delay:g} s")
        sc = tf.to_scipy()
        polys.append((np.asarray(sc.num, float), np.asarray(sc.den, float)))
    (nP, dP), (nG, dG), (nF, dF) = polys
    with np.errstate(all="ignore"):
        char = np.polyadd(np.convolve(dP, dG), np.convolve(nP, nG))
        num, den = np.convolve(np.convolve(nP, nG), nF), np.convolve(dF, char)
    if not (np.all(np.isfinite(num)) and np.all(np.isfinite(den))):
        raise ValueError("P, G and F must have coefficients whose products stay finite (the inner loop overflows); "
                         "rescale them")
    if not np.any(den):
        raise ValueError("P, G and F give an ill-posed inner loop (1 + P G identically zero)")
    return TransferFunction.from_poly(num, den)


def deviated_two_mass(uncertainty: float) -> TransferFunction:
    """Seed 003 Fig. 10: the plant with ``c1, c2, k2 = nominal * (1 - uncertainty / 100)``.

    >>> from posicast.cases import modes_of
    >>> round(modes_of(deviated_two_mass(70.0))[0].omega, 3)
    1.783
    """
    u = v.real(uncertainty, "uncertainty")
    if not -1e6 <= u < 100.0:
        raise ValueError(f"uncertainty must be in [-1e6, 100) percent (100 % removes c1, c2, k2), got {u:g}")
    f = 1.0 - u / 100.0
    return two_mass_plant(50.0 * f, 0.1 * f, 10.0 * f)
