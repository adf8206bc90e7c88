"""The exact optimum's faster helpers give the numbers of the plain ones (issue #15, wave 6).

:class:`~posicast.tune.refine.RootsOver` (a branch tracker's root over its window),
:func:`~posicast.tune.refine.exact_ends` (several ends zoomed in together) and
:func:`~posicast.tune.branches.branch_values` must be bit-for-bit what
:func:`~posicast.tune.refine.roots_at`, :func:`~posicast.tune.refine.exact_end` and
:func:`~posicast.tune.branches.branch_value` give one at a time: the designs depend on it.
"""

from __future__ import annotations

import numpy as np
import pytest

from posicast import cases
from posicast.shapers import design
from posicast.tune import tune_pd
from posicast.tune.branches import BranchTracker, active_branches, branch_value, branch_values
from posicast.tune.refine import RootsOver, exact_end, exact_ends, roots_at


@pytest.fixture(scope="module")
def solved():
    crane = cases.ALL["gantry_crane"]
    r = tune_pd(crane.G, design("dezv", crane.mode), "control_action", ms=1.2, F=crane.F, n_lines=41)
    cols = r.region.problem.columns
    kx, ky = r.point
    return cols, float(kx), float(ky)


def _branches(cols, kx, ky):
    br = active_branches(cols, kx, ky * (1 + 1e-9), -np.inf, band=2.0)
    assert br, "the design's top is bounded by a branch"
    return br


def test_roots_over_a_window_equal_roots_at(solved):
    cols, kx, ky = solved
    col = _branches(cols, kx, ky)[0].column
    w = np.linspace(cols.omega[max(col - 6, 0)], cols.omega[min(col + 6, cols.n_grid - 1)], 401)
    vals = cols.data.values(w)
    for ci in range(cols.n_constraints):
        for root in (0, 1, 2):
            fast = RootsOver(cols, vals, ci, root)
            for x in (kx, 0.5 * kx, -kx, 0.0, 3.7 * kx):
                assert np.array_equal(fast(x), roots_at(cols, x, vals, ci, root), equal_nan=True)


def test_ends_zoomed_together_equal_each_alone(solved):
    cols, kx, ky = solved
    ends = _branches(cols, kx, ky)
    for x in (kx, 1.01 * kx):
        for upper in (True, False):
            cols.cache.pop("exact_ends", None)  # no memo: computed afresh each time
            together = exact_ends(cols, x, ends, upper)
            alone = []
            for e in ends:
                cols.cache.pop("exact_ends", None)
                alone.append(exact_end(cols, x, e, upper))
            assert together == alone
    cols.cache.pop("exact_ends", None)
    together = branch_values(cols, kx, ends, reach=1)
    alone = []
    for e in ends:
        cols.cache.pop("exact_ends", None)
        alone.append(branch_value(cols, kx, e, reach=1))
    assert together == alone


def test_tracker_follows_the_exact_branch(solved):
    cols, kx, ky = solved
    br = _branches(cols, kx, ky)[0]
    t = BranchTracker(cols, br)
    y_exact = branch_value(cols, kx, br)[0]
    assert abs(t(kx) - y_exact) <= 1e-6 * abs(y_exact)


def test_polish_first_round_evaluates_each_column_once_with_the_same_numbers(solved):
    from posicast.tune.refine import _first_round

    cols, kx, ky = solved
    col = np.array([5, 700, 5, 5, 1200, 700, 3, 1200])
    lo, hi = cols.omega[col - 1], cols.omega[col + 1]
    w = lo[:, None] + (hi - lo)[:, None] * np.linspace(0.0, 1.0, 9)[None, :]
    once, every = _first_round(cols, col, w), cols.data.values(w.ravel())
    assert once.keys() == every.keys()
    assert all(np.array_equal(once[k], every[k]) for k in every)
