"""Matplotlib views of shapers: sensitivity curves and impulse responses.

Each function draws and returns ``(fig, ax)``; matplotlib is imported only here.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from .. import _validate as v
from ..shapers.base import Shaper
from .vibration import SensitivityCurve, _check_shaper, sensitivity_curve

__all__ = ["sensitivity_plot", "impulse_plot"]


def _axes(ax: Any) -> tuple[Any, Any]:
    import matplotlib.pyplot as plt
    from matplotlib.axes import Axes

    if ax is None:
        fig, ax = plt.subplots(figsize=(7, 4))
    elif isinstance(ax, Axes):
        fig = ax.figure
    else:
        raise TypeError(f"ax must be a matplotlib Axes or None, got {type(ax).__name__}")
    return fig, ax


def _plot_items(items: Any, labels: Any) -> list[Shaper | SensitivityCurve]:
    """``items`` as a non-empty list of shapers/curves (one is accepted alone), ``labels`` one string per item."""
    if isinstance(items, (Shaper, SensitivityCurve)):
        items = [items]
    if not isinstance(items, (list, tuple)) or not all(isinstance(it, (Shaper, SensitivityCurve)) for it in items):
        raise TypeError("items must be a sequence of posicast Shaper or SensitivityCurve")
    if not items:
        raise ValueError("items must not be empty")
    if labels is not None:
        if isinstance(labels, str) or not isinstance(labels, (list, tuple)) or not all(
                isinstance(lab, str) for lab in labels):
            raise TypeError("labels must be a sequence of strings")
        if len(labels) != len(items):
            raise ValueError(f"labels has {len(labels)} entries for {len(items)} items")
    return list(items)


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

    Raises
    ------
    TypeError, ValueError
        ``items`` not Shapers/SensitivityCurves (a single one is accepted) or empty,
        ``vtol`` not None or in (0, 1e6), ``labels`` not strings or of the wrong
        length, ``ax`` not an Axes; ``ratio``/``reference`` as in :func:`sensitivity_curve`.

    Examples
    --------
    >>> from posicast import Mode, design
    >>> fig, ax = sensitivity_plot([design("zv", Mode(1.0, 0.0))], ratio=[0.5, 1.0, 1.5])
    >>> len(ax.lines)                       # the curve and the tolerance line
    2
    """
    items = _plot_items(items, labels)
    if vtol is not None:
        vtol = v.real_in_range(vtol, "vtol", 0.0, 1e6, lo_open=True, hi_open=True)
    v.instance_of(percent, (bool, np.bool_), "percent", "True or False")
    curves = [it if isinstance(it, SensitivityCurve) else sensitivity_curve(it, ratio=ratio, reference=reference)
              for it in items]
    fig, ax = _axes(ax)
    scale = 100.0 if percent else 1.0
    for i, curve in enumerate(curves):
        ax.plot(curve.ratio, scale * curve.vibration, label=curve.name if labels is None else labels[i])
    if vtol is not None:
        ax.axhline(scale * vtol, color="k", ls="--", lw=0.8, label=f"Vtol = {scale * vtol:g}{'%' if percent else ''}")
    ax.set_xlabel(r"$\omega / \omega_{model}$")
    ax.set_ylabel("residual vibration" + (" [%]" if percent else ""))
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return fig, ax


@v.renamed_keywords(shaper="S")
def impulse_plot(S: Shaper, ax: Any = None, n_points: int = 1000) -> tuple[Any, Any]:
    """Impulses as stems, distributed densities and an IIR part's impulse response as curves.

    Parameters
    ----------
    S : Shaper
    ax : matplotlib Axes, optional
    n_points : int
        Samples of each curve (distributed density on ``[0, duration]``; the
        impulse response of a delay-free IIR part over ``8 /`` its slowest decay
        rate), an integer in ``[2, 1000000]``.  Lumped impulses are drawn as stems
        at their exact times whatever ``n_points``.

    Returns
    -------
    fig, ax

    Raises
    ------
    TypeError
        ``S`` not a Shaper, ``n_points`` not an integer, ``ax`` not an Axes.
    ValueError
        ``n_points`` outside ``[2, 1000000]``.

    Examples
    --------
    >>> from posicast import Mode, design
    >>> fig, ax = impulse_plot(design("dezv", Mode(5.49, 0.008)), n_points=50)
    >>> len(ax.lines[-1].get_xdata())
    50
    """
    S = _check_shaper(S)
    n_points = v.integer_in_range(n_points, "n_points", 2, 1_000_000)
    fig, ax = _axes(ax)
    t, a = S.impulses
    if t.size:
        ax.stem(t, a, basefmt=" ", label="impulses")
    if S.distributed:
        T = max(p.end for p in S.distributed)
        tt = np.linspace(0, T, n_points)
        ax.plot(tt, S.density(tt), label="distributed density [1/s]")
    if S.continuous is not None:
        cont = S.continuous
        if cont.is_rational():
            from scipy import signal

            num = cont.num.coeffs[0][::-1]
            den = cont.den.coeffs[0][::-1]
            poles = np.roots(den)
            rate = float(np.min(-poles.real)) if poles.size else 1.0
            horizon = 8.0 / rate if rate > 0 else 8.0
            tt = np.linspace(0.0, horizon, n_points)
            _, y = signal.impulse((num, den), T=tt)
            ax.plot(tt, y, label="IIR part: impulse response [1/s]")
        else:
            ax.text(0.5, 0.9, "IIR part with delays: not drawn", transform=ax.transAxes, ha="center")
    ax.set_xlabel("t [s]")
    ax.set_title(S.name)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return fig, ax
