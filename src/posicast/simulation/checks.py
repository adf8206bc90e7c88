"""Argument checks and up-front work limits of :func:`posicast.simulate` (issue #13)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .. import _validate as v
from ..core.transfer import TransferFunction
from ..loops.loop import Loop
from ..shapers.base import Shaper
from .layout import RingLayout

__all__ = ["MAX_BYTES", "MAX_SECONDS", "MAX_SUBSTEPS", "as_signal", "check_time", "refuse_work", "shaper_object",
           "check_rates", "check_saturation", "controller_period", "check_mode_nyquist", "default_substeps"]

# Up-front work limits (issue #13): a simulation is refused, with the estimate and the parameter to
# change, before it allocates anything large.  Costs measured on the reference machine (2 cores):
# about 350 MB peak per 10^6 samples of t in the exact and sampled modes; 1 us and 25 us per internal
# step for the fine-step (shaper in the loop, run in chunks: its memory is that of the signals kept,
# issue #15) and the sample-by-sample (saturation/rate limit) runs.
MAX_BYTES = 2e9
MAX_SECONDS = 60.0
_BYTES_PER_SAMPLE = 350.0
# the linear fine run (shaper in the loop, in chunks): at most 12 signals of 8 bytes kept per sample of t
_BYTES_PER_KEPT_SAMPLE = 8.0 * 12
_BYTES_PER_FINE_STEP = 8.0 * 40  # repeated inputs, states and outputs of the nonlinear fine run
_SECONDS_PER_FINE_STEP = 1.0e-6
_SECONDS_PER_NONLINEAR_STEP = 25e-6
MAX_SUBSTEPS = 1_000_000


def as_signal(x: Any, name: str, n: int) -> np.ndarray:
    if x is None:
        return np.zeros(n)
    if np.isscalar(x):
        raise TypeError(f"{name} must be an array on t (or None), got a scalar")
    arr = v.strict_real_array(x, name, allow_empty=True)
    if arr.ndim != 1 or arr.size != n:
        raise ValueError(f"{name} must have the length of t ({n}), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains NaN or inf")
    return arr


def check_time(t: Any) -> tuple[np.ndarray, float]:
    if isinstance(t, (str, bytes)) or np.isscalar(t) or t is None:
        raise TypeError(f"t must be an array of times, got {type(t).__name__}")
    n = int(np.size(t)) if isinstance(t, np.ndarray) else None
    if n is not None:  # before any copy of a large grid
        refuse_samples(n)
    t = v.strict_real_array(t, "t", allow_empty=True)
    if t.ndim != 1 or t.size < 2:
        raise ValueError("t must be a 1-D array of at least 2 times")
    refuse_samples(t.size)
    dt = (t[-1] - t[0]) / (t.size - 1)
    atol = 1e-12 * max(1.0, abs(t[-1]))
    piece = 1 << 20  # the steps checked a piece at a time: no temporaries of the grid's size
    if dt <= 0 or not all(np.allclose(np.diff(t[k: k + piece + 1]), dt, rtol=1e-9, atol=atol)
                          for k in range(0, t.size - 1, piece)):
        raise ValueError("t must be uniform and increasing")
    return t, float(dt)


def refuse_samples(n: int, per: float = _BYTES_PER_KEPT_SAMPLE) -> None:
    """Refuse ``n`` samples of ``per`` bytes each beyond :data:`MAX_BYTES` (by default the cheapest method's cost;
    :func:`refuse_work` checks again with the chosen method's)."""
    v.refuse_large(per * n, MAX_BYTES, f"simulating {n:.3g} samples", f"use fewer samples in t "
                   f"(at most about {MAX_BYTES / per:.3g}: a coarser step or a shorter time)", "bytes")


def refuse_work(layout: RingLayout, S: Shaper | None, n: int, dt: float, sample_rate: Any, substeps: int | None,
                nonlinear: bool) -> None:
    """Estimate the internal steps of the run chosen by ``simulate`` and refuse it if too large."""
    in_loop = S is not None and layout.shaper is not None
    if sample_rate is not None or nonlinear or not in_loop:  # every signal over the whole grid, and temporaries
        refuse_samples(n, _BYTES_PER_SAMPLE)
    if sample_rate is not None:
        steps, fine = float(n), False  # the controller runs at most once per step of t
    elif nonlinear or in_loop:
        sub = substeps if substeps is not None else max(1, int(math.ceil(dt / 1e-3 - 1e-9)))
        steps, fine = float(n) * sub * (1.0 if nonlinear else 3.0), True  # + the comparison run
    else:
        return  # exact continuous mode: covered by the per-sample estimate
    change = ("use fewer samples in t" + (", fewer substeps" if sample_rate is None else "")
              + (" or sample_rate (the sampled mode runs at the controller rate)" if sample_rate is None else ""))
    if fine and nonlinear:  # the linear fine run works in chunks: the per-sample estimate covers it
        v.refuse_large(_BYTES_PER_FINE_STEP * steps, MAX_BYTES, f"the simulation's {steps:.3g} internal steps",
                       change, "bytes")
    per = _SECONDS_PER_NONLINEAR_STEP if nonlinear else _SECONDS_PER_FINE_STEP
    v.refuse_large(per * steps, MAX_SECONDS, f"the simulation's {steps:.3g} internal steps", change, "s")


def shaper_object(loop: Loop) -> Shaper | None:
    S = loop.shaper
    if S is None:
        return None
    if not isinstance(S, Shaper):
        raise TypeError(
            "simulation needs the loop's shaper as a posicast Shaper (impulses and kernels), "
            f"got {type(S).__name__}"
        )
    return S


def check_rates(S: Shaper | None, h: float, name: str, rate: float) -> None:
    if S is None:
        return
    times = S.impulses[0]
    pos = times[times > 0]
    first = [float(pos.min())] if pos.size else []
    first += [p.delay + (0 if p.delay > 0 else p.length) for p in S.distributed]
    if first and min(first) < h * (1 - 1e-9):
        raise ValueError(
            f"{name} = {rate:g} Hz is too low: the shaper's shortest delay {min(first):.4g} s is below one "
            f"sample ({h:.4g} s); use {name} >= {1.0 / min(first):.4g} Hz"
        )
    for m in S.modes:
        if m.omega / (2 * math.pi) >= 0.5 * rate:
            raise ValueError(
                f"{name} = {rate:g} Hz is too low: the shaper's mode {m.freq_hz:.4g} Hz is at or above "
                f"the Nyquist frequency {0.5 * rate:.4g} Hz"
            )


def check_saturation(saturation: Any) -> tuple[float, float] | None:
    if saturation is None:
        return None
    if isinstance(saturation, (int, float)) and not isinstance(saturation, bool):
        if not saturation > 0:
            raise ValueError(f"saturation must be > 0 (symmetric limit) or (u_min, u_max), got {saturation!r}")
        return -float(saturation), float(saturation)
    try:
        lo, hi = (float(x) for x in saturation)
    except (TypeError, ValueError) as exc:
        raise TypeError("saturation must be a number or a pair (u_min, u_max)") from exc
    if not lo < hi:
        raise ValueError(f"saturation needs u_min < u_max, got ({lo:g}, {hi:g})")
    return lo, hi


def controller_period(sample_rate: Any, dt: float, n: int) -> tuple[float, int]:
    if isinstance(sample_rate, bool) or not isinstance(sample_rate, (int, float, np.integer, np.floating)) \
            or not sample_rate > 0 or not math.isfinite(sample_rate):
        raise ValueError(f"sample_rate must be a positive number of Hz (or None), got {sample_rate!r}")
    Ts = 1.0 / float(sample_rate)
    if not Ts <= dt * (n - 1):
        raise ValueError(f"sample_rate = {float(sample_rate):g} Hz: the controller period {Ts:.6g} s is longer than "
                         f"the simulated time {dt * (n - 1):.6g} s")
    ratio = Ts / dt
    m = int(round(ratio))
    if m < 1 or abs(ratio - m) > 1e-6 * ratio:
        raise ValueError(
            f"sample_rate: the controller period {Ts:.6g} s must be an integer multiple of the step of t "
            f"({dt:.6g} s)"
        )
    return Ts, m


def check_mode_nyquist(tf: TransferFunction, rate: float) -> None:
    if tf.den.degree < 1:
        return
    poles = np.roots(tf.den.coeffs[0, ::-1])
    if poles.size and np.max(np.abs(poles)) / (2 * math.pi) >= 0.5 * rate:
        f = float(np.max(np.abs(poles)) / (2 * math.pi))
        raise ValueError(
            f"sample_rate = {rate:g} Hz is too low: a plant mode at {f:.4g} Hz is at or above the Nyquist "
            f"frequency {0.5 * rate:.4g} Hz"
        )


def default_substeps(dt: float) -> int:
    """Internal steps per step of ``t``: enough for ``h <= 1 ms``, at least 1."""
    return max(1, int(math.ceil(dt / 1e-3 - 1e-9)))
