"""Seed 003 Fig. 1 as a loop: channels, stability, simulation, Fig. 10-11 (issue #18)."""

from __future__ import annotations

import numpy as np
import pytest

import posicast
from posicast import cases
from posicast.qft import deviated_two_mass, inner_closed_loop, inner_loop, model_matching, zvdk

CASE = cases.ALL["two_mass"]
FM, G_PAPER, C_IN = CASE.extras["F_m"], CASE.extras["G_qft"], CASE.extras["C_inner"]
MODE = posicast.Mode(3.2074, 0.0389)


def _direct(P, G, F, C, S, s):
    """Solve Fig. 1's signal equations at one s: y = T_i r_s, r_s = S C (r_b - y)."""
    Ti = P(s) * G(s) * F(s) / (1 + P(s) * G(s))
    return S(s) * C(s) * Ti / (1 + S(s) * C(s) * Ti)


def test_channels_match_the_signal_equations():
    S = zvdk(MODE, 0)
    loop = model_matching(P=CASE.G, G=G_PAPER, F=FM, C=C_IN, S=S)
    for s in (0.3j, 2.0 + 1.0j, 3.2j):
        assert abs(loop.transfer("w", "y")(s) - _direct(CASE.G, G_PAPER, FM, C_IN, S, s)) < 1e-9
    assert len(loop.channels()) == 4 * 5
    assert loop.is_stable()
    # the inner loop's own poles are the closed loop's: no spurious integrator pole at 0
    Ti = inner_closed_loop(CASE.G, G_PAPER, FM)
    assert posicast.stability(Ti).stable
    assert Ti.dc_gain == pytest.approx(1.0)


def test_simulated_step_follows_the_reference_without_vibration():
    S = zvdk(MODE, 0)
    t = np.arange(0.0, 12.0, 0.01)
    loop = model_matching(P=CASE.G, G=G_PAPER, F=FM, C=C_IN, S=S)
    r = posicast.simulate(loop, t, w=np.ones_like(t))
    tail = r.y[t > 8.0]
    assert abs(tail.mean() - 1.0) < 0.02 and np.ptp(tail) < 0.02
    # the exact channel has unit DC gain (the integrator of C), as the simulated tail
    assert loop.transfer("w", "y")(1e-9) == pytest.approx(1.0, abs=1e-6)


def test_fig10_time_varying_plant_with_and_without_the_inner_loop():
    """At 70 % deviation the inner loop keeps the residual vibration small; the PI + ZVD^2 alone does not."""
    P70 = deviated_two_mass(70.0)
    t = np.arange(0.0, 40.0, 0.01)
    w = np.ones_like(t)
    with_inner = posicast.simulate(model_matching(P=P70, G=G_PAPER, F=FM, C=C_IN, S=zvdk(MODE, 0)), t, w=w)
    without = posicast.simulate(posicast.control_action(G=P70, C=CASE.C, S=zvdk(MODE, 2)), t, w=w)
    late = t > 30.0
    assert np.ptp(with_inner.y[late]) < 0.01
    assert np.ptp(without.y[late]) > 5 * np.ptp(with_inner.y[late])


def test_fig11_control_effort_channel_is_the_inner_controllers_output():
    L = inner_loop(P=CASE.G, G=G_PAPER, F=FM)
    s = 2.0j
    expected = G_PAPER(s) * FM(s) / (1 + CASE.G(s) * G_PAPER(s))
    assert abs(L.transfer("w", "u")(s) - expected) < 1e-9 * abs(expected)


def test_bad_inner_loop_inputs():
    with pytest.raises(ValueError, match="P must be delay-free"):
        inner_closed_loop(posicast.TransferFunction.from_poly([1.0], [1.0, 0.0], delay=0.1), G_PAPER, FM)
    with pytest.raises(TypeError, match="G must be"):
        model_matching(P=CASE.G, G="x", F=FM, C=C_IN)


# ---------------------------------------------------------------------- the CLI
def test_cli_qft(capsys, tmp_path):
    import json

    from posicast.cli import main

    assert main(["qft", "--json", "--plot", str(tmp_path / "n.png")]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["feasible"] and out["margins"]["matching"] >= 0 and (tmp_path / "n.png").exists()
    assert main(["qft", "--stability", "-1"]) == 2
    assert "stability must be a bound > 0" in capsys.readouterr().err
    assert main(["qft", "--structure", "real_zero"]) == 2
    assert "structure must give a proper controller" in capsys.readouterr().err
    assert main(["qft", "--uncertainty", "150"]) == 2


# ---------------------------------------------------------------------- the robot case (seed 003 experiment)
def test_robot_inner_loop_with_the_printed_gain_is_unstable():
    """Seed 003 closes the motor loop with G(s) = 3 on the printed P1: 1 + 3 P1 has roots 4.15 +/- 38.06j."""
    from scipy.optimize import brentq

    from posicast.qft import PlantSet, QFTResult, qft_design

    rb = cases.ALL["flexible_joint_robot"]
    P1, Fm = rb.G, rb.extras["F_m"]
    st = posicast.stability((3.0 * P1).feedback())
    assert not st.stable
    np.testing.assert_allclose(sorted(st.unstable_roots.imag), [-38.059, 38.059], atol=1e-3)
    assert st.unstable_roots.real[0] == pytest.approx(4.1513, abs=1e-3)
    # the critical gain from the phase crossover of P1 (independent of any root finder): 1.3167 at 32.19 rad/s
    w180 = brentq(lambda w: complex(1.0 / P1(1j * w)).imag, 25.0, 40.0)
    g_crit = -complex(1.0 / P1(1j * w180)).real
    assert g_crit == pytest.approx(1.3167, abs=1e-4) and w180 == pytest.approx(32.187, abs=1e-3)
    assert posicast.stability((0.99 * g_crit * P1).feedback()).stable
    # the paper's specs (eq. 2-3) with its F_m = 25 / (s^2 + 7 s + 25): G = 3 fails, a designed lead meets them
    printed = QFTResult.check([P1], Fm, 3.0, stability=1.413, matching=0.1)
    assert not printed.feasible and "inner_loops" in printed.violated
    r = qft_design(PlantSet.from_list([P1]), Fm, stability=1.413, matching=0.1, structure=("lead",))
    assert r.feasible and posicast.stability((r.controller * P1).feedback()).stable


# ---------------------------------------------------------------------- Fig. 9 and Fig. 11
def test_fig9_root_locus_four_plants_unstable_with_the_pi_alone():
    """Without the inner loop and without its shaper, the printed PI destabilises plants 0, 3, 9, 18."""
    from posicast.qft import root_locus

    rl = root_locus(cases.two_mass_plants(), CASE.C, np.array([0.5, 1.0, 2.0, 5.0]))
    assert rl.poles.shape[:2] == (27, 4)
    assert list(np.flatnonzero(rl.crossing <= 1.0)) == [0, 3, 9, 18]
    assert np.all(rl.crossing <= 5.0)  # every plant goes unstable by 5 x the gain
    # certified: the same loops by posicast.stability; with the ZVD^2 in the loop all 27 are stable
    for i in (0, 3, 9, 18):
        assert not posicast.control_action(G=cases.two_mass_plants()[i], C=CASE.C).is_stable()
        assert posicast.control_action(G=cases.two_mass_plants()[i], C=CASE.C, S=zvdk(MODE, 2)).is_stable()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = rl.plot()
    plt.close(fig)


def test_fig11_control_effort_matches_the_one_shot_channel():
    from scipy import signal

    from posicast.qft import control_effort

    P, G, F, C = (1.0, [1.0, 1.0, 0.0]), ([5.0, 5.0], [0.05, 1.0]), ([4.0], [1.0, 0.4, 4.0]), ([0.5, 1.0], [1.0, 0.0])
    t = np.arange(0.0, 8.0, 0.005)
    eff = control_effort(P=P, G=G, F=F, C=C, S=None, t=t)
    Pt, Gt, Ft, Ct = (posicast.as_transfer(x) for x in (P, G, F, C))
    Ti = inner_closed_loop(Pt, Gt, Ft)
    wu = (Ct / (1 + Ct * Ti)) * (Gt * Ft / (1 + Pt * Gt))  # w -> u in one exact transfer function
    sc = wu.to_scipy()
    _, u_ref, _ = signal.lsim((sc.num, sc.den), np.ones_like(t), t)
    assert np.max(np.abs(eff.u - u_ref)) < 1e-3 * np.max(np.abs(u_ref))
    with pytest.raises(ValueError, match="G must make G F / \\(1 \\+ P G\\) proper"):
        control_effort(P=CASE.G, G=G_PAPER, F=FM, C=C_IN, S=None, t=t)
