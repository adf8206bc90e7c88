"""Shapers designed for the controller's sample period: zeros placed on the sampled mode poles (seed 002, eq. 4-12).

A mode pole ``p = -zeta omega + j Omega`` (seed 002 eq. 4, where the printed ``j``
is missing) is seen by a controller running at the sample period ``T`` as
``z_p = exp(p T)`` (eq. 5-6).  The shaper

    F(z) = C prod_modes [(1 - z_p z^-n)(1 - conj(z_p) z^-n)]^m         (eq. 7, stride n, multiplicity m)

has, for ``n = 1``, ``m = 1``, the taps of eq. 8-9: ``a_0 = 1``, ``a_1 = -(z_1 + z_2) =
-2 Re z_p``, ``a_2 = z_1 z_2 = |z_p|^2`` and ``C = 1 / (a_0 + a_1 + a_2)`` (unit static
gain).  Its impulses sit on the grid ``k T``; as a continuous shaper,
``S(s) = sum_k A_k exp(-s k T) = F(exp(s T))``, so ``S(p) = 0`` exactly, with
``S`` and its first ``m - 1`` derivatives vanishing there (the ZV, ZVD, ZVD^k
family: ``m = 1, 2, k + 1``).

* **Stride** ``n``: the factor in ``z^-n`` places its zero at ``z_p^n`` in the
  variable ``z^n`` and so still at ``z_p`` (taps every ``n`` samples).  With
  ``n = 1`` (the seed) a short period gives huge alternating taps
  (``C = 1 / |1 - z_p|^2 ~ 1 / (|p| T)^2`` per factor); ``stride="positive"``
  takes the smallest ``n`` with ``cos(n Omega T) <= 0``, which makes every tap
  nonnegative and the shaper at most ``2 m n T <= m (pi / Omega + 2 T)`` long.
* **ZV special case** (eq. 10-12): at ``T_vz = pi / (2 Omega)`` the pair sits on the
  imaginary axis, ``a_1 = 0``, and ``F = C (1 + a_2 z^-2)`` is the continuous ZV shaper
  (``a_2 = exp(-zeta pi / sqrt(1 - zeta^2)) = K`` of eq. 1).
* **Order from actuator limits** (seed 002 section 4.1): the actuator's shortest
  period is the sample period and the required rise time bounds the shaper's
  duration ``2 m n T``; :func:`highest_multiplicity` returns the largest ``m``
  (the seed's "ZVD_4" is ``m = 5`` at 10 ms within 100 ms).
"""

from __future__ import annotations

import math
import warnings
from typing import Any, NamedTuple, Sequence

import numpy as np

from .. import _validate as v
from ..modes import Mode
from .base import _T_MAX, MAX_IMPULSES, Shaper, check_resolution

__all__ = ["zplane_shaper", "zplane_taps", "sampled_pole", "highest_multiplicity", "OrderChoice",
           "SAMPLED_KINDS", "multiplicity_of", "GAIN_WARN"]

#: Kinds ``design(..., sample_period=T)`` builds in the z plane, and their zero multiplicity.
SAMPLED_KINDS = ("zv", "zvd", "zvdd", "zvddd", "zvdk")
_ALIAS_TOL = 1e-12  # Omega T may exceed pi by this relative rounding
#: Above this tap gain ``sum |A_k|`` a design warns (the taps alternate in sign and amplify the command).
GAIN_WARN = 1e3
MAX_STRIDE = 10**9  #: most samples between the taps of a factor
MAX_MULTIPLICITY = 1000  #: highest zero multiplicity (ZVD^999); the taps of one factor cost m^2 to expand
_GRID_COS = 1e-15  # |cos(n Omega T)| below this is the rounding of cos(pi / 2)


def multiplicity_of(kind: str, k: int = 1) -> int:
    """Zero multiplicity of a kind of the ZV family: zv 1, zvd 2, zvdd 3, zvddd 4, zvdk ``k + 1``.

    >>> multiplicity_of("zvd"), multiplicity_of("zvdk", k=4)
    (2, 5)
    """
    fixed = {"zv": 1, "zvd": 2, "zvdd": 3, "zvddd": 4}
    if kind in fixed:
        return fixed[kind]
    if kind == "zvdk":
        return v.integer(k, "k", 0) + 1
    raise ValueError(f"kind must be one of {SAMPLED_KINDS} for a z-plane design, got {kind!r}")


def _modes(mode: Any) -> tuple[Mode, ...]:
    if isinstance(mode, Mode):
        return (mode,)
    items = v.sequence(mode, "modes", min_len=1)
    if all(isinstance(m, Mode) for m in items):
        return tuple(items)
    if len(items) == 2 and not any(isinstance(m, Mode) for m in items):  # an (omega, zeta) pair
        return (Mode(items[0], items[1]),)
    raise TypeError("modes must be a posicast Mode, an (omega, zeta) pair or a sequence of Modes")


def _check_period(mode: Mode, T: float) -> float:
    """``theta = Omega T`` in ``(0, pi]``; a longer period aliases the mode (named ValueError)."""
    theta = mode.damped_omega * T
    if theta > math.pi * (1.0 + _ALIAS_TOL):
        limit = math.pi / mode.damped_omega
        raise ValueError(
            f"sample_period = {T:.6g} s is too long for the mode at {mode.freq_hz:.6g} Hz (zeta {mode.zeta:g}): "
            f"it must be <= half the damped period, pi / Omega = {limit:.6g} s (beyond it the sampled pole "
            "aliases to a lower frequency and the zero would cancel the alias, not the mode)")
    return min(theta, math.pi)


def sampled_pole(mode: Mode, sample_period: float) -> complex:
    """``z_p = exp(p T)`` of the mode's upper pole (seed 002 eq. 6).

    >>> z = sampled_pole(Mode(1.0, 0.0), math.pi / 2)      # a quarter period: z_p = j
    >>> round(z.real, 15), round(z.imag, 15)
    (0.0, 1.0)
    """
    if not isinstance(mode, Mode):
        raise TypeError(f"mode must be a posicast Mode, got {type(mode).__name__}")
    T = v.positive(sample_period, "sample_period")
    theta = _check_period(mode, T)
    r = math.exp(-mode.decay * T)
    return complex(r * math.cos(theta), r * math.sin(theta))


def _stride(mode: Mode, T: float, stride: Any) -> int:
    if isinstance(stride, str):
        v.choice(stride, "stride", ("positive",))
        theta = _check_period(mode, T)
        n = math.pi / (2.0 * theta)   # smallest n: n theta >= pi / 2
        if not n <= MAX_STRIDE:
            raise ValueError(f"sample_period = {T:.4g} s is too short for stride='positive' on the mode at "
                             f"{mode.freq_hz:.6g} Hz: the stride would be {n:.4g} samples (at most {MAX_STRIDE:g})")
        return max(1, math.ceil(n * (1.0 - 1e-12)))
    return v.integer_in_range(stride, "stride", 1, MAX_STRIDE)


def zplane_taps(mode: Mode, sample_period: float, multiplicity: int = 1, stride: int = 1) -> np.ndarray:
    """Taps ``C a_j`` of one mode's factor ``C [(1 - z_p w)(1 - conj(z_p) w)]^m`` in ``w = z^-n``.

    Tap ``j`` acts at sample ``j n``.  Seed 002 eq. 8-9 for ``n = m = 1``:
    ``a = (1, -2 Re z_p, |z_p|^2)``.  The static gain ``1 / C = |1 - z_p^n|^(2m)`` is
    computed without cancellation.

    >>> [round(float(a), 12) for a in zplane_taps(Mode(1.0, 0.0), math.pi / 2)]   # eq. 10-12: ZV
    [0.5, 0.0, 0.5]
    """
    T = v.positive(sample_period, "sample_period")
    m = v.integer_in_range(multiplicity, "multiplicity", 1, MAX_MULTIPLICITY)
    n = v.integer(stride, "stride", 1)
    theta = _check_period(mode, T)
    rn = math.exp(-mode.decay * T * n)                      # |z_p|^n
    c = math.cos(n * theta)
    if abs(c) < _GRID_COS:  # n theta = pi / 2 to rounding: eq. 10's ZV, a_1 = 0 exactly
        c = 0.0
    # |1 - z_p^n|^2 = (1 - r^n)^2 + 4 r^n sin^2(n theta / 2): no cancellation for small |p| T
    gain = math.expm1(-mode.decay * T * n) ** 2 + 4.0 * rn * math.sin(n * theta / 2.0) ** 2
    if gain == 0.0:
        raise ValueError(f"sample_period = {T:g} s puts the mode's sampled pole on z = 1 (n Omega T = 2 pi)")
    quad = np.array([1.0, -2.0 * rn * c, rn * rn]) / gain  # eq. 9: a_0, a_1 = -(z1 + z2), a_2 = z1 z2; C
    taps = np.array([1.0])
    for _ in range(m):
        taps = np.convolve(taps, quad)
    return taps


def _product(factors: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """Sparse polynomial product of ``(sample indices, taps)`` factors, equal indices merged."""
    idx, val = np.array([0]), np.array([1.0])
    for i, a in factors:
        if idx.size * i.size > MAX_IMPULSES:
            raise ValueError(f"the product of the modes' factors would have {idx.size * i.size} taps; "
                             f"at most {MAX_IMPULSES}")
        idx = np.add.outer(idx, i).ravel()
        val = np.multiply.outer(val, a).ravel()
        idx, inv = np.unique(idx, return_inverse=True)
        val = np.bincount(inv.ravel(), weights=val)
    return idx, val


def zplane_shaper(modes: Mode | Sequence[Mode], sample_period: float, multiplicity: int = 1,
                  stride: int | str | Sequence[int | str] = 1, name: str | None = None) -> Shaper:
    """A shaper with impulses on the grid ``k T`` and zeros of multiplicity ``m`` on each sampled mode pole.

    Parameters
    ----------
    modes : Mode or sequence of Mode
        The modes to cancel (one factor each; the shaper is their product).
    sample_period : float
        ``T`` [s], ``0 < T <= pi / Omega`` of every mode (half its damped period).
    multiplicity : int
        ``m >= 1`` (ZV 1, ZVD 2, ZVD^k ``k + 1``).
    stride : int, "positive" or a sequence of them (one per mode)
        Samples between the taps of a factor (1: seed 002 eq. 8); ``"positive"``
        the smallest stride with nonnegative taps.
    name : str, optional
        The shaper's name (default ``"zplane"``).

    Returns
    -------
    Shaper
        ``params`` holds ``sample_period``, ``multiplicity``, ``stride`` (per mode) and
        ``tap_gain = sum |A_k|`` (the peak gain of the shaper; large for short
        periods at stride 1).

    Raises
    ------
    ValueError
        ``sample_period`` longer than half a mode's damped period, ``multiplicity < 1``,
        ``stride < 1``, more than ``MAX_IMPULSES`` taps.
    TypeError
        A mode that is not a Mode, a non-integer multiplicity or stride.

    Examples
    --------
    >>> m = Mode.from_hz(28.0, 0.05)
    >>> S = zplane_shaper(m, 0.01, multiplicity=2)         # ZVD at 10 ms (seed 002's 28 Hz mode)
    >>> S.times.tolist()
    [0.0, 0.01, 0.02, 0.03, 0.04]
    >>> abs(S(m.pole)) < 1e-15, round(S.dc_gain, 15)
    (True, 1.0)
    """
    ms = _modes(modes)
    T = v.positive(sample_period, "sample_period")
    mult = v.integer(multiplicity, "multiplicity", 1)
    strides = list(stride) if isinstance(stride, (list, tuple)) else [stride] * len(ms)
    if len(strides) != len(ms):
        raise ValueError(f"stride must be one value or one per mode ({len(ms)}), got {len(strides)}")
    ns = [_stride(m, T, s) for m, s in zip(ms, strides)]
    if mult > MAX_MULTIPLICITY:
        raise ValueError(f"multiplicity must be <= {MAX_MULTIPLICITY}, got {mult}")
    duration = 2 * mult * T * sum(ns)
    check_resolution(T * min(ns), duration, f"a z-plane shaper at sample_period = {T:g} s")
    if not duration <= _T_MAX:
        raise ValueError(f"sample_period = {T:g} s with multiplicity {mult} and stride {ns} lasts {duration:.4g} s, "
                         f"more than {_T_MAX:g} s")
    idx, taps = _product([(np.arange(2 * mult + 1) * n, zplane_taps(m, T, mult, n)) for m, n in zip(ms, ns)])
    if not np.all(np.isfinite(taps)):
        raise ValueError(f"multiplicity = {mult} is too high at sample_period = {T:g} s: the taps overflow the float range")
    keep = taps != 0.0
    gain = float(np.abs(taps).sum())
    if gain > GAIN_WARN:
        warnings.warn(f"the z-plane shaper at sample_period = {T:g} s with stride {ns} has tap gain sum|A_k| = "
                      f"{gain:.3g}: its taps alternate in sign and amplify the command (and S(z_p) is zero only to "
                      f"~1e-16 x {gain:.3g}); stride='positive' gives nonnegative taps", stacklevel=3)
    return Shaper(idx[keep] * T, taps[keep], name=name or "zplane", modes=ms,
                  params={"sample_period": T, "multiplicity": mult, "stride": ns, "tap_gain": gain})


class OrderChoice(NamedTuple):
    """The highest-order z-plane shaper that fits the actuator (seed 002 section 4.1)."""

    multiplicity: int      #: m (ZVD^(m-1); the seed's ZVD_4 is m = 5)
    shaper: Shaper         #: the design at the actuator period
    duration: float        #: 2 m n T, the shaped step's rise time [s]
    sample_period: float   #: the actuator's period T [s]
    stride: tuple[int, ...]  #: n per mode


def highest_multiplicity(modes: Mode | Sequence[Mode], actuator_period: float, rise_time: float,
                         stride: int | str = 1) -> OrderChoice:
    """The largest multiplicity whose shaper, at the actuator's period, is no longer than ``rise_time``.

    Seed 002 section 4.1: the actuator can change its command at most every
    ``actuator_period`` (10 ms for its stepper motors), so the shaper is designed at
    that period; the shaped step rises over the shaper's duration ``2 m n T``
    (sum over the modes), which must not exceed the required ``rise_time`` (100 ms
    there).  For a mode above ``1 / (4 T) = 25 Hz`` the taps are nonnegative at stride 1
    and ``m = floor(rise_time / 2T) = 5``: the seed's "ZVD_4".

    Raises
    ------
    ValueError
        Even ``m = 1`` does not fit (the message gives the shortest rise time), or a bad period.

    Examples
    --------
    >>> c = highest_multiplicity(Mode.from_hz(28.0, 0.05), 0.01, 0.1)
    >>> c.multiplicity, round(c.duration, 12), c.shaper.is_positive
    (5, 0.1, True)
    """
    ms = _modes(modes)
    T = v.positive(actuator_period, "actuator_period")
    rise = v.positive(rise_time, "rise_time")
    ns = tuple(_stride(m, T, stride) for m in ms)
    per_m = 2.0 * T * sum(ns)
    m_float = rise / per_m * (1.0 + 1e-12)
    if m_float < 1.0:
        raise ValueError(f"rise_time = {rise:g} s is shorter than the shortest z-plane shaper for the mode(s) at "
                         f"{', '.join(f'{x.freq_hz:.6g} Hz' for x in ms)} with actuator_period = {T:g} s ({per_m:.6g} s, "
                         f"multiplicity 1, stride {list(ns)}); rise_time must be >= {per_m:.6g} s")
    # the product of the modes' factors has at most (2m + 1)^len(modes) taps
    m_cap = min(MAX_MULTIPLICITY, max(1, int((MAX_IMPULSES ** (1.0 / len(ms)) - 1.0) // 2)))
    m = min(int(m_float), m_cap)
    S = zplane_shaper(ms, T, m, list(ns), name=f"zvd{m - 1}" if m > 1 else "zv")
    return OrderChoice(m, S, m * per_m, T, ns)
