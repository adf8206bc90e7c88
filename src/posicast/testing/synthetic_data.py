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

import functools
import math
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np
from scipy import signal

from .. import _validate as v
from ..identification.data import Dataset
from ..identification.excitation import ResonanceTest, commanded_acceleration
from ..identification.spectral import welch_psd
from ..modes import Mode

__all__ = ["EXCITATIONS", "excitation", "simulate_modes", "sensor", "synthetic", "SyntheticData", "klipper_sweep", "klipper_log",
           "klipper_record", "klipper_dataset", "klipper_resonances"]

#: Kinds of :func:`excitation` (the identification inputs; not posicast.loops.EXCITATIONS, the loop signals).
EXCITATIONS = ("step", "impulse", "ramp", "harmonic", "random_binary", "chirp")
G = 9.80665


def _modes(modes: Any) -> list[Mode]:
    if isinstance(modes, Mode):
        return [modes]
    out = list(modes) if isinstance(modes, (list, tuple)) else None
    if not out or not all(isinstance(m, Mode) for m in out):
        raise TypeError("modes must be a posicast.Mode or a non-empty list of Mode")
    return out


#: Most samples a synthetic record may hold (about 400 MB per signal).
MAX_SAMPLES = 50_000_000


def _samples(n: Any, name: str = "n", minimum: int = 2) -> int:
    n = v.integer(n, name, minimum)
    if n > MAX_SAMPLES:
        raise ValueError(f"{name} = {n} samples would need about {8 * n * 6 / 2**30:.3g} GiB; at most "
                         f"{MAX_SAMPLES} are generated (lower {name} or sample_rate)")
    return n


def _rate(fs: Any, ms: Sequence[Mode] = ()) -> float:
    """A sample rate in [1e-6, 1e9] Hz, at least 1e-6 of the fastest mode's frequency (exact ZOH sampling)."""
    fs = v.positive(fs, "sample_rate")
    low = max([1e-6] + [m.omega / (2 * math.pi) * 1e-6 for m in ms])
    if not low <= fs <= 1e9:
        raise ValueError(f"sample_rate must be in [{low:.3g}, 1e9] Hz (at least a millionth of the fastest mode), got {fs:g}")
    return fs


def _seed(seed: Any) -> int | None:
    return None if seed is None else v.integer(seed, "seed", 0)


@v.renamed_keywords(fs="sample_rate")
def excitation(kind: str, n: int, sample_rate: float, *, seed: int | None = None, delay: int = 0,
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
    sample_rate : float
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
    fs = sample_rate  # the sample rate [Hz], fs in the formulas
    n = _samples(n)
    fs = _rate(fs)
    delay = v.integer(delay, "delay", 0)
    seed = _seed(seed)
    if not isinstance(kind, str) or kind not in EXCITATIONS:
        raise ValueError(f"kind must be one of {', '.join(EXCITATIONS)}; got {kind!r}")
    if period is not None:
        period = v.positive(period, "period")
        if period * fs > 1e15:
            raise ValueError(f"period must be at most 1e15 samples (1e15 / fs = {1e15 / fs:.3g} s), got {period:g}")
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
    raise ValueError(f"kind must be one of {', '.join(EXCITATIONS)}; got {kind!r}")


def _mode_tf(m: Mode, output: str, gain: float) -> tuple[np.ndarray, np.ndarray]:
    w, z = m.omega, m.zeta
    den = np.array([1.0, 2.0 * z * w, w * w])
    if output == "position":
        num = np.array([0.0, 0.0, gain * w * w])
    else:  # acceleration: s^2 F(s)
        num = gain * w * w * np.array([1.0, 0.0, 0.0])
    return num, den


def _zoh(num: Any, den: Any, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """ZOH-exact discrete (b, a) via the state space (scipy.signal.cont2discrete).

    Memoised in memory (never on disk) on the exact coefficients: a Monte Carlo
    study discretises the same mode at the same rate once per trial, and
    ``cont2discrete``'s matrix exponential of the badly scaled companion form
    costs milliseconds (issue #15: 1700 identical calls in the seed 002 trials of ``make reproduce``).
    """
    b, a = _zoh_cached(tuple(map(float, np.ravel(num))), tuple(map(float, np.ravel(den))), float(fs))
    return b.copy(), a.copy()


@functools.lru_cache(maxsize=256)
def _zoh_cached(num: tuple[float, ...], den: tuple[float, ...], fs: float) -> tuple[np.ndarray, np.ndarray]:
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


@v.renamed_keywords(fs="sample_rate")
def simulate_modes(modes: Mode | Sequence[Mode], u: Any, sample_rate: float, *, output: str = "position",
                   gains: Sequence[float] | None = None) -> np.ndarray:
    """Exact ZOH samples of ``sum_k gains_k F_k(s) u`` (seed 002 eq. 16), from rest.

    Examples
    --------
    >>> y = simulate_modes(Mode.from_hz(28.0, 0.05), np.ones(4000), 400.0)
    >>> round(float(y[-1]), 6)        # DC gain of eq. 16 is 1
    1.0
    """
    fs = sample_rate  # the sample rate [Hz], fs in the formulas
    ms = _modes(modes)
    u = v.real_array(u, "u")
    if u.ndim != 1:
        raise ValueError("u must be one-dimensional")
    _samples(u.size, "u's length", 1)
    fs = _rate(fs, ms)
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


@v.renamed_keywords(fs="sample_rate")
def sensor(y: Any, *, sample_rate: float, noise: float = 0.0, density: float = 0.0, bits: int | None = 12,
           full_scale: float | None = None, rng: np.random.Generator | None = None,
           scale_range: float | None = None) -> np.ndarray:
    """Add white noise (``noise`` x range std, plus ``density`` per sqrt(Hz)) and quantise.

    ``density`` is in output units per sqrt(Hz) (seed 002: 220e-6 g/sqrt(Hz)); its
    standard deviation at rate ``fs`` is ``density * sqrt(fs / 2)``.  ``full_scale``
    (default 1.25 max|y|) is the +- range of the ``bits``-bit converter.
    """
    fs = sample_rate  # the sample rate [Hz], fs in the formulas
    y = v.real_array(y, "y")
    fs = v.positive(fs, "sample_rate")
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
        if bits > 52:
            raise ValueError(f"bits must be in [2, 52] (a converter's resolution), got {bits}")
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
    sample_rate: float

    @property
    def fs(self) -> float:
        """The 0.1 name of :attr:`sample_rate` (with a FutureWarning)."""
        warnings.warn("SyntheticData.fs is now SyntheticData.sample_rate", FutureWarning, stacklevel=2)
        return self.sample_rate


@v.renamed_keywords(fs="sample_rate")
def synthetic(modes: Mode | Sequence[Mode], input: str = "step", *, sample_rate: float = 400.0, n: int = 800,
              noise: float = 0.0, input_noise: float = 0.0, output: str = "position", bits: int | None = 12,
              density: float = 0.0, full_scale: float | None = None, seed: int | None = None,
              delay: int = 0, gains: Sequence[float] | None = None, period: float | None = None) -> SyntheticData:
    """Seed 002's identification experiment: input, exact response, sensor.

    Parameters
    ----------
    modes : Mode or list of Mode
        True modes (seed 002: 28 Hz, zeta 0.05).
    input : str
        One of :data:`EXCITATIONS`.
    sample_rate, n : float, int
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
    >>> d.t.shape, round(d.sample_rate)
    ((400,), 400)
    """
    fs = sample_rate  # the sample rate [Hz], fs in the formulas
    ms = _modes(modes)
    fs = _rate(fs, ms)
    n = _samples(n, "n", 4)
    if not isinstance(input, str) or input not in EXCITATIONS:
        raise ValueError(f"input must be one of {', '.join(EXCITATIONS)}; got {input!r}")
    if not 0.0 <= v.real(input_noise, "input_noise") < 1.0:
        raise ValueError(f"input_noise must be in [0, 1), got {input_noise:g}")
    rng = np.random.default_rng(_seed(seed))
    u = excitation(input, n, fs, seed=int(rng.integers(2**31)), delay=delay, period=period)
    y0 = simulate_modes(ms, u, fs, output=output, gains=gains)
    y = sensor(y0, sample_rate=fs, noise=noise, density=density, bits=bits, full_scale=full_scale, rng=rng)
    if input_noise > 0:
        u_rec = u + input_noise * float(np.ptp(u) or 1.0) * rng.standard_normal(n)
    else:
        u_rec = u
    return SyntheticData(np.arange(n) / fs, u_rec, y, y0, ms, fs)


@v.renamed_keywords(fs="sample_rate")
def klipper_sweep(sample_rate: float, *, f_min: float = 5.0, f_max: float = 135.0, hz_per_sec: float = 1.0,
                  accel_per_hz: float = 60.0, method: str = "sweeping", sweeping_accel: float = 400.0,
                  sweeping_period: float = 1.2) -> np.ndarray:
    """Commanded acceleration [mm/s^2] of Klipper's ``TEST_RESONANCES`` (see :mod:`.excitation`)."""
    fs = sample_rate  # the sample rate [Hz], fs in the formulas
    test = ResonanceTest(method, f_min, f_max, hz_per_sec, accel_per_hz, sweeping_accel, sweeping_period)
    return commanded_acceleration(test, fs)[1]


@v.renamed_keywords(fs="sample_rate")
def klipper_record(modes: Mode | Sequence[Mode], *, sample_rate: float = 3200.0, gains: Sequence[float] | None = None,
                   test: ResonanceTest | None = None, direction: Sequence[float] = (1.0, 0.0, 0.0),
                   density: float = 20.0, seed: int | None = None, lead: float = 0.5, clip: float | None = None,
                   **test_options: Any) -> tuple[np.ndarray, np.ndarray]:
    """The accelerometer record of a Klipper resonance test: ``(t, accel[n, 3])`` in s and mm/s^2.

    The commanded acceleration of ``test`` (default :meth:`ResonanceTest.klipper`, or
    its fields as keywords: ``hz_per_sec=2``, ``method="pulse"`` for the older test, ...)
    drives the toolhead through ``1 + sum_k gains_k (F_k(s) - 1)``, each mode a spring
    between the motor and the toolhead, ``F_k = (2 zeta w s + w^2)/(s^2 + 2 zeta w s + w^2)``
    (unit DC gain: the toolhead follows the command at low frequency).  The result is
    projected on ``direction`` (x, y, z), white sensor noise of ``density``
    (mm/s^2)/sqrt(Hz) is added on each axis, then gravity on z, ADXL345 quantisation
    (3.9 mg per step) and its +-16 g range (or ``clip`` mm/s^2, to make clipped data).
    ``lead`` seconds of rest precede the test.  With empty ``modes`` (``[]``) and
    ``test="none"`` the record is sensor noise only.
    """
    fs = sample_rate  # the sample rate [Hz], fs in the formulas
    rng = np.random.default_rng(_seed(seed))
    if isinstance(test, str) and test == "none":
        fs = _rate(fs)
        a = np.zeros(_samples(int(round(60.0 * fs)), "60 s at fs"))
        ms: list[Mode] = []
    else:
        ms = _modes(modes)
        if test is None:
            method = test_options.pop("method", "sweeping")
            test = (ResonanceTest.klipper(**test_options) if method == "sweeping"
                    else ResonanceTest.legacy(**test_options))
        elif test_options:
            raise TypeError("give either test= or its fields as keywords, not both")
        if not isinstance(test, ResonanceTest):
            raise TypeError("test must be a posicast.identification.ResonanceTest")
        fs = _rate(fs, ms)
        _, a_cmd = commanded_acceleration(test, fs)
        lead = v.real(lead, "lead")
        if not 0.0 <= lead <= 60.0:
            raise ValueError(f"lead must be in [0, 60] s, got {lead:g}")
        a_cmd = np.concatenate((np.zeros(int(round(lead * fs))), a_cmd, np.zeros(int(0.2 * fs))))
        g = np.full(len(ms), 1.0) if gains is None else v.real_array(gains, "gains")
        if g.shape != (len(ms),):
            raise ValueError(f"gains must have one entry per mode ({len(ms)})")
        a = a_cmd * (1.0 - float(np.sum(g)))
        for m, gk in zip(ms, g):
            num = [0.0, 2.0 * m.zeta * m.omega * gk, m.omega**2 * gk]
            den = [1.0, 2.0 * m.zeta * m.omega, m.omega**2]
            a = a + signal.lfilter(*_zoh(num, den, fs), a_cmd)
    d = v.strict_real_array(direction, "direction")
    if d.shape != (3,) or not np.linalg.norm(d) > 0:
        raise ValueError(f"direction must be 3 numbers (x, y, z), not all 0, got {d.tolist()}")
    d = d / np.linalg.norm(d)
    acc = np.outer(a, d) + v.real(density, "density") * math.sqrt(fs / 2.0) * rng.standard_normal((a.size, 3))
    acc[:, 2] += G * 1000.0
    lsb = 0.0039 * G * 1000.0
    lim = 16 * G * 1000.0 if clip is None else v.positive(clip, "clip")
    acc = np.clip(np.round(acc / lsb) * lsb, -lim, lim)
    return np.arange(a.size) / fs, acc


@v.renamed_keywords(fs="sample_rate")
def klipper_log(path: str | Path, modes: Mode | Sequence[Mode], *, sample_rate: float = 3200.0,
                jitter: float = 0.0, seed: int | None = None, **options: Any) -> Path:
    """Write :func:`klipper_record` as a Klipper raw log (``#time,accel_x,accel_y,accel_z``).

    Time stamps start at 1000 s as Klipper's do; ``jitter`` (s) perturbs them, as real
    logs have.  ``options`` are :func:`klipper_record`'s.
    """
    fs = sample_rate  # the sample rate [Hz], fs in the formulas
    path = v.path_for_output(path, "path", (".csv", ".txt"))
    t, acc = klipper_record(modes, sample_rate=fs, seed=seed, **options)
    t = 1000.0 + t
    if v.real(jitter, "jitter") > 0:
        t = t + jitter * np.random.default_rng(None if seed is None else seed + 1).uniform(-0.5, 0.5, t.size)
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("#time,accel_x,accel_y,accel_z\n")
        np.savetxt(fh, np.column_stack([t, acc]), fmt=["%.6f", "%.3f", "%.3f", "%.3f"], delimiter=",")
    return path


def klipper_dataset(modes: Mode | Sequence[Mode], *, axis: str | None = "x", **options: Any) -> Dataset:
    """:func:`klipper_record` as an in-memory :class:`~posicast.identification.Dataset` (no file)."""
    t, acc = klipper_record(modes, **options)
    fs = float(options.get("sample_rate", options.get("fs", 3200.0)))
    return Dataset(f"synthetic_raw_data_{axis or 'unknown'}", "klipper_raw", t,
                   {"accel_x": acc[:, 0], "accel_y": acc[:, 1], "accel_z": acc[:, 2]}, fs, axis=axis,
                   klipper_output="raw_data")


@v.renamed_keywords(fs="sample_rate")
def klipper_resonances(path: str | Path, modes: Mode | Sequence[Mode], *, sample_rate: float = 3200.0,
                       max_freq_out: float | None = None, **options: Any) -> Path:
    """Write a ``resonances_<axis>_*.csv`` as Klipper's ``TEST_RESONANCES`` does, from :func:`klipper_record`.

    Klipper's Welch estimate (Kaiser window, beta 6, 0.5 s segments rounded up to a power
    of two, half overlap) of each axis and their sum, rows ``%.1f`` then ``%.3e``, up to
    ``max_freq_out`` (default 1.5 x the test's ``max_freq``).  ``modes=[]`` with
    ``test="none"`` writes the spectrum of sensor noise alone.
    """
    fs = sample_rate  # the sample rate [Hz], fs in the formulas
    path = v.path_for_output(path, "path", (".csv", ".txt"))
    t, acc = klipper_record(modes, sample_rate=fs, **options)
    test = options.get("test")
    top = options.get("max_freq", test.max_freq if isinstance(test, ResonanceTest) else 135.0)
    hi = 1.5 * float(top) if max_freq_out is None else v.positive(max_freq_out, "max_freq_out")
    cols = [welch_psd(acc[:, j] - acc[:, j].mean(), fs, 2.0) for j in range(3)]
    f = cols[0][0]
    P = np.column_stack([c[1] for c in cols])
    keep = f <= hi
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("freq,psd_x,psd_y,psd_z,psd_xyz\n")
        for fk, row in zip(f[keep], P[keep]):
            fh.write(f"{fk:.1f}," + ",".join(f"{x:.3e}" for x in row) + f",{row.sum():.3e}\n")
    return path
