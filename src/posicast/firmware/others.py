"""RepRapFirmware (M593), Marlin FT_MOTION (M493) and Prusa-Firmware-Buddy (M593, M74).

Each firmware designs its shapers itself; these descriptions follow their sources
(read, not copied; repositories and commits in ``docs/firmware.md``) so that a
recommendation is scored on the impulses the machine will run.
``t_d = 1/(F sqrt(1 - zeta^2))``, ``K = e^{-zeta pi / sqrt(1 - zeta^2)}``.

* **RepRapFirmware 3.4-3.6** (src/Movement/AxisShaper.cpp): one shaper for all axes,
  ``M593 P"<type>" F<Hz> S<zeta>``; types ``zvd``, ``zvdd``, ``zvddd`` (binomial),
  ``mzv`` (note: RRF runs Klipper's MZV amplitudes in **reverse order**, which cancels
  the mode only at zero damping: 16 % residual at its own design point for
  zeta = 0.1), ``ei2``, ``ei3`` (Singhose's cubic fits as Klipper master has them, but
  times in damped periods and the last amplitude one minus the others), and
  ``custom`` with at most 5 impulses (4 ``H`` values).  F in [5.72, 1000] Hz (Duet 3),
  S in [0, 0.99].  Custom syntax: 3.6 writes the amplitudes of all impulses but the
  last and the delays from the first (s); 3.4/3.5 cumulative amplitudes and segment
  durations.
* **Marlin FT_MOTION** (Marlin/src/module/ft_motion/shaping.cpp, M493.cpp): per axis
  ``M493 S1 X C<type> A<Hz> I<zeta> [Q<vtol>]``; types 1 ZV, 2 ZVD, 3 ZVDD, 4 ZVDDD,
  5 EI, 6 2HEI, 7 3HEI, 8 MZV; A in [20, 500] Hz, I in [0, 0.25]; delays rounded to the
  1 kHz trajectory samples; its MZV uses ``K`` where Klipper uses ``K^{3/4}``.  Dynamic
  frequency ``D1`` (``f = A + F z``, z in mm) and ``D2`` (``f = A + F e``, e the
  extruder position in mm).
* **Prusa-Firmware-Buddy** (lib/Marlin/.../input_shaper): per axis
  ``M593 X T<type> F<Hz> D<zeta> R<1/vtol>``; types 0 ZV, 1 ZVD, 2 MZV (Klipper's),
  3 EI, 4 2-hump EI, 5 3-hump EI (closed forms with ``K``); F clamped to [10, 100] Hz
  (MINI 150), D < 1.  Weight adjustment of Y (``M593 Y A<delta < 0> M<grams>``,
  ``M74 W<grams>``): ``f = f0 + delta min(m / M, 1)``.
"""

from __future__ import annotations

import math

import numpy as np

from .. import _validate as v
from ..modes import Mode
from .base import Firmware, Setting, ShaperType
from .klipper import _EI2_A, _EI2_T, _EI3_A, _EI3_T, _ei2_legacy, _ei3_legacy, _ei_legacy, _mzv, _zv, _zvd

__all__ = ["RepRapFirmware", "MarlinFT", "Prusa"]


def _K(z: float) -> float:
    return math.exp(-z * math.pi / math.sqrt(1.0 - z * z))


def _binomial(k: int):  # noqa: ANN202
    def design(F: float, z: float) -> tuple[np.ndarray, np.ndarray]:
        n = k + 1
        K = _K(z)
        td = 1.0 / (F * math.sqrt(1.0 - z * z))
        j = np.arange(n + 1)
        return np.array([math.comb(n, i) for i in j]) * K ** j, j * td / 2.0
    return design


def _mzv_reversed(F: float, z: float) -> tuple[np.ndarray, np.ndarray]:
    A, T = _mzv(F, z)
    return A[::-1].copy(), T


def _mzv_marlin(F: float, z: float) -> tuple[np.ndarray, np.ndarray]:
    K = _K(z)
    td = 1.0 / (F * math.sqrt(1.0 - z * z))
    B = math.sqrt(2.0) * K
    return np.array([1.0, B, K * K]), np.array([0.0, 0.375 * td, 0.75 * td])


def _ei_rrf(tt: list[list[float]], aa: list[list[float]]):  # noqa: ANN202
    """RepRapFirmware's 2-/3-hump EI (AxisShaper.cpp): Singhose's cubic fits in zeta, but times in units
    of the damped period ``1/(F sqrt(1 - zeta^2))`` (Klipper: ``1/F``) and the last amplitude ``1 -`` the
    others (Klipper: its own fit)."""
    def design(F: float, z: float) -> tuple[np.ndarray, np.ndarray]:
        zp = z ** np.arange(4)
        A = np.asarray(aa) @ zp
        A[-1] = 1.0 - float(np.sum(A[:-1]))
        return A, (np.asarray(tt) @ zp) / (F * math.sqrt(1.0 - z * z))
    return design


def _zv_pair(F: float, z: float, ratio: float) -> tuple[np.ndarray, np.ndarray]:
    """ZV at ``F`` convolved with ZV at ``ratio F`` (one shaper for two modes, 4 impulses)."""
    a1, t1 = _zv(F, z)
    a2, t2 = _zv(ratio * F, z)
    return np.outer(a1, a2).ravel(), np.add.outer(t1, t2).ravel()


def _f(x: float) -> str:
    return f"{x:.4f}".rstrip("0").rstrip(".")


class RepRapFirmware(Firmware):
    """RepRapFirmware's ``M593`` (one shaper for every axis).

    Parameters
    ----------
    version : {"3.6", "3.5", "3.4"}
        Decides how a custom shaper is written.

    Examples
    --------
    >>> rrf = RepRapFirmware()
    >>> rrf.setting("zvd", 40.0, 0.1).config()[-1]
    'M593 P"zvd" F40.0 S0.100'
    """

    name = "reprapfirmware"
    max_custom_impulses = 5

    def __init__(self, version: str = "3.6") -> None:
        self.version = v.choice(version, "version", ("3.6", "3.5", "3.4"))

    def _builtin(self) -> dict[str, ShaperType]:
        return {
            "zvd": ShaperType("zvd", _binomial(1), 5.72, 1000.0, 0.99),
            "zvdd": ShaperType("zvdd", _binomial(2), 5.72, 1000.0, 0.99),
            "zvddd": ShaperType("zvddd", _binomial(3), 5.72, 1000.0, 0.99),
            "mzv": ShaperType("mzv", _mzv_reversed, 5.72, 1000.0, 0.99),
            "ei2": ShaperType("ei2", _ei_rrf(_EI2_T, _EI2_A), 5.72, 1000.0, 0.3),
            "ei3": ShaperType("ei3", _ei_rrf(_EI3_T, _EI3_A), 5.72, 1000.0, 0.2),
        }

    def types(self) -> dict[str, ShaperType]:
        return self._builtin() | {
            # custom shapers (at most 5 impulses): the correct-order MZV, and ZV, which RRF lacks
            "custom mzv": ShaperType("custom", _mzv, 5.72, 1000.0, 0.99, label="custom mzv"),
            "custom zv": ShaperType("custom", _zv, 5.72, 1000.0, 0.99, label="custom zv"),
        }

    def extra_types(self, modes: list[Mode]) -> list[ShaperType]:
        """ZV x ZV for the two main modes (4 impulses), scanned with their frequency ratio fixed."""
        if len(modes) < 2:
            return []
        f1, f2 = sorted(m.freq_hz for m in modes[:2])
        ratio = f2 / f1
        if ratio < 1.1:
            return []
        return [ShaperType("custom", _zv_pair, 5.72, 1000.0 / ratio, 0.99, params={"ratio": ratio},
                           label=f"custom zv x zv (x{ratio:.3f})")]

    def config(self, setting: Setting, axis: str) -> list[str]:
        if setting.shaper_type.name == "custom":
            A, T = setting.impulses
            return self.custom(A, T) + [f"; = {setting.shaper_type.written} at {setting.freq:.1f} Hz, "
                                        f"damping {setting.damping:.3f}"]
        return ["; RepRapFirmware (config.g): one shaper for all axes",
                f'M593 P"{setting.shaper_type.name}" F{setting.freq:.1f} S{setting.damping:.3f}']

    def custom(self, A: np.ndarray, T: np.ndarray) -> list[str]:
        """``M593 P"custom"`` for impulses ``(A, T)`` (at most 5), in this version's syntax."""
        A = v.strict_real_array(A, "A")
        T = v.strict_real_array(T, "T")
        if A.ndim != 1 or A.shape != T.shape:
            raise ValueError(f"A and T must be 1-D of the same length, got shapes {A.shape} and {T.shape}")
        if np.any(np.diff(T) <= 0):
            raise ValueError("T must be increasing impulse times (s)")
        if A.size > self.max_custom_impulses:
            raise ValueError(f"RepRapFirmware accepts at most {self.max_custom_impulses} impulses in a custom "
                             f"shaper (4 H values); this one has {A.size}")
        if A.size < 2:
            raise ValueError("a custom shaper needs at least 2 impulses")
        if np.any(A < 0) or not A.sum() > 0:
            raise ValueError("RepRapFirmware's custom shaper needs non-negative amplitudes with a positive sum")
        A = A / A.sum()
        T = T - T[0]
        if self.version == "3.6":
            H = A[:-1]
            D = T[1:]
        else:
            H = np.cumsum(A)[:-1]
            D = np.diff(T)
        return [f"; RepRapFirmware {self.version} (config.g), custom shaper",
                'M593 P"custom" H' + ":".join(_f(h) for h in H) + " T" + ":".join(f"{d:.5f}" for d in D)]


class MarlinFT(Firmware):
    """Marlin's fixed-time motion (``FT_MOTION``, ``M493``), per axis.

    Examples
    --------
    >>> m = MarlinFT()
    >>> m.setting("zvd", 37.0, 0.1).config("x")[-1]
    'M493 S1 X C2 A37.0 I0.100'
    """

    name = "marlin"
    sample_rate = 1000.0  # FTM_FS: delays are whole trajectory samples
    codes = {"zv": 1, "zvd": 2, "zvdd": 3, "zvddd": 4, "ei": 5, "2hei": 6, "3hei": 7, "mzv": 8}

    def types(self) -> dict[str, ShaperType]:
        lo, hi, zmax = 20.0, 500.0, 0.25
        return {
            "zv": ShaperType("zv", _zv, lo, hi, zmax),
            "zvd": ShaperType("zvd", _zvd, lo, hi, zmax),
            "zvdd": ShaperType("zvdd", _binomial(2), lo, hi, zmax),
            "zvddd": ShaperType("zvddd", _binomial(3), lo, hi, zmax),
            "ei": ShaperType("ei", _ei_legacy, lo, hi, zmax),
            "2hei": ShaperType("2hei", _ei2_legacy, lo, hi, zmax),
            "3hei": ShaperType("3hei", _ei3_legacy, lo, hi, zmax),
            "mzv": ShaperType("mzv", _mzv_marlin, lo, hi, zmax),
        }

    def times(self, T: np.ndarray) -> np.ndarray:
        # Marlin rounds the first delay to samples and spaces the others by whole multiples of it
        T = np.asarray(T, dtype=float)
        if T.shape[-1] < 2:
            return T
        first = T[..., 1:2]
        n1 = np.round(first * self.sample_rate)
        ratio = np.round(T / first * 8.0) / 8.0  # multiples of the first delay (MZV: 1 and 2; others 1..4)
        return ratio * n1 / self.sample_rate

    def config(self, setting: Setting, axis: str) -> list[str]:
        code = self.codes[setting.shaper_type.name]
        line = f"M493 S1 {axis.upper()} C{code} A{setting.freq:.1f} I{setting.damping:.3f}"
        return ["; Marlin FT_MOTION (M493)", line]


class Prusa(Firmware):
    """Prusa-Firmware-Buddy's input shaper (``M593``), per axis.

    Parameters
    ----------
    printer : {"mk4", "mini", "xl", "coreone"}
        Decides the frequency range (MINI accepts up to 150 Hz, the others 100 Hz).

    Examples
    --------
    >>> Prusa().setting("mzv", 50.7, 0.1).config("x")[-1]
    'M593 X T2 F50.7 D0.100 R20'
    """

    name = "prusa"
    codes = {"zv": 0, "zvd": 1, "mzv": 2, "ei": 3, "ei_2hump": 4, "ei_3hump": 5}

    def __init__(self, printer: str = "mk4") -> None:
        self.printer = v.choice(printer, "printer", ("mk4", "mini", "xl", "coreone"))

    def types(self) -> dict[str, ShaperType]:
        hi = 150.0 if self.printer == "mini" else 100.0
        return {
            "zv": ShaperType("zv", _zv, 10.0, hi, 0.99),
            "zvd": ShaperType("zvd", _zvd, 10.0, hi, 0.99),
            "mzv": ShaperType("mzv", _mzv, 10.0, hi, 0.99),
            "ei": ShaperType("ei", _ei_legacy, 10.0, hi, 0.99),
            "ei_2hump": ShaperType("ei_2hump", _ei2_legacy, 10.0, hi, 0.99),
            "ei_3hump": ShaperType("ei_3hump", _ei3_legacy, 10.0, hi, 0.99),
        }

    def config(self, setting: Setting, axis: str) -> list[str]:
        code = self.codes[setting.shaper_type.name]
        return ["; Prusa (M593; add W to store it)",
                f"M593 {axis.upper()} T{code} F{setting.freq:.1f} D{setting.damping:.3f} R20"]

    def weight_adjustment(self, delta: float, mass_limit: float) -> list[str]:
        """``M593 Y A<delta> M<grams>``: ``f = f0 + delta min(m / M, 1)`` with ``M74 W<m>``."""
        if not delta < 0:
            raise ValueError(f"Prusa's weight-adjust delta must be < 0 Hz, got {delta:g}")
        mass_limit = v.positive(mass_limit, "mass_limit")
        return [f"M593 Y A{delta:.2f} M{mass_limit:.0f}"]

