"""Tests for posicast.shapers.ei: extra-insensitive shapers, damped, from their definitions.

Every number asserted here comes from somewhere independent of the solver:
the undamped closed forms, or the definitions themselves checked with the
residual-vibration formula of seed 004 eq. 1-3 written out again below.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from posicast.modes import Mode
from posicast.shapers import ei
from posicast.shapers.ei import ei_exact, ei_fit, ei_fit_report, ei_multi_hump

VTOLS = (0.02, 0.05, 0.1, 0.15)


# --- an independent residual-vibration formula (seed 004 eq. 1-3) -------------------


def vib(times, amps, zeta, omega):
    """V(omega) = e^{-zeta w t_n} sqrt(C^2 + S^2), C/S = sum A e^{zeta w t} cos/sin(w_d t)."""
    w = np.atleast_1d(np.asarray(omega, dtype=float))[:, None]
    t = np.asarray(times, dtype=float)[None, :]
    a = np.asarray(amps, dtype=float)[None, :]
    wd = w * math.sqrt(1.0 - zeta**2)
    g = a * np.exp(zeta * w * (t - t[0, -1]))  # the e^{-zeta w t_n} folded in (no overflow)
    c = (g * np.cos(wd * t)).sum(axis=1)
    s = (g * np.sin(wd * t)).sum(axis=1)
    return np.hypot(c, s)


def local_extrema(times, amps, mode, lo, hi, kind, n=40001):
    """Refined interior local minima (kind='min') or maxima ('max') of V(r omega_m), r in [lo, hi].

    Returns (r, V) arrays.
    """
    r = np.linspace(lo, hi, n)
    v = vib(times, amps, mode.zeta, r * mode.omega)
    sgn = 1.0 if kind == "min" else -1.0
    u = sgn * v
    idx = np.where((u[1:-1] < u[:-2]) & (u[1:-1] <= u[2:]))[0] + 1
    out_r, out_v = [], []
    h = r[1] - r[0]
    for i in idx:
        res = minimize_scalar(
            lambda x: sgn * vib(times, amps, mode.zeta, x * mode.omega)[0],
            bounds=(r[i] - h, r[i] + h), method="bounded", options={"xatol": 1e-13})
        out_r.append(res.x)
        out_v.append(sgn * res.fun)
    return np.array(out_r), np.array(out_v)


def zeros_of(times, amps, mode, lo, hi):
    """The zeros of V (refined local minima below 1e-6) in [lo, hi]; asserts that no
    other local minimum lies between the first and the last zero."""
    rm, vm = local_extrema(times, amps, mode, lo, hi, "min")
    z = rm[vm < 1e-6]
    assert len(z) >= 2
    assert not np.any((vm >= 1e-6) & (rm > z[0]) & (rm < z[-1]))
    return z


def check_basic(times, amps, n):
    assert times.shape == amps.shape == (n,)
    assert times.dtype == amps.dtype == np.float64
    assert times[0] == 0.0
    assert np.all(np.diff(times) > 0)
    assert np.all(amps >= 0)
    assert abs(amps.sum() - 1.0) < 1e-12


# --- undamped closed forms --------------------------------------------------------


def ei_closed(v, T):
    return np.array([0, T / 2, T]), np.array([(1 + v) / 4, (1 - v) / 2, (1 + v) / 4])


def hump2_closed(v, T):
    x = (v**2 * (math.sqrt(1 - v**2) + 1)) ** (1 / 3)
    a1 = (3 * x**2 + 2 * x + 3 * v**2) / (16 * x)
    a2 = 0.5 - a1
    return np.array([0, T / 2, T, 1.5 * T]), np.array([a1, a2, a2, a1])


def hump3_closed(v, T):
    a1 = (1 + 3 * v + 2 * math.sqrt(2 * v * (v + 1))) / 16
    a2 = (1 - v) / 4
    return np.array([0, T / 2, T, 1.5 * T, 2 * T]), np.array([a1, a2, 1 - 2 * (a1 + a2), a2, a1])


@pytest.mark.parametrize("v", VTOLS + (0.3, 0.6))
def test_undamped_equals_closed_forms(v):
    m = Mode(7.3, 0.0)
    T = 2 * math.pi / 7.3
    for got, want in [
        (ei_exact(m, v, definition="singhose"), ei_closed(v, T)),
        (ei_exact(m, v), ei_closed(v, T)),
        (ei_exact(m, v, definition="hump"), ei_closed(v, T)),
        (ei_multi_hump(m, v, 2), hump2_closed(v, T)),
        (ei_multi_hump(m, v, 3), hump3_closed(v, T)),
    ]:
        np.testing.assert_allclose(got[0], want[0], rtol=0, atol=1e-9)
        np.testing.assert_allclose(got[1], want[1], rtol=0, atol=1e-9)


@pytest.mark.parametrize("v", VTOLS)
def test_closed_forms_satisfy_the_definitions(v):
    """The undamped closed forms (EI, 2-hump, 3-hump) verified with the independent V."""
    m = Mode(1.0, 0.0)
    T = 2 * math.pi
    t, a = ei_closed(v, T)
    assert abs(vib(t, a, 0.0, 1.0)[0] - v) < 1e-12
    rz, vz = local_extrema(t, a, m, 0.5, 1.5, "min")
    assert len(rz) == 2 and np.all(vz < 1e-6)
    rh, vh = local_extrema(t, a, m, rz[0], rz[1], "max")
    np.testing.assert_allclose(rh, [1.0], atol=1e-6)

    t, a = hump2_closed(v, T)
    assert vib(t, a, 0.0, 1.0)[0] < 1e-12
    rz, vz = local_extrema(t, a, m, 0.3, 1.9, "min")
    assert len(rz) == 3 and np.all(vz < 1e-6)
    rh, vh = local_extrema(t, a, m, rz[0], rz[-1], "max")
    assert len(rh) == 2
    np.testing.assert_allclose(vh, v, atol=1e-9)

    t, a = hump3_closed(v, T)
    assert abs(vib(t, a, 0.0, 1.0)[0] - v) < 1e-12
    rz, vz = local_extrema(t, a, m, 0.3, 1.9, "min")
    assert len(rz) == 4 and np.all(vz < 1e-6)
    rh, vh = local_extrema(t, a, m, rz[0], rz[-1], "max")
    assert len(rh) == 3
    np.testing.assert_allclose(rh[1], 1.0, atol=1e-6)
    np.testing.assert_allclose(vh, v, atol=1e-9)


# --- damped EI: the definitions hold --------------------------------------------------


@pytest.mark.parametrize("zeta", [0.02, 0.1, 0.2, 0.3])
@pytest.mark.parametrize("v", VTOLS)
@pytest.mark.parametrize("definition", ["singhose", "hump"])
def test_ei_exact_definition(zeta, v, definition):
    m = Mode(4.0, zeta)
    t, a = ei_exact(m, v, definition=definition)
    check_basic(t, a, 3)
    assert abs(vib(t, a, zeta, m.omega)[0] - v) < 1e-9
    rz, vz = local_extrema(t, a, m, 0.5, 1.5, "min")
    assert len(rz) == 2 and rz[0] < 1 < rz[1]
    assert np.all(vz < 1e-6)
    if definition == "singhose":
        assert abs(t[-1] - m.damped_period) < 1e-12
    else:  # the hump is exactly at omega_m: dV/domega = 0 there
        h = 1e-5
        vp, vm = vib(t, a, zeta, [m.omega * (1 + h), m.omega * (1 - h)])
        assert abs(vp - vm) / (2 * h) < 1e-7
        rh, vh = local_extrema(t, a, m, rz[0], rz[1], "max")
        np.testing.assert_allclose(rh, [1.0], atol=1e-6)


def test_ei_definitions_differ_and_the_fit_follows_t3_equal_Td():
    """Singhose's fit has t3 = T_d: the evidence for definition 'singhose'."""
    for zeta, t3_want in [(0.1, 0.99591), (0.2, 0.98872), (0.3, 0.97657)]:
        m = Mode(1.0, zeta)
        td = m.damped_period
        ta, _ = ei_exact(m, 0.05, definition="hump")
        tb, _ = ei_exact(m, 0.05, definition="singhose")
        tf, _ = ei_fit(m, 0.05)
        assert abs(ta[-1] / td - t3_want) < 1e-5
        assert abs(tb[-1] / td - 1.0) < 1e-12
        # the fit's t2 is much closer to the t3 = T_d definition
        assert abs(tf[1] - tb[1]) < 0.25 * abs(tf[1] - ta[1])


def test_ei_exact_hump_of_singhose_definition_slightly_off_model():
    m = Mode(1.0, 0.3)
    t, a = ei_exact(m, 0.05, definition="singhose")
    rz, _ = local_extrema(t, a, m, 0.5, 1.5, "min")
    rh, vh = local_extrema(t, a, m, rz[0], rz[1], "max")
    assert len(rh) == 1
    assert 0.97 < rh[0] < 0.98 and 0.05 < vh[0] < 0.051


def test_ei_exact_scales_with_frequency():
    t1, a1 = ei_exact(Mode(3.0, 0.15), 0.08)
    t2, a2 = ei_exact(Mode(6.0, 0.15), 0.08)
    np.testing.assert_allclose(t2, t1 / 2, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(a2, a1, atol=1e-12)


def test_exact_answers_do_not_depend_on_the_warm_start_cache():
    ei._traces.clear()
    cold = [ei_exact(Mode(1.0, 0.23), 0.07), ei_multi_hump(Mode(1.0, 0.17), 0.06, 3)]
    ei._traces.clear()
    ei_exact(Mode(1.0, 0.29), 0.07)  # the curve traced further, other points
    ei_multi_hump(Mode(1.0, 0.21), 0.06, 3)
    ei_exact(Mode(1.0, 0.11), 0.07)
    warm = [ei_exact(Mode(1.0, 0.23), 0.07), ei_multi_hump(Mode(1.0, 0.17), 0.06, 3)]
    for c, w in zip(cold, warm):
        np.testing.assert_allclose(w[0], c[0], atol=1e-12)
        np.testing.assert_allclose(w[1], c[1], atol=1e-12)


def test_returned_arrays_are_copies():
    m = Mode(1.0, 0.1)
    t, a = ei_exact(m, 0.05)
    a[0] = 99.0
    t[1] = -1.0
    t2, a2 = ei_exact(m, 0.05)
    assert a2[0] < 1 and t2[1] > 0


# --- multi-hump ---------------------------------------------------------------------


@pytest.mark.parametrize("zeta", [0.03, 0.1, 0.2])
@pytest.mark.parametrize("v", VTOLS)
def test_two_hump_definition(zeta, v):
    m = Mode(2.5, zeta)
    t, a = ei_multi_hump(m, v, 2)
    check_basic(t, a, 4)
    assert vib(t, a, zeta, m.omega)[0] < 1e-9  # exact zero at omega_m
    rz = zeros_of(t, a, m, 0.3, 2.6)
    assert len(rz) == 3
    np.testing.assert_allclose(rz[1], 1.0, atol=1e-6)
    rh, vh = local_extrema(t, a, m, rz[0], rz[-1], "max")
    assert len(rh) == 2 and rh[0] < 1 < rh[1]
    np.testing.assert_allclose(vh, v, atol=1e-6)


@pytest.mark.parametrize("zeta", [0.03, 0.1, 0.15])
@pytest.mark.parametrize("v", VTOLS)
def test_three_hump_definition(zeta, v):
    m = Mode(2.5, zeta)
    t, a = ei_multi_hump(m, v, 3)
    check_basic(t, a, 5)
    assert abs(vib(t, a, zeta, m.omega)[0] - v) < 1e-9
    rz = zeros_of(t, a, m, 0.3, 2.6)
    assert len(rz) == 4
    rh, vh = local_extrema(t, a, m, rz[0], rz[-1], "max")
    assert len(rh) == 3
    np.testing.assert_allclose(rh[1], 1.0, atol=1e-6)
    np.testing.assert_allclose(vh, v, atol=1e-6)


def test_two_hump_matches_singhose_fit_at_5_percent():
    """Singhose's published 2-hump EI fit (V = 5 %, times in units of 1/f_n) agrees
    with the definition used here to a few 1e-3."""
    t_c = [[0.49890, 0.16270, -0.54262, 6.16180], [0.99748, 0.18382, -1.58270, 8.17120],
           [1.49920, -0.09297, -0.28338, 1.85710]]
    a_c = [[0.16054, 0.76699, 2.26560, -1.22750], [0.33911, 0.45081, -2.58080, 1.73650],
           [0.34089, -0.61533, -0.68765, 0.42261], [0.15997, -0.60246, 1.00280, -0.93145]]
    for zeta in (0.05, 0.15, 0.3):
        m = Mode(2 * math.pi, zeta)  # f_n = 1 Hz
        t, a = ei_multi_hump(m, 0.05, 2)
        tf = [np.polyval(c[::-1], zeta) for c in t_c]
        af = [np.polyval(c[::-1], zeta) for c in a_c]
        np.testing.assert_allclose(t[1:], tf, atol=6e-3)
        np.testing.assert_allclose(a, af, atol=3e-3)


@pytest.mark.parametrize("humps, zeta_ok, zeta_bad", [(2, 0.42, 0.43), (3, 0.30, 0.31)])
def test_multi_hump_range_limits(humps, zeta_ok, zeta_bad):
    t, a = ei_multi_hump(Mode(1.0, zeta_ok), 0.05, humps)
    check_basic(t, a, humps + 2)
    with pytest.raises(ValueError, match=r"zeta=.*works for 0 <= zeta <= 0\.\d+"):
        ei_multi_hump(Mode(1.0, zeta_bad), 0.05, humps)


def test_two_hump_through_its_s_bend():
    """vtol = 0.15: the solution curve folds twice near zeta = 0.24; the definition
    holds on either side and inside the bend."""
    for zeta in (0.235, 0.239, 0.245, 0.26):
        m = Mode(1.0, zeta)
        t, a = ei_multi_hump(m, 0.15, 2)
        check_basic(t, a, 4)
        assert vib(t, a, zeta, 1.0)[0] < 1e-9
        rm, vm = local_extrema(t, a, m, 0.3, 5.0, "min")
        rz = rm[vm < 1e-6]
        assert len(rz) == 3 and abs(rz[1] - 1) < 1e-6
        rh, vh = local_extrema(t, a, m, rz[0], rz[2], "max")
        assert np.max(vh) < 0.15 + 1e-6  # nothing between the outer zeros exceeds vtol
        rh, vh = local_extrema(t, a, m, rz[0], 1.6, "max")  # the two humps
        assert len(rh) == 2
        np.testing.assert_allclose(vh, 0.15, atol=1e-6)


def test_ei_range_limit_message():
    with pytest.raises(ValueError, match=r"zeta=0.9 .*EI.*vtol=0.05.*0 <= zeta <= 0\.65"):
        ei_exact(Mode(1.0, 0.9), 0.05)


# --- the curve fit ------------------------------------------------------------------


def test_fit_close_to_exact():
    for v in VTOLS:
        worst_a = worst_t = worst_v = 0.0
        for zeta in np.linspace(0.0, 0.3, 16):
            m = Mode(1.0, float(zeta))
            td = m.damped_period
            tf, af = ei_fit(m, v)
            te, ae = ei_exact(m, v, definition="singhose")
            check_basic(tf, af, 3)
            assert tf[-1] == td
            worst_a = max(worst_a, np.max(np.abs(af - ae)))
            worst_t = max(worst_t, np.max(np.abs(tf - te)) / td)
            worst_v = max(worst_v, abs(vib(tf, af, zeta, 1.0)[0] - v))
        assert worst_a < 0.012 and worst_t < 0.008 and worst_v < 0.01
        if v <= 0.05:
            assert worst_a < 0.003 and worst_t < 0.001 and worst_v < 0.003


def test_seed004_printed_fit_is_wrong():
    m = Mode(1.0, 0.2)
    tp, ap = ei._seed004_printed_ei_fit(m, 0.05)
    tf, af = ei_fit(m, 0.05)
    te, ae = ei_exact(m, 0.05, definition="singhose")
    vp = vib(tp, ap, 0.2, 1.0)[0]
    vf = vib(tf, af, 0.2, 1.0)[0]
    assert abs(vp - 0.05) > 0.03  # 0.0846
    assert abs(vf - 0.05) < 0.002
    assert abs(ap[0] - ae[0]) > 0.15  # the printed A1 lost its 0.80008 zeta term
    assert abs(tp[1] - te[1]) > 10 * abs(tf[1] - te[1])
    # over the fit's whole range the printed version is far off
    worst = max(np.max(np.abs(ei._seed004_printed_ei_fit(Mode(1.0, z), v)[1]
                              - ei_exact(Mode(1.0, z), v, definition="singhose")[1]))
                for z in (0.1, 0.2, 0.3) for v in (0.05, 0.15))
    assert worst > 0.2


def test_fit_coefficients_at_zero_damping():
    t, a = ei_fit(Mode(1.0, 0.0), 0.1)
    a1, a3 = 0.24968 + 0.024962, 0.25149 + 0.021474
    np.testing.assert_allclose(a, [a1, 1 - (a1 + a3), a3], atol=1e-12)
    assert abs(t[1] - 0.4999 * 2 * math.pi) < 1e-12


def test_fit_range_guard():
    with pytest.raises(ValueError, match="ei_exact"):
        ei_fit(Mode(1.0, 0.35), 0.05)
    with pytest.raises(ValueError, match="ei_exact"):
        ei_fit(Mode(1.0, 0.1), 0.2)
    t, a = ei_fit(Mode(1.0, 0.35), 0.05, extrapolate=True)
    assert abs(a.sum() - 1) < 1e-12


def test_fit_report():
    rep = ei_fit_report()
    assert set(rep) >= {"zeta", "max_abs_amplitude_error", "max_abs_time_error",
                        "v_at_model", "v_peak", "exact_v_peak", "vtol"}
    np.testing.assert_allclose(rep["zeta"], np.linspace(0, 0.3, 31))
    for k in ("max_abs_amplitude_error", "max_abs_time_error", "v_at_model", "v_peak"):
        assert rep[k].shape == (31,)
    assert np.all(rep["max_abs_amplitude_error"] < 3e-3)
    assert np.all(rep["max_abs_time_error"] < 1e-3)
    assert np.all(np.abs(rep["v_at_model"] - 0.05) < 3e-3)
    assert np.all(rep["v_peak"] >= rep["v_at_model"] - 1e-12)
    assert np.all(rep["exact_v_peak"] >= 0.05 - 1e-9) and rep["exact_v_peak"][-1] > 0.0504
    rep2 = ei_fit_report(0.1, [0.0, 0.2])
    assert rep2["zeta"].shape == (2,) and float(rep2["vtol"]) == 0.1
    with pytest.raises(ValueError):
        ei_fit_report(0.05, [0.1, 1.2])


# --- bad inputs ---------------------------------------------------------------------


CALLS = [
    lambda m, v: ei_fit(m, v),
    lambda m, v: ei_exact(m, v),
    lambda m, v: ei_multi_hump(m, v, 2),
    lambda m, v: ei_multi_hump(m, v, 3),
]


@pytest.mark.parametrize("call", CALLS)
@pytest.mark.parametrize("v", [0.0, 1.0, -0.1, 1.5, float("nan"), float("inf")])
def test_bad_vtol_value(call, v):
    with pytest.raises(ValueError, match=r"vtol must be in \(0, 1\)"):
        call(Mode(1.0, 0.1), v)


@pytest.mark.parametrize("call", CALLS)
def test_bad_types(call):
    with pytest.raises(TypeError):
        call((1.0, 0.1), 0.05)
    with pytest.raises(TypeError):
        call(Mode(1.0, 0.1), "0.05")
    with pytest.raises(TypeError):
        call(Mode(1.0, 0.1), None)
    with pytest.raises(TypeError):
        call(Mode(1.0, 0.1), True)


def test_fit_report_bad_vtol():
    with pytest.raises(ValueError, match=r"vtol must be in \(0, 1\)"):
        ei_fit_report(1.0)
    with pytest.raises(TypeError):
        ei_fit_report(True)


@pytest.mark.parametrize("humps", [0, 1, 4, 2.0, "2", None, True])
def test_bad_humps(humps):
    with pytest.raises(ValueError, match="humps"):
        ei_multi_hump(Mode(1.0, 0.1), 0.05, humps)


def test_bad_definition():
    with pytest.raises(ValueError, match="definition"):
        ei_exact(Mode(1.0, 0.1), 0.05, definition="zvd")


def test_numpy_scalars_accepted():
    t, a = ei_exact(Mode(1.0, 0.1), np.float64(0.05))
    t2, a2 = ei_multi_hump(Mode(1.0, 0.1), np.float32(0.25), np.int64(2))
    assert a.shape == (3,) and a2.shape == (4,)
