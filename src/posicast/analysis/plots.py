"""Matplotlib views of shapers: sensitivity curves and impulse responses.

Each function draws and returns ``(fig, ax)``; matplotlib is imported only here.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from ..shapers.base import Shaper
from .vibration import SensitivityCurve, sensitivity_curve

__all__ = ["sensitivity_plot", "impulse_plot"]


def _axes(ax: Any) -> tuple[Any, Any]:
    import matplotlib.pyplot as plt

    if ax is None:
        fig, ax = plt.subplots(figsize=(7, 4))
    else:
        fig = ax.figure
    return fig, ax


def sensitivity_plot(
    items: Sequence[Shaper | SensitivityCurve],
    ax: Any = None,
    vtol: float | None = 0.05,
    reference: str = "end",
    ratio: Any = None,
    percent: bool = True,
    labels: Sequence[str] | None = None,
) -> tuple[Any, Any]:
    """Residual vibration against ``omega / omega_model`` for several shapers (seed 004 Fig. 8-11, 14-15).

    Parameters
    ----------
    items : sequence of Shaper or SensitivityCurve
    ax : matplotlib Axes, optional
    vtol : float or None
        Draw the tolerance line.
    reference, ratio
        Passed to :func:`sensitivity_curve` for Shaper items.
    percent : bool
        Vertical axis in percent.
    labels : sequence of str, optional
        Legend entries (default: the shapers' names).

    Returns
    -------
    fig, ax
    """
    fig, ax = _axes(ax)
    scale = 100.0 if percent else 1.0
    if labels is not None and len(labels) != len(items):
        raise ValueError(f"labels has {len(labels)} entries for {len(items)} items")
    for i, it in enumerate(items):
        curve = it if isinstance(it, SensitivityCurve) else sensitivity_curve(it, ratio=ratio, reference=reference)
        ax.plot(curve.ratio, scale * curve.vibration, label=curve.name if labels is None else labels[i])
    if vtol is not None:
        ax.axhline(scale * vtol, color="k", ls="--", lw=0.8, label=f"Vtol = {scale * vtol:g}{'%' if percent else ''}")
    ax.set_xlabel(r"$\omega / \omega_{model}$")
    ax.set_ylabel("residual vibration" + (" [%]" if percent else ""))
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return fig, ax


def impulse_plot(shaper: Shaper, ax: Any = None, n_points: int = 1000) -> tuple[Any, Any]:
    """Impulses as stems and distributed densities as curves, on one time axis."""
    fig, ax = _axes(ax)
    t, a = shaper.impulses
    if t.size:
        ax.stem(t, a, basefmt=" ", label="impulses")
    if shaper.distributed:
        T = shaper.duration
        tt = np.linspace(0, T, n_points)
        ax.plot(tt, shaper.density(tt), label="distributed density [1/s]")
    ax.set_xlabel("t [s]")
    ax.set_title(shaper.name)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return fig, ax
