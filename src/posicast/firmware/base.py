"""What a printer firmware can run: its shaper types, how it measures smoothing, its config lines.

A firmware designs its shapers itself from a type name, a frequency and a damping
ratio (its own formulas, which are not always posicast's exact designs), so a
recommendation must be scored on the impulses the firmware will actually run.
Each module of :mod:`posicast.firmware` describes one firmware with a
:class:`Firmware` object; :class:`Setting` is one line it accepts.

Residual vibration here is the classic percentage vibration (seed 004 eq. 1-3):
for a mode ``(omega, zeta)`` and impulses ``(A_i, T_i)``,
``V = |sum_i A_i e^{-zeta omega (T_n - T_i)} e^{j omega sqrt(1 - zeta^2) T_i}| / sum_i A_i``,
evaluated for whole grids of shaper frequencies at once (a firmware shaper of fixed
damping scales as ``T = T(1 Hz) / F``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from .. import _validate as v
from ..modes import Mode
from ..shapers import Shaper

__all__ = ["ShaperType", "Setting", "Firmware", "vibration_grid", "smoothing_offsets"]

Impulses = tuple[np.ndarray, np.ndarray]


@dataclass(frozen=True)
class ShaperType:
    """One shaper type of a firmware.

    Attributes
    ----------
    name : str
        As written in the firmware's configuration (``"mzv"``, ``"2hump_ei"``, ``"zvd"``, ...).
    design : callable
        ``design(freq_hz, damping, **params) -> (A, T)``: amplitudes (sum 1) and times (s)
        as the firmware computes them.
    min_freq, max_freq : float
        Frequencies the firmware accepts (Hz).
    max_damping : float
        Largest damping ratio the design is valid for.
    params : dict
        Fixed extra parameters passed to ``design`` (for example ``{"n": 4, "t": 0.9}``).
    label : str
        How the setting is written when it differs from ``name`` (``"mzv(n=4,t=0.9)"``).
    tool_min_freq : float
        The lowest frequency the firmware's own calibration tool tries (0: ``min_freq``).
    """

    name: str
    design: Callable[..., Impulses]
    min_freq: float = 1.0
    max_freq: float = math.inf
    max_damping: float = 0.99
    params: dict[str, Any] = field(default_factory=dict)
    label: str = ""
    tool_min_freq: float = 0.0

    @property
    def written(self) -> str:
        return self.label or self.name

    def impulses(self, freq: float, damping: float) -> Impulses:
        """Amplitudes (sum 1) and exact times (s) at ``freq`` Hz; see :attr:`Setting.impulses` for what runs."""
        A, T = self.design(freq, damping, **self.params)
        A = np.asarray(A, dtype=float)
        return A / A.sum(), np.asarray(T, dtype=float)


@dataclass(frozen=True)
class Setting:
    """A firmware line: shaper type, frequency (Hz) and damping ratio."""

    firmware: "Firmware"
    shaper_type: ShaperType
    freq: float
    damping: float

    def __post_init__(self) -> None:
        v.instance_of(self.firmware, Firmware, "firmware", "a posicast.firmware.Firmware")
        v.instance_of(self.shaper_type, ShaperType, "shaper_type", "a ShaperType")
        st = self.shaper_type
        f = v.real(self.freq, "freq")
        if not st.min_freq <= f <= st.max_freq:
            raise ValueError(f"{self.firmware.name} {st.written}: freq must be in [{st.min_freq:g}, {st.max_freq:g}] Hz, "
                             f"got {f:g}")
        z = v.real(self.damping, "damping")
        if not 0.0 <= z < st.max_damping:
            raise ValueError(f"{self.firmware.name} {st.written}: damping must be in [0, {st.max_damping:g}), got {z:g}")
        object.__setattr__(self, "freq", f)
        object.__setattr__(self, "damping", z)

    @property
    def impulses(self) -> Impulses:
        """What the firmware runs: its amplitudes and its (quantised) times."""
        A, T = self.shaper_type.impulses(self.freq, self.damping)
        return A, self.firmware.times(T)

    def shaper(self) -> Shaper:
        """The impulses as a :class:`posicast.Shaper` (for analysis, loops, export)."""
        A, T = self.impulses
        return Shaper(T, A, name=f"{self.firmware.name}:{self.shaper_type.written}",
                      params={"freq_hz": self.freq, "damping": self.damping})

    @property
    def smoothing(self) -> float:
        return self.firmware.smoothing(*self.impulses)

    @property
    def max_accel(self) -> float:
        return self.firmware.max_accel(*self.impulses)

    def config(self, axis: str = "x") -> list[str]:
        return self.firmware.config(self, v.choice(axis, "axis", ("x", "y", "z")))

    def describe(self) -> str:
        return f"{self.shaper_type.written} @ {self.freq:.1f} Hz, damping {self.damping:.3g}"


class Firmware:
    """Base of the firmware descriptions (see :mod:`posicast.firmware`)."""

    name = "firmware"
    #: acceleration and square corner velocity at which smoothing is quoted (Klipper's convention)
    smoothing_accel = 5000.0
    scv = 5.0
    #: the smoothing at which ``max_accel`` is quoted (Klipper's calibration tool: 0.12 mm)
    target_smoothing = 0.12

    def types(self) -> dict[str, ShaperType]:
        raise NotImplementedError

    def extra_types(self, modes: list[Mode]) -> list[ShaperType]:
        """Types that depend on the machine's modes (a custom shaper for two modes); none by default."""
        return []

    def times(self, T: np.ndarray) -> np.ndarray:
        """Impulse times as the firmware runs them (its time quantisation); exact by default."""
        return T

    def config(self, setting: Setting, axis: str) -> list[str]:
        raise NotImplementedError

    def setting(self, name: str, freq: float, damping: float) -> Setting:
        """The line for shaper type ``name`` at ``freq`` Hz with design ``damping`` (validated against the type)."""
        types = self.types()
        name = v.choice(name, "name", tuple(types))
        return Setting(self, types[name], freq, damping)

    # Klipper's smoothing model (shaper_calibrate.py: the toolhead's offset from the commanded
    # path after a 90 or 180 degree turn at ``accel`` and square corner velocity ``scv``).  It is
    # the only published measure; the other firmwares use it too, for comparison.
    def smoothing(self, A: np.ndarray, T: np.ndarray, accel: float | None = None) -> float | np.ndarray:
        """Klipper's smoothing (mm) of impulses ``(A, T)``; rows of a 2-D ``T`` give an array."""
        return self._smoothing(smoothing_offsets(A, T), accel)

    def max_accel(self, A: np.ndarray, T: np.ndarray) -> float | np.ndarray:
        """Largest acceleration whose smoothing stays at :attr:`target_smoothing` (exact: it is linear in accel)."""
        return self._max_accel(smoothing_offsets(A, T))

    def smoothing_and_max_accel(self, A: np.ndarray, T: np.ndarray) -> tuple[float | np.ndarray, float | np.ndarray]:
        """:meth:`smoothing` and :meth:`max_accel` of the same impulses, their offsets computed once (issue #15:
        every scored frequency grid asks for both)."""
        offsets = smoothing_offsets(A, T)
        return self._smoothing(offsets), self._max_accel(offsets)

    def _smoothing(self, offsets: tuple[Any, Any, Any], accel: float | None = None) -> float | np.ndarray:
        c1, c2, c3 = offsets
        a = self.smoothing_accel if accel is None else accel
        out = np.maximum(math.sqrt(2.0) * (self.scv * np.asarray(c1) + 0.5 * a * np.asarray(c2)), 0.5 * a * np.asarray(c3))
        return float(out) if np.ndim(out) == 0 else out

    def _max_accel(self, offsets: tuple[Any, Any, Any]) -> float | np.ndarray:
        c1, c2, c3 = (np.asarray(c, dtype=float) for c in offsets)
        tgt = self.target_smoothing
        rest = np.maximum(tgt / math.sqrt(2.0) - self.scv * c1, 0.0)
        with np.errstate(divide="ignore"):
            a90 = np.where(c2 > 0, rest / (0.5 * np.where(c2 > 0, c2, 1.0)), np.inf)
            a180 = np.where(c3 > 0, tgt / (0.5 * np.where(c3 > 0, c3, 1.0)), np.inf)
        out = np.minimum(a90, a180)
        return float(out) if out.ndim == 0 else out


def smoothing_offsets(A: np.ndarray, T: np.ndarray) -> tuple[float | np.ndarray, float | np.ndarray, float | np.ndarray]:
    """``(sum_{T >= ts} A (T - ts), sum_{T >= ts} A (T - ts)^2, sum A (T - ts)^2)`` over ``sum A``.

    ``ts`` is the shaper's centre ``sum A T / sum A``; Klipper's 90-degree offset is
    ``sqrt(2) (scv c1 + accel c2 / 2)`` and its 180-degree offset ``accel c3 / 2``.
    Rows of a 2-D ``T`` are separate shapers (then arrays are returned).
    """
    A, T = _impulse_arrays(A, T)
    ts = np.sum(A * T, axis=-1, keepdims=True)
    d = T - ts
    after = np.where(T >= ts, A, 0.0)
    out = (np.sum(after * d, axis=-1), np.sum(after * d * d, axis=-1), np.sum(A * d * d, axis=-1))
    return tuple(float(x) for x in out) if T.ndim == 1 else out  # type: ignore[return-value]


def vibration_grid(A: np.ndarray, T: np.ndarray, bins: np.ndarray, zetas: np.ndarray) -> np.ndarray:
    """Residual vibration of modes at ``bins`` Hz (damping ``zetas``) through each of several shapers.

    ``A`` (amplitudes) and ``T`` (times, s) have one row per shaper (``[n_shapers,
    n_impulses]``; a 1-D ``A`` is shared).  Returns ``V[n_shapers, len(bins), len(zetas)]``.
    Computed as ``|sum_i A_i e^{s (T_i - T_n)}|`` with ``s = zeta omega + j omega_d``
    (seed 004 eq. 1-3: ``|e^{-s T_n}| = e^{-zeta omega T_n}``), one complex exponential
    per term; the exponents are never positive, so no damping or duration overflows.
    Single precision while every phase stays under 1e4 rad (all printer shapers: 2 pi x
    300 Hz x 0.2 s = 377 rad), double beyond.
    """
    A, T = _impulse_arrays(A, T)
    T = np.atleast_2d(T)
    A = np.broadcast_to(A, T.shape)
    bins = v.strict_real_array(bins, "bins")
    zetas = v.strict_real_array(zetas, "zetas")
    if bins.ndim != 1 or zetas.ndim != 1:
        raise ValueError("bins and zetas must be one-dimensional arrays")
    if np.any(bins <= 0) or np.any(bins > 1e6):
        raise ValueError("bins must be frequencies in (0, 1e6] Hz")
    if np.any((zetas < 0) | (zetas >= 1)):
        raise ValueError("zetas must be damping ratios in [0, 1)")
    v.refuse_large(16.0 * T.size * bins.size * zetas.size, 2e9, "vibration_grid's exponentials",
                   "pass fewer shapers, bins or damping ratios", "bytes")
    return _vibration_grid(A, T, bins, zetas)


def unchecked_vibration_grid(A: np.ndarray, T: np.ndarray, bins: np.ndarray, zetas: np.ndarray) -> np.ndarray:
    """:func:`vibration_grid` without its argument checks, for callers whose shapers and bins are already
    valid (a firmware's own designs on a measured spectrum's bins): the same numbers, bit for bit."""
    A = np.asarray(A, dtype=float)
    T = np.atleast_2d(np.asarray(T, dtype=float))
    A = np.broadcast_to(A / A.sum(axis=-1, keepdims=True), T.shape)
    return _vibration_grid(A, T, np.asarray(bins, dtype=float), np.asarray(zetas, dtype=float))


def _vibration_grid(A: np.ndarray, T: np.ndarray, bins: np.ndarray, zetas: np.ndarray) -> np.ndarray:
    """:func:`vibration_grid` of checked arrays: ``A`` and ``T`` ``[n_shapers, n_impulses]`` (``A`` summing to
    1 per row), ``bins`` and ``zetas`` 1-D and valid."""
    w = 2.0 * math.pi * bins[:, None]
    z = zetas[None, :]
    sigma = (z * w).ravel()  # [bins * zetas]
    s = sigma + 1j * (w * np.sqrt(1.0 - z * z)).ravel()
    Tn = np.max(T, axis=1, keepdims=True)
    # single precision while the phases stay under 1e4 rad (error < 1e-3 rad), double beyond; real exp,
    # cos and sin (vectorised in numpy for float32, unlike the complex exp)
    real = np.float32 if float(np.max(np.abs(s))) * float(np.max(Tn - T, initial=0.0)) < 1e4 else np.float64
    D = (T - Tn).astype(real)  # [shapers, impulses], <= 0
    Ar = A.astype(real)
    # the exponentials laid out [shapers, impulses, bins * zetas] (the long axis last: numpy's vector loops,
    # issue #15).  The latest impulse (D = 0 when every shaper ends with it) contributes e^0 cos 0 = 1 and
    # e^0 sin 0 = 0 exactly: its exponentials are not computed.  Same terms, same sums: the same numbers as
    # one exponential per term.
    n = D.shape[1]
    m = n - 1 if n > 1 and not np.any(D[:, -1]) else n
    Dm = D[:, :m, None]
    decay = Dm * sigma.astype(real)[None, None, :]
    np.exp(decay, out=decay)
    phase = Dm * s.imag.astype(real)[None, None, :]
    if real is np.float32 and n < 16:
        # einsum's order: one running sum when the amplitudes are laid out by impulse (a 1-D A broadcast
        # over the shapers), its 4-lane vector loop when they are contiguous per shaper
        width = 1 if Ar.flags.f_contiguous and not Ar.flags.c_contiguous else 4
        terms = [_lane_sums(np.cos(phase), decay, Ar, m, width),
                 _lane_sums(np.sin(phase, out=phase), decay, Ar, m, width, last=0.0)]
    else:
        terms = _einsum_sums(phase, decay, Ar, m)
    S = np.hypot(*terms)  # [shapers, bins*zetas]
    return S.astype(float).reshape(T.shape[0], np.size(bins), np.size(zetas))


def _lane_sums(x: np.ndarray, decay: np.ndarray, Ar: np.ndarray, m: int, width: int, last: float = 1.0
               ) -> np.ndarray:
    """``sum_i Ar[:, i] decay[:, i] x[:, i]`` over the impulses (``x``, ``decay``: ``[shapers, m, bins * zetas]``,
    overwritten; the impulses from ``m`` on contribute ``Ar * last``), for fewer than 16 impulses.

    Summed in the order numpy's ``einsum`` sums them in :func:`_einsum_sums` on numpy 2.4 for x86-64 (impulse
    ``i`` into partial sum ``i mod width``, then ``(p0 + p1) + (p2 + p3)``; ``width`` 1 or 4, which the
    amplitudes' memory layout decides there), but on the long axis with no transposed copies: the numbers
    of wave 5, bit for bit, at about half the cost (issue #15, wave 6: a float32 rounding-level change of
    these sums flips a per-type pick of the demo's synthetic log).  The order is now this function's own,
    whatever einsum does on another numpy or CPU.
    """
    x *= decay
    x *= Ar[:, :m, None]  # the terms
    lanes: list[np.ndarray] = []
    for i in range(Ar.shape[1]):
        term = x[:, i] if i < m else Ar[:, i, None] * np.asarray(last, x.dtype)
        if i < width:
            lanes.append(term)
        else:
            lanes[i % width] += term  # a view into x: summed in place
    lanes += [np.zeros(1, x.dtype)] * (4 - len(lanes))
    out = lanes[0] + lanes[1]
    out += lanes[2] + lanes[3]
    return out


def _einsum_sums(phase: np.ndarray, decay: np.ndarray, Ar: np.ndarray, m: int) -> list[np.ndarray]:
    """The cosine and sine sums of :func:`_vibration_grid` by ``einsum`` over ``[shapers, bins * zetas,
    impulses]`` (many impulses, a convolved shaper, or double precision); ``phase`` is overwritten."""
    n = Ar.shape[1]
    full = np.empty((phase.shape[0], phase.shape[2], n), phase.dtype)  # reused: few large temporaries
    full[:, :, m:] = 1.0
    x = np.cos(phase)
    x *= decay
    full[:, :, :m] = x.transpose(0, 2, 1)
    terms = [np.einsum("fki,fi->fk", full, Ar)]
    x = np.sin(phase, out=phase)
    x *= decay
    full[:, :, :m] = x.transpose(0, 2, 1)
    full[:, :, m:] = 0.0
    terms.append(np.einsum("fki,fi->fk", full, Ar))
    return terms


def _impulse_arrays(A: Any, T: Any) -> tuple[np.ndarray, np.ndarray]:
    """Amplitudes (normalised to sum 1 per shaper) and times (s): finite, times >= 0, shapes agreeing."""
    A = v.strict_real_array(A, "A")
    T = v.strict_real_array(T, "T")
    if A.ndim == 0 or T.ndim == 0:
        raise ValueError("A and T must be arrays of impulse amplitudes and times, not scalars")
    if A.ndim > 2 or T.ndim > 2 or A.shape[-1] != T.shape[-1]:
        raise ValueError(f"A and T must hold the same number of impulses (last axis), got shapes {A.shape} "
                         f"and {T.shape}")
    if A.ndim == 2 and T.ndim == 2 and A.shape[0] != T.shape[0]:
        raise ValueError(f"A and T must have one row per shaper, got {A.shape[0]} and {T.shape[0]} rows")
    if np.any(T < 0):
        raise ValueError("T must be impulse times >= 0 s")
    total = A.sum(axis=-1, keepdims=True)
    if np.any(total <= 0):
        raise ValueError("the amplitudes A must have a positive sum (a shaper's DC gain)")
    return A / total, T
