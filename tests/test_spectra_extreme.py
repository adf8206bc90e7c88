"""Extreme but finite gains and scales in the spectral tools (issue: reliability on hostile inputs).

Bad input gets a clear error, never a wrong answer; no hang, no traceback.  The roots are compared
with independent numbers: closed forms of factored polynomials, numpy's eigenvalue roots where they
are well conditioned, and the Lambert W branches for ``s + a e^{-s}`` (``s = W_k(-a)``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import lambertw

import posicast as pc
from posicast import QuasiPolynomial
from posicast.spectra import BudgetExceeded
from posicast.spectra.bounds import bound_from_gamma


def _lambert(a: float, k: int) -> complex:
    """The root ``W_k(-a)`` of ``s + a e^{-s}`` (s e^s = -a)."""
    return complex(lambertw(-a, k))


# ------------------------------------------------------------------ rational loops: (s + 1)(s + kp)
@pytest.mark.parametrize("kp", [1e-300, 1e-12, 1e12, 1e100])
def test_rational_loop_with_extreme_gain(kp):
    """s (s + 1) + kp (s + 1) = (s + 1)(s + kp): roots -1 and -kp exactly (before: kp = 1e-300 was marginal,
    1e100 refused as out of range, although the coefficients normalised are [1, 1, 1e-100])."""
    q = QuasiPolynomial.from_poly(np.polymul([1.0, 1.0], [1.0, kp]))
    r = pc.roots(q, (-2.0 * max(kp, 1.0), 1.0, -1.0, 1.0))
    assert r.count == 2
    np.testing.assert_allclose(np.sort(r.roots.real), np.sort([-1.0, -kp]), rtol=1e-12)
    st = pc.stability(q)
    assert st.stable and not st.marginal


def test_pd_loop_with_gain_1e12_matches_closed_form():
    """s (s + 1)(0.01 s + 1) + kp (s + 1) = (s + 1)(0.01 s^2 + s + kp): -1 and -50 +- j sqrt(100 kp - 2500)."""
    kp = 1e12
    q = QuasiPolynomial.from_poly(np.polyadd(np.polymul([1.0, 1.0, 0.0], [0.01, 1.0]), [kp, kp]))
    exact = np.array([-1.0, complex(-50.0, np.sqrt(100 * kp - 2500)), complex(-50.0, -np.sqrt(100 * kp - 2500))])
    r = pc.roots(q, (-100.0, 1.0, -2e7, 2e7))
    assert r.count == 3
    for z in exact:
        assert np.min(np.abs(r.roots - z)) <= 1e-9 * abs(z)
    assert pc.stability(q).stable


def test_tiny_gain_root_next_to_zero_is_left_of_the_axis():
    """(s + 1)(s + 1e-300): the root -1e-300 is certified left of the axis (before: 'marginal')."""
    q = QuasiPolynomial.from_poly(np.polymul([1.0, 1.0], [1.0, 1e-300]))
    assert pc.rightmost(q, 1)[0] == pytest.approx(-1e-300, rel=1e-12)
    assert pc.stability(q).stable


# ------------------------------------------------------------------ s + a e^{-s}: Lambert W
@pytest.mark.parametrize("a", [1e-300, 1e-12, 1.0, 1e3])
def test_scalar_dde_extreme_gain_matches_lambert_w(a):
    q = QuasiPolynomial([[0.0, 1.0], [a, 0.0]], [0.0, 1.0])
    assert abs(pc.rightmost(q, 1)[0] - _lambert(a, 0)) <= 1e-12 * max(1.0, abs(_lambert(a, 0)))
    st = pc.stability(q)
    ks = np.arange(-int(a) - 2, int(a) + 3)
    right = [w for w in (_lambert(a, int(k)) for k in ks) if w.real >= 0]
    assert st.stable == (not right)
    assert st.unstable_roots.size == len(right)  # 318 for a = 1e3, every one a Lambert branch
    for w in right:
        assert np.min(np.abs(st.unstable_roots - w)) <= 1e-12 * abs(w)


@pytest.mark.parametrize("a", [1e12, 1e100])
def test_scalar_dde_huge_gain_refused_up_front_with_estimate(a):
    """s + a e^{-s} has about a / pi roots right of the axis: the search is refused at once with its size."""
    q = QuasiPolynomial([[0.0, 1.0], [a, 0.0]], [0.0, 1.0])
    with pytest.raises(BudgetExceeded, match=r"can reach \|s\| = .*needs about [0-9.e+]+ evaluations"):
        pc.stability(q)  # the staircase's estimate: refused before the first search


# ------------------------------------------------------------------ what cannot be represented
@pytest.mark.parametrize("C", [([1e300, 1e300], [0.01, 1.0]), ([1e300, 1e300], [1.0])])
def test_gain_1e300_refused_with_the_range(C):
    """Roots out to |s| = 1e151 or 1e300: a named ValueError stating the range (before: a bare OverflowError
    from the root bound, or an error about a Taylor expansion at a point the user never gave)."""
    T = (pc.as_transfer(C) * pc.as_transfer(([1.0], [1.0, 1.0, 0.0]))).feedback()
    with pytest.raises(ValueError, match=r"can lie as far out as \|s\| = .*float range beyond"):
        pc.stability(T)


def test_coefficients_spanning_more_than_the_float_range_refused():
    with pytest.raises(ValueError, match="coefficients span"):
        pc.stability(QuasiPolynomial.from_poly([1e300, 1.0, 1e-10]))


def test_root_bound_guard_does_not_overflow():
    """gamma R^3 with R ~ 1e151 overflowed a Python float (OverflowError) in the bound's guard."""
    q = QuasiPolynomial.from_poly([0.01, 1.01, 1e300, 1e300])
    R = bound_from_gamma(q, 0.0, 0.01)
    assert 1e151 <= R <= 1.01e151  # the modulus of -50 +- j 1e151, the roots of 0.01 s^2 + s + 1e300


def test_shaper_loop_with_huge_gain_refused_in_milliseconds():
    """A ZV shaper in a PD loop with kp = 1e12: roots up to |s| ~ 1e7 with chains 20 apart; the staircase's
    grid (billions of points) is refused before any search (before: 30 s, or a 27 GiB allocation)."""
    S = pc.design("zv", pc.Mode(10.0, 0.03))
    L = pc.control_action(G=([1.0], [1.0, 1.0, 0.0]), C=([1e12, 1e12], [0.01, 1.0]), S=S)
    with pytest.raises(BudgetExceeded, match="certified search needs about"):
        pc.stability(L)  # the staircase's estimate: refused before the first search


def test_shaper_loop_with_tiny_gain_is_stable():
    """kp = 1e-300: the loop is s (s + 1) plus a negligible shaped term; its roots -1 and about -1e-300
    (before: BudgetExceeded after 10 s: Newton stopped at s = 0, where h is all rounding)."""
    S = pc.design("zv", pc.Mode(10.0, 0.03))
    L = pc.control_action(G=([1.0], [1.0, 1.0, 0.0]), C=([1e-300], [1.0]), S=S)
    st = pc.stability(L)
    assert st.stable
    r = pc.rightmost(L, 1)[0]
    assert r == pytest.approx(-1e-300, rel=1e-9)  # h(0) = 1e-300 S(0), h'(0) = 1, S(0) = 1


# ------------------------------------------------------------------ rightmost: fewer roots than asked for
def _crane_pd_loop(kd: float, S=None):
    crane = pc.cases.ALL["gantry_crane"]
    C = pc.TransferFunction.from_poly(np.polyadd([0.01, 1.0], [kd, 0.0]), [0.01, 1.0])  # kp = 1, filter 0.01
    return pc.control_action(G=crane.G, F=crane.F, C=C, S=S)


def test_rightmost_of_a_polynomial_loop_returns_every_root():
    """The crane with a PD of kd = 4.6e16 (no shaper): a degree-10 polynomial.  rightmost(30) gives its ten
    roots, numpy's eigenvalue roots of the characteristic (before: nine, the tenth at -5e5 beyond the
    twelve steps of the search line)."""
    L = _crane_pd_loop(4.6e16)
    q = L.characteristic
    ref = np.roots(q.coeffs[0, ::-1])
    got = pc.rightmost(L, 30)
    assert got.size == 10
    for z in ref:
        assert np.min(np.abs(got - z)) <= 1e-8 * max(1.0, abs(z))
    np.testing.assert_allclose(pc.rightmost(L, 2).real, np.sort(ref.real)[::-1][:2], rtol=1e-9)


def test_rightmost_of_a_shaped_loop_with_huge_gain_refused_up_front():
    """The same loop with its DeZV shaper: roots to |s| ~ 4e5 with chains 7 apart (before: 24 s, then refused)."""
    crane = pc.cases.ALL["gantry_crane"]
    L = _crane_pd_loop(4.6e16, pc.design("dezv", crane.mode))
    with pytest.raises(BudgetExceeded, match="certified search needs about"):
        pc.rightmost(L, 2)


def test_rightmost_says_when_the_search_line_stopped():
    """s + 1000 e^{-s} has infinitely many roots, 318 right of the axis; with one step of the search line
    (Re s >= 0) only those are found: a warning says so, and the roots are the Lambert W branches."""
    q = QuasiPolynomial([[0.0, 1.0], [1000.0, 0.0]], [0.0, 1.0])
    with pytest.warns(UserWarning, match="318 of the 400 .*max_alpha_steps"):
        got = pc.rightmost(q, 400, max_alpha_steps=1)
    assert got.size == 318
    assert abs(got[0] - _lambert(1000.0, 0)) <= 1e-12 * abs(got[0])


# ------------------------------------------------------------------ found by the fuzz pass
def test_root_cluster_near_zero_ends_in_a_named_error_not_a_budget_run():
    """An 11th-order plant with poles at |s| ~ 0.0094, a PD of kd = 7.7e7 and a DZV shaper: the
    characteristic's coefficients span 1e-23..0.6 and its roots next to the removable s = 0 cannot be
    separated.  Each reconciliation level halved the grid step while the part shrank only to ~60 %,
    so the grid grew 4x a level (3438 x 3039 nodes by level 10; minutes).  Now the split localises
    and the search stops at its depth limit with the reason, after a few thousand evaluations a level."""
    den = np.array([1.0])
    wn, zeta = 0.00943, 0.728
    for _ in range(5):
        den = np.polymul(den, [1.0, 2 * zeta * wn, wn * wn])
    den = np.polymul(den, [1.0, wn])
    G = pc.as_transfer(([10.0 * wn**11], den)) * pc.delay(2.46)
    C = pc.TransferFunction.from_poly(np.polyadd([0.01, 1.0], [7.69e7, 0.0]), [0.01, 1.0])
    L = pc.control_action(G=G, C=C, S=pc.design("dzv", pc.Mode(10.0, 0.767)))
    with pytest.raises(pc.spectra.RootFindingError, match="could not isolate"):
        pc.roots(L.characteristic, (-10.0, 1.0, 0.0, 50.0), max_evaluations=2e6, timeout=1e4)


def test_difference_spectrum_with_delays_of_thousands_of_seconds():
    """An inverse ZVD for a 0.0023 rad/s mode (delays 2027 and 4055 s): the Hale abscissa's bracket started
    at a = -1, where exp(2027) overflowed (a RuntimeWarning, an error under the suite's filter).  Closed
    forms: with x = e^{-2027.46 a}, the Hale abscissa solves |d1| x + |d2| x^2 = 1; C_D comes from the
    roots z of 1 + d1 z + d2 z^2 (z = e^{-2027.46 s}), Re s = -ln|z| / 2027.46."""
    S = pc.design("zvd", pc.Mode(0.0023, 0.739))
    G = pc.as_transfer(([0.243**6], np.polymul(np.polymul([1, 0, 0.243**2], [1, 0, 0.243**2]), [1, 0, 0.243**2])))
    L = pc.inverse_shaper(G=G, C=([0.0023], [1.0]), S=S)
    ds = pc.spectra.difference_spectrum(L.characteristic)
    D = ds.operator
    d1, d2 = D.coeffs[1, 0] / D.coeffs[0, 0], D.coeffs[2, 0] / D.coeffs[0, 0]
    T = float(D.delays[1])
    x = max(np.roots([abs(d2), abs(d1), -1.0]).real)
    assert ds.hale_abscissa == pytest.approx(-np.log(x) / T, rel=1e-9)
    z = np.roots([d2, d1, 1.0])
    assert ds.abscissa == pytest.approx(max(-np.log(np.abs(z)) / T), rel=1e-6)
    assert ds.strongly_stable


def test_simulate_an_eleventh_order_plant_at_a_thousandth_of_a_rad_per_s():
    """The plant's companion matrix spans 1e-3..1e-33: scipy's balancing warned (a RuntimeWarning, an error
    under the suite's filter).  Independent number: for wn t << 1 the plant is K wn^11 / s^11, the loop gain
    is 4e-13 (no feedback to speak of) and only the ZVD's first impulse A0 has acted by t = 5 s (the second
    comes at pi / omega_d = 3.65 s and adds (1.35 s)^11 / 11!, a millionth), so y(5) = kp K wn^11 A0 5^11 / 11!."""
    wn, zeta, K, kp = 0.0011, 0.27, 3.81e-10, 0.0011
    den = np.array([1.0])
    for _ in range(5):
        den = np.polymul(den, [1.0, 2 * zeta * wn, wn * wn])
    den = np.polymul(den, [1.0, wn])
    S = pc.design("zvd", pc.Mode(1.0, 0.508))
    L = pc.control_action(G=([K * wn**11], den), C=([kp], [1.0]), S=S)
    t = np.linspace(0.0, 5.0, 501)
    r = pc.simulate(L, t, w=np.ones_like(t), sample_rate=100.0)
    A0 = S.impulses[1][0]
    expected = kp * K * wn**11 * A0 * 5.0**11 / math.factorial(11)
    assert np.asarray(r.y)[-1] == pytest.approx(expected, rel=1e-2)


def test_readme_example():
    """README "Extreme gains and scales" runs as printed (the block is a doctest)."""
    import doctest
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")
    section = text[text.index("*Extreme gains and scales*"):]
    start = section.index("```python") + len("```python")
    block = section[start: section.index("```", start)]
    test = doctest.DocTestParser().get_doctest(block, {}, "README extreme", "README.md", 0)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    runner.run(test)
    assert runner.failures == 0 and runner.tries == 4


def test_cli_stability_with_a_huge_derivative_gain(capsys):
    """`posicast stability --case gantry_crane --kp 1 --kd 4.6e16 ...` (refused by the CLI's gain range before):
    the rightmost root is the characteristic polynomial's (numpy's eigenvalue roots); with the case's DeZV
    shaper the search is refused at once with its estimate, one line, exit 2."""
    import json

    from posicast.cli import main

    argv = ["stability", "--case", "gantry_crane", "--kp", "1", "--kd", "4.6e16", "--derivative-filter", "0.01",
            "--roots", "2", "--quiet"]
    assert main([*argv, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    q = _crane_pd_loop(4.6e16).characteristic
    ref = np.roots(q.coeffs[0, ::-1])
    assert data["stable"] is False
    assert data["spectral_abscissa"]["value"] == pytest.approx(float(np.max(ref.real)), rel=1e-9)
    assert main([*argv, "--shaper", "dezv"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("posicast: error:") and "certified search needs about" in err[0]
