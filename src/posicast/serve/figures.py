"""The designer's plots: matplotlib figures rendered on the server as SVG text for the page.

Figures are :class:`matplotlib.figure.Figure` objects (no pyplot state, no GUI); the text
stays text in the SVG (``svg.fonttype = "none"``), so the page stays small and searchable.
One lock serialises drawing: the server computes in a thread pool and matplotlib's global
state (font cache, rcParams) is not meant for concurrent drawing.
"""

from __future__ import annotations

import io
import threading
from contextlib import contextmanager
from typing import Any, Iterator

import matplotlib
from matplotlib.figure import Figure

__all__ = ["svg_figure", "COLOURS"]

_LOCK = threading.RLock()
COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#17becf", "#7f7f7f")
_STYLE = {"svg.fonttype": "none", "font.size": 10, "axes.titlesize": 10, "axes.labelsize": 10,
          "legend.fontsize": 8, "axes.grid": True, "grid.alpha": 0.3, "svg.hashsalt": "posicast"}


@contextmanager
def svg_figure(out: dict[str, Any], key: str, width: float = 6.4, height: float = 3.4,
               ncols: int = 1) -> Iterator[tuple[Figure, Any]]:
    """A figure of ``ncols`` axes; on leaving the block its SVG text is stored in ``out[key]``.

    >>> out = {}
    >>> with svg_figure(out, "demo") as (fig, ax):
    ...     _ = ax.plot([0, 1], [0, 1])
    >>> out["demo"].lstrip().startswith("<?xml")
    True
    """
    with _LOCK, matplotlib.rc_context(_STYLE):
        fig = Figure(figsize=(width, height), layout="constrained")
        ax = fig.subplots(1, ncols)
        yield fig, ax
        buf = io.StringIO()
        fig.savefig(buf, format="svg", metadata={"Date": None})
        out[key] = buf.getvalue()
