"""Report section for ``make demo`` (issue #19): a certified stability chart checked against the D-decomposition.

Seed 000's inverse-ZV loop (section V, eq. 25-27) over the controller gain and the shaper's delay
error, swept by :func:`posicast.sweep` (serially here: a coarse grid keeps the section near 1-2 s
of CPU; ``posicast sweep chart`` runs the fine one on Dask).
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from posicast.sweeps.charts import seed000_chart

from .html import Report

__all__ = ["sweep_section"]

GAINS = np.linspace(0.1, 1.5, 15)
DELAY_ERRORS = np.linspace(-0.6, 0.6, 5)


def sweep_section(report: Report) -> None:
    """Add the sweep section to a :class:`posicast_reports.html.Report`."""
    chart = seed000_chart(GAINS, DELAY_ERRORS, client="serial", progress=False)
    r = chart.result
    report.section("Sweeps: a certified stability chart against the D-decomposition (issue #19)")
    report.paragraph(
        "Seed 000 section V (eq. 25-27): G = 1/(s<sup>2</sup> + s), C = k (10 s + 10)/(0.01 s + 1), the ZV "
        "shaper of the load's mode (ω = 10 rad/s, ζ = 0.03) as 1/S in the feedback path, its delay "
        "mistuned to (1 + e) π/Ω. Each grid point is a certified stability verdict (every closed-loop root "
        "with Re s ≥ 0, with certified disks); the dots are the D-decomposition along the gain, computed by "
        "the tuner's boundary code (seed 001 section 3): the gains where a root crosses the imaginary axis, "
        "refined exactly in frequency. The verdict may change only across a dot; the table checks it row by "
        f"row. {r.space.n_points} points, {int(np.count_nonzero(r['stable']))} stable; "
        f"{len(chart.disagreements())} disagreements.")
    step = GAINS[1] - GAINS[0]
    rows = []
    for i, e in enumerate(DELAY_ERRORS):
        stable = r["stable"][:, i]
        edge = chart.stability_edges(e)
        last = GAINS[np.flatnonzero(stable)[-1]] if np.any(stable) else np.nan
        ok = len(edge) == 1 and 0 < edge[0] - last <= step
        rows.append([f"{e:+.2f}", f"{edge[0]:.6f}" if edge else "–", f"{last:.2f}", f"{last + step:.2f}",
                     "yes" if ok else "NO"])
    report.table(["delay error e", "boundary k (D-decomposition)", "last stable grid k", "first unstable grid k",
                  "agrees to the grid step"], rows)
    fig, _ = chart.plot(rows=np.linspace(DELAY_ERRORS[0], DELAY_ERRORS[-1], 13))
    report.figure(fig, "sweep_seed000_chart", "Certified stability over (gain k, delay error e): green stable, "
                  "red unstable; black dots: D-decomposition crossings on the chart's rows and on finer rows between them.")
    plt.close(fig)
