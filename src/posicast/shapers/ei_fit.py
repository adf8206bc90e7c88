"""Singhose's damped EI curve fit (seed 004 eq. 8, corrected from Singhose's 2009 review).

The coefficients of the fit used by :func:`posicast.shapers.ei.ei_fit`
(:data:`SINGHOSE_EI_FIT`) and, to show that it is wrong, the garbled copy printed in
seed 004 eq. 8 (:data:`SEED004_PRINTED_EI_FIT`), with how the three transcription
errors were found.  :func:`eval_fit` evaluates either.
"""

from __future__ import annotations

import numpy as np

from ..modes import Mode

__all__ = ["EI_FIT_ZETA_MAX", "EI_FIT_VTOL_MAX", "SINGHOSE_EI_FIT", "SEED004_PRINTED_EI_FIT", "eval_fit"]

#: Validity range of Singhose's damped EI curve fit (Singhose 2009 review).
EI_FIT_ZETA_MAX = 0.3
EI_FIT_VTOL_MAX = 0.15

# ---------------------------------------------------------------------------
# Singhose's damped EI curve fit and the garbled copy printed in seed 004 eq. 8
# ---------------------------------------------------------------------------
#
# Each entry is a list of (coefficient, power of V, power of zeta).
#
# Seed 004 eq. 8 prints this fit with three transcription errors.  Compared
# with the version below (Singhose 2009 review; the same numbers are in
# Klipper's klippy/extras/shaper_defs.py, which writes 0.24961 for the V term
# of A1 - a 1e-5 difference that changes nothing below), the seed:
#   * A1: prints "0.80008 V zeta" and drops the "1.23328 V zeta" term; the
#     correct terms are "0.80008 zeta + 1.23328 V zeta" (the seed has no
#     first-order zeta term at all in A1);
#   * t2: drops the "4.26169 V zeta^2" term and prints "36.989 V^2 zeta^2"
#     where the fit has "336.989 V^2 zeta^3";
#   * A3: prints -4.9009 for -4.90094 (rounding only, harmless).
# How we know: ei_exact (the definition, solved to ~1e-15) against both sets,
# max over zeta in [0, 0.3] (61 points) and V in {0.02, 0.05, 0.1, 0.15}:
#                      max |dA|   max |dt|/T_d   max |V(omega_m) - vtol|
#   corrected fit       0.0096      0.0065         0.0084   (V = 0.05: 0.0025,
#                                                             0.0004, 0.0020)
#   seed 004 as printed 0.257       0.186          0.136
# The corrected fit is as good as a fit can be (its error at zeta = 0, where
# the exact EI is the closed form, is already 0.0084 in V at V = 0.15); the
# printed one is not: at zeta = 0.2, V = 0.05 it gives A1 = 0.2963 (exact
# 0.4613: the missing 0.80008 zeta (1 - V) + 1.23328 V zeta = 0.165 is the
# damping compensation of the first impulse), t2/T_d = 0.5023 (exact 0.5140)
# and V(omega_m) = 0.0846 instead of 0.05.  Swapping one formula at a time
# (same grid): the printed A1 alone raises max |dA| to 0.257 and max |dV| to
# 0.100; the printed t2 alone raises max |dt|/T_d to 0.186 and max |dV| to
# 0.015; the printed A3 (rounding) changes nothing at 4 decimals.
SINGHOSE_EI_FIT: dict[str, list[tuple[float, int, int]]] = {
    "A1": [(0.24968, 0, 0), (0.24962, 1, 0), (0.80008, 0, 1), (1.23328, 1, 1),
           (0.49599, 0, 2), (3.17316, 1, 2)],
    "A3": [(0.25149, 0, 0), (0.21474, 1, 0), (-0.83249, 0, 1), (1.41498, 1, 1),
           (0.85181, 0, 2), (-4.90094, 1, 2)],
    "t2": [(0.49990, 0, 0), (0.46159, 1, 1), (4.26169, 1, 2), (1.75601, 1, 3),
           (8.57843, 2, 1), (-108.644, 2, 2), (336.989, 2, 3)],
}

# Seed 004 eq. 8 exactly as printed (kept only to demonstrate that it is wrong).
SEED004_PRINTED_EI_FIT: dict[str, list[tuple[float, int, int]]] = {
    "A1": [(0.24968, 0, 0), (0.24962, 1, 0), (0.80008, 1, 1), (0.49599, 0, 2),
           (3.17316, 1, 2)],
    "A3": [(0.25149, 0, 0), (0.21474, 1, 0), (-0.83249, 0, 1), (1.41498, 1, 1),
           (0.85181, 0, 2), (-4.9009, 1, 2)],
    "t2": [(0.49990, 0, 0), (0.46159, 1, 1), (1.75601, 1, 3), (8.57843, 2, 1),
           (-108.644, 2, 2), (36.989, 2, 2)],
}


def _poly(terms: list[tuple[float, int, int]], v: float, z: float) -> float:
    """``sum c V^i zeta^j`` over the terms ``(c, i, j)``."""
    return float(sum(c * v**i * z**j for c, i, j in terms))


def eval_fit(coeffs: dict[str, list[tuple[float, int, int]]], mode: Mode,
             vtol: float) -> tuple[np.ndarray, np.ndarray]:
    """Impulse times (s) and amplitudes of a fit ``coeffs`` (A1, A3, t2/T_d) at ``mode`` and ``vtol``."""
    z = mode.zeta
    a1 = _poly(coeffs["A1"], vtol, z)
    a3 = _poly(coeffs["A3"], vtol, z)
    td = mode.damped_period
    times = np.array([0.0, _poly(coeffs["t2"], vtol, z) * td, td])
    return times, np.array([a1, 1.0 - (a1 + a3), a3])
