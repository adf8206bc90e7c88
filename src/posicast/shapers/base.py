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

from ..core.quasipoly import QuasiPolynomial
from ..core.transfer import TransferFunction, finite_complex
from ..modes import Mode

__all__ = ["Kernel", "DistributedPart", "Shaper", "KERNEL_SHAPES"]

KERNEL_SHAPES = ("uniform", "triangular", "cosine", "decreasing")


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
        if self.shape not in KERNEL_SHAPES:
            raise ValueError(f"kernel shape must be one of {KERNEL_SHAPES}, got {self.shape!r}")
        if not (math.isfinite(self.T) and self.T > 0):
            raise ValueError(f"T must be finite and > 0, got {self.T!r}")

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
        """Density at times ``t`` (zero outside ``[0, T]``)."""
        t = np.asarray(t, dtype=float)
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
        if not math.isfinite(self.weight):
            raise ValueError(f"weight must be finite, got {self.weight!r}")
        if not (math.isfinite(self.delay) and self.delay >= 0):
            raise ValueError(f"delay must be finite and >= 0, got {self.delay!r}")
        if not self.kernels or not all(isinstance(k, Kernel) for k in self.kernels):
            raise TypeError("kernels must be a non-empty tuple of Kernel")

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
        """Density at times ``t``; exact for one kernel, numerical convolution for several."""
        t = np.asarray(t, dtype=float)
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
class Shaper:
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
        t = np.asarray(self.times, dtype=float).reshape(-1)
        a = np.asarray(self.amplitudes, dtype=float).reshape(-1)
        if t.shape != a.shape:
            raise ValueError("times and amplitudes must have the same length")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(a))):
            raise ValueError("impulse times and amplitudes must be finite")
        if np.any(t < 0):
            raise ValueError("impulse times must be >= 0")
        order = np.argsort(t, kind="stable")
        t, a = _merge_impulses(t[order], a[order])
        t.flags.writeable = False
        a.flags.writeable = False
        object.__setattr__(self, "times", t)
        object.__setattr__(self, "amplitudes", a)
        object.__setattr__(self, "distributed", tuple(self.distributed))
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
            g += self.continuous.dc_gain()
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
        """Evaluate ``S(s)`` at complex ``s`` (vectorised)."""
        if self.is_lumped:  # fast exact path: sum of exponentials
            s_arr = finite_complex(s)
            out = np.exp(-np.multiply.outer(s_arr, self.times)) @ self.amplitudes
            return out if np.ndim(s) else complex(out)
        return self.transfer(s)

    def density(self, t: Any) -> np.ndarray:
        """Density of the distributed parts at times ``t`` (impulses are not included)."""
        t = np.asarray(t, dtype=float)
        out = np.zeros(t.shape)
        for p in self.distributed:
            out = out + p.density(t)
        return out

    # ------------------------------------------------------------------ combination
    def __mul__(self, other: Shaper) -> Shaper:
        """Convolution of two shapers (a shaper for both modes)."""
        if not isinstance(other, Shaper):
            return NotImplemented
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
