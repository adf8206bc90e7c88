"""Certified quasi-polynomial roots, difference operators and stability (issue #3).

Oracles: seed 000 eq. 3 (ZV zeros) and eq. 8 (DZV zeros, Lambert W, with the
misprinted 1/tau read as 1/theta), the scalar DDE's Lambert-W spectrum, numpy's
polynomial roots, and an independent count by trapezoidal integration of
h'/h along the boundary.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from scipy.special import lambertw

import posicast
from posicast import Mode, QuasiPolynomial
from posicast.spectra import (
    BudgetExceeded,
    difference_spectrum,
    rightmost,
    root_bound,
    roots,
    spectral_abscissa,
    stability,
    unstable_count,
)

SEED000_MODE = Mode(10.0, 0.03)  # F(s) = s / (s^2 + 0.6 s + 100), seed 000 eq. 26
REGION = (-20.0, 5.0, 0.0, 500.0)  # issue #3 acceptance 2


def _match(a: np.ndarray, b: np.ndarray) -> float:
    """Largest distance from a point of ``a`` to its nearest point of ``b`` (and back)."""
    if a.size == 0 and b.size == 0:
        return 0.0
    d = np.abs(a[:, None] - b[None, :])
    return float(max(d.min(axis=1).max(), d.min(axis=0).max()))


def _integral_count(h: QuasiPolynomial, rect, n: int = 200_000) -> float:
    """Independent root count: (1 / 2 pi j) * contour integral of h'/h (trapezoid)."""
    a, b, c, d = rect
    corners = [complex(a, c), complex(b, c), complex(b, d), complex(a, d), complex(a, c)]
    dh = h.derivative()
    total = 0.0 + 0.0j
    for z0, z1 in zip(corners[:-1], corners[1:]):
        t = np.linspace(0.0, 1.0, n)
        z = z0 + (z1 - z0) * t
        f = dh(z) / h(z) * (z1 - z0)
        total += np.trapezoid(f, t)
    return (total / (2j * math.pi)).real


def _seed000_loop(kind: str) -> QuasiPolynomial:
    """Seed 000 eq. 23: CE = S Q N + P M (times S's denominator for distributed shapers)."""
    S = posicast.design(kind, SEED000_MODE)
    P = QuasiPolynomial.from_poly([10.0, 10.0])  # C = (10 s + 10) / (0.01 s + 1), eq. 27
    Qc = QuasiPolynomial.from_poly([0.01, 1.0])
    M = QuasiPolynomial.from_poly([1.0])  # G = 1 / (s^2 + s), eq. 25
    N = QuasiPolynomial.from_poly([1.0, 1.0, 0.0])
    return S.num * Qc * N + P * M * S.den


# ------------------------------------------------------------------ closed forms
def test_zv_zeros_match_seed000_eq3():
    S = posicast.design("zv", SEED000_MODE)
    t, A = S.impulses
    A0, tau = A[0], t[1]
    r = roots(S.num, REGION)
    k = np.arange(0, 200)
    ref = -np.log(A0 / (1 - A0)) / tau + 1j * np.pi * (2 * k + 1) / tau
    ref = ref[ref.imag <= 500]
    assert r.count == len(r.roots) == ref.size == 25
    assert _match(r.roots, ref) < 1e-10
    assert np.all(r.residuals <= 1e-12)
    # the dominant pair sits on the mode's pole (seed 000 eq. 4)
    assert np.min(np.abs(r.roots - SEED000_MODE.pole)) < 1e-10


def test_dzv_zeros_match_seed000_eq8_lambert_w():
    S = posicast.design("dzv", SEED000_MODE)
    B = S.impulses[1][0]
    theta = S.params["theta"] if "theta" in S.params else S.duration
    a = (1 - B) / B
    k = np.arange(-200, 201)
    # seed 000 eq. 8 prints 1/tau; the zeros of eq. 7 need 1/theta
    ref = (lambertw(a * np.exp(a), k) - a) / theta
    ref = ref[(ref.imag >= -1e-9) & (ref.imag <= 500) & (ref.real >= -20)]
    r = roots(S.num, REGION)
    assert r.shifted  # s = 0 (k = 0, the removable point) lies on the edge Im s = 0
    assert r.count == len(r.roots) == ref.size
    assert _match(r.roots, ref) < 1e-10
    assert np.all(r.residuals <= 1e-12)
    # W(1, .) is the mode's pole
    assert abs((lambertw(a * np.exp(a), 1) - a) / theta - SEED000_MODE.pole) < 1e-10


def test_zvd3_zeros_are_fourfold_zv_zeros():
    S = posicast.design("zvdk", SEED000_MODE, k=3)
    Z = posicast.design("zv", SEED000_MODE)
    r = roots(S.num, REGION)
    rz = roots(Z.num, REGION)
    assert r.count == 100 == len(r.roots)
    assert np.all(r.multiplicities == 4)
    assert _match(r.distinct, rz.roots) < 1e-10
    assert np.all(r.residuals <= 1e-12)


@pytest.mark.parametrize("kind", ["dezv", "dtzv", "dczv", "dtazv"])
def test_distributed_shaper_spectra_certified(kind):
    S = posicast.design(kind, SEED000_MODE)
    r = roots(S.num, REGION)
    assert r.count == len(r.roots) > 10
    assert np.all(r.residuals <= 1e-12)
    assert np.min(np.abs(r.roots - SEED000_MODE.pole)) < 1e-9
    # independent count on a boundary kept off the roots
    rect = (-19.7, 4.9, 1.3, 470.3)
    inside = (r.roots.real > rect[0]) & (r.roots.real < rect[1]) & (r.roots.imag > rect[2]) & (r.roots.imag < rect[3])
    assert round(_integral_count(S.num, rect)) == int(inside.sum())


def test_two_mode_shaper_spectrum():
    m2 = Mode(27.0, 0.05)
    h = posicast.design("zv", SEED000_MODE).num * posicast.design("zv", m2).num
    r = roots(h, REGION)
    r1 = roots(posicast.design("zv", SEED000_MODE).num, REGION)
    r2 = roots(posicast.design("zv", m2).num, REGION)
    assert r.count == len(r.roots) == r1.count + r2.count
    assert _match(r.roots, np.concatenate([r1.roots, r2.roots])) < 1e-10
    assert np.all(r.residuals <= 1e-12)


def test_polynomial_roots_match_numpy():
    desc = [1.0, 3.0, 7.0, 5.0, 2.0, 9.0]
    ref = np.roots(desc)
    r = roots(QuasiPolynomial.from_poly(desc), (-10, 10, -10, 10))
    assert r.count == 5
    assert _match(r.roots, ref) < 1e-12


def test_scalar_dde_rightmost_root_is_principal_lambert_branch():
    # s + a + b e^{-s tau} = 0  <=>  s = -a + W_k(-b tau e^{a tau}) / tau
    for a, b, tau in [(1.0, 2.0, 1.0), (0.5, -0.3, 2.0), (-0.2, 1.5, 0.7)]:
        h = QuasiPolynomial([[a, 1.0], [b, 0.0]], [0.0, tau])
        w0 = -a + lambertw(-b * tau * np.exp(a * tau), 0) / tau
        assert abs(spectral_abscissa(h) - w0.real) < 1e-10
        top = rightmost(h, 3)
        ks = np.arange(-3, 4)
        ref = -a + lambertw(-b * tau * np.exp(a * tau), ks) / tau
        for z in top:
            assert np.min(np.abs(ref - z)) < 1e-10


# ------------------------------------------------------------------ seed 000 loops
def test_inverse_zv_loop_unstable_three_high_frequency_pairs():
    ce = _seed000_loop("zv")
    assert ce.kind == "neutral"
    st = stability(ce)
    assert not st.stable
    # seed 000 section V: "three couples of unstable higher frequency poles"
    assert st.unstable_roots.size == 6
    assert np.all(np.abs(st.unstable_roots.imag) > 40)  # well above the 10 rad/s mode
    assert st.strongly_stable  # the instability is not the difference operator's
    assert abs(st.difference_abscissa - SEED000_MODE.pole.real) < 1e-9  # C_D = the ZV zeros' line
    assert spectral_abscissa(ce) == pytest.approx(float(st.unstable_roots.real.max()), abs=1e-12)


def test_inverse_dzv_loop_stable_and_retarded():
    ce = _seed000_loop("dzv")
    assert ce.kind == "retarded"
    # S.num and S.den both vanish at s = 0: a spurious root of CE, not a pole
    assert abs(ce(0.0)) < 1e-14
    st = stability(ce, ignore=[0.0])
    assert st.stable, st.reason
    assert spectral_abscissa(ce, ignore=[0.0]) < 0


@pytest.mark.parametrize("kind", ["zv", "dzv"])
def test_lemma1_poles_approach_shaper_zeros(kind):
    """Seed 000 Lemma 1: at high frequency the loop's poles approach the shaper zeros."""
    ce = _seed000_loop(kind)
    S = posicast.design(kind, SEED000_MODE)
    region = (-20.0, 5.0, 0.0, 2000.0)
    poles = roots(ce, region, ignore=[0.0]).roots
    zeros = roots(S.num, region, ignore=[0.0]).roots
    assert np.all(roots(ce, region).residuals <= 1e-12)
    bands = [(100, 300), (300, 800), (800, 1800)]
    gaps = []
    for lo, hi in bands:
        z = zeros[(zeros.imag > lo) & (zeros.imag < hi)]
        p = poles[(poles.imag > lo - 50) & (poles.imag < hi + 50)]
        gaps.append(max(np.min(np.abs(p - zz)) for zz in z))
    assert gaps[0] > gaps[1] > gaps[2]
    assert gaps[2] < 0.05


# ------------------------------------------------------------------ neutral operators
def test_difference_spectrum_commensurate_and_not():
    d = difference_spectrum(QuasiPolynomial([[0.0, 1.0], [0.0, 0.5], [1.0, 0.25]], [0.0, 1.0, 2.0]))
    # 1 + 0.5 z + 0.25 z^2 with z = e^{-s}: |z| = 2, so Re s = -ln 2
    assert d.commensurate
    assert d.abscissa == pytest.approx(-math.log(2.0), abs=1e-12)
    assert d.strongly_stable
    d2 = difference_spectrum(QuasiPolynomial([[1.0, 1.0], [0.0, 0.3], [0.0, 0.2]], [0.0, 1.0, math.sqrt(2)]))
    assert not d2.commensurate
    assert d2.abscissa <= d2.hale_abscissa + 1e-12
    assert d2.strongly_stable
    d3 = difference_spectrum(QuasiPolynomial([[0.0, 1.0], [0.0, 1.5]], [0.0, 1.0]))
    assert d3.abscissa == pytest.approx(math.log(1.5), abs=1e-12)
    assert not d3.strongly_stable
    assert not stability(QuasiPolynomial([[1.0, 1.0], [0.0, 1.5]], [0.0, 1.0])).stable


def test_root_bound_holds():
    ce = _seed000_loop("dzv")
    R = root_bound(ce, -1.0)
    r = roots(ce, (-1.0, 5.0, -1.0, 400.0))
    assert np.all(np.abs(r.roots) <= R)


# ------------------------------------------------------------------ boundaries, budget, bad input
def test_root_on_boundary_is_shifted_and_counted():
    h = QuasiPolynomial([[0.6], [0.4]], [0.0, math.pi])
    z = -math.log(1.5) / math.pi + 1j
    r = roots(h, (z.real, 1.0, 0.0, 4.0))  # left edge through the roots at Im = 1 and 3
    assert r.shifted and r.region[0] < z.real
    assert r.count == 2 == len(r.roots)
    r2 = roots(h, (-1.0, 1.0, 1.0, 2.0))  # bottom edge through the root at Im = 1
    assert r2.count == 1 and abs(r2.roots[0] - z) < 1e-12


def test_multiple_root_of_polynomial_times_delay():
    # (s + 1)^3 (1 + 0.5 e^{-s}): a triple root at -1 and a neutral chain
    p = QuasiPolynomial.from_poly(np.poly([-1.0, -1.0, -1.0]))
    h = p * QuasiPolynomial([[1.0], [0.5]], [0.0, 1.0])
    r = roots(h, (-3.0, 1.0, -0.5, 30.0))
    assert r.count == len(r.roots) == 3 + 5
    i = int(np.argmin(np.abs(r.distinct + 1)))
    assert r.multiplicities[i] == 3 and abs(r.distinct[i] + 1) < 1e-10


def test_random_retarded_quasipolynomials_counts_agree():
    rng = np.random.default_rng(7)
    for _ in range(8):
        deg = rng.integers(2, 5)
        m = rng.integers(1, 4)
        coeffs = np.zeros((m + 1, deg + 1))
        coeffs[0] = rng.normal(size=deg + 1)
        coeffs[0, -1] = 1.0
        coeffs[1:, :deg] = rng.normal(size=(m, deg))
        delays = np.concatenate([[0.0], np.sort(rng.uniform(0.2, 2.0, size=m))])
        h = QuasiPolynomial(coeffs, delays)
        rect = (-4.3, 3.1, -20.7, 40.9)
        r = roots(h, rect)
        assert r.count == len(r.roots)
        assert np.all(r.residuals <= 1e-12)
        if not r.shifted:
            assert round(_integral_count(h, rect, 100_000)) == r.count


@pytest.mark.parametrize(
    "region, exc, word",
    [
        ((0, 0, 0, 1), ValueError, "re_min"),
        ((1, 0, 0, 1), ValueError, "re_min"),
        ((0, 1, 2, 1), ValueError, "im_min"),
        ((0, 1, 0, np.nan), ValueError, "finite"),
        ((0, 1, 0), ValueError, "4 entries"),
        ("abcd", TypeError, "region"),
    ],
)
def test_bad_region(region, exc, word):
    with pytest.raises(exc, match=word):
        roots(QuasiPolynomial([[1.0, 1.0]]), region)


def test_bad_quasipolynomials():
    with pytest.raises(ValueError, match="identically zero"):
        roots(QuasiPolynomial.zero(), (0, 1, 0, 1))
    with pytest.raises(ValueError, match="finite"):
        roots(QuasiPolynomial([[np.inf, 1.0]]), (0, 1, 0, 1))
    with pytest.raises(ValueError, match="delays"):
        roots(QuasiPolynomial([[1.0], [1.0]], [0.0, -1.0]), (0, 1, 0, 1))
    # issue #14: a transfer function is no longer refused; roots() of a system are its poles (a lumped shaper has none)
    assert roots(posicast.design("zv", SEED000_MODE).transfer, (0, 1, 0, 1)).count == 0
    with pytest.raises(TypeError, match="QuasiPolynomial"):
        roots("s+1", (0, 1, 0, 1))
    with pytest.raises(ValueError, match="advanced"):
        stability(QuasiPolynomial([[1.0, 0.0], [0.0, 1.0]], [0.0, 1.0]))


def test_budget_fails_fast():
    h = posicast.design("zv", SEED000_MODE).num
    t0 = time.perf_counter()
    with pytest.raises(BudgetExceeded, match="max_evaluations"):
        roots(h, (-1e5, 1e5, 0, 1e6))
    assert time.perf_counter() - t0 < 1.0
    with pytest.raises(BudgetExceeded):
        roots(h, (-20, 5, 0, 5000), max_evaluations=1000)
    with pytest.raises(ValueError, match="max_evaluations"):
        roots(h, (-20, 5, 0, 50), max_evaluations=-1)
    with pytest.raises(ValueError, match="ignore"):
        roots(h, (-20, 5, 0, 50), ignore=[np.nan])
    with pytest.raises(ValueError, match="max_radius"):
        spectral_abscissa(h, max_radius=np.nan)
    with pytest.raises(ValueError, match="alpha"):
        root_bound(h, np.inf)


# ---------------------------------------------------------------------------- regressions found by issue #6
def _crane_loop(structure: str, kind: str, kp: float, kd: float) -> posicast.Loop:
    case = posicast.cases.ALL["gantry_crane"]
    return case.loop(structure, posicast.design(kind, case.mode), C=([kd, kp], [1.0]))


def test_exact_root_at_zero_of_every_term_is_found():
    """Crane, inverse DeZV (seed 001 Table 1 gains): every term of the characteristic vanishes at s = 0.

    Newton reaches that simple root as z ~ 1e-32, where |h| and its term scale are both
    rounding; it used to be rejected, and the reconciliation split the box until the
    budget ran out (19 s, BudgetExceeded).  The root is now snapped onto 0.
    """
    loop = _crane_loop("inverse_shaper", "dezv", 23.3, 0.465)
    t0 = time.perf_counter()
    r = roots(loop.characteristic, (-1, 1, -1, 50), ignore=loop.cancelled)
    assert r.count == 0 and r.removed.size == 1 and r.removed[0] == 0
    assert loop.stability().stable
    assert time.perf_counter() - t0 < 2.0


def test_double_root_at_zero_is_not_counted_twice():
    """Control-action DtZV: the triangular kernel puts a double removable root at s = 0.

    Newton stalls about sqrt(eps) away from a double root (here 1.3e-6), farther than
    the merge tolerance, so the same double root used to be found twice ("argument
    principle counts 3 but 4 roots were refined").  A point inside a cluster's
    certified Pellet disk is now recognised as one of its roots.
    """
    loop = _crane_loop("control_action", "dtzv", 0.188956, -0.667836)
    st = loop.stability()
    assert st.stable
    r = roots(loop.characteristic, (-0.3, 1.0, -0.5, 100))
    assert r.count == 3 and list(r.multiplicities) == [2, 1]


def test_stability_budget_is_passed_through():
    loop = _crane_loop("control_action", "dtazv", 5.041e11, -102.2)
    t0 = time.perf_counter()
    with pytest.raises(BudgetExceeded):
        loop.stability(max_evaluations=1e6, timeout=2.0)
    assert time.perf_counter() - t0 < 3.0


def test_multiple_root_is_separated_from_a_close_simple_root():
    """Inverse DtaZV near the real-root boundary Kp = 0: an exact double root at 0 (the
    shaper's removable point) and a genuine unstable root at 0.0044.

    The Pellet disk used to be taken at the largest certified radius, which swallowed
    both (m = 3), and the second suspect certified the same disk again: "counts 3 but
    6 roots were refined".  The smallest certified disk now separates them.
    """
    from scipy.optimize import brentq

    loop = _crane_loop("inverse_shaper", "dtazv", -0.012484753462867815, -1.6797005582523572)
    # independent: the real root by bisection of the (real) characteristic on the real axis
    real_root = brentq(lambda x: complex(loop.characteristic(x)).real, 0.003, 0.006, xtol=1e-16)
    r = roots(loop.characteristic, (-0.164, 1.0, -0.546, 546.4))
    assert r.count == 3
    assert list(r.multiplicities) == [1, 2]
    assert r.distinct[1] == 0 and abs(r.distinct[0] - real_root) < 1e-9
    st = loop.stability()
    assert not st.stable
    assert np.any(np.abs(st.unstable_roots - real_root) < 1e-9)   # the real root that crossed at Kp = 0
    assert not np.any(st.unstable_roots == 0)                        # the removable double root is cancelled


def test_a_root_exactly_at_zero_is_unstable():
    """h = s^n: the root bound at Re s >= 0 is 0, which used to end the search before s = 0 was looked at."""
    for n in (1, 2, 3):
        st = stability(QuasiPolynomial.from_poly([1.0] + [0.0] * n))
        assert not st.stable and st.unstable_roots.size == n and np.all(st.unstable_roots == 0)
    assert stability(QuasiPolynomial.from_poly([1.0, 2.0])).stable


def test_unstable_count_agrees_with_the_located_roots():
    """The perimeter-only count (used to label tuning cells) against stability(), which locates every
    root with Re s >= 0: random retarded quasi-polynomials, shifted so that some are unstable, and the
    crane's inverse-DeZV loop with its removable root at s = 0 ignored."""
    rng = np.random.default_rng(11)
    counts = []
    for _ in range(12):
        deg = int(rng.integers(2, 5))
        m = int(rng.integers(1, 3))
        coeffs = np.zeros((m + 1, deg + 1))
        coeffs[0] = rng.uniform(0.2, 3.0, size=deg + 1)
        coeffs[0, -1] = 1.0
        coeffs[0, 0] -= rng.uniform(0.0, 4.0)  # a shift of the constant term: some unstable, some not
        coeffs[1:, :deg] = rng.normal(size=(m, deg))
        h = QuasiPolynomial(coeffs, np.concatenate([[0.0], np.sort(rng.uniform(0.2, 2.0, size=m))]))
        n = unstable_count(h)
        counts.append(n)
        assert n == stability(h).unstable_roots.size
    assert min(counts) == 0 and max(counts) >= 1  # both kinds were exercised
    case = posicast.cases.ALL["gantry_crane"]
    for kp, expect in ((23.3, 0), (400.0, None)):
        loop = case.loop("inverse_shaper", posicast.design("dezv", case.mode), C=([0.465, kp], [1.0]))
        n = unstable_count(loop.characteristic, ignore=loop.cancelled)
        assert n == loop.stability().unstable_roots.size
        if expect is not None:
            assert n == expect


# ---------------------------------------------------------------------------- issue #13: hard and hostile inputs
def test_neutral_not_strongly_stable_roots_between_cd_and_hale_abscissa():
    """Appeltans & Michiels, TDS-CONTROL manual (2023), example 2.6 with tau2 = 2:
    s - 1/4 + (1/3 - 3 s/4) e^{-s} + (s/2) e^{-2 s}.  C_D = -ln(2)/2 = -0.3466, Hale abscissa
    0.1616: the rightmost pair -0.17012 +- 0.82383j lies between them, where Hale's bound is
    infinite.  spectral_abscissa returned C_D and rightmost(h, 2) returned [].  Reference:
    40-digit mpmath Newton polish of qpmr's roots; independent count by the h'/h integral."""
    h = QuasiPolynomial([[-0.25, 1.0], [1.0 / 3.0, -0.75], [0.0, 0.5]], [0.0, 1.0, 2.0])
    z0 = -0.17011804615991857031 + 0.82382686198763387123j
    ds = difference_spectrum(h)
    assert not ds.strongly_stable and ds.abscissa < z0.real < ds.hale_abscissa
    a = spectral_abscissa(h)
    assert abs(a - z0.real) < 1e-9 and a.error < 1e-9
    top = rightmost(h, 2)
    assert top.size == 2 and _match(top, np.array([z0, z0.conjugate()])) < 1e-9
    rect = (-0.3, 0.5, 0.1, 50.0)  # between the chains (Re -> C_D) and the Hale line: only z0
    assert round(_integral_count(h, rect)) == 1
    assert roots(h, rect).count == 1
    assert not stability(h).stable  # the verdict stays: not strongly stable


def test_multiple_dominant_root_gives_abscissa_and_rightmost():
    """A sixfold dominant root (multiplicity-induced dominancy, Mazanti, Boussaada & Niculescu 2021,
    n = 3, tau = 1): s^3 + 9 s - 6 + e^{-3} (3 s^2 + 42 s + 159) e^{-s} has s = -3 of multiplicity 6
    (Q^{(j)}(-3) = 0, j < 6, checked with mpmath).  The search line Re s = -3 went through the
    cluster and spectral_abscissa/rightmost raised RootFindingError; roots() found it."""
    e3 = math.exp(-3.0)
    h = QuasiPolynomial([[-6.0, 9.0, 0.0, 1.0], [159.0 * e3, 42.0 * e3, 3.0 * e3, 0.0]], [0.0, 1.0])
    a = spectral_abscissa(h)
    assert abs(a + 3.0) < 1e-9 and 0 < a.error < 0.1
    top = rightmost(h, 7)
    assert np.allclose(top[:6], -3.0, atol=1e-9) and top[6].real < -3.5
    poly = QuasiPolynomial.from_poly(np.poly([-1.0] * 6))  # (s + 1)^6: the line Re s = -1 hit it too
    assert spectral_abscissa(poly) == -1.0 and np.allclose(rightmost(poly, 6), -1.0)


def test_zvd3_high_frequency_clusters_are_certified():
    """ZVD^3 (= ZV^4) numerator up to 1e4 rad/s: 500 fourfold clusters.  High up the float delays
    are no longer exactly commensurate and each cluster splits into four roots ~3e-3 apart; one of
    them was taken for a simple root and the cluster "could not be isolated" (11-14 s, then
    RootFindingError; qpmr: 2000 roots in 8 s).  Each cluster sits on a ZV zero (seed 000 eq. 3)."""
    S = posicast.design("zvdk", SEED000_MODE, k=3)
    t0 = time.perf_counter()
    r = roots(S.num, (-20.0, 5.0, 0.0, 1e4))
    assert time.perf_counter() - t0 < 8.0
    assert r.count == len(r.roots) == 2000
    assert np.all(r.multiplicities == 4)
    Z = posicast.design("zv", SEED000_MODE)
    A0, tau = Z.impulses[1][0], Z.impulses[0][1]
    k = np.arange(0, 600)
    ref = -np.log(A0 / (1 - A0)) / tau + 1j * np.pi * (2 * k + 1) / tau
    ref = ref[ref.imag <= 1e4]
    assert ref.size == 500 and _match(r.distinct, ref) < 1e-9


def test_zvd_cubed_sixfold_clusters_are_certified():
    """design("zvd") convolved three times (ZV^6): sixfold zeros.  The cluster at 10 rad/s could not be
    isolated (its points scatter 1e-2 around it, the mean was too far off); high up the clusters are
    0.04 wide (the phase of exp(-s tau) is rounded to 1e-12) and need a wider certified disk.
    qpmr: 1500 of the 3000 roots up to 1e4 rad/s, 31 s; posicast: 3000 in about 3 s."""
    Z = posicast.design("zvd", SEED000_MODE).num
    r = roots(Z * Z * Z, (-20.0, 5.0, 0.0, 2000.0))
    assert r.count == len(r.roots) == 600 and np.all(r.multiplicities == 6)
    zv = roots(posicast.design("zv", SEED000_MODE).num, (-20.0, 5.0, 0.0, 2000.0))
    assert _match(r.distinct, zv.roots) < 1e-9


def test_roots_on_the_imaginary_axis_are_marginal():
    """s + e^{-s pi/2}: roots +-j exactly.  stability() said stable and spectral_abscissa returned
    +4e-18 (a rounding sign); now: marginal, abscissa exactly 0 with its certified error."""
    h = QuasiPolynomial([[0.0, 1.0], [1.0, 0.0]], [0.0, math.pi / 2])
    st = stability(h)
    assert not st.stable and st.marginal and "marginal" in st.reason
    assert np.allclose(np.sort_complex(st.unstable_roots), [-1j, 1j], atol=1e-12)
    assert 0 < st.axis_error < 1e-12
    a = spectral_abscissa(h)
    assert float(a) == 0.0 and a.marginal and 0 < a.error < 1e-12
    assert not bool(st)
    # a decided case keeps the old attributes and is not marginal
    st2 = stability(QuasiPolynomial([[1.0, 1.0], [0.5, 0.0]], [0, 1]))
    assert st2.stable and not st2.marginal and st2.axis_error == 0.0


@pytest.mark.parametrize(
    "call, exc, word",
    [
        (lambda h: roots(h, (-1, 1, 0, 1), max_evaluations=math.inf), ValueError, "max_evaluations"),
        (lambda h: roots(h, (-1, 1, 0, 1), max_evaluations=np.nan), ValueError, "max_evaluations"),
        (lambda h: roots(h, (-1, 1, 0, 1), max_evaluations=True), TypeError, "max_evaluations"),
        (lambda h: roots(h, (-1, 1, 0, 1), timeout=math.inf), ValueError, "timeout"),
        (lambda h: roots(h, (-1, 1, 0, 1), timeout=1j), TypeError, "timeout"),
        (lambda h: roots(h, (0, 1j, 0, 1)), TypeError, "region"),
        (lambda h: roots(h, (True, 2, 0, 1)), TypeError, "region"),
        (lambda h: roots(h, (1e200, 2e200, 0, 1)), ValueError, "float range"),
        (lambda h: stability(h, max_evaluations=math.inf), ValueError, "max_evaluations"),
        (lambda h: unstable_count(h, max_evaluations=math.inf), ValueError, "max_evaluations"),
        (lambda h: root_bound(h, 1j), TypeError, "alpha"),
        (lambda h: rightmost(h, True), ValueError, "n must be"),
        (lambda h: rightmost(h, 1, max_radius=np.nan), ValueError, "max_radius"),
    ],
)
def test_hostile_arguments_are_named_errors(call, exc, word):
    h = QuasiPolynomial([[1.0, 1.0], [0.5, 0.0]], [0.0, 1.0])
    with pytest.raises(exc, match=word):
        call(h)


def test_absurd_region_refused_up_front_with_the_estimate():
    h = QuasiPolynomial([[1.0, 1.0], [0.5, 0.0]], [0.0, 1.0])
    t0 = time.perf_counter()
    with pytest.raises(BudgetExceeded, match=r"needs a [0-9.e+]+-point grid"):
        roots(h, (-1e6, 1e6, -1e6, 1e6), max_evaluations=1e12)
    with pytest.raises(ValueError, match=r"1e\d+ and leave the float range; keep the region within"):
        roots(QuasiPolynomial.from_poly([1.0] + [0.0] * 9 + [1.0]), (0.0, 1.0, 1e100, 2e100))
    assert time.perf_counter() - t0 < 1.0
