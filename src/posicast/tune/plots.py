"""Gain-plane regions (seed 001 Fig. 5-6) and the Nyquist plot with the Ms circle (Fig. 7).

Each function draws and returns ``(fig, ax)``; matplotlib is imported only here.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from .. import _validate as v
from ..loops import nyquist_plot
from .regions import Region
from .result import TuningResult

__all__ = ["region_plot", "regions_plot", "tuning_nyquist_plot"]

_COLORS = ("tab:blue", "tab:red", "tab:green", "tab:orange", "tab:purple", "tab:brown", "tab:pink", "tab:gray")
_NAMES = {"kp": "$K_p$", "ki": "$K_i$", "kd": "$K_d$"}


def _axes(ax: Any, size: tuple[float, float] = (6.5, 5)) -> tuple[Any, Any]:
    v.axes(ax, "ax")
    import matplotlib.pyplot as plt

    if ax is None:
        fig, ax = plt.subplots(figsize=size)
        return fig, ax
    return ax.figure, ax


def _y_window(region: Region, extra: Sequence[float] = ()) -> np.ndarray:
    ext = region.extent()
    vals = [v for v in ((ext[2], ext[3]) if ext else ()) if math.isfinite(v)] + [v for v in extra if math.isfinite(v)]
    if not vals:
        vals = [0.0, 1.0]
    lo, hi = min(vals), max(vals)
    pad = 0.15 * max(hi - lo, 1e-9)
    return np.linspace(lo - pad, hi + pad, 500)


def _as_region(item: Any) -> tuple[Region, TuningResult | None]:
    if isinstance(item, TuningResult):
        return item.region, item
    if isinstance(item, Region):
        return item, None
    raise TypeError(f"item must be a TuningResult or a Region, got {type(item).__name__}")


def region_plot(item: TuningResult | Region, ax: Any = None, *, stability: bool = True,
                constraints: bool = True, label: str | None = None) -> tuple[Any, Any]:
    """The admissible region in the gain plane, with its parts.

    Draws the stable cells (light grey, one spectrum check per cell), each
    constraint's H-infinity boundary (thin line), the admissible set (filled),
    and the chosen controller (star).  Axes: the scanned gain horizontally, the
    maximised one vertically (for a PD, ``Kd`` and ``Kp``: seed 001 eq. 16).

    Parameters
    ----------
    item : TuningResult or Region
    ax : matplotlib Axes, optional
    stability, constraints : bool
        Draw the stability region / the per-constraint boundaries.
    label : str, optional
        Legend entry of the admissible set.

    Returns
    -------
    fig, ax
    """
    region, result = _as_region(item)
    if label is not None and not isinstance(label, str):
        raise TypeError(f"label must be a string or None, got {type(label).__name__}")
    fig, ax = _axes(ax)
    extra = [result.point[1]] if result is not None and result.point is not None else []
    y = _y_window(region, extra)
    X, Y = np.meshgrid(region.x, y, indexing="ij")
    big = 2.0 * float(np.ptp(y))
    if stability:
        st = region.field(y, "stable")
        if (st > 0).any():
            ax.contourf(X, Y, st, levels=[0.0, big], colors=["0.88"])
            ax.plot([], [], color="0.75", lw=6, label="stable (D-decomposition + spectrum)")
    if constraints:
        for ci, c in enumerate(region.constraints):
            h = region.field(y, "hinf", ci)
            if (h > 0).any() and (h < 0).any():
                ax.contour(X, Y, h, levels=[0.0], colors=[_COLORS[(ci + 3) % len(_COLORS)]],
                           linewidths=0.8, linestyles="--")
                ax.plot([], [], color=_COLORS[(ci + 3) % len(_COLORS)], lw=0.8, ls="--", label=c.label)
    adm = region.field(y, "admissible")
    if (adm > 0).any():
        ax.contourf(X, Y, adm, levels=[0.0, big], colors=["tab:blue"], alpha=0.45)
        ax.contour(X, Y, adm, levels=[0.0], colors=["tab:blue"], linewidths=1.2)
        ax.plot([], [], color="tab:blue", lw=6, alpha=0.45, label=label or "admissible")
    if result is not None and result.point is not None:
        ax.plot(*result.point, marker="*", ms=14, color="k", ls="none",
                label=f"max {_NAMES.get(region.y_name, region.y_name)}: ({result.point[0]:.4g}, {result.point[1]:.4g})")
    ax.set_xlabel(_NAMES.get(region.x_name, region.x_name))
    ax.set_ylabel(_NAMES.get(region.y_name, region.y_name))
    ax.grid(True, alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=8, loc="best")
    if region.empty:
        ax.set_title("no admissible controller in this range", fontsize=9)
    return fig, ax


def regions_plot(items: Sequence[TuningResult], labels: Sequence[str] | None = None, ax: Any = None,
                 title: str | None = None) -> tuple[Any, Any]:
    """Several designs' admissible regions in one plane (seed 001 Fig. 5-6: one boundary per shaper).

    Parameters
    ----------
    items : sequence of TuningResult
        Designs in the same gain plane (same controller family).
    labels : sequence of str, optional
    ax : matplotlib Axes, optional
    title : str, optional

    Returns
    -------
    fig, ax
    """
    items = v.sequence(items, "items", min_len=1)
    for it in items:
        if not isinstance(it, TuningResult):
            raise TypeError(f"items must be TuningResult objects, got {type(it).__name__}")
    v.labels(labels, "labels", len(items))
    if title is not None and not isinstance(title, str):
        raise TypeError(f"title must be a string or None, got {type(title).__name__}")
    planes = {(it.family.x, it.family.y) for it in items}
    if len(planes) != 1:
        raise ValueError(f"the designs lie in different gain planes: {sorted(planes)}")
    fig, ax = _axes(ax, (7, 5.5))
    for k, it in enumerate(items):
        col = _COLORS[k % len(_COLORS)]
        region = it.region
        extra = [it.point[1]] if it.point is not None else []
        y = _y_window(region, extra)
        X, Y = np.meshgrid(region.x, y, indexing="ij")
        adm = region.field(y, "admissible")
        lab = labels[k] if labels is not None else it.region.family.describe()
        if (adm > 0).any():
            ax.contour(X, Y, adm, levels=[0.0], colors=[col], linewidths=1.4)
        if it.point is not None:
            ax.plot(*it.point, marker="o", color=col, ls="none")
        ax.plot([], [], color=col, lw=1.4, marker="o", label=lab)
    x_name, y_name = planes.pop()
    ax.set_xlabel(_NAMES.get(x_name, x_name))
    ax.set_ylabel(_NAMES.get(y_name, y_name))
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    if title:
        ax.set_title(title, fontsize=10)
    return fig, ax


def tuning_nyquist_plot(items: TuningResult | Sequence[TuningResult], ax: Any = None,
                        labels: Sequence[str] | None = None, omega: Any = None,
                        zoom: float | bool | None = None) -> tuple[Any, Any]:
    """Nyquist curves of the chosen loops with the Ms circle (seed 001 Fig. 7).

    The circle drawn is the first design's ``Ms`` constraint; an active design's
    curve touches it.  ``zoom``: the window about ``-1``, see
    :func:`posicast.loops.nyquist_plot` (by default zoomed when the curve goes far).
    """
    seq = [items] if isinstance(items, TuningResult) else v.sequence(items, "items", min_len=1)
    for it in seq:
        if not isinstance(it, TuningResult):
            raise TypeError(f"items must be TuningResult objects, got {type(it).__name__}")
    v.axes(ax, "ax")
    if omega is not None:
        omega = v.strict_real_array(omega, "omega")
    loops = [it.loop for it in seq if it.loop is not None]
    if not loops:
        raise ValueError("items: no design to draw, every region is empty")
    v.labels(labels, "labels", len(loops))
    ms = next((c.gamma for c in seq[0].constraints if c.kind == "S" and c.weight is None), None)
    if omega is None:
        fd = seq[0].region.problem.fd
        omega = fd.omega[fd.omega > 0]
    return nyquist_plot(loops, omega=omega, ms=ms if ms is not None else None, ax=ax, labels=labels, zoom=zoom)
