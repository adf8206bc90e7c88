"""Streaming shaper and export (issue #4 section 2, acceptance 4 and the sampled part of 2, 6)."""

import json
import shutil
import subprocess

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import posicast as pc
from posicast.io.export import export_shaper
from posicast.simulation.streaming import FRACTIONAL, ShaperFilter, discretize, shape_signal

MODE = pc.Mode(10.0, 0.03)  # seed 000 eq. 26: F = s / (s^2 + 0.6 s + 100)
FS = 1000.0
KINDS = ["zv", "zvd", "ei", "dzv", "dezv", "dtzv", "dczv", "dtazv", "notch"]


def _chunked(filt, x, sizes):
    out, i = [], 0
    for n in sizes:
        out.append(filt.process(x[i : i + n]))
        i += n
    out.append(filt.process(x[i:]))
    return np.concatenate(out)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("fractional", FRACTIONAL)
def test_streaming_equals_batch_over_seeded_random_chunkings(kind, fractional):
    S = pc.design(kind, MODE)
    rng = np.random.default_rng(4)
    x = rng.standard_normal(2500)
    batch = shape_signal(S, x, FS, fractional)
    filt = ShaperFilter(S, FS, fractional)
    for trial in range(5):
        filt.reset()
        sizes = rng.choice([0, 0, 1, 1, 2, 3, 17, 100, 700], size=60)
        assert np.max(np.abs(_chunked(filt, x, sizes) - batch)) <= 1e-12
    filt.reset()
    pushed = np.array([filt.push(float(v)) for v in x[:400]])
    assert np.max(np.abs(pushed - batch[:400])) <= 1e-12


@settings(max_examples=60, deadline=None)
@given(
    sizes=st.lists(st.integers(0, 90), min_size=0, max_size=40),
    kind=st.sampled_from(["zv", "dzv", "notch", "dtzv"]),
    fractional=st.sampled_from(FRACTIONAL),
)
def test_streaming_equals_batch_hypothesis(sizes, kind, fractional):
    S = pc.design(kind, MODE)
    x = np.sin(np.arange(1200) * 0.37) + (np.arange(1200) > 300)
    batch = shape_signal(S, x, FS, fractional)
    assert np.max(np.abs(_chunked(ShaperFilter(S, FS, fractional), x, sizes) - batch)) <= 1e-12


@pytest.mark.parametrize("kind", KINDS)
def test_taps_sum_to_dc_gain_and_step_settles(kind):
    S = pc.design(kind, MODE)
    for fr in FRACTIONAL:
        D = discretize(S, FS, fr)
        if S.continuous is None:
            assert D.taps.sum() == pytest.approx(S.dc_gain, abs=1e-15)
        assert D.dc_gain == pytest.approx(S.dc_gain, abs=1e-11)  # Tustin's IIR DC: rounding only
    y = shape_signal(S, np.ones(3000), FS)
    assert y[-1] == pytest.approx(1.0, abs=1e-9)


def test_initial_state_is_steady():
    f = ShaperFilter(pc.design("dzv", MODE), FS, initial=2.5)
    assert np.allclose(f.process(np.full(50, 2.5)), 2.5, atol=1e-13)


def test_residual_vibration_of_the_taps_zv_seed000_at_1khz():
    # Acceptance 2 (sampled part) as a property of the taps: |S_d(p)| = |sum_k w_k exp(-p k Ts)| at
    # the pole p of seed 000's F (omega 10, zeta 0.03), relative to the unshaped (S = 1, |1| = 1).
    # The ZV delay pi/Omega = 0.3143 s is not a multiple of 1 ms.
    S = pc.design("zv", MODE)
    assert S.times[1] == pytest.approx(0.31430073, abs=1e-8)
    res = {fr: abs(discretize(S, FS, fr).at_s(MODE.pole)) for fr in FRACTIONAL}
    print("ZV residual |S_d(p)| at 1 kHz:", {k: f"{v:.3g}" for k, v in res.items()})
    # measured: round 1.57e-3, linear 5.51e-6, lagrange3 1.01e-10
    # (the ~6e-5 quoted in issue #4 is the y amplitude in the loop, not this relative |S_d(p)|;
    # rounding 0.30 ms of delay leaves |S(p)| ~ A_1 |p| delta = 0.52 * 10 * 3.0e-4 = 1.6e-3)
    assert res["round"] == pytest.approx(0.52355511 * abs(MODE.pole) * (0.314 - 0.31430073) * -1, rel=0.05)
    assert res["lagrange3"] < res["linear"] < res["round"] / 100
    assert res["linear"] < 1e-5
    assert res["lagrange3"] < 1e-9


@pytest.mark.parametrize("kind", ["dzv", "dezv", "dtzv", "dczv", "dtazv", "zvd"])
def test_residual_vibration_distributed_and_products(kind):
    S = pc.design(kind, MODE)
    lin = abs(discretize(S, FS, "linear").at_s(MODE.pole))
    lag = abs(discretize(S, FS, "lagrange3").at_s(MODE.pole))
    print(kind, f"linear {lin:.3g}  lagrange3 {lag:.3g}")
    assert lin < 5e-6  # measured 0.9e-6 .. 4.0e-6 for the distributed kinds, 2.5e-6 for zvd
    assert lag < 1e-9  # measured 1.7e-11 .. 7.4e-11, 4.5e-11 for zvd
    # a two-mode product with a convolution of kernels (DZV * DeZV)
    m2 = pc.Mode(30.0, 0.1)
    P = S * pc.design("dezv", m2)
    D = discretize(P, FS, "lagrange3")
    assert abs(D.at_s(MODE.pole)) < 1e-9 and abs(D.at_s(m2.pole)) < 1e-7  # measured 2.6e-11, 3.9e-9


def test_bad_inputs():
    S = pc.design("zv", MODE)
    with pytest.raises(ValueError, match=r"sample_rate = 3 Hz.*Nyquist.*> 3\.18"):
        discretize(S, 3.0)  # ZV: delay pi/Omega >= 1 sample and mode < Nyquist coincide (3.18 Hz)
    with pytest.raises(ValueError, match=r"sample_rate = 300 Hz.*0\.002 s is below one sample.*>= 500 Hz"):
        discretize(pc.Shaper([0.0, 0.002], [0.5, 0.5]), 300.0)
    with pytest.raises(ValueError, match=r"sample_rate.*below one sample.*>= 500 Hz"):
        discretize(pc.design("dezv", MODE, T=0.002), 300.0)  # a 2 ms kernel
    with pytest.raises(ValueError, match=r"sample_rate.*Nyquist.*> 318\.3"):
        discretize(pc.design("zv", pc.Mode(1000.0, 0.03)), 300.0)
    with pytest.raises(ValueError, match="sample_rate"):
        ShaperFilter(S, -1.0)
    with pytest.raises(ValueError, match="fractional"):
        discretize(S, FS, "cubic")
    with pytest.raises(TypeError, match="S must be"):
        discretize("zv", FS)
    f = ShaperFilter(S, FS)
    with pytest.raises(ValueError, match="sample"):
        f.push(float("nan"))
    with pytest.raises(ValueError, match=r"chunk.*sample 2"):
        f.process([0.0, 1.0, np.nan])
    with pytest.raises(ValueError, match="x must be finite"):
        shape_signal(S, [np.inf], FS)
    with pytest.raises(ValueError, match="1-D"):
        f.process(np.zeros((2, 2)))


# ---------------------------------------------------------------------- export
@pytest.mark.parametrize("kind", ["zv", "dzv", "notch"])
def test_json_round_trip(kind):
    S = pc.design(kind, MODE)
    D = discretize(S, FS)
    doc = json.loads(export_shaper(S, FS, "json", form="dense"))
    assert np.array_equal(doc["taps"], D.taps)  # exact: JSON floats round-trip
    assert doc["sample_rate"] == FS
    assert doc["design"]["impulses"]["times"] == S.times.tolist()
    assert doc["design"]["impulses"]["amplitudes"] == S.amplitudes.tolist()
    sp = json.loads(export_shaper(S, FS, "json"))["sparse"]      # the sparse form: the same taps
    assert np.array_equal(sp["index"], D.sparse.index) and np.array_equal(sp["weight"], D.sparse.weight)
    if kind == "notch":
        assert np.array_equal(doc["iir"]["b"], D.b) and np.array_equal(doc["iir"]["a"], D.a)
    else:
        assert doc["iir"] is None


def test_export_bad_inputs():
    S = pc.design("zv", MODE)
    with pytest.raises(ValueError, match="format"):
        export_shaper(S, FS, "xml")
    with pytest.raises(ValueError, match="name"):
        export_shaper(S, FS, "c", name="1bad-name")


_C_MAIN = r"""
#include <stdio.h>
#include "shaper.h"
int main(void) {
    shaper_state st;
    int n;
    shaper_init(&st, (shaper_real)0);
    for (n = 0; n < NSAMPLES; ++n) printf("%.17g\n", (double)shaper_step(&st, (shaper_real)(n >= 10 ? 1.0 : 0.0)));
    return 0;
}
"""


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
@pytest.mark.parametrize("kind", ["zv", "dzv"])
@pytest.mark.parametrize("acc", ["double", "float"])
def test_c_export_compiles_and_runs(kind, acc, tmp_path):
    S = pc.design(kind, MODE)
    (tmp_path / "shaper.h").write_text(export_shaper(S, FS, "c", precision=acc))
    (tmp_path / "main.c").write_text(_C_MAIN)
    n = 900
    exe = tmp_path / "run"
    subprocess.run(
        ["cc", "-std=c99", "-Wall", "-Werror", f"-DNSAMPLES={n}", "-o", str(exe),
         str(tmp_path / "main.c")],
        check=True, capture_output=True,
    )
    out = np.array(subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout.split(), float)
    x = (np.arange(n) >= 10).astype(float)
    ref = shape_signal(S, x, FS)
    err = np.max(np.abs(out - ref))
    N = discretize(S, FS).n_taps
    print(kind, acc, N, "taps: C vs shape_signal:", err)
    # issue #16: sparse taps and running sums, sums in double; float coefficients and history: ~1e-7
    assert err <= (1e-12 if acc == "double" else 1e-6)
    assert N > 100 if kind == "dzv" else True


def test_sample_rate_beyond_the_tap_budget_is_refused_with_the_estimate():
    """A ZV at 10 rad/s is pi/10 s long: at 1e12 Hz that is 3.1e11 taps (2.5 TB), refused before allocation."""
    from posicast.simulation.streaming import MAX_TAPS

    S = pc.design("zv", pc.Mode(10.0, 0.0))
    with pytest.raises(ValueError, match=r"would need about 3\.14e\+11 taps .*lower sample_rate"):
        discretize(S, 1e12)
    n = discretize(S, 0.9 * MAX_TAPS / (np.pi / 10)).n_taps  # just inside the budget
    assert n <= MAX_TAPS
    D = discretize(S, 100.0)
    with pytest.raises(ValueError, match="z must be nonzero"):
        D(0.0)
    with pytest.raises(ValueError, match="s = "):
        D.at_s(-1e6)  # exp(-1e4) underflows: z = 0
