"""The seed 000 loop with the inverse DZV inside it (issue #15, part B), shared by bench_simulate*.py.

``S = a0 + a1 (1 - e^{-sT}) / (sT)`` (seed 000 eq. 6 and 20); the inverse-shaper
architecture ``e = w - z / S``, ``v = C e``, ``z = G v``, ``y = F z`` with
G, F, C of seed 000 eq. 25-27.  Three ways to run it, and the exact answers they
are judged against.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy import signal

import posicast

G = ([1.0], [1.0, 1.0, 0.0])
F = ([1.0, 0.0], [1.0, 0.6, 100.0])
C = ([10.0, 10.0], [0.01, 1.0])
MODE = posicast.Mode(10.0, 0.03)
STEP = 5.0  # the set-point step [s]


def shaper() -> posicast.Shaper:
    return posicast.design("dzv", MODE)


def loop() -> posicast.Loop:
    return posicast.inverse_shaper(G=G, F=F, C=C, S=shaper())


def dzv_numbers() -> tuple[float, float, float]:
    """``(a0, a1, T)`` of the DZV."""
    S = shaper()
    part = S.distributed[0]
    return float(S.amplitudes[0]), float(part.weight), float(part.kernels[0].T)


def _ss(tf, h: float, method: str):
    num, den = tf
    with warnings.catch_warnings():  # BadCoefficients: an exact zero of the discretised numerator, rounded
        warnings.simplefilter("ignore")
        d = signal.cont2discrete((num, den), h, method=method)
        A, B, Cm, D = signal.tf2ss(np.squeeze(d[0]), d[1])
    return A, B[:, 0], Cm[0], float(D[0, 0])


def hand_written(w: np.ndarray, h: float) -> np.ndarray:
    """What a user writes: one Python step per sample, Tustin C, ZOH G and F, the inverse DZV from
    ``S m = z`` with the kernel's integral by the trapezoid rule (fractional end interpolated) as a
    running sum.  Returns ``y``."""
    a0, a1, T = dzv_numbers()
    Ac, Bc, Cc, Dc = _ss(C, h, "bilinear")
    Ag, Bg, Cg, _ = _ss(G, h, "zoh")
    Af, Bf, Cf, Df = _ss(F, h, "zoh")
    M = int(np.floor(T / h))
    f = T / h - M
    c = a1 / T
    N = w.size
    m = np.zeros(N + M + 2)  # m[j + M + 1] = m_j, zero before the start
    o = M + 1
    xc, xg, xf = np.zeros(Ac.shape[0]), np.zeros(Ag.shape[0]), np.zeros(Af.shape[0])
    y = np.empty(N)
    run = 0.0  # sum of m_{j-1} .. m_{j-M+1}
    denom = a0 + c * h / 2
    for j in range(N):
        z = Cg @ xg
        mM, mM1 = m[o + j - M], m[o + j - M - 1]
        tail = f * h * (mM + (mM + f * (mM1 - mM))) / 2  # from t - T to t - M h
        mj = (z - c * (h * (run + mM / 2) + tail)) / denom
        m[o + j] = mj
        run += mj - m[o + j - M + 1]
        e = w[j] - mj
        v = Cc @ xc + Dc * e
        y[j] = Cf @ xf + Df * z
        xc = Ac @ xc + Bc * e
        xg = Ag @ xg + Bg * v
        xf = Af @ xf + Bf * z
    return y


def control_system(order: int = 10):
    """The loop in python-control with the delay ``e^{-sT}`` as ``pade(T, order)``: ``w -> y``."""
    import control

    a0, a1, T = dzv_numbers()
    num, den = control.pade(T, order)
    num = np.concatenate([np.zeros(len(den) - len(num)), num])
    kern_num = np.polysub(den, num)[:-1]  # (1 - e^{-sT}) / (sT): the constant terms cancel, divide by s
    Sn = np.polyadd(a0 * T * np.asarray(den), a1 * kern_num)
    Sd = T * np.asarray(den)
    with warnings.catch_warnings():  # scipy's BadCoefficients on the pade numerator: the tool's own loss
        warnings.simplefilter("ignore")
        Cs, Gs, Fs = control.tf(*C), control.tf(*G), control.tf(*F)
        inv_S = control.tf(Sd, Sn)
        return control.ss(Fs * control.feedback(Cs * Gs, inv_S))


def run_control(sys_c, t: np.ndarray, w: np.ndarray) -> np.ndarray:
    import control

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return np.asarray(control.forced_response(sys_c, T=t, U=w).outputs)


def references(h: float, n: int, substeps: int = 16) -> tuple[np.ndarray, np.ndarray, float]:
    """Exact ``y`` on ``t = k h`` for the held step at STEP (ZOH) and for the step interpolated linearly from
    STEP - h (python-control's input model), from one posicast run of the unit step at t = 0 with
    ``substeps`` internal steps per ``h / substeps`` sample (its own error estimate returned too).

    The FOH answer is the average of the step response over the ramp's start times (trapezoid rule on
    the fine grid, error ~ (h / substeps)^2)."""
    hf = h / substeps
    lead = int(round(STEP / hf))
    nf = n * substeps + substeps
    tf_ = np.arange(nf) * hf
    r = posicast.simulate(loop(), tf_, w=np.ones(nf), outputs=("y",))
    ys = np.concatenate([np.zeros(lead + substeps), r.y])  # ys[i] = y_step(i hf - STEP - h)
    idx = np.arange(n) * substeps + substeps  # t_k - STEP - h, on the fine grid, shifted by lead
    y_zoh = ys[idx]
    shifts = np.arange(substeps + 1)  # ramp from STEP - h: starts STEP - h + i hf
    wts = np.full(substeps + 1, 1.0)
    wts[[0, -1]] = 0.5
    y_foh = sum(wt * ys[idx + substeps - i] for i, wt in zip(shifts, wts)) / substeps
    return y_zoh, y_foh, r.accuracy
