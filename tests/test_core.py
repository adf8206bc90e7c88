"""The exact quasi-rational transfer-function core.

References are independent of the code under test: direct numpy evaluation of
the defining formula, expm1-based limits, numerical integration of densities,
finite differences.
"""

import numpy as np
import pytest
from scipy import signal

from posicast import QuasiPolynomial, TransferFunction, as_transfer, delay

rng = np.random.default_rng(20261122)
S_PTS = rng.normal(size=40) * 3 + 1j * rng.normal(size=40) * 10


def test_quasipolynomial_evaluates_its_definition():
    h = QuasiPolynomial([[1.0, -2.0, 0.5], [3.0, 0.0, 0.0], [0.0, 1.0, 0.0]], [0.0, 0.3, 1.1])
    ref = (1 - 2 * S_PTS + 0.5 * S_PTS**2) + 3 * np.exp(-0.3 * S_PTS) + S_PTS * np.exp(-1.1 * S_PTS)
    np.testing.assert_allclose(h(S_PTS), ref, rtol=1e-13)
    assert isinstance(h(1.0 + 2j), complex)


def test_equal_delays_merge_and_zero_rows_vanish():
    h = QuasiPolynomial([[1.0, 1.0], [2.0, 0.0], [-2.0, 0.0]], [0.5, 0.1 + 0.2, 0.3])
    assert h.delays.tolist() == [0.5]
    assert (QuasiPolynomial([[1.0], [-1.0]], [0.3, 0.3])).is_zero


def test_kind_retarded_neutral_advanced():
    # DZV zero equation (seed 000 eq. 7) is retarded; ZV (eq. 2) is neutral.
    B, th = 0.27, 0.57
    assert QuasiPolynomial([[1 - B, B * th], [-(1 - B), 0.0]], [0.0, th]).kind == "retarded"
    zv = QuasiPolynomial([[0.5], [0.5]], [0.0, 1.0])
    assert zv.kind == "neutral"
    assert QuasiPolynomial([[1.0, 0.0], [0.0, 1.0]], [0.0, 1.0]).kind == "advanced"
    assert QuasiPolynomial.from_poly([1.0, 2.0], 0.4).kind == "polynomial"
    # a common delay factor does not change the kind
    assert zv.shift(2.0).kind == "neutral"


def test_difference_operator_of_neutral_loop():
    # s (A + (1-A) e^{-s tau}) + 1: neutral, difference operator 1 + (1-A)/A e^{-s tau}
    A, tau = 0.6, 0.3
    h = QuasiPolynomial([[1.0, A], [0.0, 1 - A]], [0.0, tau])
    d = h.difference_operator()
    np.testing.assert_allclose(d.coeffs.ravel(), [1.0, (1 - A) / A])
    np.testing.assert_allclose(d.delays, [0.0, tau])
    with pytest.raises(ValueError, match="neutral"):
        QuasiPolynomial([[1.0, 1.0], [1.0, 0.0]], [0.0, 1.0]).difference_operator()


def test_algebra_matches_pointwise_algebra():
    a = QuasiPolynomial([[1.0, 2.0], [0.5, 0.0]], [0.0, 0.7])
    b = QuasiPolynomial([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]], [0.2, 1.3])
    np.testing.assert_allclose((a * b)(S_PTS), a(S_PTS) * b(S_PTS), rtol=1e-12)
    np.testing.assert_allclose((a + b)(S_PTS), a(S_PTS) + b(S_PTS), rtol=1e-12)
    np.testing.assert_allclose((a - 2.0)(S_PTS), a(S_PTS) - 2.0, rtol=1e-12)
    np.testing.assert_allclose(a.shift(0.4)(S_PTS), a(S_PTS) * np.exp(-0.4 * S_PTS), rtol=1e-12)


def test_derivative_matches_finite_difference():
    a = QuasiPolynomial([[1.0, 2.0, -1.0], [0.5, 3.0, 0.0]], [0.0, 0.7])
    s = 0.3 + 0.8j
    h = 1e-6
    fd = (a(s + h) - a(s - h)) / (2 * h)
    assert abs(a.derivative()(s) - fd) < 1e-8 * abs(fd)
    fd2 = (a(s + 1e-4) - 2 * a(s) + a(s - 1e-4)) / 1e-8
    assert abs(a.derivative(2)(s) - fd2) < 1e-5 * abs(fd2)


def test_taylor_coefficients_reproduce_the_function():
    a = QuasiPolynomial([[1.0, 2.0, -1.0], [0.5, 3.0, 0.0]], [0.0, 0.7])
    s0 = -0.4 + 2.0j
    c, _ = a.taylor(s0, 20)
    for h in (1e-3, 0.1 + 0.2j):
        assert abs(np.polynomial.polynomial.polyval(h, c) - a(s0 + h)) < 1e-13 * abs(a(s0 + h))


def test_quasipolynomial_rejects_bad_input():
    with pytest.raises(ValueError, match="finite"):
        QuasiPolynomial([[np.nan]], [0.0])
    with pytest.raises(ValueError, match="delays must be >= 0"):
        QuasiPolynomial([[1.0]], [-0.1])
    with pytest.raises(ValueError, match="delays must be finite"):
        QuasiPolynomial([[1.0]], [np.inf])
    with pytest.raises(ValueError, match="rows"):
        QuasiPolynomial([[1.0], [2.0]], [0.0])
    with pytest.raises(TypeError):
        QuasiPolynomial([["a"]], [0.0])


# ---------------------------------------------------------------- transfer functions
def _G(s):
    return 1.0 / (s**2 + s)


def _C(s):
    return (10 * s + 10) / (0.01 * s + 1)


def test_series_parallel_feedback_inverse_are_exact():
    G = TransferFunction.from_poly([1.0], [1.0, 1.0, 0.0])  # seed 000 eq. 25
    C = TransferFunction.from_poly([10.0, 10.0], [0.01, 1.0])  # seed 000 eq. 27
    S = TransferFunction(QuasiPolynomial([[0.6], [0.4]], [0.0, 0.31]), QuasiPolynomial.constant(1.0))
    s = S_PTS
    Sv = 0.6 + 0.4 * np.exp(-0.31 * s)
    np.testing.assert_allclose((C * G * S)(s), _C(s) * _G(s) * Sv, rtol=1e-12)
    np.testing.assert_allclose((C + G)(s), _C(s) + _G(s), rtol=1e-12)
    np.testing.assert_allclose((C - G)(s), _C(s) - _G(s), rtol=1e-12)
    np.testing.assert_allclose(S.inverse()(s), 1 / Sv, rtol=1e-12)
    np.testing.assert_allclose((C / S)(s), _C(s) / Sv, rtol=1e-12)
    # inverse-shaper loop of seed 000 Fig. 3: CG / (1 + CG/S)
    L = (C * G).feedback(S.inverse())
    np.testing.assert_allclose(L(s), _C(s) * _G(s) / (1 + _C(s) * _G(s) / Sv), rtol=1e-11)
    # positive feedback
    P = (C * G).feedback(0.5, sign=+1)
    np.testing.assert_allclose(P(s), _C(s) * _G(s) / (1 - 0.5 * _C(s) * _G(s)), rtol=1e-11)
    # its characteristic quasi-polynomial is neutral (seed 000 Lemma 1 discussion)
    assert L.den.kind == "neutral"


def test_removable_singularity_of_uniform_delay_at_zero():
    T = 0.57
    tf = TransferFunction(QuasiPolynomial([[1.0], [-1.0]], [0.0, T]), QuasiPolynomial([[0.0, T]]))
    x = np.array([0.0, 1e-300, 1e-15, 1e-9, 1e-6, 1e-3, 0.3, 2.0, 50.0])
    with np.errstate(invalid="ignore"):
        ref = -np.expm1(-x * T) / (x * T)
    ref[0] = 1.0
    np.testing.assert_allclose(tf(x), ref, rtol=2e-15)
    z = 1e-8j
    assert abs(tf(z) - (-np.expm1(-z * T) / (z * T))) < 1e-15


def test_removable_singularities_of_cosine_kernel_off_the_origin():
    # (1 - e^{-sT}) 4pi^2 / (sT (s^2T^2 + 4pi^2)) has removable points at s = +-2 pi j / T
    from posicast import Kernel

    k = Kernel("cosine", 0.6)
    tf = k.transfer()
    s0 = 2j * np.pi / 0.6
    near = tf(np.array([s0 + 1e-7, s0 - 1e-7j]))
    assert np.all(np.isfinite(near))
    assert abs(tf(s0) - near[0]) < 1e-6
    assert abs(tf(0.0) - 1.0) < 1e-15


def test_true_pole_evaluates_to_infinity():
    tf = TransferFunction.from_poly([1.0], [1.0, 0.0])
    assert np.isinf(tf(0.0))
    assert tf.dc_gain == float("inf")
    with pytest.warns(FutureWarning, match="dc_gain is a property"):  # the old call still answers
        assert tf.dc_gain() == float("inf")


def test_dc_gain_through_integrator_cancellation():
    # s * (1/s) with delays: exact limit 1 * e^0
    tf = TransferFunction.from_poly([1.0, 0.0], [1.0]) * TransferFunction.from_poly([1.0], [1.0, 0.0], delay=0.2)
    assert abs(tf(0.0) - 1.0) < 1e-15


def test_conversions_in_and_out():
    tf = as_transfer(([2.0, 1.0], [1.0, 3.0, 2.0]))
    ref = (2 * S_PTS + 1) / (S_PTS**2 + 3 * S_PTS + 2)
    np.testing.assert_allclose(tf(S_PTS), ref, rtol=1e-13)
    np.testing.assert_allclose(as_transfer(signal.lti([2.0, 1.0], [1.0, 3.0, 2.0]))(S_PTS), ref, rtol=1e-12)
    ss = signal.lti([2.0, 1.0], [1.0, 3.0, 2.0]).to_ss()
    np.testing.assert_allclose(as_transfer(ss)(S_PTS), ref, rtol=1e-10)
    num, den = tf.to_scipy().num, tf.to_scipy().den
    np.testing.assert_allclose(num, [2.0, 1.0])
    np.testing.assert_allclose(den, [1.0, 3.0, 2.0])
    assert as_transfer(3.0)(1j) == 3.0
    with pytest.raises(TypeError, match="plant"):
        as_transfer("G", name="plant")


def test_python_control_interoperability():
    control = pytest.importorskip("control")
    G = control.tf([2.0, 1.0], [1.0, 3.0, 2.0])
    ref = (2 * S_PTS + 1) / (S_PTS**2 + 3 * S_PTS + 2)
    np.testing.assert_allclose(as_transfer(G)(S_PTS), ref, rtol=1e-12)
    np.testing.assert_allclose(as_transfer(control.ss(G))(S_PTS), ref, rtol=1e-10)
    back = as_transfer(G).feedback().to_control()
    ref_cl = control.feedback(G, 1)
    w = np.array([0.1, 1.0, 10.0])
    np.testing.assert_allclose(back(1j * w), ref_cl(1j * w), rtol=1e-12)
    with pytest.raises(ValueError, match="delays"):
        (as_transfer(G) * delay(0.1)).to_control()


def test_delay_factored_out_converts_when_rational_up_to_common_delay():
    tf = TransferFunction.from_poly([1.0], [1.0, 1.0], delay=0.2) / delay(0.2)
    assert tf.to_scipy().den.tolist() == [1.0, 1.0]


def test_transfer_function_rejects_bad_input():
    with pytest.raises(ValueError, match="den"):
        TransferFunction.from_poly([1.0], [0.0, 0.0])
    with pytest.raises(ValueError, match="finite"):
        TransferFunction.from_poly([np.nan], [1.0])
    with pytest.raises(ValueError, match="delay"):
        TransferFunction.from_poly([1.0], [1.0], delay=-1.0)
    with pytest.raises(ValueError, match="tau"):
        delay(np.nan)
    with pytest.raises(ValueError, match="omega"):
        TransferFunction.constant(1.0).freqresp([np.nan])


# ---------------------------------------------------------------- issue #13: hostile input
def test_evaluation_outside_the_float_range_is_a_named_error():
    """exp(800) overflows a double (max ~1.8e308 = exp(709.8)): the value at s = -800 is not representable."""
    h = QuasiPolynomial([[1.0], [1.0]], [0.0, 1.0])  # 1 + exp(-s)
    assert abs(h(-700.0) - (1.0 + np.exp(700.0))) <= 1e-12 * np.exp(700.0)
    with pytest.raises(ValueError, match="s = -800"):
        h(-800.0)
    with pytest.raises(ValueError, match="omega"):
        TransferFunction.from_poly([1.0], [1.0, 0.0, 0.0, 0.0]).freqresp([1e200])  # (1e200)^3 overflows
    with pytest.raises(TypeError, match="s must be a complex"):
        h("1j")
    with pytest.raises(ValueError, match="s must be finite"):
        h([1.0, np.nan])


def test_orders_and_operands_are_bounded_and_named():
    h = QuasiPolynomial([[1.0, 1.0], [0.5, 0.0]], [0.0, 1.0])
    with pytest.raises(ValueError, match=r"order must be an integer in \[0, 1000\]"):
        h.derivative(10**12)  # would loop for hours
    with pytest.raises(ValueError, match=r"order must be an integer in \[0, 170\]"):
        h.taylor(0.0, 171)  # 1/171! underflows
    with pytest.raises(TypeError, match="order"):
        h.derivative(1.5)
    with pytest.raises(ValueError, match="factor"):
        h.scaled(1e300).scaled(1e300)
    with pytest.raises(ValueError, match="delay must be >= 0"):
        h.shift(-1.0)
    with pytest.raises(TypeError, match="other"):
        h.equals("h")
    with pytest.raises(TypeError, match="complex"):  # no silent loss of an imaginary part
        QuasiPolynomial([[1j]])


def test_ill_posed_operations_are_value_errors_and_zero_divisions():
    from posicast.core.transfer import IllPosed

    one = TransferFunction.constant(1.0)
    with pytest.raises(IllPosed):
        one.feedback(1.0, sign=+1)  # 1 / (1 - 1): identically zero denominator
    with pytest.raises(ValueError):
        TransferFunction(QuasiPolynomial.zero(), QuasiPolynomial.constant(1.0)).inverse()
    with pytest.raises(ZeroDivisionError):
        TransferFunction(QuasiPolynomial.zero(), QuasiPolynomial.constant(1.0)).inverse()
    with pytest.raises(TypeError, match="sign"):
        one.feedback(1.0, sign="-")
    with pytest.raises(TypeError, match="other"):
        one.feedback("C")


def test_horner_is_numpys_polyval_bit_for_bit():
    """issue #15: the in-place Horner rule gives numpy's polyval exactly (same operations, same order),
    for real and complex points, one or several polynomials, a constant, integer coefficients and 0-d points."""
    from numpy.polynomial import polynomial as npP

    from posicast.core.quasipoly import horner

    rng = np.random.default_rng(5)
    x_c = rng.standard_normal(300) + 1j * rng.standard_normal(300)
    for c in (rng.standard_normal(7), rng.standard_normal((7, 4)), rng.standard_normal((1, 3)), np.array([3, -2, 1]),
              rng.standard_normal(5) + 1j * rng.standard_normal(5)):
        for x in (x_c, np.abs(x_c), np.array(0.7 - 2.0j), x_c.reshape(20, 15)):
            assert np.array_equal(horner(x, c), npP.polyval(x, c))
