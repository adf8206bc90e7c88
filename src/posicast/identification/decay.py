"""Free-decay (ring-down) identification (``method="decay"``, the input ignored).

Matrix pencil (Hua & Sarkar 1990) on the record for the starting poles, then the
output-error refinement of the free response (:mod:`.output_error`).
"""

from __future__ import annotations

import numpy as np
from scipy import linalg

from .. import _validate as v
from ..modes import Mode
from .output_error import ZETA_MIN, OESettings, significant_oe
from .results import Identification
from .significance import NoModeFound

__all__ = ["fit_decay", "matrix_pencil"]


@v.renamed_keywords(fs="sample_rate")
def fit_decay(y: np.ndarray, sample_rate: float, n_modes: int, *, covariance: str, offset: bool,
              weights: np.ndarray | None) -> Identification:
    """Modes of a free decay: matrix-pencil poles refined by the output-error fit of the free response."""
    fs = sample_rate  # the sample rate [Hz], fs in the formulas
    start = matrix_pencil(y - np.mean(y), 1.0 / fs, n_modes)
    settings = OESettings(covariance=covariance, feedthrough=False, offset=offset, initial_state=True,
                          weights=weights)
    return significant_oe(None, y, fs, len(start), settings, start=start, method="decay").identification


def matrix_pencil(y: np.ndarray, h: float, n_modes: int) -> list[Mode]:
    """Matrix pencil (Hua & Sarkar 1990) on a free decay: poles of the 2 n_modes dominant components."""
    n = y.size
    L = n // 3
    Yh = linalg.hankel(y[: n - L], y[n - L - 1:])
    U, s, Vt = np.linalg.svd(Yh, full_matrices=False)
    M = 2 * n_modes + 1  # + 1 for an offset
    V = Vt[:M].T
    V1, V2 = V[:-1], V[1:]
    z = np.linalg.eigvals(np.linalg.pinv(V1) @ V2)
    modes = []
    for zi in z:
        if zi.imag <= 1e-9 or abs(zi) >= 1.0:
            continue
        s_ = np.log(zi) / h
        modes.append(Mode(float(abs(s_)), float(np.clip(-s_.real / abs(s_), ZETA_MIN, 0.9))))
    modes.sort(key=lambda m: m.omega)
    if not modes:
        raise NoModeFound("no mode found (decay): no decaying oscillation in y (is it a ring-down record?)")
    return modes[:n_modes]
