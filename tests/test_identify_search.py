"""Issue #15 (wave 5): the output-error search without scipy's per-call overhead gives scipy's answers.

``identification/trust_region.py`` follows scipy's trust-region reflective method step by step; the
reference here is ``scipy.optimize.least_squares(method="trf")`` itself, run on the same problems."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import optimize

import posicast
from posicast.identification import output_error
from posicast.identification.output_error import OEModel
from posicast.identification.trust_region import trust_region_reflective
from posicast.testing import synthetic

TRUE = posicast.Mode.from_hz(28.0, 0.05)  # seed 002 section 3.2
TOL = {"ftol": 1e-12, "xtol": 1e-10, "gtol": 1e-12}


def _scipy(fun, jac, x0, lb, ub, max_nfev):
    return optimize.least_squares(fun, x0, jac=jac, bounds=(lb, ub), method="trf", x_scale="jac",
                                  max_nfev=max_nfev, **TOL)


@pytest.mark.parametrize("inp, n, noise, seed", [("random_binary", 2000, 0.05, 0), ("step", 20, 0.01, 4),
                                                 ("chirp", 2000, 0.05, 1), ("ramp", 20, 0.01, 13)])
def test_the_search_takes_scipys_steps_on_the_oe_residual(inp, n, noise, seed):
    """Same start, same residual: the same optimum (to the search's tolerance) after as many evaluations."""
    d = synthetic(TRUE, inp, n=n, noise=noise, seed=seed)
    h = 1.0 / d.sample_rate
    model = OEModel(d.u, d.y, h, 1, feedthrough=False, offset=False, initial_state=False)
    lo, hi = output_error._bounds(1, h, 2 * math.pi * 0.5 / (n * h))
    x0 = np.clip(np.array([math.log(TRUE.omega * 1.1), 0.1]), lo + 1e-9, hi - 1e-9)
    ours = trust_region_reflective(model.residual, model.jacobian, x0, lo, hi, max_nfev=400, **TOL)
    ref = _scipy(model.residual, model.jacobian, x0, lo, hi, 400)
    assert np.max(np.abs(ours.x / ref.x - 1)) < 1e-9
    assert abs(ours.cost / ref.cost - 1) < 1e-12
    assert ours.nfev == ref.nfev
    assert np.array_equal(ours.fun, model.residual(ours.x))


def test_an_optimum_on_a_bound_is_scipys():
    """Rosenbrock with its minimum (1, 1) cut off by x1 >= 1.5: the reflective steps end on the bound, one ulp
    inside it, where scipy ends (scipy's documentation: x = (1.22437075, 1.5))."""
    fun = lambda x: np.array([10 * (x[1] - x[0] ** 2), 1 - x[0]])  # noqa: E731
    jac = lambda x: np.array([[-20 * x[0], 10], [-1, 0]])  # noqa: E731
    lb, ub = np.array([-3.0, 1.5]), np.array([3.0, 3.0])
    x0 = np.array([2.0, 2.0])
    ours = trust_region_reflective(fun, jac, x0, lb, ub, max_nfev=200, **TOL)
    ref = _scipy(fun, jac, x0, lb, ub, 200)
    assert np.allclose(ours.x, [1.22437075, 1.5], atol=1e-8)
    assert np.max(np.abs(ours.x - ref.x)) < 1e-12 and ours.nfev == ref.nfev
    assert ours.x[1] > 1.5  # strictly feasible, as scipy's iterates


def test_the_search_stops_at_its_evaluation_budget():
    fun = lambda x: np.array([10 * (x[1] - x[0] ** 2), 1 - x[0]])  # noqa: E731
    jac = lambda x: np.array([[-20 * x[0], 10], [-1, 0]])  # noqa: E731
    lb, ub = np.array([-2.0, -2.0]), np.array([2.0, 3.0])
    out = trust_region_reflective(fun, jac, np.array([-1.2, 1.0]), lb, ub, max_nfev=5, **TOL)
    ref = _scipy(fun, jac, np.array([-1.2, 1.0]), lb, ub, 5)
    assert out.nfev == ref.nfev == 5 and np.max(np.abs(out.x - ref.x)) < 1e-12


@pytest.mark.parametrize("x0, lb, ub, word", [([3.0, 0.0], [-2.0, -2.0], [2.0, 2.0], "x0"),
                                             ([0.0, 0.0], [1.0, -2.0], [1.0, 2.0], "lb and ub"),
                                             ([0.0, 0.0], [-2.0], [2.0], "lb and ub")])
def test_the_search_refuses_bad_bounds(x0, lb, ub, word):
    with pytest.raises(ValueError, match=word):
        trust_region_reflective(lambda x: x, lambda x: np.eye(2), np.array(x0), np.array(lb), np.array(ub),
                                max_nfev=10, **TOL)


@pytest.mark.parametrize("kw", [{}, {"feedthrough": False, "offset": False, "initial_state": False}, "weights"])
@pytest.mark.parametrize("with_input", [True, False])
def test_batched_start_costs_equal_the_residuals(kw, with_input):
    """The start's candidates ranked in one batch: each cost is the residual's sum of squares (2 modes, the
    first one held, as the greedy start asks)."""
    d = synthetic(TRUE, "random_binary", n=1500, noise=0.05, seed=5)
    if kw == "weights":
        kw = {"weights": (np.random.default_rng(2).random(d.y.size) > 0.1).astype(float)}
    model = OEModel(d.u if with_input else None, d.y, 1.0 / d.sample_rate, 2, **kw)
    thetas = [np.array([math.log(TRUE.omega), 0.05, math.log(w), z])
              for w, z in ((300.0, 0.02), (500.0, 0.1), (900.0, 0.3), (60.0, 0.6))]
    direct = [float(model.residual(th) @ model.residual(th)) for th in thetas]
    assert np.allclose(model.costs(thetas), direct, rtol=1e-10, atol=0)


def test_free_response_rows_are_the_complex_powers():
    """lambda^k from exp, cos and sin in real passes equals numpy's complex exp (to rounding)."""
    d = synthetic(TRUE, "step", n=3000, noise=0.01, seed=0)
    h = 1.0 / d.sample_rate
    model = OEModel(None, d.y, h, 1, offset=False)
    rows = model.basis(np.array([math.log(TRUE.omega), 0.03])).T
    w, z = TRUE.omega, 0.03
    lam_k = np.exp(complex(-z * w, w * math.sqrt(1 - z * z)) * h * np.arange(d.y.size))
    assert np.max(np.abs(rows[0] - lam_k.real)) < 1e-13 and np.max(np.abs(rows[1] - lam_k.imag)) < 1e-13


@pytest.mark.parametrize("n", [1, 2, 20, 2000])
def test_forced_response_filter_is_lfilters(n, monkeypatch):
    """The compiled filter called directly gives lfilter's output, bit for bit, and the fallback is lfilter."""
    u = np.random.default_rng(n).standard_normal(n)
    lam = complex(0.95, 0.2)
    ref = output_error.signal.lfilter([0.0, 1.0], [1.0, -2.0 * lam.real, abs(lam) ** 2], u)
    assert np.array_equal(output_error._forced(lam, u), ref)
    monkeypatch.setattr(output_error, "_linear_filter", None)
    assert np.array_equal(output_error._forced(lam, u), ref)
