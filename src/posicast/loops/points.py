"""Where a loop's blocks change and cancel: feature frequencies (removable points live in :mod:`posicast.core.removable`)."""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np
from numpy.polynomial import polynomial as P

from .. import _validate as v
from ..core.removable import removable_points, vanishing_order  # noqa: F401 - re-exported: loops' names since 0.1
from ..core.transfer import TransferFunction

__all__ = ["feature_frequencies", "removable_points", "vanishing_order"]

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
