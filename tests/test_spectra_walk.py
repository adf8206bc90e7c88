"""The boundary walk and the search's shortcuts of issue #15 (speed), against analytic roots.

* :func:`~posicast.spectra.argument_principle.winding` cuts a failing segment into as many
  pieces as the certification test asks for: counts next to a root a hair inside or outside
  an edge are still exact.
* :meth:`~posicast.spectra.solver.Solver._split` counts one part and subtracts: both parts'
  counts equal independent certified counts.
* :func:`~posicast.spectra.candidates.grid_candidates` adds the local minima of ``|h|`` on
  elongated cells: a thin strip's roots are found on the first search.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from posicast import QuasiPolynomial
from posicast.spectra.argument_principle import OnBoundary, count_in_rect, winding
from posicast.spectra.candidates import grid_candidates
from posicast.spectra.evaluation import Evaluator
from posicast.spectra.solver import Solver
from posicast.sweeps.charts import seed000_loop

# ZV numerator 0.6 + 0.4 exp(-s pi) (seed 000 eq. 3): zeros at -ln(1.5)/pi + j (2k + 1)
ZV = QuasiPolynomial([[0.6], [0.4]], [0.0, math.pi])
ZV_RE = -math.log(1.5) / math.pi


def _ev(q: QuasiPolynomial) -> Evaluator:
    return Evaluator(q, 10**8, time.monotonic() + 60.0)


@pytest.mark.parametrize("gap", [1e-3, 1e-5, -1e-5, -1e-3])
def test_winding_next_to_a_root_on_the_edge_is_exact(gap):
    """Top edge at Im = 5 + gap: the zero at ZV_RE + 5j is inside for gap > 0, outside for gap < 0."""
    rect = (-1.0, 1.0, 0.0, 5.0 + gap)
    expected = 3 if gap > 0 else 2  # Im = 1, 3 (and 5)
    assert count_in_rect(_ev(ZV), rect, 0.5) == expected


def test_winding_raises_on_a_root_on_the_path():
    with pytest.raises(OnBoundary) as hit:
        winding(_ev(ZV), [complex(-1, 0), complex(1, 0), complex(1, 3), complex(-1, 3)], 0.5, 1e-9)
    assert abs(hit.value.point - complex(ZV_RE, 3.0)) < 1e-3


@pytest.mark.parametrize("rect", [(-1.0, 1.0, 0.0, 20.0), (-0.9, 0.3, 0.5, 9.5), (-5.0, 5.0, -4.0, 4.0)])
def test_split_counts_add_up_to_independent_counts(rect):
    ev = _ev(ZV)
    step = 0.25
    count = count_in_rect(ev, rect, step)
    kids, counts = Solver(ev, rect, step)._split(rect, step, count)
    analytic = [sum(1 for k in range(-50, 50) if k0[0] < ZV_RE < k0[1] and k0[2] < 2 * k + 1 < k0[3]) for k0 in kids]
    assert counts == analytic
    assert counts == [count_in_rect(_ev(ZV), k, step) for k in kids]


def test_thin_strip_roots_found_without_reconciliation():
    """Seed 000's inverse-ZV loop at gain 1.3, delay error +0.3: its roots right of the axis lie in a
    thin strip whose grid cells are 0.25 x 8.3; the minima of |h| find them on the first search
    (the cells' winding alone found none of them there: reconciliation had to split five times)."""
    q = seed000_loop(1.3, 0.3).characteristic
    ev = _ev(q)
    rect = (0.0, 1.0, -2.158, 2159.845)
    step = math.pi / (3.0 * float(q.delays[-1]))
    count = count_in_rect(ev, rect, step)
    assert count >= 1
    solver = Solver(ev, rect, step)
    solver.search(rect, step)
    assert solver.n_in(rect) == count
    # each found root is a root: independent evaluation with the exact quasi-polynomial
    for f in solver.found:
        assert abs(q(f.point)) <= 1e-9 * float(q.magnitude_scale(f.point))
    cand = grid_candidates(ev, rect, step)
    for f in solver.found:
        assert np.min(np.abs(cand - f.point)) < 2 * step


def test_evaluation_caches_are_not_pickled_and_give_the_same_numbers():
    """QuasiPolynomial and TransferFunction keep evaluation constants (issue #15); a pickle holds only
    num/den (coefficients and delays), and the copy evaluates to the same numbers as the closed form."""
    import pickle

    from posicast import TransferFunction

    H = TransferFunction(ZV, QuasiPolynomial([[100.0, 0.6, 1.0]]))  # ZV / (s^2 + 0.6 s + 100)
    s = np.array([0.0, 0.3j, 10j, -0.3 + 9.99j, 2.0 - 50j])
    before = H(s)
    H2 = pickle.loads(pickle.dumps(H))
    assert H2._nd_plan is None and H2._taylor_cache == {} and H2.num._plan is None
    assert np.array_equal(H2(s), before)
    closed = (0.6 + 0.4 * np.exp(-s * math.pi)) / (s**2 + 0.6 * s + 100.0)
    np.testing.assert_allclose(before, closed, rtol=1e-14, atol=0)


def test_roots_on_one_vertical_line_come_in_increasing_imaginary_order():
    """The ZV zeros ZV_RE + j (2k + 1) share their real part (to rounding): they are listed by Im s,
    not by the sign of each one's rounding error in Re s."""
    from posicast import roots

    r = roots(ZV, (-2.0, 2.0, 0.0, 100.0))
    np.testing.assert_allclose(r.roots, ZV_RE + 1j * np.arange(1, 100, 2), rtol=0, atol=1e-9)
