"""Quasi-polynomials from the literature: roots, counts, abscissae and verdicts (issue #13).

The cases and their sources are in ``tests/data/published_qp.py``: QPmR examples
(Vyhlídal & Zítek), the TDS-CONTROL manual's neutral example 2.6 (Appeltans &
Michiels), Lambert-W closed forms, multiplicity-induced-dominancy designs
(Mazanti, Boussaada & Niculescu) and critical delays.  Printed numbers are
compared to the digits printed; closed forms and 40-digit mpmath references
to 1e-9.  Every root count is the argument principle's (certified) and equals
the reference count (qpmr's, or the closed form's).
"""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.special import lambertw

from posicast import QuasiPolynomial
from posicast.spectra import difference_spectrum, rightmost, roots, spectral_abscissa, stability

_spec = importlib.util.spec_from_file_location("published_qp", Path(__file__).parent / "data" / "published_qp.py")
D = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(D)


def _qp(case: dict) -> QuasiPolynomial:
    return QuasiPolynomial(case["coeffs"], case["delays"])


def _nearest(z: np.ndarray, p: complex) -> float:
    return float(np.min(np.abs(z - p)))


def _printed(z: np.ndarray, p: complex, tol: float) -> bool:
    """``p`` is a root of ``z`` rounded to the printed digits: real and imaginary parts within ``tol``."""
    w = z[np.argmin(np.abs(z - p))]
    return abs(w.real - p.real) <= tol and abs(w.imag - p.imag) <= tol


def _lambert_roots(a: float, b: float, tau: float, ks) -> np.ndarray:
    """s + a + b e^{-s tau} = 0: s = -a + W_k(-b tau e^{a tau}) / tau."""
    return np.array([-a + complex(lambertw(-b * tau * math.exp(a * tau), k)) / tau for k in ks])


# ---------------------------------------------------------------------------------------- QPmR
def test_vz2009_s_plus_exp_printed_and_lambert_w():
    c = D.VZ_EX1
    h = _qp(c)
    r = roots(h, c["region"])
    assert r.count == len(r.roots) == c["count"]  # certified, = the 5 printed roots
    for p in c["printed"]:
        assert _printed(r.roots, p, c["printed_tol"])  # to the 4 printed decimals
    lw = c["lambert"]
    ref = _lambert_roots(lw["a"], lw["b"], lw["tau"], lw["branches"])
    ref = ref[ref.imag > 0]
    assert ref.size == 5
    for z in ref:
        assert _nearest(r.roots, z) < 1e-9
    a = spectral_abscissa(h)
    assert abs(a - ref[0].real) < 1e-9 and a.error < 1e-9
    top = rightmost(h, 2)
    assert np.allclose(np.sort_complex(top), np.sort_complex([ref[0], ref[0].conjugate()]), atol=1e-9)


@pytest.mark.parametrize("case", [D.QPMR_HELP, D.VZ_LARGE, D.VZ_NEUTRAL], ids=lambda c: c["name"])
def test_qpmr_examples_count_roots_and_abscissa(case):
    h = _qp(case)
    r = roots(h, case["region"])
    assert r.count == len(r.roots) == case["count"]  # argument principle = qpmr's count
    assert np.all(r.residuals <= 1e-12)
    for z in case["reference"]:
        assert _nearest(r.roots, z) < 1e-9, z
    a = spectral_abscissa(h)
    assert abs(a - case["abscissa"]) < 1e-9 and a.error < 1e-9
    st = stability(h)
    assert st.stable is case["stable"] and not st.marginal
    assert abs(st.unstable_roots[0].real - case["abscissa"]) < 1e-9


# ------------------------------------------------------------------------------ TDS-CONTROL 2.6
def test_appeltans_example_2_6_not_strongly_stable_neutral():
    c = D.APPELTANS_26
    h = _qp(c)
    ds = difference_spectrum(h)
    assert ds.strongly_stable is c["strongly_stable"]
    assert abs(ds.abscissa - c["difference_abscissa"]) < 1e-12
    assert abs(ds.hale_abscissa - c["hale_abscissa"]) < 1e-12
    r = roots(h, c["region"])
    assert r.count == len(r.roots) == c["count"]  # qpmr: 20
    for z in c["reference"]:
        assert _nearest(r.roots, z) < 1e-9
    for p in c["printed"]:
        assert _printed(r.roots, p, c["printed_tol"])
    # the rightmost pair lies between C_D and the Hale abscissa: found by the sharper root bound
    top = rightmost(h, 2)
    z0 = c["reference"][0]
    assert np.allclose(np.sort_complex(top), np.sort_complex([z0, z0.conjugate()]), atol=1e-9)
    a = spectral_abscissa(h)
    assert abs(a - c["abscissa"]) < 1e-9 and a.error < 1e-9 and a.source == "root"
    st = stability(h)
    assert not st.stable and not st.marginal  # exponentially stable, but not robustly: not strongly stable
    assert st.unstable_roots.size == 0  # certified: no root with Re s >= 0 (C_D < 0)
    assert "not strongly stable" in st.reason


def test_appeltans_example_2_6_perturbed_delay_is_unstable():
    c = D.APPELTANS_26_PERTURBED
    h = _qp(c)
    ds = difference_spectrum(h)
    assert ds.commensurate and ds.strongly_stable is c["strongly_stable"]
    assert abs(ds.abscissa - c["difference_abscissa"]) < 1e-9
    z = c["reference"][0]
    r = roots(h, (z.real - 0.05, z.real + 0.05, z.imag - 1.0, z.imag + 1.0))
    assert r.count == 1 and abs(r.roots[0] - z) < 1e-9
    assert not stability(h).stable


# ---------------------------------------------------------------------------------- Lambert W
@pytest.mark.parametrize("case", D.LAMBERT, ids=lambda c: f"a={c['a']},b={c['b']},tau={c['tau']}")
def test_scalar_dde_lambert_w(case):
    a, b, tau = case["a"], case["b"], case["tau"]
    h = QuasiPolynomial([[a, 1.0], [b, 0.0]], [0.0, tau])
    near = _lambert_roots(a, b, tau, case["branches"])
    allr = _lambert_roots(a, b, tau, range(-60, 61))
    top = near[np.argmax(near.real)]
    assert top.real == near[list(case["branches"]).index(0)].real  # the principal branch is the rightmost
    region = (near.real.min() - 0.3, near.real.max() + 0.3, -0.1, float(np.abs(near.imag).max()) + 0.1)
    r = roots(h, region)
    inside = allr[(allr.real > region[0]) & (allr.real < region[1]) & (allr.imag > region[2]) & (allr.imag < region[3])]
    # a real W_0 and W_{-1} pair shows up twice in a -60..60 sweep only once each: unique by value
    inside = np.unique(np.round(inside, 12))
    assert r.count == len(r.roots) == inside.size
    for z in inside:
        assert _nearest(r.roots, z) < 1e-9
    sa = spectral_abscissa(h)
    assert abs(sa - top.real) < 1e-9 and sa.error < 1e-9


# -------------------------------------------------------------- multiplicity-induced dominancy
def test_mid_first_order_double_root_is_dominant():
    c = D.MID_1
    a, tau = c["a"], c["tau"]
    b = math.exp(-1.0 - a * tau) / tau
    s0 = -a - 1.0 / tau
    assert s0 == c["s0"]
    h = QuasiPolynomial([[a, 1.0], [b, 0.0]], [0.0, tau])
    r = roots(h, (-3.7, -2.3, -0.5, 0.5))
    assert r.count == 2 and list(r.multiplicities) == [2] and abs(r.distinct[0] - s0) < 1e-9
    sa = spectral_abscissa(h)
    assert abs(sa - s0) < 1e-9 and sa.error < 1e-5  # a double root: certified to ~sqrt(eps)
    top = rightmost(h, 3)
    assert np.allclose(top[:2], s0, atol=1e-9) and top[2].real < s0 - 1.0  # dominant
    # closed form: the branch point of Lambert W (W_0 = W_{-1} = -1 at -1/e)
    assert abs(-b * tau * math.exp(a * tau) + math.exp(-1.0)) < 1e-15
    assert stability(h).stable


@pytest.mark.parametrize("name", ["MID_2", "MID_3", "mazanti"])
def test_mid_generic_multiple_dominant_root(name):
    c = D.mazanti2021_prop61() if name == "mazanti" else getattr(D, name)
    h = _qp(c)
    s0, m = c["s0"], c["multiplicity"]
    if name == "mazanti":
        assert abs(s0 - c["s0_mp"]) < 1e-12 and round(s0, 3) == c["printed_s0"]
    r = roots(h, (s0 - 0.7, s0 + 0.7, -0.6, 0.6))
    assert r.count == m and list(r.multiplicities) == [m]  # one certified cluster of m roots
    assert abs(r.distinct[0] - s0) < 1e-9
    sa = spectral_abscissa(h)  # used to raise RootFindingError (a search edge through the cluster)
    assert abs(sa - s0) < 1e-9 and sa.error < 0.02 * abs(s0)  # the cluster: about (rounding)^(1/m) wide
    top = rightmost(h, m + 1)
    assert np.allclose(top[:m], s0, atol=1e-9)
    assert top[m].real < s0 - 0.5  # strictly dominant
    assert stability(h).stable


# ----------------------------------------------------------------------------- critical delays
@pytest.mark.parametrize("case", D.CRITICAL, ids=lambda c: f"a={c['a']}")
def test_critical_delay_is_marginal(case):
    a = case["a"]
    tau = math.pi / (2.0 * a)
    h = QuasiPolynomial([[0.0, 1.0], [a, 0.0]], [0.0, tau])
    st = stability(h)
    assert not st.stable and st.marginal and "marginal" in st.reason
    assert np.allclose(np.sort_complex(st.unstable_roots), [-1j * a, 1j * a], atol=1e-12)
    assert np.all(st.unstable_roots.real == 0.0) and st.axis_error < 1e-10
    sa = spectral_abscissa(h)
    assert float(sa) == 0.0 and sa.marginal and sa.error < 1e-10
    # 1e-8 either side of the critical delay the verdict is decided, not marginal
    below = stability(QuasiPolynomial([[0.0, 1.0], [a, 0.0]], [0.0, tau * (1 - 1e-8)]))
    above = stability(QuasiPolynomial([[0.0, 1.0], [a, 0.0]], [0.0, tau * (1 + 1e-8)]))
    assert below.stable and not below.marginal
    assert not above.stable and not above.marginal and above.unstable_roots.size == 2


def test_neutral_with_a_root_at_zero_is_marginal():
    """x'(t) + 0.5 x'(t - 1) = 0: s (1 + 0.5 e^{-s}), roots 0 and -ln 2 + j (2k + 1) pi."""
    h = QuasiPolynomial([[0.0, 1.0], [0.0, 0.5]], [0.0, 1.0])
    st = stability(h)
    assert not st.stable and st.marginal and list(st.unstable_roots) == [0.0]
    assert st.strongly_stable and abs(st.difference_abscissa + math.log(2.0)) < 1e-12
    sa = spectral_abscissa(h)
    assert float(sa) == 0.0 and sa.marginal
    r = roots(h, (-1.0, 0.5, -0.5, 10.0))
    ref = np.array([0.0, -math.log(2.0) + 1j * math.pi, -math.log(2.0) + 3j * math.pi])
    assert r.count == 3 and all(_nearest(r.roots, z) < 1e-9 for z in ref)
