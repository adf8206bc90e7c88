"""Residual vibration, sensitivity and insensitivity against analytic formulas and seed 004's claims."""

import math

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")

import posicast as pc
from posicast import Mode, design, insensitivity, residual_vibration, sensitivity_curve


def _seed004_V(times, amps, omega, zeta):
    """Seed 004 eq. 1-3 written out independently: e^{-zeta w t_n} sqrt(C^2 + S^2)."""
    wd = omega * math.sqrt(1 - zeta**2)
    C = np.sum(amps * np.exp(zeta * omega * times) * np.cos(wd * times))
    S = np.sum(amps * np.exp(zeta * omega * times) * np.sin(wd * times))
    return math.exp(-zeta * omega * times[-1]) * math.hypot(C, S)


@pytest.mark.parametrize("kind", ["zv", "zvd", "zvddd", "mzv", "mis_zvd", "ei", "ei3"])
def test_residual_vibration_is_seed004_eq1_to_3(kind):
    m = Mode(4.0, 0.12)
    S = design(kind, m)
    for r in (0.5, 0.93, 1.0, 1.2, 1.7):
        ref = _seed004_V(S.times, S.amplitudes, r * m.omega, m.zeta)
        assert abs(residual_vibration(S, r * m.omega, m.zeta) - ref) < 1e-13


def test_undamped_zvdk_sensitivity_is_cos_power():
    # For zeta = 0, ZVD^k gives V(r) = |cos(pi r / 2)|^(k+1) exactly.
    r = np.linspace(0.05, 2.5, 300)
    for k in range(5):
        S = design("zvdk", Mode(3.0, 0.0), k=k)
        c = sensitivity_curve(S, ratio=r)
        np.testing.assert_allclose(c.vibration, np.abs(np.cos(np.pi * r / 2)) ** (k + 1), atol=1e-13)


@pytest.mark.parametrize("k", [0, 1, 2, 3])
def test_insensitivity_of_undamped_zvdk_is_analytic(k):
    # |cos(pi r/2)|^(k+1) <= V  <=>  |r - 1| <= (2/pi) arcsin(V^(1/(k+1)))
    S = design("zvdk", Mode(3.0, 0.0), k=k)
    ins = insensitivity(S, 0.05)
    ref = 4 / math.pi * math.asin(0.05 ** (1 / (k + 1)))
    assert abs(ins.width - ref) < 1e-10
    assert abs(ins.low + ins.high - 2) < 1e-10


@pytest.mark.parametrize("zeta", [0.0, 0.05, 0.14])
def test_insensitivity_ordering_claimed_by_seed004(zeta):
    """Issue #2 acceptance 6: ZV < ZVD < ZVDD < ZVDDD and EI > ZVD at 5 %."""
    m = Mode(8.98, zeta)
    w = {k: insensitivity(design(k, m), 0.05).width for k in ("zv", "zvd", "zvdd", "zvddd")}
    w["ei"] = insensitivity(design("ei", m, vtol=0.05), 0.05).width
    assert w["zv"] < w["zvd"] < w["zvdd"] < w["zvddd"]
    assert w["ei"] > w["zvd"]


def test_distributed_residual_against_direct_integration():
    # V for a distributed shaper through the exact TF equals the vibration left by
    # numerically convolving its impulse response with the mode (after t_end).
    from scipy.integrate import quad

    m = Mode(8.98, 0.14)
    S = design("dzv", m)
    act = Mode(1.15 * m.omega, m.zeta)
    p = act.pole
    integral = S.amplitudes @ np.exp(-p * S.times)
    part = S.distributed[0]
    re = quad(lambda t: (part.density(t) * np.exp(-p * t)).real, part.delay, part.end, epsabs=1e-14)[0]
    im = quad(lambda t: (part.density(t) * np.exp(-p * t)).imag, part.delay, part.end, epsabs=1e-14)[0]
    ref = abs(integral + re + 1j * im) * math.exp(-act.decay * S.duration)
    assert abs(residual_vibration(S, act.omega, act.zeta) - ref) < 1e-12


def test_references_and_iir():
    m = Mode(5.49, 0.2)
    S = design("zv", m)
    w = 1.3 * m.omega
    a = residual_vibration(S, w, m.zeta, reference="unshaped")
    b = residual_vibration(S, w, m.zeta, reference="end")
    assert abs(b - a * math.exp(-m.zeta * w * S.duration)) < 1e-15
    notch = design("notch", m)
    with pytest.raises(ValueError, match="unshaped"):
        residual_vibration(notch, w, m.zeta)
    assert residual_vibration(notch, m.omega, m.zeta, reference="unshaped") < 1e-12


def test_vectorised_over_omega():
    S = design("zvd", Mode(2.0, 0.05))
    w = np.linspace(0.5, 4.0, 7)
    out = residual_vibration(S, w, 0.05)
    assert out.shape == (7,)
    assert all(abs(out[i] - residual_vibration(S, float(w[i]), 0.05)) < 1e-15 for i in range(7))


def test_bad_input_to_analysis():
    S = design("zv", Mode(1.0, 0.1))
    with pytest.raises(ValueError, match="omega"):
        residual_vibration(S, [1.0, -1.0], 0.1)
    with pytest.raises(ValueError, match="omega"):
        residual_vibration(S, np.nan, 0.1)
    with pytest.raises(ValueError, match="zeta"):
        residual_vibration(S, 1.0, 1.0)
    with pytest.raises(ValueError, match="reference"):
        residual_vibration(S, 1.0, 0.1, reference="start")
    with pytest.raises(TypeError, match="shaper"):
        residual_vibration("zv", 1.0, 0.1)
    with pytest.raises(ValueError, match="vtol"):
        insensitivity(S, 1.5)
    with pytest.raises(ValueError, match="several modes"):
        insensitivity(S * design("zv", Mode(3.0, 0.1)), 0.05)


def test_plots_return_figure_and_axes():
    m = Mode(5.49, 0.008)
    fig, ax = pc.sensitivity_plot([design("zv", m), design("zvd", m), design("dzv", m)])
    assert len(ax.lines) == 4  # three curves and the tolerance line
    fig2, ax2 = pc.impulse_plot(design("dtzv", m))
    assert ax2.get_xlabel() == "t [s]"
    import matplotlib.pyplot as plt

    plt.close("all")
