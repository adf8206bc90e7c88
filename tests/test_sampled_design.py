"""Issue #16 acceptance 1 and 6: z-plane shapers for the controller's sample period (seed 002 eq. 4-12)."""

import math
import warnings

import numpy as np
import pytest

import posicast as pc
from posicast.shapers.sampled import (GAIN_WARN, highest_multiplicity, sampled_pole, zplane_shaper,
                                      zplane_taps)
from posicast.simulation.streaming import discretize

M28 = pc.Mode.from_hz(28.0, 0.05)     # seed 002 section 3.2
SLOW = pc.Mode.from_hz(0.05, 0.01)    # a crane-like mode
PERIODS = [1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 0.0125, math.pi / M28.damped_omega]   # up to half the period


def eq8_taps(mode, T):
    """Seed 002 eq. 6, 8, 9 written out with complex numbers (independent of the module)."""
    beta, Om = mode.zeta * mode.omega, mode.omega * math.sqrt(1 - mode.zeta ** 2)
    z1 = np.exp(-T * beta) * np.exp(1j * T * Om)          # eq. 6
    z2 = np.conj(z1)
    a = np.array([1.0, -(z1 + z2), z1 * z2])              # eq. 9
    return (a / a.sum()).real                              # C = 1 / (a0 + a1 + a2)


@pytest.mark.parametrize("T", PERIODS)
def test_zv_taps_are_eq8_and_zero_on_sampled_pole(T):
    S = pc.design("zv", M28, sample_period=T, stride=1) if T >= 1e-3 else None
    if S is None:
        with pytest.warns(UserWarning, match="stride='positive'"):
            S = pc.design("zv", M28, sample_period=T, stride=1)
    ref = eq8_taps(M28, T)
    full = np.zeros(3)
    full[np.rint(S.times / T).astype(int)] = S.amplitudes
    assert np.allclose(full, ref, rtol=1e-13, atol=1e-13 * np.abs(ref).sum())
    assert np.allclose(S.times / T, np.rint(S.times / T), atol=1e-12)  # on the grid k T
    zp = sampled_pole(M28, T)
    val = abs(np.polyval(S.amplitudes[::-1], 1.0 / zp))    # F(z_p) = sum A_k z_p^-k
    assert val <= 1e-12                                    # measured 7.8e-13 at 0.1 ms (tap gain 1.3e4)
    assert abs(S(M28.pole)) <= 1e-12                       # the same as a continuous shaper
    assert S.dc_gain == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("mult", [1, 2, 3, 5])
@pytest.mark.parametrize("T", PERIODS)
@pytest.mark.parametrize("mode", [M28, SLOW], ids=["28Hz", "0.05Hz"])
def test_multiplicity_derivatives_vanish(mode, T, mult):
    # positive stride: |S(z_p)| <= 1e-12 absolutely at every period from 0.1 ms to half the period;
    # d^j/ds^j S(s) at p, j < m: sum_k A_k (-t_k)^j e^{-p t_k} = 0 (relative to sum |A_k| t_k^j)
    S = zplane_shaper(mode, T, mult, "positive")
    assert S.is_positive and S.dc_gain == pytest.approx(1.0, abs=1e-13)
    assert abs(S(mode.pole)) <= 1e-12
    k = S.times / T
    assert np.allclose(k, np.rint(k), atol=1e-9)
    for j in range(mult):
        d = np.sum(S.amplitudes * k ** j * np.exp(-mode.pole * S.times))
        assert abs(d) <= 1e-12 * np.sum(np.abs(S.amplitudes) * k ** j)
    # the m-th derivative does not vanish: the multiplicity is exactly m (at half the period the
    # pair merges on the negative real axis, z_p = -|z_p|, and the zero there is double: 2m)
    order = 2 * mult if T * mode.damped_omega == pytest.approx(math.pi, rel=1e-12) else mult
    d = np.sum(S.amplitudes * k ** order * np.exp(-mode.pole * S.times))
    assert abs(d) > 1e-6 * np.sum(np.abs(S.amplitudes) * k ** order)


@pytest.mark.parametrize("kind,mult", [("zv", 1), ("zvd", 2), ("zvdd", 3), ("zvddd", 4)])
def test_kinds_have_their_multiplicity_and_stride_one_matches_polynomial(kind, mult):
    T = 0.01
    S = pc.design(kind, M28, sample_period=T)
    zp = sampled_pole(M28, T)
    ref = np.real(np.poly([zp] * mult + [np.conj(zp)] * mult))  # monic in z: coefficients of z^-k
    ref = ref / ref.sum()
    assert np.allclose(S.amplitudes, ref, atol=1e-14)
    assert S.times.size == 2 * mult + 1 and S.duration == pytest.approx(2 * mult * T, rel=1e-15)
    assert pc.design("zvdk", M28, sample_period=T, k=mult - 1).amplitudes == pytest.approx(S.amplitudes, abs=0)


def test_zv_special_case_eq10_12():
    # at T_vz = pi / (2 Omega) (eq. 11 with T = 1/omega_n) a_1 = 0 and F is the continuous ZV (eq. 12)
    for mode in (M28, SLOW, pc.Mode(8.98, 0.14)):
        Tvz = math.pi / (2.0 * mode.damped_omega)
        assert Tvz == pytest.approx(math.pi * (1 / mode.omega) / (2 * math.sqrt(1 - mode.zeta ** 2)), rel=1e-15)
        S, Z = pc.design("zv", mode, sample_period=Tvz), pc.design("zv", mode)
        assert S.n_impulses == 2
        assert np.allclose(S.times, Z.times, rtol=1e-15) and np.allclose(S.amplitudes, Z.amplitudes, atol=2e-16)
        K = math.exp(-mode.zeta * math.pi / math.sqrt(1 - mode.zeta ** 2))   # eq. 1's K = a_2 of eq. 12
        assert S.amplitudes[1] == pytest.approx(K / (1 + K), rel=1e-14)


def test_discretised_continuous_shaper_reports_its_residual():
    # the measurements: continuous ZV / ZVD discretised at 100 Hz leave 12.8 % / 4.6 % on the 28 Hz mode
    zv, zvd = discretize(pc.design("zv", M28), 100.0), discretize(pc.design("zvd", M28), 100.0)
    assert zv.residual == pytest.approx(0.1277, abs=5e-4)
    assert zvd.residual == pytest.approx(0.0456, abs=5e-4)
    assert "residual" in repr(zv)
    assert discretize(pc.design("zv", M28, sample_period=0.01), 100.0).residual < 1e-15


def test_several_modes_and_actuator_order():
    m2 = pc.Mode.from_hz(70.0, 0.02)
    S = pc.design("zvd", [M28, m2], sample_period=1e-3, stride="positive")
    assert S.is_positive and all(abs(S(m.pole)) < 1e-14 for m in S.modes)
    assert S.params["stride"] == [9, 4]
    # seed 002 section 4.1: 10 ms actuator period, 100 ms rise time -> "ZVD_4" (multiplicity 5)
    c = highest_multiplicity(M28, 0.01, 0.1)
    assert (c.multiplicity, c.stride) == (5, (1,)) and c.shaper.name == "zvd4"
    assert c.duration == pytest.approx(0.1, rel=1e-12) and c.shaper.duration <= 0.1 + 1e-12
    assert highest_multiplicity(M28, 0.01, 0.099).multiplicity == 4
    slow = highest_multiplicity(pc.Mode.from_hz(2.0, 0.05), 0.01, 1.5, stride="positive")
    assert slow.stride == (13,) and slow.multiplicity == 5 and slow.shaper.is_positive


def test_short_period_stride_one_warns_and_says_why():
    with pytest.warns(UserWarning, match="tap gain"):
        S = pc.design("zvd", SLOW, sample_period=1e-3, stride=1)
    assert S.params["tap_gain"] > GAIN_WARN and not S.is_positive
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        P = pc.design("zvd", SLOW, sample_period=1e-4, stride="positive")
    assert P.n_impulses == 5 and P.params["stride"] == [50003]


def test_bad_input_named_errors():
    half = math.pi / M28.damped_omega
    pc.design("zv", M28, sample_period=half)       # half the period is allowed
    with pytest.raises(ValueError, match="sample_period = .* too long .* half the damped period"):
        pc.design("zv", M28, sample_period=half * 1.001)
    with pytest.raises(ValueError, match="multiplicity must be an integer >= 1, got 0"):
        zplane_shaper(M28, 0.01, 0)
    with pytest.raises(ValueError, match="k must be an integer >= 0"):
        pc.design("zvdk", M28, sample_period=0.01, k=-1)
    with pytest.raises(ValueError, match="stride must be an integer >= 1"):
        zplane_shaper(M28, 0.01, 1, 0)
    with pytest.raises(ValueError, match="sample_period must be > 0"):
        pc.design("zv", M28, sample_period=0.0)
    with pytest.raises(ValueError, match="sample_period is supported for kinds"):
        pc.design("ei", M28, sample_period=0.01)
    with pytest.raises(TypeError, match="takes no parameter 'stride'"):
        pc.design("zv", M28, stride=2)
    with pytest.raises(TypeError, match="multiplicity must be an integer"):
        zplane_taps(M28, 0.01, 1.5)
    with pytest.raises(ValueError, match="rise_time = .* shorter"):
        highest_multiplicity(M28, 0.01, 0.01)


def test_design_default_stride_is_the_smallest_with_nonnegative_taps():
    """design(..., sample_period=T) gives usable taps by default: the seed's adjacent taps where they are
    nonnegative (28 Hz at 10 ms), otherwise the smallest stride with nonnegative taps and the same exact zeros."""
    seed = pc.design("zvd", M28, sample_period=0.01, stride=1)
    default = pc.design("zvd", M28, sample_period=0.01)
    assert default.params["stride"] == [1] and np.array_equal(default.amplitudes, seed.amplitudes)
    with warnings.catch_warnings():
        warnings.simplefilter("error")             # no tap-gain warning with the default
        S = pc.design("zvd", M28, sample_period=1e-3)
    n = math.ceil(math.pi / (2 * M28.damped_omega * 1e-3))   # n Omega T >= pi / 2
    assert S.params["stride"] == [n] and S.is_positive and abs(S(M28.pole)) <= 1e-12
