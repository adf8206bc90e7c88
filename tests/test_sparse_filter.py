"""Issue #16 acceptance 2, 3 and 6: sparse real-time filters, forward and inverse, and the inverse's stability."""

import math

import numpy as np
import pytest
from scipy import signal

import posicast as pc
from posicast.shapers.base import Shaper
from posicast.simulation.sparse import SparseEngine, inverse_stability
from posicast.simulation.streaming import ShaperFilter, _dense_shape, discretize, shape_signal

FS = 1000.0
MODE = pc.Mode.from_hz(3.0, 0.05)
KINDS = ["zv", "zvd", "zvddd", "ei", "ei3", "mzv", "dzv", "dezv", "dtzv", "dczv", "dtazv", "notch"]
RUNNING_SUMS = {"dzv": 1, "dezv": 1, "dtzv": 2, "dtazv": 1, "dczv": 1}  # segments per kind (kernel pieces)


def _signal(n, seed=0):
    rng = np.random.default_rng(seed)
    return np.cumsum(rng.standard_normal(n)) / 10.0 + np.where(np.arange(n) > n // 3, 2.0, 0.0)


@pytest.mark.parametrize("kind", KINDS)
def test_sparse_equals_dense_convolution(kind):
    D = discretize(pc.design(kind, MODE), FS)
    x = _signal(4000)
    y = shape_signal(D, x, FS)
    ref = _dense_shape(D, x)                         # the dense filter every tap (before issue #16)
    assert np.max(np.abs(y - ref)) <= 1e-12 * max(1.0, np.max(np.abs(x)))
    sp = D.sparse
    assert len(sp.segments) == RUNNING_SUMS.get(kind, 0)
    dense = sp.dense()
    assert np.max(np.abs(dense[: D.n_taps] - D.taps)) <= 1e-15 and not np.any(dense[D.n_taps:])
    if kind in RUNNING_SUMS:      # the kernel's taps are in the segments: few sparse taps remain
        assert sp.index.size <= 12 and sp.n_terms <= 16


def test_per_sample_work_does_not_grow_with_the_shaper_duration():
    # the same ZVD (and DZV) for a mode 100 times slower: same number of terms per sample
    fast, slow = pc.Mode.from_hz(5.0, 0.02), pc.Mode.from_hz(0.05, 0.02)
    for kind in ("zvd", "dzv", "dtazv", "dczv"):
        a, b = discretize(pc.design(kind, fast), 10000.0), discretize(pc.design(kind, slow), 10000.0)
        assert b.sparse.span > 90 * a.sparse.span
        assert a.sparse.n_terms == b.sparse.n_terms


@pytest.mark.parametrize("kind", ["zvd", "dzv", "dtzv", "dczv", "notch"])
@pytest.mark.parametrize("inverse", [False, True])
def test_streaming_equals_batch_exactly(kind, inverse):
    S = pc.design(kind, pc.Mode.from_hz(3.0, 0.1))
    if inverse and kind == "notch":
        with pytest.raises(ValueError, match="IIR part"):
            ShaperFilter(S, FS, inverse=True)
        return
    x = _signal(3000, 1)
    batch = shape_signal(S, x, FS, inverse=inverse)
    f = ShaperFilter(S, FS, inverse=inverse)
    rng = np.random.default_rng(2)
    out, i = [], 0
    while i < x.size:
        n = int(rng.integers(0, 400))
        out.append(f.process(x[i: i + n]))
        i += n
    f2 = ShaperFilter(S, FS, inverse=inverse)
    single = [f2.push(v) for v in x[:500]]
    assert np.array_equal(np.concatenate(out), batch)           # bit for bit, however chunked
    assert np.array_equal(single, batch[:500])


def test_running_sums_resynchronise_exactly():
    # a resync every 50 samples (at absolute sample numbers) leaves the output that of the dense taps
    for kind in ("dtzv", "dczv"):
        D = discretize(pc.design(kind, pc.Mode.from_hz(20.0, 0.05)), FS)
        x = _signal(2000, 3) * 1e3
        ref = signal.lfilter(D.taps, [1.0], x)
        for resync in (50, 97, None):
            e = SparseEngine(D.sparse, False, 0.0, resync=resync)
            y = np.concatenate([e.process(x[:333]), e.process(x[333:])])
            assert np.max(np.abs(y - ref)) <= 1e-12 * np.max(np.abs(x))


@pytest.mark.parametrize("kind", ["zv", "dzv"])
@pytest.mark.parametrize("case_name", ["flexible_link", "simulation_example"])
def test_inverse_filters_equal_the_simulators_recursions(kind, case_name):
    # Acceptance 3: seed 000 eq. 19 (inverse ZV) and eq. 20 (inverse DZV) as the simulator runs them inside
    # the inverse-shaper loop: m = (1/S)(z); the streaming inverse filter fed the loop's z gives the same m.
    case = pc.cases.ALL[case_name]
    fs = case.sample_rate or 1000.0
    S = pc.design(kind, case.mode)
    loop = case.loop("inverse_shaper", S)
    t = np.arange(0.0, 8.0, 1.0 / fs)
    r = pc.simulate(loop, t, np.where(t >= 0.5, 1.0, 0.0), d=np.where(t >= 4.0, 0.3, 0.0), sample_rate=fs)
    z, m = r.signals["z"], r.signals["m"]
    f = ShaperFilter(S, fs, inverse=True)
    mm = np.concatenate([f.process(z[:777]), f.process(z[777:])])
    err = np.max(np.abs(mm - m))
    print(case_name, kind, f.stability, f"max |m_filter - m_simulator| = {err:.2e}")
    assert err <= 1e-12 * max(1.0, np.max(np.abs(m)))          # measured 4e-16 (zv), 4e-15 (dzv) at 200 Hz
    assert f.stability.verdict == "stable"
    # the inverse decays no faster than the mode it cancels: |z| >= exp(-zeta omega / fs) for the mode's zero
    assert f.stability.spectral_radius >= math.exp(-case.mode.decay / fs) * (1 - 1e-5)


def test_inverse_stability_verdicts():
    undamped = pc.Mode(math.pi * 100.0 / 20.0, 0.0)       # ZV delay pi/omega = 20 samples at 100 Hz, on the grid
    S = pc.design("zv", undamped)
    st = discretize(S, 100.0).inverse_stability()
    assert st.verdict == "marginal" and st.spectral_radius == pytest.approx(1.0, abs=1e-12)
    with pytest.raises(ValueError, match="is marginal: S_d.z. has a zero of modulus 1"):
        ShaperFilter(S, 100.0, inverse=True)
    f = ShaperFilter(S, 100.0, inverse=True, allow_marginal=True)     # the neutral recursion: runs, never decays
    y = f.process(np.r_[1.0, np.zeros(199)])
    assert np.max(np.abs(y[-40:])) == pytest.approx(2.0, rel=1e-12)   # m[n] = 2 x[n] - m[n-20]: +-2 forever
    bad = Shaper([0.0, 0.2], [0.3, 0.7], name="negative-heavy")       # |z|^20 = 0.7/0.3 > 1
    with pytest.raises(ValueError, match=r"is unstable: S_d\(z\) has a zero of modulus 1.04327"):
        shape_signal(bad, np.ones(10), 100.0, inverse=True)
    assert discretize(bad, 100.0).inverse_stability().spectral_radius == pytest.approx((0.7 / 0.3) ** (1 / 20), rel=1e-12)
    with pytest.raises(ValueError, match="nonzero undelayed tap"):
        ShaperFilter(Shaper([0.01, 0.2], [0.5, 0.5]), 100.0, inverse=True)
    with pytest.raises(TypeError, match="inverse must be True or False"):
        ShaperFilter(S, 100.0, inverse=1)


def test_winding_number_radius_matches_the_analytic_one():
    # degree above the np.roots limit: ZV on the grid with 1000 samples of delay, zeros |z| = K^(1/1000)
    zeta = 0.05
    m = pc.Mode(math.pi * 1000.0 / 1000.0 / math.sqrt(1 - zeta ** 2), zeta)
    D = discretize(pc.design("zv", m), 1000.0)
    assert D.n_taps == 1001
    K = math.exp(-zeta * math.pi / math.sqrt(1 - zeta ** 2))
    st = D.inverse_stability()
    # all 1000 zeros share one modulus: the bisection stops where the finest FFT grid no longer resolves them
    assert st.verdict == "stable" and abs(st.spectral_radius - K ** (1 / 1000)) <= st.resolution
    assert st.resolution == pytest.approx(1.2e-5, rel=0.01)
    assert inverse_stability(D.taps[:401], 1000.0).spectral_radius == pytest.approx(
        float(np.max(np.abs(np.roots(D.taps[:401])))), rel=1e-12)
