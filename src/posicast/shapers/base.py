"""The :class:`Shaper` type: an exact transfer function plus its impulse-response description.

A shaper's impulse response is the sum of

* lumped impulses ``sum_i a_i delta(t - t_i)``,
* distributed parts ``w * k(t - t0)`` whose kernel ``k`` is a unit-area delay
  distribution of finite support (uniform, triangular, cosine, decreasing ramp,
  or a convolution of such kernels), and
* optionally a ``continuous`` remainder of infinite support given only by its
  exact transfer function (the IIR notch of seed 001 eq. 13).

The transfer function is built exactly from that description, so the two never
disagree.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .. import _validate as v
from ..core.quasipoly import QuasiPolynomial
from ..core.transfer import TransferFunction, finite_complex
from ..core.verbs import SystemVerbs
from ..modes import Mode

__all__ = ["Kernel", "DistributedPart", "Shaper", "KERNEL_SHAPES", "MAX_IMPULSES", "DECAY_MAX", "TIME_RESOLUTION"]

KERNEL_SHAPES = ("uniform", "triangular", "cosine", "decreasing")
#: Other names accepted for a kernel shape (normalised on construction).
KERNEL_ALIASES = {"rectangular": "uniform", "equal": "uniform", "trigonometric": "cosine"}

#: Most lumped impulses a Shaper may hold (a few MB; every evaluation is chunked).
MAX_IMPULSES = 100_000
#: Largest decay ``zeta * omega * duration`` a designed shaper may span: its amplitudes then
#: stay above ``e^-600 ~ 1e-261`` of the first and ``S(p)`` stays finite.
DECAY_MAX = 600.0
#: Shortest time interval of a designed shaper, relative to ``max(1 s, duration)``.  posicast.core
#: merges delays closer than ``1e-12 max(1 s, delay)``; this keeps a margin of 1000 above that.
TIME_RESOLUTION = 1e-9
#: Most complex exponentials one evaluation chunk holds (memory ~ 16 bytes each).
_CHUNK = 1 << 21
#: Lengths of a kernel: far inside the float range, so that T**3 stays a normal number.
_T_MIN, _T_MAX = 1e-100, 1e100


@dataclass(frozen=True)
class Kernel:
    """A unit-area delay distribution on ``[0, T]``.

    ``uniform`` (1/T, seed 000 eq. 6 and seed 001 G1), ``triangular`` (symmetric,
    peak at T/2, seed 001 G2), ``cosine`` ((1 - cos(2 pi t / T)) / T, seed 001 G3),
    ``decreasing`` (2 (T - t) / T^2, seed 001 G4).
    """

    shape: str
    T: float

    def __post_init__(self) -> None:
        if not isinstance(self.shape, str):
            raise TypeError(f"kernel shape must be a string, one of {KERNEL_SHAPES}; got {type(self.shape).__name__}")
        shape = KERNEL_ALIASES.get(self.shape.strip().lower(), self.shape.strip().lower())
        if shape not in KERNEL_SHAPES:
            raise ValueError(f"kernel shape must be one of {KERNEL_SHAPES}, got {self.shape!r}")
        object.__setattr__(self, "shape", shape)
        object.__setattr__(self, "T", v.real_in_range(self.T, "T", _T_MIN, _T_MAX))

    def transfer(self) -> TransferFunction:
        """Exact Laplace transform (seed 001 eq. 12, G1..G4)."""
        T = self.T
        if self.shape == "uniform":  # (1 - e^{-sT}) / (sT)
            num = QuasiPolynomial([[1.0], [-1.0]], [0.0, T])
            den = QuasiPolynomial([[0.0, T]])
        elif self.shape == "triangular":  # 4 (1 - 2 e^{-sT/2} + e^{-sT}) / (s^2 T^2)
            num = QuasiPolynomial([[4.0], [-8.0], [4.0]], [0.0, T / 2, T])
            den = QuasiPolynomial([[0.0, 0.0, T * T]])
        elif self.shape == "cosine":  # 4 pi^2 (1 - e^{-sT}) / (sT (s^2 T^2 + 4 pi^2))
            c = 4.0 * math.pi**2
            num = QuasiPolynomial([[c], [-c]], [0.0, T])
            den = QuasiPolynomial([[0.0, c * T, 0.0, T**3]])
        else:  # decreasing: 2 (sT - 1 + e^{-sT}) / (s^2 T^2)
            num = QuasiPolynomial([[-2.0, 2.0 * T], [2.0, 0.0]], [0.0, T])
            den = QuasiPolynomial([[0.0, 0.0, T * T]])
        return TransferFunction(num, den)

    def density(self, t: Any) -> np.ndarray:
        """Density at times ``t`` (zero outside ``[0, T]``; ``t`` finite reals)."""
        t = v.strict_real_array(t, "t", allow_empty=True)
        T = self.T
        inside = (t >= 0) & (t <= T)
        if self.shape == "uniform":
            val = np.full(t.shape, 1.0 / T)
        elif self.shape == "triangular":
            val = 4.0 / T**2 * np.minimum(t, T - t)
        elif self.shape == "cosine":
            val = (1.0 - np.cos(2.0 * math.pi * t / T)) / T
        else:
            val = 2.0 * (T - t) / T**2
        return np.where(inside, val, 0.0)


@dataclass(frozen=True)
class DistributedPart:
    """``weight * (k_1 * k_2 * ...)(t - delay)``: a weighted, delayed convolution of kernels."""

    weight: float
    delay: float
    kernels: tuple[Kernel, ...]

    def __post_init__(self) -> None:
        w = v.finite_real(self.weight, "weight")
        object.__setattr__(self, "weight", w + 0.0)
        object.__setattr__(self, "delay", v.real_in_range(self.delay, "delay", 0.0, _T_MAX) + 0.0)
        kernels = self.kernels
        if isinstance(kernels, Kernel):
            kernels = (kernels,)
        if not isinstance(kernels, (tuple, list)) or not kernels or not all(isinstance(k, Kernel) for k in kernels):
            raise TypeError("kernels must be a non-empty tuple of Kernel")
        object.__setattr__(self, "kernels", tuple(kernels))
        if self.delay + self.length > _T_MAX:
            raise ValueError(f"delay + kernel lengths must be <= {_T_MAX:g}, got {self.delay + self.length:g}")

    @property
    def length(self) -> float:
        return float(sum(k.T for k in self.kernels))

    @property
    def end(self) -> float:
        return self.delay + self.length

    def transfer(self) -> TransferFunction:
        tf = TransferFunction(
            QuasiPolynomial([[self.weight]], [self.delay]), QuasiPolynomial.constant(1.0)
        )
        for k in self.kernels:
            tf = tf * k.transfer()
        return tf

    def density(self, t: Any, resolution: int = 4000) -> np.ndarray:
        """Density at times ``t``; exact for one kernel, numerical convolution for several.

        ``resolution`` (integer in [2, 20000]) is the grid of the numerical convolution.
        """
        t = v.strict_real_array(t, "t", allow_empty=True)
        resolution = v.integer_in_range(resolution, "resolution", 2, 20000,
                                        " (each extra kernel costs resolution**2 operations)")
        local = t - self.delay
        if len(self.kernels) == 1:
            return self.weight * self.kernels[0].density(local)
        # Convolve the kernels on a fine grid, then interpolate.
        L = self.length
        dt = L / resolution
        grid = np.arange(resolution + 1) * dt
        dens = self.kernels[0].density(grid)
        for k in self.kernels[1:]:
            dens = np.convolve(dens, k.density(grid))[: resolution + 1] * dt
        return self.weight * np.interp(local, grid, dens, left=0.0, right=0.0)


@dataclass(frozen=True, eq=False)
class Shaper(SystemVerbs):
    """A signal shaper: exact transfer function plus impulse-response description.

    Build shapers with :func:`posicast.design`; combine them with ``S1 * S2``
    (convolution, e.g. one shaper per mode).

    Attributes
    ----------
    times, amplitudes : ndarray
        Lumped impulses (sorted by time).
    distributed : tuple of DistributedPart
        Distributed-delay parts.
    continuous : TransferFunction or None
        An infinite-support remainder (IIR part), or None.
    name : str
        Kind and parameters, e.g. ``"zvd"``.
    modes : tuple of Mode
        The modes it was designed for.
    """

    times: np.ndarray
    amplitudes: np.ndarray
    distributed: tuple[DistributedPart, ...] = ()
    continuous: TransferFunction | None = None
    name: str = "shaper"
    modes: tuple[Mode, ...] = ()
    params: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        t = v.strict_real_array(self.times, "times", allow_empty=True)
        a = v.strict_real_array(self.amplitudes, "amplitudes", allow_empty=True)
        if t.ndim > 1 or a.ndim > 1:
            raise ValueError(f"times and amplitudes must be 1-D, got shapes {t.shape} and {a.shape}")
        t, a = t.reshape(-1), a.reshape(-1)
        if t.shape != a.shape:
            raise ValueError(f"times and amplitudes must have the same length, got {t.size} and {a.size}")
        if t.size > MAX_IMPULSES:
            raise ValueError(f"times has {t.size} impulses; at most {MAX_IMPULSES} are supported")
        if np.any(t < 0) or np.any(t > _T_MAX):
            raise ValueError(f"impulse times must be in [0, {_T_MAX:g}]")
        dist = self.distributed
        if isinstance(dist, DistributedPart):
            dist = (dist,)
        if not isinstance(dist, (tuple, list)) or not all(isinstance(p, DistributedPart) for p in dist):
            raise TypeError("distributed must be a tuple of DistributedPart")
        if self.continuous is not None:
            v.instance_of(self.continuous, TransferFunction, "continuous", "a posicast TransferFunction or None")
        v.instance_of(self.name, str, "name", "a string")
        modes = self.modes
        if isinstance(modes, Mode):
            modes = (modes,)
        if not isinstance(modes, (tuple, list)) or not all(isinstance(m, Mode) for m in modes):
            raise TypeError("modes must be a tuple of posicast Mode")
        object.__setattr__(self, "modes", tuple(modes))
        v.instance_of(self.params, dict, "params", "a dict")
        t = t + 0.0  # -0.0 -> 0.0
        order = np.argsort(t, kind="stable")
        t, a = _merge_impulses(t[order], a[order])
        t.flags.writeable = False
        a.flags.writeable = False
        object.__setattr__(self, "times", t)
        object.__setattr__(self, "amplitudes", a)
        object.__setattr__(self, "distributed", tuple(dist))
        object.__setattr__(self, "_transfer", None)

    # ------------------------------------------------------------------ descriptions
    @property
    def impulses(self) -> tuple[np.ndarray, np.ndarray]:
        """Lumped impulses ``(times, amplitudes)``."""
        return self.times, self.amplitudes

    @property
    def duration(self) -> float:
        """Time of the last impulse or end of the last distributed part (``inf`` for an IIR part)."""
        if self.continuous is not None:
            return math.inf
        ends = [float(self.times[-1])] if self.times.size else [0.0]
        ends += [p.end for p in self.distributed]
        return max(ends)

    @property
    def n_impulses(self) -> int:
        return int(self.times.size)

    @property
    def is_lumped(self) -> bool:
        return not self.distributed and self.continuous is None

    @property
    def is_positive(self) -> bool:
        """True if the impulse response is nonnegative (amplitudes and weights >= 0, no IIR part)."""
        return bool(
            self.continuous is None
            and np.all(self.amplitudes >= 0)
            and all(p.weight >= 0 for p in self.distributed)
        )

    @property
    def dc_gain(self) -> float:
        """Static gain ``S(0)``: sum of amplitudes and weights (plus the IIR part's DC gain)."""
        g = float(self.amplitudes.sum()) + sum(p.weight for p in self.distributed)
        if self.continuous is not None:
            g += self.continuous.dc_gain
        return g

    @property
    def transfer(self) -> TransferFunction:
        """The exact quasi-rational transfer function ``S(s)``."""
        tf = getattr(self, "_transfer")
        if tf is None:
            tf = TransferFunction(
                QuasiPolynomial(self.amplitudes[:, np.newaxis], self.times)
                if self.times.size
                else QuasiPolynomial.zero(),
                QuasiPolynomial.constant(1.0),
            )
            for p in self.distributed:
                tf = tf + p.transfer()
            if self.continuous is not None:
                tf = tf + self.continuous
            object.__setattr__(self, "_transfer", tf)
        return tf

    @property
    def num(self) -> QuasiPolynomial:
        return self.transfer.num

    @property
    def den(self) -> QuasiPolynomial:
        return self.transfer.den

    def __call__(self, s: Any) -> Any:
        """Evaluate ``S(s)`` at complex ``s`` (vectorised).

        Raises ValueError where the value overflows the float range
        (``|e^{-s t}|`` beyond ``1e308``, i.e. ``Re(s) < -709 / duration`` about);
        an IIR part gives ``inf`` at its poles.
        """
        if self.is_lumped:  # fast exact path: sum of exponentials
            s_arr = finite_complex(s)
            out = lumped_sum(self.times, self.amplitudes, s_arr.reshape(-1)).reshape(s_arr.shape)
        else:
            out = np.asarray(self.transfer(s), dtype=complex)
        bad = np.isnan(out) if self.continuous is not None else ~np.isfinite(out)
        if np.any(bad):
            s_bad = complex(np.asarray(s, dtype=complex).reshape(-1)[int(np.flatnonzero(bad.reshape(-1))[0])])
            span = self.span
            raise ValueError(
                f"S(s) of {self.name!r} overflows the float range at s = {s_bad:.6g} (its terms e^(-s t) reach "
                f"e^{-s_bad.real * span:.4g}); s must have Re(s) >= about {-700.0 / max(span, 1e-300):.4g}")
        return out if np.ndim(s) else complex(out)

    @property
    def span(self) -> float:
        """Longest delay in the exact transfer function (the duration, or for an IIR shaper the
        longest delay of its parts; 0 for a delay-free shaper)."""
        ends = [float(self.times[-1])] if self.times.size else [0.0]
        ends += [p.end for p in self.distributed]
        if self.continuous is not None:
            ends.append(float(self.continuous.max_delay))
        return max(ends)

    def density(self, t: Any) -> np.ndarray:
        """Density of the distributed parts at times ``t`` (impulses are not included)."""
        t = v.strict_real_array(t, "t", allow_empty=True)
        out = np.zeros(t.shape)
        for p in self.distributed:
            out = out + p.density(t)
        return out

    # ------------------------------------------------------------------ combination
    def __mul__(self, other: Shaper) -> Shaper:
        """Convolution of two shapers (a shaper for both modes)."""
        if not isinstance(other, Shaper):
            return NotImplemented
        n = self.n_impulses * other.n_impulses
        if n > MAX_IMPULSES:
            raise ValueError(f"the convolution of {self.name!r} ({self.n_impulses} impulses) and {other.name!r} "
                             f"({other.n_impulses}) would have {n} impulses; at most {MAX_IMPULSES} are supported")
        ta = np.add.outer(self.times, other.times).ravel()
        aa = np.multiply.outer(self.amplitudes, other.amplitudes).ravel()
        parts: list[DistributedPart] = []
        for t_i, a_i in zip(self.times, self.amplitudes):
            parts += [DistributedPart(a_i * p.weight, t_i + p.delay, p.kernels) for p in other.distributed]
        for t_i, a_i in zip(other.times, other.amplitudes):
            parts += [DistributedPart(a_i * p.weight, t_i + p.delay, p.kernels) for p in self.distributed]
        for p in self.distributed:
            for q in other.distributed:
                parts.append(DistributedPart(p.weight * q.weight, p.delay + q.delay, p.kernels + q.kernels))
        cont = None
        if self.continuous is not None or other.continuous is not None:
            full = self.transfer * other.transfer
            finite = Shaper(ta, aa, tuple(parts)).transfer
            cont = full - finite
        return Shaper(
            ta,
            aa,
            tuple(parts),
            cont,
            name=f"{self.name}*{other.name}",
            modes=self.modes + other.modes,
        )

    # ------------------------------------------------------------------ export
    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready description."""
        return {
            "name": self.name,
            "params": {k: (float(v) if isinstance(v, (int, float, np.floating)) else v) for k, v in self.params.items()},
            "modes": [{"omega": m.omega, "zeta": m.zeta} for m in self.modes],
            "impulses": {"times": self.times.tolist(), "amplitudes": self.amplitudes.tolist()},
            "distributed": [
                {
                    "weight": p.weight,
                    "delay": p.delay,
                    "kernels": [{"shape": k.shape, "T": k.T} for k in p.kernels],
                }
                for p in self.distributed
            ],
            "continuous": None
            if self.continuous is None
            else {
                "num": {"coeffs": self.continuous.num.coeffs.tolist(), "delays": self.continuous.num.delays.tolist()},
                "den": {"coeffs": self.continuous.den.coeffs.tolist(), "delays": self.continuous.den.delays.tolist()},
            },
            "duration": self.duration if math.isfinite(self.duration) else None,
            "dc_gain": self.dc_gain,
        }

    def __repr__(self) -> str:
        parts = f", {len(self.distributed)} distributed" if self.distributed else ""
        iir = ", IIR" if self.continuous is not None else ""
        return f"Shaper({self.name!r}, {self.n_impulses} impulses{parts}{iir}, duration={self.duration:.6g})"


def lumped_sum(times: np.ndarray, amps: np.ndarray, s: np.ndarray, shift: np.ndarray | None = None) -> np.ndarray:
    """``e^{shift} sum_i A_i e^{-s t_i}`` for 1-D complex ``s``, in chunks of bounded memory.

    Impulses of zero amplitude are skipped (``0 * e^{x}`` is 0 for every finite ``x``).  Where
    the largest exponent exceeds 700 the sum is scaled by it first, so the result overflows
    only when the value itself is beyond the float range (then it is ``inf``).
    """
    keep = amps != 0
    t, a = times[keep], amps[keep]
    out = np.zeros(s.shape, dtype=complex)
    if t.size == 0 or s.size == 0:
        return out
    step = max(1, _CHUNK // t.size)
    with np.errstate(over="ignore", invalid="ignore"):
        for i in range(0, s.size, step):
            e = -np.multiply.outer(s[i: i + step], t)
            if shift is not None:
                e += shift[i: i + step, None]
            c = np.max(e.real, axis=1)
            big = c > 700.0
            if not np.any(big):
                out[i: i + step] = np.exp(e) @ a
                continue
            c = np.where(big, c, 0.0)
            val = np.exp(e - c[:, None]) @ a
            mag = np.abs(val)
            logm = np.log(np.where(mag > 0, mag, 1.0)) + c
            unit = np.where(mag > 0, val / np.where(mag > 0, mag, 1.0), 0.0)
            out[i: i + step] = np.where(logm > 709.78, complex(np.inf), unit * np.exp(np.minimum(logm, 709.78)))
    return out


def _merge_impulses(t: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge impulses at (numerically) equal times."""
    if t.size == 0:
        return t.copy(), a.copy()
    tol = 1e-12 * max(1.0, float(t[-1]))
    out_t = [t[0]]
    out_a = [a[0]]
    for ti, ai in zip(t[1:], a[1:]):
        if ti - out_t[-1] <= tol:
            out_a[-1] += ai
        else:
            out_t.append(ti)
            out_a.append(ai)
    return np.array(out_t), np.array(out_a)


def check_mode(mode: Any, name: str = "mode") -> Mode:
    """``mode`` if it is a :class:`Mode`, else TypeError."""
    v.instance_of(mode, Mode, name, "a posicast Mode")
    return mode


def sigma_of(zeta: float) -> float:
    """``zeta / sqrt(1 - zeta^2)``: decay per radian of the damped oscillation."""
    return zeta / math.sqrt((1.0 - zeta) * (1.0 + zeta))


def check_decay(mode: Mode, periods: float, what: str) -> None:
    """Refuse a design whose duration (``periods`` damped periods) spans a decay beyond :data:`DECAY_MAX`.

    The decay over the shaper is ``zeta omega t_end = 2 pi sigma periods``; above ``e^600`` the
    last amplitudes fall below ``1e-261`` of the first (they underflow as ``zeta -> 1``) and
    ``S(p)`` overflows, so the zero cannot be placed in double precision.
    """
    D = 2.0 * math.pi * sigma_of(mode.zeta) * periods
    if D > DECAY_MAX:
        s_max = DECAY_MAX / (2.0 * math.pi * periods)
        z_max = s_max / math.sqrt(1.0 + s_max * s_max)
        z_shown = math.floor(z_max * 1e6) / 1e6
        raise ValueError(
            f"zeta={mode.zeta:.10g} is too close to 1 for {what}: over its {periods:.4g} damped periods the mode "
            f"decays by e^-{D:.4g} (DECAY_MAX = {DECAY_MAX:g}: its amplitudes would fall below 1e-261 of the first, "
            f"beyond double precision); zeta must be <= {z_shown:.6f} for it")


def check_resolution(shortest: float, duration: float, what: str) -> None:
    """Refuse a design whose shortest time interval is below ``TIME_RESOLUTION * max(1 s, duration)``."""
    floor = TIME_RESOLUTION * max(1.0, duration)
    if not shortest >= floor:
        raise ValueError(
            f"{what}: its shortest time interval {shortest:.4g} s is below {floor:.4g} s = {TIME_RESOLUTION:g} x "
            f"max(1 s, duration {duration:.4g} s), the delay resolution posicast keeps (posicast.core merges delays "
            "closer than 1e-12 x max(1 s, delay)); for a fast mode give omega in rad/ms or rad/us (times then "
            "come out in ms or us), for a long kernel choose a shorter T")
