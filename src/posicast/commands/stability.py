"""``posicast stability``: the certified verdict, spectral abscissa and rightmost roots of a system or loop.

The system is described by the options of :mod:`.systems`.  A loop's poles are the
roots of its characteristic quasi-polynomial less its removable points; a plant's are
its denominator's.  Exit status 0 whatever the verdict (the verdict is the result);
``--plot`` draws the poles in a rectangle around the rightmost ones.
"""

from __future__ import annotations

import argparse
import json
import math
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import _validate as v
from ..loops import spectrum_plot
from ..loops.plots import complex_plane
from ..spectra import rightmost, spectral_abscissa, stability
from ..spectra.systems import characteristic_of
from .figures import pyplot, save_atomic
from .progress import working
from .systems import System, system_of

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["run"]


def run(args: argparse.Namespace) -> int:
    """Print the verdict (text or ``--json``) and write the spectrum figure if asked."""
    n = v.integer_in_range(args.roots, "--roots", 1, 200)
    system = system_of(args)
    with working("certifying the spectrum", args.quiet):
        st = stability(system.target)
        sa = spectral_abscissa(system.target)
        ch = characteristic_of(system.target)
        if ch.quasi.is_polynomial:  # no more roots than its degree: do not search for more
            n = max(1, min(n, ch.quasi.degree - ch.removable.size))
        rm = rightmost(system.target, n)
        fig = _figure(system, rm, sa) if args.plot else None
    if fig is not None:  # everything computed: only now write
        save_atomic(fig, args.plot, "--plot")
    if args.json:
        print(json.dumps(_json(system, st, sa, rm), indent=2))
        return 0
    print(system.description)
    print(("STABLE" if st.stable else "MARGINAL" if st.marginal else "UNSTABLE") + f" ({st.kind}): {st.reason}")
    err = f" +- {sa.error:.3g}" if math.isfinite(sa.error) and sa.error > 0 else ""
    print(f"spectral abscissa: {float(sa):.10g}{err} ({sa.source})")
    if st.difference is not None:
        print(f"difference operator: abscissa C_D = {st.difference.abscissa:.6g}, strongly stable: "
              f"{st.difference.strongly_stable}")
    print(f"rightmost roots ({len(rm)}):")
    for z in rm:
        print(f"  {z.real:+.10g} {'+' if z.imag >= 0 else '-'} {abs(z.imag):.10g}j")
    if args.plot:
        print(f"wrote {args.plot}")
    return 0


def _number(x: Any) -> float | None:
    """JSON has no NaN or infinity: null."""
    return float(x) if x is not None and math.isfinite(float(x)) else None


def _pairs(z: np.ndarray) -> list[list[float]]:
    return [[float(r.real), float(r.imag)] for r in np.asarray(z, dtype=complex)]


def _json(system: System, st: Any, sa: Any, rm: np.ndarray) -> dict[str, Any]:
    return {
        "system": system.description, "loop": system.loop is not None,
        "architecture": None if system.loop is None else system.loop.architecture,
        "stable": bool(st.stable), "marginal": bool(st.marginal), "kind": st.kind, "reason": st.reason,
        "unstable_roots": _pairs(st.unstable_roots), "axis_error": float(st.axis_error),
        "spectral_abscissa": {"value": _number(sa), "error": _number(sa.error), "source": sa.source,
                              "marginal": bool(sa.marginal)},
        "difference_abscissa": None if st.difference is None else _number(st.difference.abscissa),
        "strongly_stable": None if st.difference is None else bool(st.difference.strongly_stable),
        "rightmost": _pairs(rm),
    }


def _region(rm: np.ndarray, sa: float) -> tuple[float, float, float, float]:
    """A rectangle around the rightmost roots and the imaginary axis."""
    pts = np.asarray(rm, dtype=complex)
    scale = max(1.0, float(np.max(np.abs(pts)))) if pts.size else 1.0
    re = np.append(pts.real, 0.0 if not math.isfinite(sa) else sa)
    pad = 0.15 * scale
    top = (float(np.max(np.abs(pts.imag))) if pts.size else 0.0) + pad
    return float(re.min()) - pad, max(float(re.max()), 0.0) + pad, -top, top


def _figure(system: System, rm: np.ndarray, sa: float) -> Figure:
    pyplot()  # the Agg backend before anything draws
    region = _region(rm, sa)
    if system.loop is not None:
        fig, ax = spectrum_plot(system.loop, region, labels=[system.loop.architecture])
    else:
        plt = pyplot()
        fig, ax = plt.subplots(figsize=(7, 6))
        p = system.target.poles(region).roots
        ax.plot(p.real, p.imag, "s", mfc="none", color="tab:blue", label="poles")
        complex_plane(ax, region)
    ax.set_title(f"{system.description}; spectral abscissa {float(sa):.4g}", fontsize=9)
    return fig
