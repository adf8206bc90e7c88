"""Issue #18, acceptance 6: the whole QFT design over seed 003's 27 plants (bounds, shaping, verification).

No Python package does QFT (MATLAB's QFT toolbox shapes the loop by hand), so the comparator is
the issue's budget, 10 s, and the check of the paper's own printed design on the same dense grid.
Prints the medians side by side and the ratio.  ``--quick``: one repetition.
"""

from __future__ import annotations

import statistics
import sys
import time

import numpy as np

from posicast import cases
from posicast.qft import PlantSet, nichols_bounds, qft_design, verify
from posicast.qft.specs import dense_grid

TARGET = 10.0


def _timed(fn, reps):
    times, out = [], None
    for _ in range(reps):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def main(argv: list[str]) -> int:
    reps = 1 if "--quick" in argv else 3
    c = cases.ALL["two_mass"]
    Fm, G_paper = c.extras["F_m"], c.extras["G_qft"]
    freqs = np.array([0.05, 0.1, 0.5, 1.0, 2.0, 3.2, 5.0, 20.0])

    def whole():
        ps = PlantSet.two_mass()
        nichols_bounds(ps, freqs, Fm, None, 1.413, 0.1)  # the bounds of the Nichols chart
        return qft_design(ps, Fm, stability=1.413, matching=0.1, frequencies=freqs)  # shaping + verification

    t_design, r = _timed(whole, reps)
    ps = PlantSet.two_mass()
    t_bounds, _ = _timed(lambda: nichols_bounds(ps, freqs, Fm, None, 1.413, 0.1), reps)
    t_check, chk = _timed(lambda: verify(ps, G_paper, Fm, Fm, 1.413, 0.1, dense_grid(1e-3, 1e4, 1000)), reps)
    print(f"{'task':52s} {'median [s]':>10s}")
    print(f"{'posicast qft_design, 27 plants (bounds+shaping+check)':52s} {t_design:10.3f}")
    print(f"{'  of which the Nichols bounds (8 freq. x 201 x 181)':52s} {t_bounds:10.3f}")
    print(f"{'budget of issue #18':52s} {TARGET:10.3f}   ratio {t_design / TARGET:.2f}")
    print(f"{'check of the printed G alone (dense grid, certified)':52s} {t_check:10.3f}   ratio "
          f"{t_design / t_check:.1f}")
    print(f"design feasible: {r.feasible}, margins {dict((k, round(x, 3)) for k, x in r.margins.items())}, "
          f"HF gain {r.high_frequency_gain:.4g}; printed G feasible: {chk.ok} (violated {chk.violated})")
    return 0 if t_design < TARGET and r.feasible else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
