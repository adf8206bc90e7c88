"""How a resonance test excites the machine: Klipper's ``TEST_RESONANCES`` and its PSD files.

A printer's resonance test does not excite all frequencies equally, and the
firmware writes its spectra at different stages of its own processing.  The
identification fits ``PSD(f) = E(f) |H(f)|^2 + noise``, so ``E`` must match how
the data were taken.  Klipper (klippy/extras/resonance_tester.py, read for the
description below, GPL code not used) commands, per axis:

* **vibrations**: a square-wave acceleration ``+-accel_per_hz f`` in quarter-period
  pieces ``1/(4 f)`` (pattern ``+ - - +``), the frequency rising linearly at
  ``hz_per_sec`` from ``min_freq`` (5 Hz) to ``max_freq`` (135 Hz);
* **sweeping** (on by default since Klipper v0.13, Dec 2024): a slow square wave of
  ``+-sweeping_accel`` (400 mm/s^2) with ``sweeping_period`` (1.2 s) added to it, so
  that the toolhead drifts back and forth while it vibrates.

Excitation PSD (one-sided Welch average over the record of a sweep over ``B`` Hz):
a sine of amplitude ``a(f) = (4/pi) accel_per_hz f`` (the square wave's fundamental)
swept at ``r`` Hz/s leaves ``a^2/(2 r)`` of energy per Hz, spread over the
``B / r`` s of the record:

    E_vib(f) = (8 / pi^2) accel_per_hz^2 f^2 / B          for min_freq < f < max_freq

(independent of the sweep rate; the square wave's third harmonic carries 0.4 %).
The sweep's square wave has lines at odd multiples of ``1/P`` of power
``8 S^2 / (pi^2 k^2)``: as a density ``E_sweep(f) = 4 S^2 / (pi^2 P f^2)``.  It
dominates below about 7 Hz and made posicast report a 6 Hz, zeta 0.6 "mode" before
it was modelled.

The **older method** (Klipper <= v0.12, and Kalico by default) moved the toolhead
out and back by ``accel_per_hz f t^2 / 2`` per quarter period with ``accel_per_hz``
75, up to 133.3 Hz, and no sweep.  Klipper's planner joins each "back" move with the
next "out" move (same direction), so the toolhead sees the same square wave at ``f``
(only the very first move is shorter); its excitation is the formula above.

Files Klipper writes (klippy/extras/shaper_calibrate.py):

* ``resonances_<axis>_*.csv`` (``TEST_RESONANCES``): the raw Welch PSD
  (Kaiser window, beta 6, 0.5 s segments, half overlap) of each axis and their sum,
  rows up to ``1.5 max_freq``;
* ``calibration_data_<axis>_*.csv`` (``SHAPER_CALIBRATE``): the same PSD divided by
  ``f + 0.1`` and, below 10 Hz, multiplied by ``exp(1 - (10 / (f + 0.1))^2)``,
  followed by one column per fitted shaper.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .. import _validate as v

__all__ = ["ResonanceTest", "commanded_acceleration", "excitation_psd", "klipper_normalisation",
           "estimate_sweep", "SweepEstimate"]

METHODS = ("sweeping", "pulse")


@dataclass(frozen=True)
class ResonanceTest:
    """A printer firmware's resonance test, as configured.

    Parameters
    ----------
    method : {"sweeping", "pulse"}
        ``"sweeping"``: Klipper >= v0.13 (vibrations plus a slow sweep; the sweep is
        off when ``sweeping_period`` is 0).  ``"pulse"``: Klipper <= v0.12 and Kalico
        (out-and-back moves; the same square wave, no sweep).
    min_freq, max_freq : float
        Nominal frequency range, Hz.
    hz_per_sec : float
        Sweep rate, Hz/s (Klipper: 0 < rate <= 2).
    accel_per_hz : float
        Acceleration amplitude per Hz, mm/s (Klipper 60, before v0.13 75).
    sweeping_accel, sweeping_period : float
        The slow sweep (mm/s^2, s); period 0 turns it off.

    Examples
    --------
    >>> t = ResonanceTest.klipper()
    >>> t.duration, t.excited_band
    (130.0, (5.0, 135.0))
    >>> round(ResonanceTest.legacy().excited_band[1], 2)
    133.33
    """

    method: str = "sweeping"
    min_freq: float = 5.0
    max_freq: float = 135.0
    hz_per_sec: float = 1.0
    accel_per_hz: float = 60.0
    sweeping_accel: float = 400.0
    sweeping_period: float = 1.2

    def __post_init__(self) -> None:
        v.choice(self.method, "method", METHODS)
        lo = v.positive(self.min_freq, "min_freq")
        hi = v.positive(self.max_freq, "max_freq")
        if not 1.0 <= lo < hi <= 1000.0:
            raise ValueError(f"need 1 <= min_freq < max_freq <= 1000 Hz (Klipper: min_freq >= 1), got {lo:g} and "
                             f"{hi:g}")
        v.real_in_range(self.hz_per_sec, "hz_per_sec", 1e-3, 100.0)
        v.positive(self.accel_per_hz, "accel_per_hz")
        v.nonnegative(self.sweeping_accel, "sweeping_accel")
        v.nonnegative(self.sweeping_period, "sweeping_period")

    @classmethod
    def klipper(cls, **kw: float) -> ResonanceTest:
        """Klipper >= v0.13 defaults (``[resonance_tester]``)."""
        return replace(cls(), **kw)

    @classmethod
    def legacy(cls, **kw: float) -> ResonanceTest:
        """Klipper <= v0.12 / Kalico defaults: out-and-back pulses, accel_per_hz 75, max 133.33 Hz, no sweep."""
        return replace(cls("pulse", 5.0, 10000.0 / 75.0, 1.0, 75.0, 0.0, 0.0), **kw)

    @property
    def duration(self) -> float:
        """Length of the test, s."""
        return (self.max_freq - self.min_freq) / self.hz_per_sec

    @property
    def excited_band(self) -> tuple[float, float]:
        """The band the vibrations sweep, Hz."""
        return (self.min_freq, self.max_freq)

    @property
    def sweeping(self) -> bool:
        return self.method == "sweeping" and self.sweeping_period > 0 and self.sweeping_accel > 0


def _segments(test: ResonanceTest) -> tuple[np.ndarray, np.ndarray]:
    """Switch times and the acceleration held after each, of the vibration part."""
    f, sign, t = test.min_freq, 1.0, 0.0
    n_est = int(2 * (test.max_freq ** 2 - test.min_freq ** 2) / (2 * test.hz_per_sec) + 8)
    if n_est > 5e7:
        raise ValueError(f"the test has about {n_est:.3g} segments; raise hz_per_sec or narrow min_freq..max_freq")
    times, accels = [], []
    while f <= test.max_freq:
        t_seg = 1.0 / (4.0 * f)
        a = test.accel_per_hz * f
        times += [t, t + t_seg]
        accels += [sign * a, -sign * a]
        t += 2 * t_seg
        f += 2.0 * t_seg * test.hz_per_sec
        sign = -sign
    times.append(t)
    accels.append(0.0)
    return np.asarray(times), np.asarray(accels)


@v.renamed_keywords(fs="sample_rate")
def commanded_acceleration(test: ResonanceTest, sample_rate: float) -> tuple[np.ndarray, np.ndarray]:
    """The commanded toolhead acceleration (mm/s^2) averaged over each sample period.

    Returns ``(t, a)`` sampled at ``fs`` Hz over the whole test.  The average over a
    sample period is exact for the piecewise-constant command (switches need not
    fall on samples).

    Examples
    --------
    >>> t, a = commanded_acceleration(ResonanceTest.klipper(max_freq=20.0), 3200.0)
    >>> round(float(t[-1]), 1), round(float(np.abs(a).max()))   # 15 s; 60 * 20 + 400 at most
    (15.0, 1600)
    """
    fs = sample_rate  # the sample rate [Hz], fs in the formulas
    fs = v.positive(fs, "sample_rate")
    sw, acc = _segments(test)
    n = int(math.floor(sw[-1] * fs)) + 1
    if n > 2e8:
        raise ValueError(f"{n:.3g} samples at fs = {fs:g} Hz; lower fs, raise hz_per_sec or narrow "
                         "min_freq..max_freq")
    # exact integral of the piecewise-constant acceleration, then averaged per sample
    if test.sweeping:
        P, S = test.sweeping_period, test.sweeping_accel
        first = P * math.sqrt(2.0) / 8.0
        sweep_sw = [0.0, first, first + P * (math.sqrt(2.0) / 8.0 + 0.25)]
        while sweep_sw[-1] < sw[-1]:
            sweep_sw.append(sweep_sw[-1] + P / 2.0)
        sweep_sw = np.asarray(sweep_sw)
        sweep_a = S * np.where(np.arange(sweep_sw.size) % 2 == 0, 1.0, -1.0)
        grid = np.union1d(sw, sweep_sw[sweep_sw < sw[-1]])
        a_grid = acc[np.searchsorted(sw, grid, side="right") - 1] + \
            sweep_a[np.searchsorted(sweep_sw, grid, side="right") - 1]
        a_grid[-1] = 0.0
        sw, acc = grid, a_grid
    vel = np.concatenate(([0.0], np.cumsum(acc[:-1] * np.diff(sw))))  # velocity at each switch

    def velocity(t: np.ndarray) -> np.ndarray:
        i = np.clip(np.searchsorted(sw, t, side="right") - 1, 0, sw.size - 1)
        return vel[i] + acc[i] * (t - sw[i])

    edges = np.arange(n + 1) / fs
    a = np.diff(velocity(edges)) * fs
    return edges[:-1], a


def excitation_psd(test: ResonanceTest, f: np.ndarray) -> np.ndarray:
    """Expected one-sided acceleration PSD of the command, (mm/s^2)^2/Hz, at ``f`` Hz.

    ``E_vib(f) = (8/pi^2) accel_per_hz^2 f^2 / B`` inside the excited band plus
    ``E_sweep(f) = 4 S^2 / (pi^2 P f^2)`` (module docstring).
    """
    v.instance_of(test, ResonanceTest, "test", "a ResonanceTest")
    f = v.strict_real_array(f, "f")
    if np.any(f < 0):
        raise ValueError("f must be frequencies >= 0 Hz")
    lo, hi = test.excited_band
    aph = test.accel_per_hz
    out = np.where((f >= lo) & (f <= hi), 8.0 / math.pi ** 2 * aph ** 2 * f ** 2 / (hi - lo), 0.0)
    if test.sweeping:
        with np.errstate(divide="ignore"):
            out = out + np.where(f > 0, 4.0 * test.sweeping_accel ** 2 / (math.pi ** 2 * test.sweeping_period)
                                 / np.maximum(f, 1e-300) ** 2, 0.0)
    return out


def klipper_normalisation(f: np.ndarray) -> np.ndarray:
    """The factor Klipper applies to a PSD before fitting shapers (``calibration_data`` files).

    ``1/(f + 0.1)``, times ``exp(1 - (10/(f + 0.1))^2)`` below 10 Hz
    (klippy/extras/shaper_calibrate.py, ``normalize_to_frequencies``).
    """
    f = v.strict_real_array(f, "f")
    if np.any(f < 0):
        raise ValueError("f must be frequencies >= 0 Hz")
    g = 1.0 / (f + 0.1)
    return np.where(f < 10.0, g * np.exp(1.0 - (10.0 / (f + 0.1)) ** 2), g)


@dataclass(frozen=True)
class SweepEstimate:
    """The frequency sweep read from a raw log: ``f(t) = f0 + rate (t - t0)`` while it runs.

    Attributes
    ----------
    start, end : float
        Swept band seen in the data, Hz.
    rate : float
        Hz/s.
    t_start, t_end : float
        When the sweep runs, s from the record's start.
    residual : float
        RMS deviation of the tracked frequency from the line, Hz.
    tracked : float
        Share of the frames whose spectral peak follows the line.
    """

    start: float
    end: float
    rate: float
    t_start: float
    t_end: float
    residual: float
    tracked: float


@v.renamed_keywords(fs="sample_rate")
def estimate_sweep(y: np.ndarray, sample_rate: float, *, window: float = 1.0) -> SweepEstimate | None:
    """Track a linear frequency sweep in a record (spectrogram ridge and a robust line).

    Returns None when no sweep is found (fewer than 60 % of the active frames on one
    line, or a rate that is not positive).
    """
    fs = sample_rate  # the sample rate [Hz], fs in the formulas
    y = v.strict_real_array(y, "y")
    if y.ndim != 1:
        raise ValueError(f"y must be one-dimensional, got shape {y.shape}")
    fs = v.positive(fs, "sample_rate")
    window = v.real_in_range(window, "window", 1e-3, 100.0)
    q = max(1, int(fs // 1000))  # the sweep is tracked below 500 Hz: a q-sample mean, then every q-th sample
    if q > 1:
        m = y.size // q
        y = y[: m * q].reshape(m, q).mean(axis=1)
        fs = fs / q
    nper = max(16, int(round(window * fs)))
    if y.size < 4 * nper:
        return None
    hop = nper // 2
    n_frames = (y.size - nper) // hop + 1
    idx = np.arange(nper)[None, :] + hop * np.arange(n_frames)[:, None]
    seg = y[idx]
    seg = seg - seg.mean(axis=1, keepdims=True)
    spec = np.abs(np.fft.rfft(seg * np.hanning(nper), axis=1)) ** 2
    f = np.fft.rfftfreq(nper, 1.0 / fs)
    band = (f >= 2.0) & (f <= 0.45 * fs)
    spec = spec[:, band]
    fb = f[band]
    peak = fb[np.argmax(spec, axis=1)]
    power = spec.max(axis=1)
    tc = (np.arange(n_frames) * hop + nper / 2) / fs
    active = power > 1e-3 * np.median(power[power > 0]) if np.any(power > 0) else np.zeros(n_frames, bool)
    if active.sum() < 8:
        return None
    t_a, f_a = tc[active], peak[active]
    # robust line: Theil-Sen on a subsample, then refine on the inliers
    rng = np.random.default_rng(0)
    m = t_a.size
    i = rng.integers(0, m, 4000)
    j = rng.integers(0, m, 4000)
    ok = np.abs(t_a[i] - t_a[j]) > 1e-9
    if not ok.any():
        return None
    slope = float(np.median((f_a[i][ok] - f_a[j][ok]) / (t_a[i][ok] - t_a[j][ok])))
    icpt = float(np.median(f_a - slope * t_a))
    tol = max(3.0 * fs / nper, 2.0)
    inl = np.abs(f_a - (icpt + slope * t_a)) < tol
    if inl.sum() < 0.6 * m or slope <= 0:
        return None
    slope, icpt = np.polyfit(t_a[inl], f_a[inl], 1)
    res = f_a[inl] - (icpt + slope * t_a[inl])
    if slope <= 0:
        return None
    t0, t1 = float(t_a[inl].min()), float(t_a[inl].max())
    half = window / 2.0
    t0, t1 = t0 - half, t1 + half
    return SweepEstimate(float(icpt + slope * t0), float(icpt + slope * t1), float(slope), max(t0, 0.0), t1,
                         float(np.sqrt(np.mean(res ** 2))), float(inl.mean()))
