"""Synthetic identification data reproducing seed 002's sensor (sections 3.2 and 4).

* The "true" system is the continuous mode of seed 002 eq. 16,
  ``F(s) = omega^2 / (s^2 + 2 zeta omega s + omega^2)`` (a sum of such modes
  for several), sampled **exactly** under a zero-order hold: the input is held
  between samples, as a digital controller holds its command.  (The seed itself
  discretises with the backward difference of eq. 18, which distorts the mode
  at 28 Hz / 400 Hz; posicast's data are exact samples of the continuous system.)
* ``output="position"`` returns F u; ``output="acceleration"`` returns
  ``s^2 F u`` (what an accelerometer on the mass measures).
* The sensor: white noise of ``noise`` times the clean output's peak-to-peak
  range (standard deviation), optional noise density (seed 002 section 4:
  LSM303DLHC, 220 ug/sqrt(Hz) at 400 Hz), then ``bits``-bit quantisation over
  ``+-full_scale`` (seed 002: 12-bit).

Klipper-format logs (``#time,accel_x,accel_y,accel_z``) of a resonance test
come from :func:`klipper_log`.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np
from scipy import signal

from .. import _validate as v
from ..modes import Mode

__all__ = ["INPUTS", "excitation", "simulate", "sensor", "synthetic", "SyntheticData", "klipper_sweep", "klipper_log"]

INPUTS = ("step", "impulse", "ramp", "harmonic", "random_binary", "chirp")
G = 9.80665


def _modes(modes: Any) -> list[Mode]:
    if isinstance(modes, Mode):
        return [modes]
    out = list(modes) if isinstance(modes, (list, tuple)) else None
    if not out or not all(isinstance(m, Mode) for m in out):
        raise TypeError("modes must be a posicast.Mode or a non-empty list of Mode")
    return out


def excitation(kind: str, n: int, fs: float, *, seed: int | None = None, delay: int = 0,
               freq: float | None = None, period: float | None = None) -> np.ndarray:
    """Input signal of ``n`` samples at ``fs`` Hz (held between samples).

    Parameters
    ----------
    kind : {"step", "impulse", "ramp", "harmonic", "random_binary", "chirp"}
        Seed 002 Fig. 8 signals (unit pulse, step, ramp, harmonic) plus a
        random binary sequence (levels +-1, held 2-6 samples) and a linear chirp
        from 0.5 Hz to 0.4 fs over the record.
    n : int
        Number of samples, >= 2.
    fs : float
        Sample rate in Hz, > 0.
    seed : int, optional
        Seed of the random binary sequence.
    delay : int
        Samples of rest before a step / impulse / ramp starts (>= 0).
    freq : float, optional
        Frequency of the harmonic input in Hz (default fs / 40).
    period : float, optional
        ``"step"`` only: repeat the step every ``period`` seconds, alternating
        up and down (a back-and-forth move); default a single step.

    Examples
    --------
    >>> excitation("step", 5, 400.0, delay=2).tolist()
    [0.0, 0.0, 1.0, 1.0, 1.0]
    """
    n = v.integer(n, "n", 2)
    fs = v.positive(fs, "fs")
    delay = v.integer(delay, "delay", 0)
    k = np.arange(n)
    if kind == "step":
        if period is None:
            return (k >= delay).astype(float)
        m = max(1, int(round(v.positive(period, "period") * fs)))
        return np.where(k >= delay, ((k - delay) // m + 1) % 2, 0).astype(float)
    if kind == "impulse":
        return (k == delay).astype(float)
    if kind == "ramp":
        return np.clip((k - delay) / max(n - 1 - delay, 1), 0.0, None)
    if kind == "harmonic":
        f = fs / 40.0 if freq is None else v.positive(freq, "freq")
        return np.sin(2.0 * math.pi * f * k / fs)
    if kind == "random_binary":
        rng = np.random.default_rng(seed)
        holds = rng.integers(2, 7, size=n)
        levels = np.repeat(np.where(rng.random(n) < 0.5, -1.0, 1.0), holds)[:n]
        return levels
    if kind == "chirp":
        t = k / fs
        return signal.chirp(t, f0=0.5, t1=max(t[-1], 1.0 / fs), f1=0.4 * fs, method="linear")
    raise ValueError(f"kind must be one of {', '.join(INPUTS)}; got {kind!r}")


def _mode_tf(m: Mode, output: str, gain: float) -> tuple[np.ndarray, np.ndarray]:
    w, z = m.omega, m.zeta
    den = np.array([1.0, 2.0 * z * w, w * w])
    if output == "position":
        num = np.array([0.0, 0.0, gain * w * w])
    else:  # acceleration: s^2 F(s)
        num = gain * w * w * np.array([1.0, 0.0, 0.0])
    return num, den


def _zoh(num: Any, den: Any, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """ZOH-exact discrete (b, a) via the state space (scipy.signal.cont2discrete)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", signal.BadCoefficients)
        A, B, C, D = signal.tf2ss(num, den)
    Ad, Bd, Cd, Dd, _ = signal.cont2discrete((A, B, C, D), 1.0 / fs, method="zoh")
    lam = np.linalg.eigvals(Ad)
    a = np.real(np.poly(lam))
    # numerator of C (zI - Ad)^-1 Bd + D = (C adj(zI - Ad) Bd + D det) / det
    # matrix determinant lemma: det(zI - Ad + Bd Cd) - det(zI - Ad) = Cd adj(zI - Ad) Bd
    n = Ad.shape[0]
    b = np.real(np.poly(Ad - Bd @ Cd)) - a + Dd.item() * a
    return b[: n + 1], a


def simulate(modes: Mode | Sequence[Mode], u: Any, fs: float, *, output: str = "position",
             gains: Sequence[float] | None = None) -> np.ndarray:
    """Exact ZOH samples of ``sum_k gains_k F_k(s) u`` (seed 002 eq. 16), from rest.

    Examples
    --------
    >>> y = simulate(Mode.from_hz(28.0, 0.05), np.ones(4000), 400.0)
    >>> round(float(y[-1]), 6)        # DC gain of eq. 16 is 1
    1.0
    """
    ms = _modes(modes)
    u = v.real_array(u, "u")
    if u.ndim != 1:
        raise ValueError("u must be one-dimensional")
    fs = v.positive(fs, "fs")
    if output not in ("position", "acceleration"):
        raise ValueError(f"output must be 'position' or 'acceleration', got {output!r}")
    g = np.ones(len(ms)) if gains is None else v.real_array(gains, "gains")
    if g.shape != (len(ms),):
        raise ValueError(f"gains must have one entry per mode ({len(ms)})")
    y = np.zeros_like(u)
    for m, gk in zip(ms, g):
        num, den = _mode_tf(m, output, float(gk))
        y += signal.lfilter(*_zoh(num, den, fs), u)
    return y


def sensor(y: Any, *, fs: float, noise: float = 0.0, density: float = 0.0, bits: int | None = 12,
           full_scale: float | None = None, rng: np.random.Generator | None = None,
           scale_range: float | None = None) -> np.ndarray:
    """Add white noise (``noise`` x range std, plus ``density`` per sqrt(Hz)) and quantise.

    ``density`` is in output units per sqrt(Hz) (seed 002: 220e-6 g/sqrt(Hz)); its
    standard deviation at rate ``fs`` is ``density * sqrt(fs / 2)``.  ``full_scale``
    (default 1.25 max|y|) is the +- range of the ``bits``-bit converter.
    """
    y = v.real_array(y, "y")
    fs = v.positive(fs, "fs")
    if not 0.0 <= v.real(noise, "noise") < 1.0:
        raise ValueError(f"noise must be in [0, 1) (fraction of the output range), got {noise:g}")
    if v.real(density, "density") < 0:
        raise ValueError(f"density must be >= 0, got {density:g}")
    rng = np.random.default_rng() if rng is None else rng
    rng_y = float(np.ptp(y)) if scale_range is None else scale_range
    sd = noise * rng_y
    total = math.hypot(sd, density * math.sqrt(fs / 2.0))
    out = y + total * rng.standard_normal(y.shape) if total > 0 else y.copy()
    if bits is not None:
        bits = v.integer(bits, "bits", 2)
        fsc = 1.25 * float(np.max(np.abs(y))) if full_scale is None else v.positive(full_scale, "full_scale")
        if fsc == 0:
            return out
        q = 2.0 * fsc / 2**bits
        out = np.clip(np.round(out / q) * q, -fsc, fsc - q)
    return out


@dataclass(frozen=True)
class SyntheticData:
    """A synthetic record: time, input, measured and clean output, true modes."""

    t: np.ndarray
    u: np.ndarray
    y: np.ndarray
    y_clean: np.ndarray
    modes: list[Mode]
    fs: float


def synthetic(modes: Mode | Sequence[Mode], input: str = "step", *, fs: float = 400.0, n: int = 800,
              noise: float = 0.0, input_noise: float = 0.0, output: str = "position", bits: int | None = 12,
              density: float = 0.0, full_scale: float | None = None, seed: int | None = None,
              delay: int = 0, gains: Sequence[float] | None = None, period: float | None = None) -> SyntheticData:
    """Seed 002's identification experiment: input, exact response, sensor.

    Parameters
    ----------
    modes : Mode or list of Mode
        True modes (seed 002: 28 Hz, zeta 0.05).
    input : str
        One of :data:`INPUTS`.
    fs, n : float, int
        Sample rate (seed 002: 400 Hz) and number of samples.
    noise : float
        Output noise standard deviation as a fraction of the clean output's
        peak-to-peak range, in [0, 1) (seed 002 Table 3: 0-5 %).
    input_noise : float
        The same for the *recorded* input (seed 002 adds noise to both; a
        controller that logs its own command records it exactly: default 0).
    output : {"position", "acceleration"}
    bits, density, full_scale : sensor, see :func:`sensor`.
    seed : int, optional
        Random seed (noise and random binary input).
    period : float, optional
        Alternating step every ``period`` s (``input="step"`` only).

    Examples
    --------
    >>> d = synthetic(Mode.from_hz(28.0, 0.05), "step", n=400, noise=0.01, seed=1)
    >>> d.t.shape, round(d.fs)
    ((400,), 400)
    """
    ms = _modes(modes)
    fs = v.positive(fs, "fs")
    n = v.integer(n, "n", 4)
    if not 0.0 <= v.real(input_noise, "input_noise") < 1.0:
        raise ValueError(f"input_noise must be in [0, 1), got {input_noise:g}")
    rng = np.random.default_rng(seed)
    u = excitation(input, n, fs, seed=int(rng.integers(2**31)), delay=delay, period=period)
    y0 = simulate(ms, u, fs, output=output, gains=gains)
    y = sensor(y0, fs=fs, noise=noise, density=density, bits=bits, full_scale=full_scale, rng=rng)
    if input_noise > 0:
        u_rec = u + input_noise * float(np.ptp(u) or 1.0) * rng.standard_normal(n)
    else:
        u_rec = u
    return SyntheticData(np.arange(n) / fs, u_rec, y, y0, ms, fs)


def klipper_sweep(fs: float, *, f_min: float = 5.0, f_max: float = 133.0, hz_per_sec: float = 1.0,
                  accel_per_hz: float = 75.0) -> np.ndarray:
    """Commanded acceleration [mm/s^2] of Klipper's ``TEST_RESONANCES`` sweep.

    Klipper (resonance_tester.py) sweeps the frequency linearly at
    ``hz_per_sec`` and, in each half period, accelerates at
    ``+-accel_per_hz * f``: a square wave of rising frequency and amplitude.
    """
    fs = v.positive(fs, "fs")
    dur = (f_max - f_min) / hz_per_sec
    t = np.arange(int(dur * fs)) / fs
    f = f_min + hz_per_sec * t
    phase = 2.0 * math.pi * (f_min * t + 0.5 * hz_per_sec * t * t)
    return accel_per_hz * f * np.where(np.sin(phase) >= 0.0, 1.0, -1.0)


def klipper_log(path: str | Path, modes: Mode | Sequence[Mode], *, fs: float = 3200.0,
                gains: Sequence[float] | None = None, f_min: float = 5.0, f_max: float = 133.0,
                hz_per_sec: float = 1.0, accel_per_hz: float = 75.0, direction: Sequence[float] = (1.0, 0.0, 0.0),
                density: float = 0.0, seed: int | None = None, jitter: float = 0.0) -> Path:
    """Write a synthetic Klipper raw accelerometer log of a resonance test.

    The toolhead acceleration is the sweep of :func:`klipper_sweep` through
    ``1 + sum_k gains_k (F_k(s) - 1)`` (each mode a spring between motor and
    toolhead, unit DC gain), projected on ``direction`` (x, y, z), plus sensor
    noise of ``density`` mm/s^2/sqrt(Hz) on each axis, and gravity on z.
    Columns ``#time,accel_x,accel_y,accel_z`` in mm/s^2 as Klipper writes them.
    ``jitter`` (s) perturbs the time stamps, as real logs have.
    """
    ms = _modes(modes)
    fs = v.positive(fs, "fs")
    a_cmd = klipper_sweep(fs, f_min=f_min, f_max=f_max, hz_per_sec=hz_per_sec, accel_per_hz=accel_per_hz)
    g = np.full(len(ms), 1.0) if gains is None else v.real_array(gains, "gains")
    a = a_cmd * (1.0 - float(np.sum(g)))
    for m, gk in zip(ms, g):
        # toolhead acceleration through a spring: (2 zeta w s + w^2)/(s^2 + 2 zeta w s + w^2)
        num = [0.0, 2.0 * m.zeta * m.omega * gk, m.omega**2 * gk]
        den = [1.0, 2.0 * m.zeta * m.omega, m.omega**2]
        a = a + signal.lfilter(*_zoh(num, den, fs), a_cmd)
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)
    rng = np.random.default_rng(seed)
    acc = np.outer(a, d) + density * math.sqrt(fs / 2.0) * rng.standard_normal((a.size, 3))
    acc[:, 2] += G * 1000.0
    t = 1000.0 + np.arange(a.size) / fs
    if jitter > 0:
        t = t + jitter * rng.uniform(-0.5, 0.5, t.size)
    path = Path(path)
    data = np.column_stack([t, acc])
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("#time,accel_x,accel_y,accel_z\n")
        np.savetxt(fh, data, fmt=["%.6f", "%.3f", "%.3f", "%.3f"], delimiter=",")
    return path
