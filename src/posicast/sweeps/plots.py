"""Matplotlib views of sweeps: a value over a 2-D grid, with optional boundary curves on top.

matplotlib is imported when a plot is drawn, never at import time.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from .. import _validate as v

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from .result import SweepResult

__all__ = ["value_map", "histogram"]


def _axes(ax: Axes | None) -> tuple[Figure, Axes]:
    import matplotlib.pyplot as plt

    if v.axes(ax) is None:
        fig, ax = plt.subplots(figsize=(6.0, 4.2))
        return fig, ax
    return ax.figure, ax


def _edges(x: np.ndarray) -> np.ndarray:
    """Cell edges around grid values (midpoints, half a step beyond the ends)."""
    if x.size == 1:
        return np.array([x[0] - 0.5, x[0] + 0.5])
    mid = 0.5 * (x[1:] + x[:-1])
    return np.concatenate([[x[0] - (mid[0] - x[0])], mid, [x[-1] + (x[-1] - mid[-1])]])


def value_map(result: SweepResult, value: str, ax: Axes | None = None,
              curves: Sequence[tuple[np.ndarray, np.ndarray]] = (), curve_label: str = "",
              **kwargs: Any) -> tuple[Figure, Axes]:
    """``result[value]`` over a 2-D numeric grid: first parameter on x, second on y.

    ``curves``: ``(x, y)`` point sets drawn on top (e.g. D-decomposition boundaries),
    labelled ``curve_label``.  Failed and missing points are drawn grey.
    """
    if result.space.kind != "grid" or len(result.shape) != 2:
        raise ValueError(f"value_map needs a 2-D grid sweep, got {result.space.kind} of shape {result.shape}")
    v.choice(value, "value", tuple(result.values))
    x, y = result.space.axes
    if x.dtype.kind == "U" or y.dtype.kind == "U":
        raise ValueError("value_map needs numeric grid axes")
    fig, ax = _axes(ax)
    z = np.asarray(result.values[value], dtype=float)
    z = np.where(result.ok, z, np.nan)
    kw = {"cmap": "RdYlGn" if result.values[value].dtype.kind == "b" else "viridis", "shading": "flat"}
    kw.update(kwargs)
    mesh = ax.pcolormesh(_edges(x), _edges(y), z.T, **kw)
    bad = ~result.ok
    if np.any(bad):
        xi, yi = np.nonzero(bad)
        ax.scatter(x[xi], y[yi], marker="x", color="0.4", s=12, label="failed or missing")
    if result.values[value].dtype.kind != "b":
        fig.colorbar(mesh, ax=ax, label=value)
    for k, (cx, cy) in enumerate(curves):
        ax.plot(cx, cy, ".", color="k", ms=2.5, label=curve_label if k == 0 and curve_label else None)
    ax.set_xlim(_edges(x)[[0, -1]])
    ax.set_ylim(_edges(y)[[0, -1]])
    ax.set_xlabel(result.space.names[0])
    ax.set_ylabel(result.space.names[1])
    if curve_label or np.any(bad):
        ax.legend(loc="upper right", fontsize=8)
    return fig, ax


def histogram(result: SweepResult, value: str, ax: Axes | None = None, bins: int = 30,
              **kwargs: Any) -> tuple[Figure, Axes]:
    """Histogram of a numeric value over the points that succeeded (Monte Carlo sweeps)."""
    v.choice(value, "value", tuple(result.values))
    bins = v.integer_in_range(bins, "bins", 1, 10**6)
    data = np.asarray(result.values[value], dtype=float)[result.ok]
    data = data[np.isfinite(data)]
    fig, ax = _axes(ax)
    ax.hist(data, bins=bins, **kwargs)
    ax.set_xlabel(value)
    ax.set_ylabel("points")
    if kwargs.get("label") is not None:
        ax.legend(fontsize=8)
    return fig, ax
