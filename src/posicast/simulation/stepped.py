"""The stepped method: the continuous loop with its shaper inside, on an internal step, with an error estimate.

Every block is discretised for piecewise-linear signals (FOH) on the internal
step ``h = dt / substeps``, delays are fractional
(:class:`~posicast.simulation.shaped_loop.ShapedLoop`).  The response carries
``accuracy``, the difference to a run at ``2 h`` (an error estimate of the
``2 h`` run, and a bound of about three times that of this one); with an odd
number of substeps the comparison run is at ``h / 2``.

Both runs go through ``t`` in chunks of :data:`CHUNK` internal steps, side by side,
carrying their states: the memory is that of the signals kept (``keep``) plus
one chunk, however long ``t`` is (issue #15: an hour at 1 kHz).
"""

from __future__ import annotations

from typing import Collection

import numpy as np

from ..loops.loop import Loop
from ..shapers.base import Shaper
from .layout import RingLayout, Signals
from .shaped_loop import ShapedLoop

__all__ = ["Stepped", "run_stepped", "CHUNK"]

#: Internal steps per chunk of a stepped run (its working memory: a few tens of MB).
CHUNK = 1 << 16


class Stepped:
    """A stepped run: the signals on ``t`` and the estimated error of ``y``."""

    def __init__(self, signals: Signals, accuracy: float) -> None:
        self.signals = signals
        self.accuracy = accuracy


def _fine(run: ShapedLoop, part: Signals, sub: int) -> Signals:
    fine = {k: np.repeat(v, sub) for k, v in part.items()} if sub > 1 else part
    out = run.advance(fine)
    return {k: v[::sub] for k, v in out.items()} if sub > 1 else out


def run_stepped(loop: Loop, layout: RingLayout, S: Shaper, sig: Signals, h: float, substeps: int,
                keep: Collection[str] | None = None) -> Stepped:
    """The run at ``h`` and its ``accuracy``: max ``|y|`` difference to the run at ``2 h`` (odd ``substeps``: ``h / 2``).

    ``keep``: the names of the signals to return (None: all).
    """
    main = ShapedLoop(loop, layout, S, h, "foh", "foh")
    if substeps % 2 == 0:
        other, other_sub = ShapedLoop(loop, layout, S, 2 * h, "foh", "foh"), substeps // 2
    else:  # odd substeps: the comparison run uses twice as many steps (h / 2) instead of 2 h
        other, other_sub = ShapedLoop(loop, layout, S, h / 2, "foh", "foh"), 2 * substeps
    N = sig["w"].size
    chunk = max(1, CHUNK // max(substeps, other_sub))  # samples of t per chunk
    out: Signals | None = None
    accuracy = 0.0
    for k in range(0, N, chunk):
        part = {name: x[k: k + chunk] for name, x in sig.items()}
        a = _fine(main, part, substeps)
        b = _fine(other, part, other_sub)
        accuracy = float(np.max([accuracy, np.max(np.abs(a["y"] - b["y"]))]))  # NaN once diverged, as one run
        if out is None:
            out = {name: np.empty(N) for name in a if keep is None or name in keep}
        for name, values in out.items():
            values[k: k + chunk] = a[name]
    if out is None:  # an empty grid: the names from a run of no samples
        out = {name: x for name, x in _fine(main, sig, substeps).items() if keep is None or name in keep}
    return Stepped(out, accuracy)
