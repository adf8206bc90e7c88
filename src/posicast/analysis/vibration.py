"""Residual vibration, sensitivity curves and insensitivity of shapers.

Residual vibration (seed 004 eq. 1-3, seed 003's "percentage vibration"),
generalised to any shaper through its exact transfer function: a mode with
natural frequency ``omega`` and damping ``zeta`` has the pole
``p = -zeta omega + j omega sqrt(1 - zeta^2)``.  After the shaper has ended
(``t >= t_end``) the shaped impulse response of the mode is
``e^{-beta t} |S(p)| sin(Omega t + phi)``, so

* ``reference="end"`` (default): ``V = e^{-zeta omega t_end} |S(p)|``, the
  amplitude relative to an unshaped impulse applied at ``t_end``.  This is the
  Singer-Seering form printed by seeds 003 and 004 (their
  ``e^{-zeta omega t_n} sqrt(C^2 + S^2)``, with ``t_n`` the last impulse); it is the
  form in which the EI shapers' ``vtol`` is defined, hence the default.
* ``reference="unshaped"``: ``V = |S(p)|``, the amplitude relative to the
  unshaped response at the same time.  It is the only form that makes sense for
  an IIR shaper (infinite duration) and it is the stricter one for damped modes.

For ``zeta = 0`` both coincide.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import brentq

from .. import _validate as v
from ..modes import Mode
from ..shapers.base import Shaper

__all__ = [
    "residual_vibration",
    "SensitivityCurve",
    "sensitivity_curve",
    "Insensitivity",
    "insensitivity",
]

_REFERENCES = ("end", "unshaped")


def _check_shaper(shaper: Any) -> Shaper:
    if not isinstance(shaper, Shaper):
        raise TypeError(f"shaper must be a posicast Shaper (from posicast.design), got {type(shaper).__name__}")
    return shaper


def _check_zeta(zeta: Any) -> float:
    z = v.real(zeta, "zeta")
    if not 0.0 <= z < 1.0:
        raise ValueError(f"zeta must be in [0, 1), got {z:g}")
    return z


def residual_vibration(shaper: Shaper, omega: Any, zeta: float, reference: str = "end") -> Any:
    """Residual vibration of a mode ``(omega, zeta)`` excited through ``shaper``.

    Parameters
    ----------
    shaper : Shaper
        Lumped, distributed or IIR shaper.
    omega : float or array_like
        Natural frequency (rad/s) of the actual mode, > 0; vectorised.
    zeta : float
        Damping ratio of the actual mode, ``0 <= zeta < 1``.
    reference : {"end", "unshaped"}
        Normalisation, see the module docstring.  ``"end"`` needs a finite
        shaper duration.

    Returns
    -------
    float or ndarray
        ``V`` (0 = no vibration, 1 = as much as an unshaped step).

    Examples
    --------
    >>> from posicast import Mode, design
    >>> S = design("zv", Mode(10.0, 0.1))
    >>> float(residual_vibration(S, 10.0, 0.1)) < 1e-12
    True
    >>> round(float(residual_vibration(design("zv", Mode(1.0, 0.0)), 1.1, 0.0)), 6)
    0.156434
    """
    S = _check_shaper(shaper)
    w = v.real_array(omega, "omega")
    if np.any(w <= 0):
        raise ValueError(f"omega must be > 0, got min {w.min():g}")
    z = _check_zeta(zeta)
    if reference not in _REFERENCES:
        raise ValueError(f"reference must be one of {_REFERENCES}, got {reference!r}")
    p = w * complex(-z, math.sqrt(1.0 - z * z))
    mag = np.abs(S(p))
    if reference == "end":
        t_end = S.duration
        if not math.isfinite(t_end):
            raise ValueError(
                f"shaper {S.name!r} has infinite duration (IIR part): use reference='unshaped'"
            )
        mag = mag * np.exp(-z * w * t_end)
    return mag if np.ndim(omega) else float(mag)


def _design_mode(shaper: Shaper, mode: Mode | None) -> Mode:
    if mode is not None:
        if not isinstance(mode, Mode):
            raise TypeError(f"mode must be a posicast.Mode, got {type(mode).__name__}")
        return mode
    if len(shaper.modes) != 1:
        raise ValueError("shaper was designed for several modes (or none): pass mode= to choose one")
    return shaper.modes[0]


@dataclass(frozen=True)
class SensitivityCurve:
    """Residual vibration over normalised frequency ``omega / omega_model``.

    Attributes
    ----------
    ratio : ndarray
        ``omega / omega_model``.
    vibration : ndarray
        Residual vibration at each ratio.
    mode : Mode
        The model mode (``ratio = 1``).
    name : str
        The shaper's name.
    reference : str
        Normalisation used.
    """

    ratio: np.ndarray
    vibration: np.ndarray
    mode: Mode
    name: str
    reference: str

    def plot(self, ax: Any = None, **kwargs: Any) -> Any:
        """Draw on ``ax`` (created if None); returns the axes."""
        from .plots import sensitivity_plot

        return sensitivity_plot([self], ax=ax, **kwargs)[1]


def sensitivity_curve(
    shaper: Shaper,
    ratio: Any = None,
    mode: Mode | None = None,
    reference: str = "end",
) -> SensitivityCurve:
    """Sensitivity curve of ``shaper`` around its design mode.

    Parameters
    ----------
    shaper : Shaper
    ratio : array_like, optional
        Frequency ratios ``omega / omega_model`` (> 0), default 801 points on [0, 2]
        (the first point is 1e-3 instead of 0).
    mode : Mode, optional
        Model mode; defaults to the (single) mode the shaper was designed for.
        The damping is held at the model value while the frequency varies.
    reference : {"end", "unshaped"}

    Examples
    --------
    >>> from posicast import Mode, design
    >>> c = sensitivity_curve(design("zvd", Mode(2.0, 0.0)), ratio=[0.9, 1.0, 1.1])
    >>> [round(float(x), 4) for x in c.vibration]
    [0.0245, 0.0, 0.0245]
    """
    S = _check_shaper(shaper)
    m = _design_mode(S, mode)
    r = np.linspace(0.0, 2.0, 801) if ratio is None else v.real_array(ratio, "ratio").reshape(-1)
    if ratio is None:
        r[0] = 1e-3
    if np.any(r <= 0):
        raise ValueError("ratio must be > 0")
    vib = residual_vibration(S, r * m.omega, m.zeta, reference)
    return SensitivityCurve(r, np.asarray(vib), m, S.name, reference)


@dataclass(frozen=True)
class Insensitivity:
    """Width of the frequency band around the model where ``V <= vtol``.

    ``low`` and ``high`` are the band edges as ratios ``omega / omega_model``;
    ``width = high - low`` (0 when ``V(model) > vtol``).
    """

    width: float
    low: float
    high: float
    vtol: float


def insensitivity(
    shaper: Shaper,
    vtol: float = 0.05,
    mode: Mode | None = None,
    reference: str = "end",
    max_ratio: float = 10.0,
) -> Insensitivity:
    """Insensitivity: the normalised width of the band around the model with ``V <= vtol``.

    The band is the connected set of ``omega / omega_model`` containing 1 on which
    the residual vibration stays at or below ``vtol`` (a hump touching ``vtol``
    exactly, as an EI shaper's at the model, does not split it).  Edges are
    located with Brent's method to ~1e-12.

    Examples
    --------
    >>> from posicast import Mode, design
    >>> ins = insensitivity(design("zv", Mode(1.0, 0.0)), 0.05)
    >>> round(ins.width, 4)                  # 2 arcsin(0.05) * 2 / pi
    0.0637
    """
    S = _check_shaper(shaper)
    m = _design_mode(S, mode)
    tol = v.in_open_interval(vtol, "vtol", 0.0, 1.0)
    max_ratio = v.real(max_ratio, "max_ratio")
    if max_ratio <= 1.0:
        raise ValueError(f"max_ratio must be > 1, got {max_ratio:g}")
    slack = tol * 1e-9

    def V(r: Any) -> Any:
        return residual_vibration(S, np.asarray(r) * m.omega, m.zeta, reference)

    if float(V(1.0)) > tol + slack:
        return Insensitivity(0.0, 1.0, 1.0, tol)
    # Fine grid on each side of 1 (step 1e-4 near the model, coarser far away).
    right = np.unique(np.concatenate([1.0 + np.linspace(0, 1.0, 10001), np.linspace(2.0, max_ratio, 8001)]))
    left = np.linspace(1.0, 1e-3, 10000)
    edges = []
    for grid in (left, right):
        vals = V(grid)
        above = np.flatnonzero(vals > tol + slack)
        if above.size == 0:
            edges.append(float(grid[-1]))  # band reaches the end of the search range
            continue
        j = above[0]
        a, b = grid[j - 1], grid[j]
        if float(V(a)) >= tol:  # within the slack of a touching hump: the edge is a
            edges.append(float(a))
            continue
        edges.append(brentq(lambda r: float(V(r)) - tol, a, b, xtol=1e-13, rtol=1e-13))
    lo, hi = min(edges), max(edges)
    return Insensitivity(hi - lo, lo, hi, tol)
