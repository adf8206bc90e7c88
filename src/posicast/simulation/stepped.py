"""The stepped method: the continuous loop with its shaper inside, on an internal step, with an error estimate.

Every block is discretised for piecewise-linear signals (FOH) on the internal
step ``h = dt / substeps``, delays are fractional
(:class:`~posicast.simulation.shaped_loop.ShapedLoop`).  The response carries
``accuracy``, the difference to a run at ``2 h`` (an error estimate of the
``2 h`` run, and a bound of about three times that of this one); with an odd
number of substeps the comparison run is at ``h / 2``.
"""

from __future__ import annotations

import numpy as np

from ..loops.loop import Loop
from ..shapers.base import Shaper
from .layout import RingLayout, Signals
from .shaped_loop import ShapedLoop

__all__ = ["Stepped", "run_stepped"]


class Stepped:
    """A stepped run: the signals on ``t`` and the estimated error of ``y``."""

    def __init__(self, signals: Signals, accuracy: float) -> None:
        self.signals = signals
        self.accuracy = accuracy


def _fine(loop: Loop, layout: RingLayout, S: Shaper, sig: Signals, h: float, sub: int) -> Signals:
    fine = {k: np.repeat(v, sub) for k, v in sig.items()}
    out = ShapedLoop(loop, layout, S, h, "foh", "foh").response(fine)
    return {k: v[::sub] for k, v in out.items()}


def run_stepped(loop: Loop, layout: RingLayout, S: Shaper, sig: Signals, h: float, substeps: int) -> Stepped:
    """The run at ``h`` and its ``accuracy``: max ``|y|`` difference to the run at ``2 h`` (odd ``substeps``: ``h / 2``)."""
    out = _fine(loop, layout, S, sig, h, substeps)
    if substeps % 2 == 0:
        coarse = _fine(loop, layout, S, sig, 2 * h, substeps // 2)
    else:  # odd substeps: the comparison run uses twice as many steps (h / 2) instead of 2 h
        coarse = _fine(loop, layout, S, sig, h / 2, 2 * substeps)
    accuracy = float(np.max(np.abs(out["y"] - coarse["y"]))) if sig["w"].size else 0.0
    return Stepped(out, accuracy)
