"""Issue #16 acceptance 5: the seed 000 experiment loop (Quanser flexible link, eq. 28-29) as it runs at 200 Hz."""

import numpy as np
import pytest
from scipy import signal

import posicast as pc
from posicast.simulation.sampled_spectrum import SampledLoop, sampled_loop
from posicast.simulation.streaming import discretize

CASE = pc.cases.flexible_link()
FS = 200.0


def _tf_roots(S, d, method="bilinear"):
    """Closed-loop poles from z^-1 polynomials (independent of SampledLoop's state space):
    control action 1 + C G S_d = 0, inverse shaper S_d + C G = 0, with d samples of delay on G."""
    h = 1.0 / FS
    (nc,), dc, _ = signal.cont2discrete((CASE.C.num.coeffs[0][::-1], CASE.C.den.coeffs[0][::-1]), h, method=method)
    (ng,), dg, _ = signal.cont2discrete((CASE.G.num.coeffs[0][::-1], CASE.G.den.coeffs[0][::-1]), h, method="zoh")
    # descending powers of z of equal length -> ascending powers of z^-1
    nc, dc, ng, dg = (np.trim_zeros(np.atleast_1d(p), "f") for p in (nc, dc, ng, dg))
    nc, dc = np.pad(nc, (dc.size - nc.size, 0)), dc
    ng, dg = np.pad(ng, (dg.size - ng.size, 0)), dg
    ng = np.concatenate([np.zeros(d), ng])                         # z^-d
    w = np.array([1.0]) if S is None else discretize(S, FS).taps
    inverse = S is not None and S is not None and _tf_roots.inverse
    a = np.convolve(np.convolve(w, dc), dg) if inverse else np.convolve(dc, dg)
    b = np.convolve(nc, ng) if inverse else np.convolve(np.convolve(nc, ng), w)
    n = max(a.size, b.size)
    char = np.pad(a, (0, n - a.size)) + np.pad(b, (0, n - b.size))  # in z^-1, ascending
    return np.roots(char)


def test_state_space_poles_equal_the_transfer_function_poles():
    for arch, kind, d in [("control_action", None, 0), ("control_action", None, 2), ("control_action", "zv", 1),
                          ("inverse_shaper", "zv", 0), ("inverse_shaper", "dzv", 2)]:
        S = None if kind is None else pc.design(kind, CASE.mode)
        _tf_roots.inverse = arch == "inverse_shaper"
        ref = _tf_roots(S, d)
        L = SampledLoop(CASE.loop(arch, S), FS, computation_delay=d)
        z = L.poles()
        ref = ref[np.abs(ref) > 1e-5]       # the delay lines add poles at z = 0 (split to ~1e-7 by rounding)
        z = z[np.abs(z) > 1e-5]
        assert z.size == ref.size
        assert L.spectral_radius == pytest.approx(np.max(np.abs(ref)), abs=1e-7)


def test_seed000_experiment_spectral_radius_at_200hz():
    """The paper (section VI-B): the inverse ZV loop was unstable in the 200 Hz experiment, the inverse DZV not.

    Continuous model (eq. 28-29): inverse ZV stable, abscissa -0.82.  Sampled at 200 Hz (Tustin C, ZOH G, the
    shaper's taps on the grid): still stable, spectral radius 0.99665 (slowest poles s = -0.67 +- 45.7j).
    With a computation delay of 2 samples (10 ms between reading z and applying u) it is unstable
    (radius 1.000035), while the inverse DZV keeps radius 0.987.
    """
    none = SampledLoop(CASE.loop("control_action"), FS)
    zv = SampledLoop(CASE.loop("inverse_shaper", pc.design("zv", CASE.mode)), FS)
    dzv = SampledLoop(CASE.loop("inverse_shaper", pc.design("dzv", CASE.mode)), FS)
    print(f"200 Hz: no shaper {none.spectral_radius:.6f}, inverse ZV {zv.spectral_radius:.6f}, "
          f"inverse DZV {dzv.spectral_radius:.6f}")
    assert none.spectral_radius == pytest.approx(0.926647, abs=2e-6)
    assert zv.spectral_radius == pytest.approx(0.996649, abs=2e-6) and zv.stability() == "stable"
    assert dzv.spectral_radius == pytest.approx(0.981004, abs=2e-6)
    s = zv.s_poles(2)
    assert s[0].real == pytest.approx(-0.67, abs=0.01) and abs(s[0].imag) == pytest.approx(45.74, abs=0.05)
    assert pc.spectral_abscissa(CASE.loop("inverse_shaper", pc.design("zv", CASE.mode))) == pytest.approx(-0.82, abs=0.005)
    radii = {d: SampledLoop(CASE.loop("inverse_shaper", pc.design("zv", CASE.mode)), FS, computation_delay=d)
             for d in (1, 2)}
    assert radii[1].stability() == "stable" and radii[2].stability() == "unstable"
    assert radii[2].spectral_radius == pytest.approx(1.000035, abs=2e-6)
    assert SampledLoop(CASE.loop("inverse_shaper", pc.design("dzv", CASE.mode)), FS,
                       computation_delay=2).spectral_radius == pytest.approx(0.987355, abs=2e-6)


def test_sampled_loop_bad_input():
    L = CASE.loop("control_action")
    with pytest.raises(ValueError, match="computation_delay must be an integer >= 0"):
        SampledLoop(L, FS, computation_delay=-1)
    with pytest.raises(ValueError, match="sample_rate must be > 0"):
        SampledLoop(L, 0.0)
    with pytest.raises(ValueError, match="controller_method must be one of"):
        sampled_loop(L, FS, controller_method="euler")
    with pytest.raises(TypeError, match="loop must be a posicast Loop"):
        SampledLoop("loop", FS)
    with pytest.raises(ValueError, match="IIR part"):
        SampledLoop(CASE.loop("control_action", pc.design("notch", CASE.mode)), FS)
