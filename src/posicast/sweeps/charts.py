"""Certified stability charts of a loop over two parameters, checked against the D-decomposition.

A chart sweeps a loop's certified stability verdict (:func:`posicast.stability`:
every root with ``Re s >= 0`` found, with certified disks) over a grid of two
parameters, one of them the controller gain ``k`` (``C = k C_1``).  Along the
gain, the closed loop's characteristic ``D_C D_P + k N_C N_P`` is affine in ``k``,
so its D-decomposition boundaries (seed 001 section 3; the curves the tuner
computes, :mod:`posicast.tune.boundaries`) are where a root crosses the imaginary
axis: the verdict may change only across them.  :meth:`StabilityChart.disagreements`
checks exactly that, row by row, to the grid resolution.

The ready-made chart is seed 000's inverse-ZV loop (section V, eq. 25-27:
``G = 1 / (s^2 + s)``, ``C = (10 s + 10) / (0.01 s + 1)``, ZV for the load's mode
``omega = 10``, ``zeta = 0.03`` placed as ``1 / S`` in the feedback path) over the
gain ``k`` and the relative error ``e`` of the shaper's delay
(``S = A_0 + A_1 exp(-s (1 + e) pi / Omega)``, seed 000 eq. 4).

>>> chart = seed000_chart([0.5, 1.0], [0.0], client="serial")
>>> chart.result["stable"].tolist(), [round(k, 4) for k in chart.stability_edges(0.0)]
([[True], [False]], [0.7948])
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, NamedTuple, Sequence

import numpy as np

from .. import _validate as v
from ..cases import ALL as CASES
from ..core.quasipoly import QuasiPolynomial
from ..loops import Loop, inverse_shaper
from ..shapers import Shaper, design
from ..spectra import stability
from ..tune.boundaries import complex_breaks, complex_curve, crossing_frequency, infinite_boundary, real_boundary
from ..tune.family import ControllerFamily
from ..tune.frequency import FrequencyData, columns_of
from .engine import sweep
from .plots import value_map
from .result import SweepResult
from .space import check_arguments

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["GainBreaks", "gain_breaks", "StabilityChart", "stability_chart", "stability_point", "seed000_loop",
           "seed000_chart"]


# ---------------------------------------------------------------------- D-decomposition along the gain
class GainBreaks(NamedTuple):
    """Where ``k C_1`` puts a closed-loop root on the imaginary axis, for gains in a window.

    ``gain`` sorted; ``kind`` ``'c'`` (a pair crosses at ``+-j omega``), ``'r'`` (a real root at
    0) or ``'i'`` (roots from infinity: the neutral difference operator's strong stability);
    ``omega`` the crossing frequency (NaN for ``'r'``, ``'i'``).
    """

    gain: np.ndarray
    kind: np.ndarray
    omega: np.ndarray


def _poly(tf_part: Any) -> np.ndarray:
    return np.atleast_1d(np.asarray(tf_part, dtype=float))


def gain_breaks(loop: Loop, window: tuple[float, float]) -> GainBreaks:
    """The D-decomposition along the controller gain of ``loop`` (``C -> k C``), for ``k`` in ``window``.

    Uses the tuner's boundaries (seed 001 section 3): the complex-root boundary
    ``Im(1 + k L_1(j omega)) = 0`` on the tuner's refined frequency grid, each crossing
    refined exactly in frequency (:func:`~posicast.tune.boundaries.crossing_frequency`),
    the real-root boundary at ``s = 0`` and the infinite-root (strong stability) boundary.
    ``loop.C`` must be rational (no delay).
    """
    lo, hi = (v.finite_real(x, "window") for x in v.pair(window, "window"))
    if not lo < hi:
        raise ValueError(f"window must be (low, high) with low < high, got {window!r}")
    try:
        C1 = loop.C.to_scipy()
    except ValueError as exc:
        raise ValueError(f"gain_breaks needs a rational controller (no delay): {exc}") from None
    num, den = _poly(C1.num), _poly(C1.den)
    n = max(num.size, den.size)
    num, den = np.pad(num, (n - num.size, 0)), np.pad(den, (n - den.size, 0))
    # k C_1 as the tuner's affine family on the scan line kx = 0 (nx = ny: the line's direction only)
    family = ControllerFamily("gain", "kd", "kp", dC=den, n0=np.zeros(1), nx=num, ny=num)
    loop0 = Loop(loop.architecture, G=loop.G, C=1.0, F=loop.F, S=loop.S)
    P = loop0.plant_gain
    dC = QuasiPolynomial.from_poly(np.trim_zeros(den, "f"))
    nC = QuasiPolynomial.from_poly(np.trim_zeros(num, "f"))
    terms = (dC * P.den, nC * P.num, nC * P.num)
    m0 = int(np.count_nonzero(loop0.cancelled == 0))
    fd = FrequencyData(loop0, family, (), scale=(1.0, max(abs(lo), abs(hi))), limit_for_delays=True)
    cols = columns_of(fd)
    cb = complex_breaks(cols, complex_curve(cols), np.zeros(1))[0]
    gains, kinds, omegas = [], [], []
    for y, col, err in zip(cb.ky, cb.columns if cb.columns is not None else np.full(cb.ky.size, -1), cb.error):
        if not lo - err <= y <= hi + err:  # the grid's bracket lies outside the window: no refinement
            continue
        w, y_exact = crossing_frequency(cols, 0.0, int(col)) if col >= 0 else (math.nan, math.nan)
        y = y_exact if math.isfinite(y_exact) else y
        if lo <= y <= hi:
            gains.append(y), kinds.append("c"), omegas.append(w)
    y0 = real_boundary(terms, m0).break_at(0.0)
    extra = ([(y0, "r")] if y0 is not None else []) + [(y, "i") for y in infinite_boundary(terms).breaks(0.0)]
    for y, kind in extra:
        if lo <= y <= hi:
            gains.append(float(y) + 0.0), kinds.append(kind), omegas.append(math.nan)
    order = np.argsort(gains, kind="stable")
    return GainBreaks(np.asarray(gains, dtype=float)[order], np.asarray(kinds, dtype=str)[order],
                      np.asarray(omegas, dtype=float)[order])


# ---------------------------------------------------------------------- the chart
def stability_point(loop: Callable[..., Loop], **point: Any) -> dict[str, Any]:
    """The certified verdict of ``loop(**point)``: ``stable``, ``marginal`` and ``unstable_roots`` (count)."""
    st = stability(loop(**point))
    return {"stable": bool(st.stable), "marginal": bool(st.marginal), "unstable_roots": int(st.unstable_roots.size)}


@dataclass(frozen=True, eq=False)
class StabilityChart:
    """A certified stability chart over (gain, other parameter) and its D-decomposition.

    Attributes
    ----------
    result : SweepResult
        The sweep: values ``stable``, ``marginal``, ``unstable_roots`` on the grid.
    gain : str
        The name of the gain parameter (the first axis).
    breaks : tuple of GainBreaks
        One per value of the second parameter (the rows), for gains within the chart.
    """

    result: SweepResult
    gain: str
    breaks: tuple[GainBreaks, ...]
    loop: Callable[..., Loop] | None = None

    def curves(self, rows: Sequence[float] | None = None) -> list[tuple[np.ndarray, np.ndarray]]:
        """D-decomposition points ``(gains, row values)`` on the chart's rows, or on ``rows`` (finer rows
        draw the curves between the chart's; each row costs one frequency-grid computation)."""
        names = self.result.space.names
        gains, other = self.result.space.axes
        if rows is None:
            return [(br.gain, np.full(br.gain.size, y)) for br, y in zip(self.breaks, other)]
        if self.loop is None:
            raise ValueError("this chart has no loop to compute more rows from")
        window = (float(gains.min()), float(gains.max()))
        out = []
        for y in v.strict_real_array(rows, "rows"):
            br = gain_breaks(self.loop(**{names[0]: 1.0, names[1]: float(y)}), window)
            out.append((br.gain, np.full(br.gain.size, y)))
        return out

    def stability_edges(self, row_value: float) -> list[float]:
        """The D-decomposition gains of one row where the chart's verdict changes (the stability boundary)."""
        other = self.result.space.axes[1]
        i = int(np.argmin(np.abs(other - row_value)))
        gains = self.result.space.axes[0]
        stable = self.result.values["stable"][:, i]
        out = []
        for j in range(gains.size - 1):
            if self.result.ok[j, i] and self.result.ok[j + 1, i] and stable[j] != stable[j + 1]:
                b = self.breaks[i].gain
                inside = b[(b >= gains[j]) & (b <= gains[j + 1])]
                out += [float(x) for x in inside[:1]]
        return out

    def disagreements(self) -> list[tuple[float, float, float]]:
        """``(row value, k_j, k_j+1)`` where the verdict changes between two neighbouring gains with no
        D-decomposition boundary between them (empty: the chart agrees to the grid resolution)."""
        gains, other = self.result.space.axes
        stable = self.result.values["stable"]
        bad = []
        for i in range(other.size):
            b = self.breaks[i].gain
            for j in range(gains.size - 1):
                if not (self.result.ok[j, i] and self.result.ok[j + 1, i]) or stable[j, i] == stable[j + 1, i]:
                    continue
                if not np.any((b >= gains[j]) & (b <= gains[j + 1])):
                    bad.append((float(other[i]), float(gains[j]), float(gains[j + 1])))
        return bad

    def plot(self, ax: Axes | None = None, rows: Sequence[float] | None = None,
             **kwargs: Any) -> tuple[Figure, Axes]:
        """The verdict (green stable, red unstable) with the D-decomposition crossings as black dots
        (on the chart's rows and on ``rows``, see :meth:`curves`)."""
        curves = self.curves() + (self.curves(rows) if rows is not None else [])
        fig, ax = value_map(self.result, "stable", ax, curves=curves, curve_label="D-decomposition", **kwargs)
        ax.set_title("certified stability; D-decomposition along the gain")
        return fig, ax


def stability_chart(loop: Callable[..., Loop], parameters: dict[str, Sequence[float]], *, gain: str | None = None,
                    **sweep_kwargs: Any) -> StabilityChart:
    """Sweep the certified stability of ``loop(**point)`` over a 2-D grid; D-decomposition per row.

    Parameters
    ----------
    loop : callable
        ``loop(gain=..., other=...)`` returns a :class:`~posicast.Loop` whose controller is
        ``gain`` times a fixed rational ``C_1(other)`` (picklable: module-level, or a partial).
    parameters : dict
        Two grid axes, the gain first.
    gain : str, optional
        The gain's name (default: the first parameter).
    **sweep_kwargs
        :func:`posicast.sweep`'s options (``store``, ``client``, ``workers``, ``batch_size``, ...).
    """
    if not isinstance(parameters, dict) or len(parameters) != 2:
        raise ValueError("parameters must be a dict of exactly two grid axes, the gain first")
    names = list(parameters)
    gain = names[0] if gain is None else gain
    if gain != names[0]:
        raise ValueError(f"gain must be the first parameter ({names[0]!r}), got {gain!r}")
    check_arguments(loop, tuple(names))
    _check_gain_scales(loop, gain, names[1], parameters[names[1]])
    result = sweep(functools.partial(stability_point, loop), parameters, **sweep_kwargs)
    gains, other = result.space.axes
    window = (float(gains.min()), float(gains.max()))
    breaks = tuple(gain_breaks(loop(**{gain: 1.0, names[1]: float(y)}), window) for y in other)
    return StabilityChart(result, gain, breaks, loop)


def _check_gain_scales(loop: Callable[..., Loop], gain: str, other: str, values: Any) -> None:
    """``loop(gain=k).C`` must be ``k`` times ``loop(gain=1).C`` (the D-decomposition along the gain assumes it)."""
    y = float(np.asarray(values, dtype=float).ravel()[0]) if np.size(values) else 0.0
    c1, c2 = (loop(**{gain: k, other: y}).C for k in (1.0, 2.0))
    s = 0.7j + 0.3  # a generic point (no pole or zero of a controller of the seeds there)
    a, b = complex(c1(s)), complex(c2(s))
    if not (np.isfinite(a) and abs(b - 2.0 * a) <= 1e-9 * max(abs(b), 1e-300)):
        raise ValueError(f"loop({gain}=k, ...).C must be k times a fixed controller (C(s) at k = 2 is "
                         f"{b:.6g}, twice k = 1 gives {2 * a:.6g}): the D-decomposition runs along the gain")


# ---------------------------------------------------------------------- seed 000
_SEED000 = CASES["simulation_example"]
_ZV = design("zv", _SEED000.mode)


def seed000_loop(gain: float = 1.0, delay_error: float = 0.0) -> Loop:
    """Seed 000's inverse-ZV loop (section V, eq. 25-27) with ``C = gain C_27`` and the ZV's delay
    ``(1 + delay_error) pi / Omega`` (seed 000 eq. 4); ``delay_error`` in (-1, 10].

    >>> seed000_loop(0.5).characteristic.kind
    'neutral'
    """
    g = v.finite_real(gain, "gain")
    e = v.real_in_range(delay_error, "delay_error", -1.0, 10.0, lo_open=True)
    S = Shaper(_ZV.times * (1.0 + e), _ZV.amplitudes, name="zv", modes=_ZV.modes,
               params={"delay_error": e})
    return inverse_shaper(G=_SEED000.G, F=_SEED000.F, C=g * _SEED000.C, S=S)


def seed000_chart(gain: Sequence[float], delay_error: Sequence[float], **sweep_kwargs: Any) -> StabilityChart:
    """:func:`stability_chart` of :func:`seed000_loop` over ``gain`` x ``delay_error``."""
    return stability_chart(seed000_loop, {"gain": gain, "delay_error": delay_error}, **sweep_kwargs)
