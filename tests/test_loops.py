"""Loops with shapers (seed 001 Fig. 1-3 and eq. 1-4, seed 000 Sec. III-V and eq. 11-16, 23).

References are independent of the code under test: the seeds' closed-form
channel formulas evaluated with plain numpy at random complex points, and a
direct solution of each block diagram's linear signal equations at a point.
"""

import math

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")

import posicast
from posicast import Mode, QuasiPolynomial, TransferFunction, design
from posicast.loops import (
    Loop,
    Margins,
    NyquistResponse,
    bode_plot,
    control_action,
    feedforward,
    inverse_shaper,
    nyquist_plot,
    removable_points,
    spectrum_plot,
)

rng = np.random.default_rng(20261207)
PTS = rng.uniform(-3.0, 3.0, 30) + 1j * rng.uniform(-40.0, 40.0, 30)

# Seed 000 simulation example, eq. 25-27
G_DESC = (np.array([1.0]), np.array([1.0, 1.0, 0.0]))  # G = 1 / (s^2 + s)
F_DESC = (np.array([1.0, 0.0]), np.array([1.0, 0.6, 100.0]))  # F = s / (s^2 + 0.6 s + 100)
C_DESC = (np.array([10.0, 10.0]), np.array([0.01, 1.0]))  # C = (10 s + 10) / (0.01 s + 1)
MODE = Mode(10.0, 0.03)  # the poles of F: -0.3 +/- 9.9955j

SHAPER_KINDS = ["zv", "dzv", "dczv", "dtzv", "notch"]
BUILDERS = {"feedforward": feedforward, "control_action": control_action, "inverse_shaper": inverse_shaper}


def Gv(s):
    return np.polyval(G_DESC[0], s) / np.polyval(G_DESC[1], s)


def Fv(s):
    return np.polyval(F_DESC[0], s) / np.polyval(F_DESC[1], s)


def Cv(s):
    return np.polyval(C_DESC[0], s) / np.polyval(C_DESC[1], s)


def make(arch, kind, **kw):
    S = None if kind is None else design(kind, MODE)
    return BUILDERS[arch](G=G_DESC, F=F_DESC, C=C_DESC, S=S, **kw), S


def Sv(S, s):
    return np.ones_like(s) if S is None else np.asarray(S(s))


def close(a, b, rtol=1e-12):
    a, b = np.asarray(a), np.asarray(b)
    err = np.abs(a - b) / np.maximum(np.abs(b), 1e-300)
    return bool(np.all(err <= rtol)), float(err.max())


# ---------------------------------------------------------------------- seed formulas
@pytest.mark.parametrize("kind", SHAPER_KINDS + [None])
def test_feedforward_is_seed001_eq1_eq2(kind):
    loop, S = make("feedforward", kind)
    s = PTS
    G, F, C, Sh = Gv(s), Fv(s), Cv(s), Sv(S, s)
    cases = {
        ("w", "y"): F * Sh * C * G / (1 + C * G),  # eq. 1
        ("n", "y"): -F * C * G / (1 + C * G),  # eq. 2
        ("d", "y"): F / (1 + C * G),  # eq. 2
    }
    for (src, dst), ref in cases.items():
        ok, err = close(loop.transfer(src, dst)(s), ref)
        assert ok, (src, dst, err)


@pytest.mark.parametrize("kind", SHAPER_KINDS + [None])
def test_control_action_is_seed001_eq3(kind):
    loop, S = make("control_action", kind)
    s = PTS
    G, F, C, Sh = Gv(s), Fv(s), Cv(s), Sv(S, s)
    cases = {
        ("w", "y"): F * C * Sh * G / (1 + C * Sh * G),
        ("n", "y"): -F * C * Sh * G / (1 + C * Sh * G),
        ("d", "y"): F / (1 + C * Sh * G),
    }
    for (src, dst), ref in cases.items():
        ok, err = close(loop.transfer(src, dst)(s), ref)
        assert ok, (src, dst, err)


@pytest.mark.parametrize("kind", SHAPER_KINDS + [None])
def test_inverse_shaper_is_seed001_eq4_corrected(kind):
    # Seed 001 eq. 4 prints the denominators as S + C S G; from Fig. 3
    # (e = w - (z + n)/S) they are S + C G, as in seed 000 eq. 15-16.
    loop, S = make("inverse_shaper", kind)
    s = PTS
    G, F, C, Sh = Gv(s), Fv(s), Cv(s), Sv(S, s)
    cases = {
        ("w", "y"): F * C * Sh * G / (Sh + C * G),
        ("n", "y"): -F * C * G / (Sh + C * G),
        ("d", "y"): F * Sh / (Sh + C * G),
    }
    for (src, dst), ref in cases.items():
        ok, err = close(loop.transfer(src, dst)(s), ref)
        assert ok, (src, dst, err)


def test_seed001_eq4_as_printed_is_wrong():
    loop, S = make("inverse_shaper", "dzv")
    s = PTS
    G, F, C, Sh = Gv(s), Fv(s), Cv(s), Sv(S, s)
    printed = F * C * Sh * G / (Sh + C * Sh * G)
    got = loop.transfer("w", "y")(s)
    assert np.median(np.abs(got - printed) / np.abs(printed)) > 1e-2


def _seed000_polys(s):
    P, Q = np.polyval(C_DESC[0], s), np.polyval(C_DESC[1], s)
    M, N = np.polyval(G_DESC[0], s), np.polyval(G_DESC[1], s)
    Lp, H = np.polyval(F_DESC[0], s), np.polyval(F_DESC[1], s)
    return P, Q, M, N, Lp, H


@pytest.mark.parametrize("kind", ["zv", "dzv", "dtazv"])
def test_control_action_is_seed000_eq11_eq12(kind):
    loop, S = make("control_action", kind)
    s = PTS
    P, Q, M, N, Lp, H = _seed000_polys(s)
    Sh = Sv(S, s)
    T_wy = P * M * Sh / (Q * N + P * Sh * M) * Lp / H  # eq. 11
    T_dy = Q * N / (Q * N + P * Sh * M) * Lp / H  # eq. 12
    assert close(loop.transfer("w", "y")(s), T_wy)[0]
    assert close(loop.transfer("d", "y")(s), T_dy)[0]
    assert close(loop.transfer("w", "z")(s), T_wy * H / Lp)[0]
    assert close(loop.transfer("d", "z")(s), T_dy * H / Lp)[0]


@pytest.mark.parametrize("kind", ["zv", "dzv", "dczv"])
def test_inverse_shaper_is_seed000_eq15_eq16_eq23(kind):
    loop, S = make("inverse_shaper", kind)
    s = PTS
    P, Q, M, N, Lp, H = _seed000_polys(s)
    Sh = Sv(S, s)
    T_wy = P * M * Sh / (Sh * Q * N + P * M) * Lp / H  # eq. 15
    T_dy = Q * N * Sh / (Sh * Q * N + P * M) * Lp / H  # eq. 16
    assert close(loop.transfer("w", "y")(s), T_wy)[0]
    assert close(loop.transfer("d", "y")(s), T_dy)[0]
    # eq. 23 with S = S.num / S.den: CE = S.num Q N + P M S.den
    Sn, Sd = S.num(s), S.den(s)
    assert close(loop.characteristic(s), Sn * Q * N + P * M * Sd)[0]
    if kind == "zv":  # S.den = 1: exactly seed 000 eq. 23
        assert close(loop.characteristic(s), Sh * Q * N + P * M)[0]


def test_characteristics_of_the_three_architectures():
    S = design("dzv", MODE)
    s = PTS
    P, Q, M, N, _, _ = _seed000_polys(s)
    Sn, Sd = S.num(s), S.den(s)
    assert close(make("feedforward", "dzv")[0].characteristic(s), Q * N + P * M)[0]
    assert close(make("control_action", "dzv")[0].characteristic(s), Q * N * Sd + P * M * Sn)[0]
    assert close(make("inverse_shaper", "dzv")[0].characteristic(s), Q * N * Sn + P * M * Sd)[0]


# ---------------------------------------------------------------------- direct block diagram
def _solve_diagram(arch, s, G, C, F, Sh, src):
    """Signals for a unit input at ``src``, from the block diagram's linear equations.

    Unknowns: e, v, u, z, y, r, m.  ``u`` is the actuator command; the plant input is u + di.
    """
    w = 1.0 if src == "w" else 0.0
    d = 1.0 if src == "d" else 0.0
    di = 1.0 if src == "di" else 0.0
    n = 1.0 if src == "n" else 0.0
    E, V, U, Z, Y, R, Mm = range(7)
    A = np.zeros((7, 7), dtype=complex)
    b = np.zeros(7, dtype=complex)
    # z = G (u + di) + d
    A[0, Z], A[0, U], b[0] = 1, -G, G * di + d
    # y = F z
    A[1, Y], A[1, Z] = 1, -F
    # v = C e
    A[2, V], A[2, E] = 1, -C
    if arch == "feedforward":
        A[3, R], b[3] = 1, Sh * w  # r = S w
        A[4, E], A[4, R], A[4, Z], b[4] = 1, -1, 1, -n  # e = r - (z + n)
        A[5, U], A[5, V] = 1, -1  # u = v
        A[6, Mm] = 1  # unused
    elif arch == "control_action":
        A[3, R] = 1
        A[4, E], A[4, Z], b[4] = 1, 1, w - n  # e = w - (z + n)
        A[5, U], A[5, V] = 1, -Sh  # u = S v
        A[6, Mm] = 1
    else:
        A[3, R] = 1
        A[4, E], A[4, Mm], b[4] = 1, 1, w  # e = w - m
        A[5, U], A[5, V] = 1, -1  # u = v
        A[6, Mm], A[6, Z], b[6] = Sh, -1, n  # S m = z + n
    x = np.linalg.solve(A, b)
    return {"e": x[E], "v": x[V], "u": x[U], "z": x[Z], "y": x[Y], "r": x[R], "m": x[Mm]}


@pytest.mark.parametrize("arch", list(BUILDERS))
@pytest.mark.parametrize("kind", ["zv", "dzv", "dczv", "notch", None])
def test_every_channel_matches_the_block_diagram(arch, kind):
    loop, S = make(arch, kind)
    chans = loop.channels()
    assert set(chans) == {(a, b) for a in loop.inputs for b in loop.outputs}
    for s in PTS[:12]:
        G, C, F = Gv(s), Cv(s), Fv(s)
        Sh = complex(Sv(S, s))
        for src in loop.inputs:
            sig = _solve_diagram(arch, s, G, C, F, Sh, src)
            for dst in loop.outputs:
                got = chans[(src, dst)](s)
                ref = sig[dst]
                assert abs(got - ref) <= 1e-11 * max(abs(ref), 1e-3 * max(abs(v) for v in sig.values())), (
                    src,
                    dst,
                    s,
                    got,
                    ref,
                )


@pytest.mark.parametrize("arch", list(BUILDERS))
def test_channels_share_the_common_denominator(arch):
    loop, _ = make(arch, "dzv")
    ch = loop.characteristic
    for (src, dst), tf in loop.channels().items():
        if dst == "r":
            continue
        # denominator = characteristic x (blocks outside the loop)
        ratio = tf.den(PTS) / ch(PTS)
        outside = np.ones_like(PTS)
        if dst == "y":
            outside = outside * np.polyval(F_DESC[1], PTS)
        if arch == "feedforward" and src == "w":
            outside = outside * loop.S.den(PTS)
        assert close(ratio, outside)[0], (src, dst)


@pytest.mark.parametrize("arch", list(BUILDERS))
def test_loop_gain_sensitivities(arch):
    loop, S = make(arch, "dczv")
    s = PTS
    G, C, Sh = Gv(s), Cv(s), Sv(S, s)
    L_ref = {"feedforward": C * G, "control_action": C * Sh * G, "inverse_shaper": C * G / Sh}[arch]
    assert close(loop.loop_gain(s), L_ref)[0]
    assert close(loop.sensitivity(s), 1 / (1 + L_ref))[0]
    assert close(loop.complementary_sensitivity(s), L_ref / (1 + L_ref))[0]
    # d -> z is the sensitivity in all three architectures; seed 001 eq. 15
    assert close(loop.transfer("d", "z")(s), loop.sensitivity(s))[0]
    assert close(loop.sensitivity(s) + loop.complementary_sensitivity(s), np.ones_like(s))[0]


def test_feedforward_r_channel_and_no_shaper():
    loop, S = make("feedforward", "zv")
    assert close(loop.transfer("w", "r")(PTS), S(PTS))[0]
    for src in ("d", "di", "n"):
        assert loop.transfer(src, "r").num.is_zero
    plain = feedforward(G=G_DESC, C=C_DESC)
    assert close(plain.transfer("w", "r")(PTS), np.ones_like(PTS))[0]
    # F = None is F = 1: y = z
    assert close(plain.transfer("d", "y")(PTS), plain.transfer("d", "z")(PTS))[0]
    # without a shaper the three architectures coincide
    for build in (control_action, inverse_shaper):
        other = build(G=G_DESC, C=C_DESC)
        for src in ("w", "d", "di", "n"):
            for dst in ("e", "v", "u", "z", "y"):
                assert close(other.transfer(src, dst)(PTS), plain.transfer(src, dst)(PTS))[0]


def test_removable_singularities_evaluate_to_their_limits():
    # The channels of a DZV loop are 0/0 at s = 0 (the shaper's removable point).
    loop, S = make("inverse_shaper", "dzv")
    s0 = 1e-7 + 1e-7j
    for (src, dst), tf in loop.channels().items():
        assert abs(tf(0.0) - tf(s0)) <= 1e-5 * max(1.0, abs(tf(s0))), (src, dst)
    assert abs(loop.transfer("w", "z")(0.0) - 1.0) < 1e-12
    assert abs(loop.transfer("d", "z")(0.0)) < 1e-12


# ---------------------------------------------------------------------- cancelled points
def test_inverse_dzv_characteristic_vanishes_at_zero_and_is_cancelled():
    loop, S = make("inverse_shaper", "dzv")
    ch = loop.characteristic
    assert abs(ch(0.0)) <= 1e-14 * ch.magnitude_scale(0.0)
    assert abs(ch.derivative()(0.0)) > 1e-3 * ch.derivative().magnitude_scale(0.0)
    np.testing.assert_array_equal(loop.cancelled, [0.0])
    assert loop.characteristic.kind == "retarded"


def test_cancelled_per_architecture_and_shaper():
    T = design("dczv", MODE).params["T"]
    assert make("feedforward", "dzv")[0].cancelled.size == 0  # shaper outside the loop
    for arch in ("control_action", "inverse_shaper"):
        assert make(arch, "zv")[0].cancelled.size == 0
        assert make(arch, "notch")[0].cancelled.size == 0
        assert make(arch, None)[0].cancelled.size == 0
        assert make(arch, "dtzv")[0].cancelled.tolist() == [0.0, 0.0]  # den T^2 s^2, num of order 2 at 0
        c = np.sort_complex(make(arch, "dczv")[0].cancelled)
        np.testing.assert_allclose(c, [-2j * np.pi / T, 0, 2j * np.pi / T], atol=1e-12 * 2 * np.pi / T)


def test_cancelled_multiplicity_matches_the_characteristic():
    # Each cancelled point is a root of the characteristic of exactly that multiplicity here.
    S2 = design("dzv", MODE) * design("dczv", Mode(23.0, 0.05))
    for arch in ("control_action", "inverse_shaper"):
        loop = BUILDERS[arch](G=G_DESC, C=C_DESC, S=S2)
        pts, mult = np.unique(np.round(loop.cancelled, 9), return_counts=True)
        assert 0 in pts
        for p, m in zip(pts, mult):
            c, scale = loop.characteristic.taylor(complex(p), m + 1)
            assert np.all(np.abs(c[:m]) <= 1e-8 * scale[:m]), (p, m, c[:m], scale[:m])
            assert abs(c[m]) > 1e-6 * scale[m], (p, m)


def test_removable_points_helper():
    S = design("dtzv", MODE)  # den T^2 s^2, num vanishing to order 2 at 0
    np.testing.assert_array_equal(removable_points(S.num, S.den), [0.0, 0.0])
    # a genuine pole of the denominator is not removable
    num = QuasiPolynomial.from_poly([1.0, 0.0, 0.0])  # s^2
    den = QuasiPolynomial.from_poly([1.0, 0.0, 0.0, 0.0])  # s^3
    np.testing.assert_array_equal(removable_points(num, den), [0.0, 0.0])
    # a delayed denominator: not handled, empty
    d2 = QuasiPolynomial([[1.0], [1.0]], [0.0, 1.0])
    assert removable_points(num, d2).size == 0


def test_shaper_zeros_are_zeros_of_Twz_and_Tdz_in_the_inverse_loop():
    # Seed 000 eq. 21-22: the ZV zero -(1/tau) ln(A/(1-A)) + j pi/tau is a zero of both
    loop, S = make("inverse_shaper", "zv")
    A, tau = S.amplitudes[0], S.times[1]
    z0 = -math.log(A / (1 - A)) / tau + 1j * math.pi / tau
    assert abs(S(z0)) < 1e-14
    for src in ("w", "d"):
        assert abs(loop.transfer(src, "z")(z0)) < 1e-12
    # ... but not of n -> z: the noise still excites the mode (seed 001 Sec. 2)
    assert abs(loop.transfer("n", "z")(z0) + 1.0) < 1e-12
    # in the control-action loop the zero is only in w -> z (seed 000 eq. 12-14)
    ca, _ = make("control_action", "zv")
    assert abs(ca.transfer("w", "z")(z0)) < 1e-12
    assert abs(ca.transfer("d", "z")(z0) - 1.0) < 1e-12


def test_channel_cancelled():
    loop, _ = make("inverse_shaper", "dzv")
    for key in loop.channels():
        np.testing.assert_array_equal(loop.channel_cancelled(*key), [0.0])
    ff, _ = make("feedforward", "dzv")
    np.testing.assert_array_equal(ff.channel_cancelled("w", "y"), [0.0])
    np.testing.assert_array_equal(ff.channel_cancelled("w", "r"), [0.0])
    assert ff.channel_cancelled("d", "y").size == 0


# ---------------------------------------------------------------------- validation, repr
def test_unknown_channel_names():
    loop, _ = make("control_action", "zv")
    with pytest.raises(ValueError, match=r"src must be one of \('w', 'd', 'di', 'n'\)"):
        loop.transfer("x", "y")
    with pytest.raises(ValueError, match="dst must be one of"):
        loop.transfer("w", "r")  # r only exists in the feedforward loop
    with pytest.raises(ValueError, match="dst must be one of"):
        loop.transfer("w", "m")
    assert "m" in make("inverse_shaper", "zv")[0].outputs
    assert "r" in make("feedforward", "zv")[0].outputs
    with pytest.raises(ValueError, match="src"):
        loop.frequency_response(3, "y", [1.0])


@pytest.mark.parametrize("name", ["G", "C", "F", "S"])
def test_bad_block_types_name_the_argument(name):
    kw = {"G": G_DESC, "C": C_DESC, "F": F_DESC, "S": design("zv", MODE)}
    kw[name] = "not a system"
    with pytest.raises(TypeError, match=rf"^{name}"):
        inverse_shaper(**kw)
    kw[name] = ([1.0, np.nan], [1.0])
    with pytest.raises(ValueError, match=rf"^{name}"):
        control_action(**kw)


def test_bad_loops():
    with pytest.raises(TypeError, match="G"):
        feedforward(G=None, C=1.0)
    with pytest.raises(TypeError, match="C"):
        feedforward(G=G_DESC, C=None)
    with pytest.raises(ValueError, match="S is identically zero"):
        inverse_shaper(G=G_DESC, C=C_DESC, S=0.0)
    with pytest.raises(ValueError, match="ill-posed"):
        feedforward(G=1.0, C=-1.0)
    with pytest.raises(ValueError, match="architecture"):
        Loop("series", G=G_DESC, C=C_DESC)


def test_accepts_scipy_and_python_control_blocks():
    control = pytest.importorskip("control")
    from scipy import signal

    ref, S = make("inverse_shaper", "dzv")
    loop = inverse_shaper(
        G=control.tf(*G_DESC), C=signal.TransferFunction(*C_DESC), F=control.tf(*F_DESC), S=S.transfer
    )
    for src in loop.inputs:
        assert close(loop.transfer(src, "y")(PTS), ref.transfer(src, "y")(PTS))[0]


def test_repr_and_attributes():
    loop, S = make("inverse_shaper", "dzv")
    r = repr(loop)
    assert "inverse_shaper" in r and "dzv" in r and "retarded" in r and "cancelled" in r
    assert loop.architecture == "inverse_shaper"
    assert loop.shaper is S
    assert isinstance(loop.G, TransferFunction) and isinstance(loop.S, TransferFunction)
    assert "no shaper" in repr(feedforward(G=G_DESC, C=C_DESC))
    assert make("inverse_shaper", "zv")[0].characteristic.kind == "neutral"
    assert make("control_action", "notch")[0].characteristic.kind == "polynomial"


def test_public_exports():
    for name in ("feedforward", "control_action", "inverse_shaper", "Loop"):
        assert name in posicast.__all__ and hasattr(posicast, name)


# ---------------------------------------------------------------------- frequency domain
def test_frequency_response_and_nyquist():
    loop, S = make("inverse_shaper", "dzv")
    w = np.linspace(0.0, 60.0, 301)
    H = loop.frequency_response("d", "y", w)
    ref = np.array([loop.transfer("d", "y")(1j * x) for x in w])
    np.testing.assert_allclose(H, ref, rtol=1e-14)
    data = loop.nyquist(w[1:])
    assert isinstance(data, NyquistResponse)
    s = 1j * w[1:]
    ok, err = close(data.response, Cv(s) * Gv(s) / Sv(S, s))
    assert ok, err
    with pytest.raises(ValueError, match="omega"):
        loop.frequency_response("w", "y", [np.inf])


@pytest.mark.parametrize("arch", list(BUILDERS))
def test_margins_peak_sensitivity(arch):
    loop, _ = make(arch, "dzv")
    m = loop.margins()
    assert isinstance(m, Margins)
    # brute force on a very fine grid around the reported peak and globally
    w = np.linspace(0.01, 400.0, 400_001)
    Sg = np.abs(1.0 / (1.0 + loop.loop_gain.freqresp(w)))
    assert m.ms >= Sg.max() * (1 - 1e-9)
    assert m.ms <= Sg.max() * (1 + 1e-3)  # the refinement only climbs the grid's peak
    for dw in (1e-4, -1e-4):  # a local maximum
        assert abs(loop.sensitivity(1j * (m.omega_ms + dw))) <= m.ms
    assert abs(abs(loop.sensitivity(1j * m.omega_ms)) - m.ms) < 1e-12 * m.ms
    assert abs(m.sm - 1 / m.ms) < 1e-15
    assert m.ms >= 1.0 or arch == "feedforward"


def test_margins_match_python_control_for_a_rational_loop():
    control = pytest.importorskip("control")
    G = ([1.0], [1.0, 3.0, 2.0, 0.0])
    loop = feedforward(G=G, C=2.0)
    m = loop.margins()
    gm, pm, sm, wpc, wgc, wms = control.stability_margins(control.tf(2.0, G[1]))
    assert abs(m.gm - gm) < 1e-8 * gm
    assert abs(m.pm - pm) < 1e-7
    assert abs(m.omega_gm - wpc) < 1e-8
    assert abs(m.omega_pm - wgc) < 1e-8
    assert abs(m.sm - sm) < 1e-6


def test_margins_seed000_example_inverse_dzv_vs_zv():
    dzv, _ = make("inverse_shaper", "dzv")
    zv, _ = make("inverse_shaper", "zv")
    # ZV zeros near the imaginary axis make |1/S(j w)| large at odd multiples of pi/tau
    assert zv.margins().ms > dzv.margins().ms


# ---------------------------------------------------------------------- spectra (need posicast.spectra)
def _spectra(*names):
    mod = pytest.importorskip("posicast.spectra")
    for n in names:
        if not hasattr(mod, n):
            pytest.skip(f"posicast.spectra.{n} not available yet")
    return mod


def test_poles_ignore_the_removable_point():
    _spectra("roots")
    loop, _ = make("inverse_shaper", "dzv")
    res = loop.poles((-10.0, 5.0, -120.0, 120.0))
    assert res.count == len(res.roots)
    assert np.all(np.abs(res.roots) > 1e-6)  # s = 0 is not a closed-loop pole
    np.testing.assert_allclose(res.removed, [0.0], atol=1e-9)
    assert np.all(res.roots.real < 0)
    # each root is a root of the characteristic
    ch = loop.characteristic
    assert np.all(np.abs(ch(res.roots)) <= 1e-9 * ch.magnitude_scale(res.roots))


def test_inverse_zv_has_three_unstable_pairs():
    # Seed 000 Sec. V: "there appear three couples of unstable higher frequency poles"
    _spectra("roots")
    loop, _ = make("inverse_shaper", "zv")
    res = loop.poles((-1.0, 5.0, -400.0, 400.0))
    unstable = res.roots[res.roots.real > 0]
    assert unstable.size == 6
    assert np.all(np.abs(unstable.imag) > 40)


def test_channel_zeros_contain_the_shaper_zero():
    _spectra("roots")
    loop, S = make("inverse_shaper", "dzv")
    p = MODE.pole
    for src in ("w", "d"):
        z = loop.zeros((-5.0, 1.0, -50.0, 50.0), channel=(src, "z")).roots
        assert np.min(np.abs(z - p)) < 1e-8
        assert np.min(np.abs(z - p.conjugate())) < 1e-8
    zw = loop.zeros((-5.0, 1.0, -50.0, 50.0), channel=("w", "z")).roots
    assert np.all(np.abs(zw) > 1e-6)  # the removable point is not a zero of w -> z
    with pytest.warns(FutureWarning, match="channel"):  # the 0.1 call still answers
        zd = loop.zeros("d", "z", (-5.0, 1.0, -50.0, 50.0)).roots
    assert np.sum(np.abs(zd) < 1e-9) == 1  # the integrator's zero of d -> z stays
    with pytest.raises(ValueError, match="identically zero"):
        make("feedforward", "zv")[0].zeros((-1, 1, -1, 1), channel=("d", "r"))


def test_stability_reports():
    _spectra("roots", "stability", "spectral_abscissa")
    dzv, _ = make("inverse_shaper", "dzv")
    zv, _ = make("inverse_shaper", "zv")
    assert dzv.is_stable()
    st = dzv.stability()
    assert st.stable and st.kind == "retarded"
    assert dzv.spectral_abscissa() < 0
    assert not zv.is_stable()
    st = zv.stability()
    assert st.kind == "neutral" and not st.stable
    assert zv.spectral_abscissa() > 0
    assert make("feedforward", "zv")[0].is_stable()


# ---------------------------------------------------------------------- plots
def test_bode_and_nyquist_plots():
    import matplotlib.pyplot as plt

    dzv, _ = make("inverse_shaper", "dzv")
    ca, _ = make("control_action", "dzv")
    w = np.logspace(-1, 2, 200)
    fig, (am, ap) = bode_plot([dzv, ca, dzv.sensitivity], "d", "y", w)
    assert len(am.lines) == 3 and len(ap.lines) == 3
    plt.close(fig)
    fig, (am, ap) = bode_plot(dzv, "w", "y", w, ax=plt.subplots()[1])
    assert ap is None
    plt.close("all")
    fig, ax = nyquist_plot(dzv, w, ms=2.0)
    xs = ax.lines[-2].get_xdata()  # the Ms = 2 circle: center -1, radius 1/2
    assert abs(xs.max() + 0.5) < 1e-3 and abs(xs.min() + 1.5) < 1e-3
    plt.close(fig)
    fig, ax = nyquist_plot([dzv, ca], w)
    plt.close(fig)
    with pytest.raises(TypeError, match="loop"):
        nyquist_plot("x", w)
    with pytest.raises(ValueError, match="ms"):
        nyquist_plot(dzv, w, ms=0.5)


def test_spectrum_plot():
    _spectra("roots")
    import matplotlib.pyplot as plt

    dzv, _ = make("inverse_shaper", "dzv")
    zv, _ = make("inverse_shaper", "zv")
    fig, ax = spectrum_plot([zv, dzv], (-6.0, 2.0, -60.0, 60.0))
    labels = [ln.get_label() for ln in ax.lines]
    assert "poles of F" in labels
    assert sum("zeros of S" in lb for lb in labels) == 2
    assert sum("closed-loop poles" in lb for lb in labels) == 2
    plt.close(fig)


def test_bode_plot_refuses_nonpositive_frequencies():
    import matplotlib

    matplotlib.use("Agg")
    from posicast.loops import bode_plot

    loop = posicast.control_action(G=([1.0], [1.0, 1.0, 0.0]), C=2.0)
    with pytest.raises(ValueError, match="omega must be > 0"):
        bode_plot(loop, "w", "y", [-1.0, 1.0])


# ---------------------------------------------------------------------- registry (issue #14)
def _feedback_shaper(b):
    """``e = w - S (z + n)``, ``v = C e``, ``u = v``, ``z = G (u + di) + d``, ``y = F z``: the shaper on the measurement."""
    from posicast.loops.ring import IDENTITY, Ring, Tap

    nodes = ("e", "v", "u", "up", "z", "zn", "m")
    blocks = (IDENTITY, b.C, IDENTITY, IDENTITY, b.G, IDENTITY, b.S)
    inputs = {"w": Tap(0), "d": Tap(4), "di": Tap(3), "n": Tap(5)}
    outputs = {"e": Tap(0), "v": Tap(1), "u": Tap(2), "z": Tap(4), "y": Tap(4, b.F), "m": Tap(6)}
    return Ring(nodes, blocks, inputs, outputs)


@pytest.fixture
def feedback_shaper():
    from posicast.loops import register_architecture, unregister_architecture

    register_architecture("feedback_shaper", _feedback_shaper)
    yield "feedback_shaper"
    unregister_architecture("feedback_shaper")


def test_a_new_architecture_is_one_registry_entry(feedback_shaper):
    """A shaper in the feedback path: its channels match the hand formulas, and simulate runs it (no other code)."""
    from scipy import signal

    from posicast.loops import ARCHITECTURES

    assert feedback_shaper in ARCHITECTURES
    G, C, F = (1, [1, 1, 0]), ([10, 10], [0.01, 1]), ([1, 0], [1, 0.6, 100])
    mode = Mode(10.0, 0.03)
    S = design("zv", mode)
    loop = Loop(feedback_shaper, G=G, C=C, F=F, S=S)
    g, c, f = (posicast.as_transfer(x) for x in (G, C, F))
    for omega in (0.3, 2.0, 9.5, 40.0):
        s = 1j * omega
        Gs, Cs, Fs = complex(g(s)), complex(c(s)), complex(f(s))
        Ss = complex(sum(a * np.exp(-s * ti) for ti, a in zip(*S.impulses)))   # ZV: sum of delayed impulses
        L = Cs * Gs * Ss
        assert abs(complex(loop.transfer("w", "z")(s)) - Cs * Gs / (1 + L)) < 1e-12 * abs(Cs * Gs / (1 + L))
        assert abs(complex(loop.transfer("n", "u")(s)) - (-Cs * Ss / (1 + L))) < 1e-12 * abs(Cs * Ss / (1 + L))
        assert abs(complex(loop.transfer("d", "y")(s)) - Fs / (1 + L)) < 1e-12 * abs(Fs / (1 + L))
        assert abs(complex(loop.transfer("w", "m")(s)) - Ss * Cs * Gs / (1 + L)) < 1e-12 * abs(Ss * Cs * Gs / (1 + L))
    assert loop.cancelled.size == 0 and loop.characteristic.kind == "retarded"

    # simulate: the notch shaper (rational) makes the loop rational, so scipy gives an independent exact reference
    notch = design("notch", mode)
    loop = Loop(feedback_shaper, G=G, C=C, F=F, S=notch)
    t = np.arange(0.0, 6.0, 1e-3)
    w = (t >= 0.5).astype(float)
    runs = [posicast.simulate(loop, t, w=w, substeps=k) for k in (8, 32)]
    assert all(r.mode == "continuous" and r.diverged is None for r in runs)
    Sn = posicast.as_transfer(notch)
    ns, ds = Sn.num.coeffs[0][::-1], Sn.den.coeffs[0][::-1]   # descending powers
    ncg = np.polymul(C[0], G[0])
    num = np.polymul(ncg, ds)                      # z / w = C G / (1 + C G S), by hand
    den = np.polyadd(np.polymul(np.polymul(C[1], G[1]), ds), np.polymul(ncg, ns))
    Phi, Gam, Cz, Dz, _ = signal.cont2discrete(signal.tf2ss(num, den), 1e-3, "zoh")
    _, z_ref, _ = signal.dlsim((Phi, Gam, Cz, Dz, 1e-3), w)
    err = [np.max(np.abs(r.z - z_ref[:, 0])) for r in runs]
    # the stepped method converges to the exact response (first order after the step of w, as for control_action)
    assert err[0] < 1e-3 and err[1] < err[0] / 3
    # sampled and nonlinear (inactive limits) runs walk the same ring
    sampled = posicast.simulate(loop, t, w=w, sample_rate=1000.0)
    assert np.max(np.abs(sampled.z - z_ref[:, 0])) < 1e-2


def test_registry_refuses_bad_entries_and_keeps_the_seeds():
    from posicast.loops import register_architecture, unregister_architecture

    with pytest.raises(ValueError, match="name must not be a registered architecture"):
        register_architecture("feedforward", _feedback_shaper)
    with pytest.raises(TypeError, match="build must be a callable"):
        register_architecture("x", 3)
    with pytest.raises(ValueError, match="name must be one of"):
        unregister_architecture("control_action")
    assert tuple(posicast.loops.ARCHITECTURES) == ("feedforward", "control_action", "inverse_shaper", "model_matching")
