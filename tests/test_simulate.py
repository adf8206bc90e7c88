"""Time-domain simulation (issue #4): seed 000 section V, exact fractional delays, bad input."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy import signal

import posicast
from posicast.simulate import DivergenceWarning, simulate

MODE = posicast.Mode(10.0, 0.03)  # F(s) = s / (s^2 + 0.6 s + 100), seed 000 eq. 26
G = ([1.0], [1.0, 1.0, 0.0])  # eq. 25
F = ([1.0, 0.0], [1.0, 0.6, 100.0])  # eq. 26
C = ([10.0, 10.0], [0.01, 1.0])  # eq. 27
T_END = 40.0


def _run(arch, kind, sample_rate=None, t_end=T_END, dt=1e-3):
    S = posicast.design(kind, MODE) if kind else None
    loop = getattr(posicast, arch)(G=G, F=F, C=C, S=S)
    t = np.arange(0.0, t_end, dt)
    w = (t >= 5.0).astype(float)  # set-point at t = 5 (seed 000 Fig. 7-8)
    d = 0.5 * (t >= 20.0)  # output disturbance at t = 20
    return simulate(loop, t, w=w, d=d, sample_rate=sample_rate)


def _vib(r, lo, hi):
    sel = (r.time > lo) & (r.time < hi)
    return float(np.ptp(r.y[sel]) / 2)


@pytest.mark.parametrize("sample_rate", [None, 1000.0, 200.0])
def test_seed000_fig8_claims(sample_rate):
    """Seed 000 section V: which scheme suppresses y's oscillation after w and after d."""
    none = _run("control_action", None, sample_rate)
    ca = _run("control_action", "zv", sample_rate)
    inv_dzv = _run("inverse_shaper", "dzv", sample_rate)
    base_w, base_d = _vib(none, 12, 20), _vib(none, 30, 40)
    assert base_w > 1e-3 and base_d > 1e-3
    # control-action shaper: suppresses after the set-point change, not after the disturbance
    assert _vib(ca, 12, 20) < 1e-3 * base_w
    assert _vib(ca, 30, 40) > 0.5 * base_d
    # inverse DZV: suppresses both
    assert _vib(inv_dzv, 12, 20) < 1e-3 * base_w
    assert _vib(inv_dzv, 30, 40) < 0.05 * base_d


def test_inverse_zv_diverges_at_high_frequency():
    """Seed 000: the inverse ZV loop's unstable high-frequency poles make it diverge."""
    with pytest.warns(DivergenceWarning, match="diverged"):
        r = _run("inverse_shaper", "zv", 1000.0, t_end=600.0)
    assert r.diverged is not None and r.diverged > 20.0
    # the growing oscillation is at one of the unstable pole frequencies (51, 71 or 90 rad/s)
    seg = r.y[-20000:] - np.mean(r.y[-20000:])
    f = np.fft.rfftfreq(seg.size, 1e-3) * 2 * np.pi
    peak = f[np.argmax(np.abs(np.fft.rfft(seg * np.hanning(seg.size))))]
    assert 40.0 < peak < 100.0
    # the spectral analysis agrees: the loop is unstable
    loop = posicast.inverse_shaper(G=G, F=F, C=C, S=posicast.design("zv", MODE))
    assert not loop.is_stable()


def _analytic_feedforward(t, S):
    """y = sum_i A_i y_step(t - 5 - t_i) with y_step from the residues of T_wy(s) / s."""
    T0 = posicast.feedforward(G=G, F=F, C=C).transfer("w", "y").to_scipy()
    rr, pp, _ = signal.residue(T0.num, np.polymul(T0.den, [1.0, 0.0]))

    def ystep(tt):
        out = np.zeros(tt.shape, dtype=complex)
        for ri, pi in zip(rr, pp):
            out += ri * np.exp(pi * np.clip(tt, 0.0, None))
        return np.where(tt >= 0, out.real, 0.0)

    times, amps = S.impulses
    return sum(a * ystep(t - 5.0 - ti) for ti, a in zip(times, amps))


def test_feedforward_zv_exact_fractional_delay_continuous():
    S = posicast.design("zv", MODE)
    tau = S.impulses[0][1]
    assert abs(tau / 1e-3 - round(tau / 1e-3)) > 0.1  # 0.3143 s: not a multiple of the step
    loop = posicast.feedforward(G=G, F=F, C=C, S=S)
    t = np.arange(0.0, 30.0, 1e-3)
    r = simulate(loop, t, w=(t >= 5.0).astype(float))
    ya = _analytic_feedforward(t, S)
    assert np.max(np.abs(r.y - ya)) < 1e-10
    assert r.residual_vibration(15.0) <= 1e-7
    assert r.mode == "continuous (exact)"


def test_feedforward_zv_sampled_fractional_taps_beat_rounding():
    S = posicast.design("zv", MODE)
    loop = posicast.feedforward(G=G, F=F, C=C, S=S)
    t = np.arange(0.0, 30.0, 1e-3)
    r = simulate(loop, t, w=(t >= 5.0).astype(float), sample_rate=1000.0)
    res = r.residual_vibration(15.0)
    # the same shaper with its delay rounded to the millisecond
    times, amps = S.impulses
    Sr = posicast.Shaper(times=np.round(times, 3), amplitudes=amps)
    rr = simulate(posicast.feedforward(G=G, F=F, C=C, S=Sr), t, w=(t >= 5.0).astype(float), sample_rate=1000.0)
    res_round = rr.residual_vibration(15.0)
    print(f"sampled 1 kHz residual: fractional taps {res:.3e}, rounded delay {res_round:.3e}")
    assert res < 5e-7
    assert res_round > 20 * res


@pytest.mark.filterwarnings("ignore::scipy.signal.BadCoefficients")
def test_sampled_delay_free_loop_matches_state_space_reference():
    """Sampled mode against an independent step-by-step state-space recursion."""
    loop = posicast.control_action(G=G, F=F, C=C)
    t = np.arange(0.0, 10.0, 1e-3)
    w = (t >= 1.0).astype(float)
    r = simulate(loop, t, w=w, sample_rate=1000.0)
    Cd = signal.cont2discrete(C, 1e-3, method="bilinear")
    Gd = signal.cont2discrete(G, 1e-3, method="zoh")
    Ac, Bc, Cc, Dc = signal.tf2ss(np.squeeze(Cd[0]), Cd[1])
    Ag, Bg, Cg, Dg = signal.tf2ss(np.squeeze(Gd[0]), Gd[1])
    xc = np.zeros(Ac.shape[0])
    xg = np.zeros(Ag.shape[0])
    z = np.zeros(t.size)
    for k in range(t.size):
        z[k] = (Cg @ xg).item()
        e = w[k] - z[k]
        v = (Cc @ xc).item() + Dc.item() * e
        xc = Ac @ xc + Bc[:, 0] * e
        xg = Ag @ xg + Bg[:, 0] * v
    assert np.max(np.abs(r.z - z)) < 1e-9
    # the load y = (F G) u, G's pole at 0 cancelled by F's zero, as a state recursion from the discretised
    # state space (not a transfer polynomial)
    FG = signal.tf2ss([1.0], np.polymul([1.0, 0.6, 100.0], [1.0, 1.0]))
    Af, Bf, Cf, _, _ = signal.cont2discrete(FG, 1e-3, method="zoh")
    xf = np.zeros(Af.shape[0])
    y = np.zeros(t.size)
    for k in range(t.size):
        y[k] = (Cf @ xf).item()
        xf = Af @ xf + Bf[:, 0] * r.u[k]
    assert np.max(np.abs(r.y - y)) < 1e-11


@pytest.mark.parametrize(
    "kwargs, exc, word",
    [
        ({"sample_rate": 2.0}, ValueError, "sample_rate"),  # ZV delay 0.314 s < one sample
        ({"sample_rate": 10.0}, ValueError, "Nyquist"),  # F has a 50 rad/s (7.96 Hz) mode
        ({"w": np.ones(5)}, ValueError, "length"),
        ({"w": np.full(4000, np.nan)}, ValueError, "NaN"),
        ({"sample_rate": 333.3}, ValueError, "multiple"),
        ({"sample_rate": -1.0}, ValueError, "sample_rate"),
    ],
)
def test_bad_input(kwargs, exc, word):
    loop = posicast.control_action(G=G, F=([1.0, 0.0], [1.0, 2.0, 2500.0]), C=C, S=posicast.design("zv", MODE))
    t = np.arange(0.0, 4.0, 1e-3)
    args = {"w": np.ones(t.size)}
    args.update(kwargs)
    with pytest.raises(exc, match=word):
        simulate(loop, t, **args)


def test_bad_loop_and_time():
    with pytest.raises(TypeError, match="loop"):
        simulate("loop", np.arange(3.0))
    loop = posicast.control_action(G=G, F=F, C=C)
    with pytest.raises(ValueError, match="uniform"):
        simulate(loop, np.array([0.0, 1.0, 3.0]))


@pytest.mark.parametrize("arch, kind", [("control_action", "zv"), ("inverse_shaper", "zv"),
                                        ("inverse_shaper", "dzv"), ("feedforward", "zv")])
def test_inactive_limits_reproduce_the_linear_loop(arch, kind):
    """The sample-by-sample (nonlinear) path with limits that never bind equals the filter path."""
    S = posicast.design(kind, MODE)
    loop = getattr(posicast, arch)(G=G, F=F, C=C, S=S)
    t = np.arange(0.0, 8.0, 1e-3)
    w = (t >= 1.0).astype(float)
    d = 0.3 * (t >= 4.0)
    lin = simulate(loop, t, w=w, d=d, sample_rate=200.0)
    nl = simulate(loop, t, w=w, d=d, sample_rate=200.0, saturation=1e9, rate_limit=1e12)
    for key in ("z", "y", "u"):
        assert np.max(np.abs(lin.signals[key] - nl.signals[key])) < 1e-7


def test_saturation_and_rate_limit_bind():
    loop = posicast.control_action(G=G, F=F, C=C, S=posicast.design("zv", MODE))
    t = np.arange(0.0, 20.0, 1e-3)
    w = (t >= 1.0).astype(float)
    free = simulate(loop, t, w=w, sample_rate=1000.0)
    assert free.peak("u") > 5.0
    sat = simulate(loop, t, w=w, sample_rate=1000.0, saturation=(-2.0, 2.0))
    assert sat.peak("u") <= 2.0 + 1e-12
    assert sat.settling_time("z") > free.settling_time("z")
    rl = simulate(loop, t, w=w, sample_rate=1000.0, rate_limit=20.0)
    assert np.max(np.abs(np.diff(rl.u))) <= 20.0 * 1e-3 * (1 + 1e-9)
    with pytest.raises(ValueError, match="saturation"):
        simulate(loop, t, w=w, saturation=(1.0, -1.0))
    with pytest.raises(ValueError, match="rate_limit"):
        simulate(loop, t, w=w, rate_limit=0.0)


def test_in_loop_filter_path_matches_state_space_recursion():
    """Control-action ZV at 1 kHz against an independent step-by-step recursion (accuracy of the filter path)."""
    S = posicast.design("zv", MODE)
    loop = posicast.control_action(G=G, F=F, C=C, S=S)
    t = np.arange(0.0, 6.0, 1e-3)
    w = (t >= 1.0).astype(float)
    r = simulate(loop, t, w=w, sample_rate=1000.0)
    ref = simulate(loop, t, w=w, sample_rate=1000.0, saturation=1e12)  # the explicit recursion
    assert np.max(np.abs(r.z - ref.z)) < 1e-7
