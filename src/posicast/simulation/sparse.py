"""Sparse real-time shaper filters: O(#impulses) per sample, distributed kernels by running sums (seed 000 eq. 19-20).

A discretised shaper is kept as

* **sparse taps** ``(index, weight)``: the lumped impulses (a fractional delay
  split across two taps, :mod:`posicast.simulation.taps`) and the edge taps of the
  distributed parts;
* **segments**: runs of taps ``w_k = c0 + c1 (k - s) / L`` on ``s <= k <= e``
  (``L = e - s``) inside a uniform, decreasing or triangular kernel.  Their
  contribution ``c0 M0[n] + c1 M1[n]`` with ``M0[n] = sum_k x[n-k]``,
  ``M1[n] = sum_k (k - s)/L x[n-k]`` is updated in O(1) per sample (the running
  integral of seed 000 eq. 20):
  ``M0[n] = M0[n-1] + x[n-s] - x[n-e-1]``,
  ``M1[n] = M1[n-1] + (M0[n-1] - x[n-1-e]) / L - x[n-1-e]``.
  Inside a cosine kernel the taps are ``c0 + c1 cos(W (k - s)) + c2 sin(W (k - s))``
  and the rotating sum ``Mc[n] = sum_k exp(jW (k - s)) x[n-k]`` obeys
  ``Mc[n] = exp(jW) Mc[n-1] + x[n-s] - exp(jW (L + 1)) x[n-1-e]``.
  Every ``resync`` samples (at absolute sample numbers, so chunking never changes
  the arithmetic) the sums are recomputed exactly (``math.fsum``): the rounding of
  the recursion cannot drift over a long run.

The forward filter is ``y = S x``; the inverse (``1/S``, seed 000 eq. 19-20 on the
sample grid) is ``m[n] = (x[n] - sum_{k >= 1} w_k m[n-k]) / w_0``, run in blocks
no longer than the first delayed tap.  Whether that recursion is stable is the
question whether every zero of ``S_d(z) = sum_k w_k z^-k`` lies inside the unit
circle: :func:`inverse_stability` answers it with the spectral radius.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from scipy import signal

from .. import _validate as v

__all__ = ["Segment", "SparseTaps", "InverseStability", "SparseEngine", "inverse_stability", "sparse_from_parts"]

#: Shortest run of kernel taps worth a running sum (shorter runs stay sparse taps).
MIN_SEGMENT = 8
#: A run is a segment only if the line fits its taps to this fraction of its largest tap.
FIT_TOL = 1e-12
#: Kernel shapes whose pieces are polynomials of degree <= 1 (the cosine kernel stays sparse taps).
_DEGREE = {"uniform": 0, "decreasing": 1, "triangular": 1, "cosine": -1}  # -1: a sinusoid plus a constant
#: |spectral radius - 1| below this is "marginal" (zeros on the unit circle to rounding).
MARGINAL_TOL = 1e-9
_ROOTS_MAX = 400  # up to this degree the zeros of S_d come from np.roots; above by winding numbers
_FFT_MAX = 1 << 22  # finest grid on a circle (2 pi / 2^22 = 1.5e-6 between points)
_RESOLUTION = 8 * 2 * math.pi / _FFT_MAX  # 1.2e-5: closer to a zero than a few grid steps, the phase is not followed


@dataclass(frozen=True)
class Segment:
    """Taps on ``start <= k <= stop``: ``c0 + c1 (k - start) / L`` (``L = max(stop - start, 1)``), or for
    ``omega != 0`` (radians per sample) ``c0 + c1 cos(omega (k - start)) + c2 sin(omega (k - start))``."""

    start: int
    stop: int
    c0: float
    c1: float = 0.0
    c2: float = 0.0
    omega: float = 0.0

    @property
    def length(self) -> int:
        return max(self.stop - self.start, 1)

    def basis(self) -> np.ndarray:
        """The second (and third) basis function on the segment: rows ``(k - s)/L`` or ``cos, sin``."""
        j = np.arange(self.stop - self.start + 1, dtype=float)
        if self.omega:
            return np.vstack([np.cos(self.omega * j), np.sin(self.omega * j)])
        return (j / self.length)[None, :]

    def weights(self) -> np.ndarray:
        b = self.basis()
        return self.c0 + (self.c1 * b[0] + self.c2 * b[1] if self.omega else self.c1 * b[0])


@dataclass(frozen=True, eq=False)
class SparseTaps:
    """A discretised shaper's FIR part as sparse taps plus running-sum segments."""

    index: np.ndarray
    weight: np.ndarray
    segments: tuple[Segment, ...] = ()

    @property
    def span(self) -> int:
        """Largest delay in samples."""
        return max([int(self.index[-1]) if self.index.size else 0] + [g.stop for g in self.segments])

    @property
    def n_terms(self) -> int:
        """Terms per sample: sparse taps plus two per segment (running sums)."""
        return int(self.index.size) + 2 * len(self.segments)

    def dense(self) -> np.ndarray:
        """The equivalent dense taps ``w_0 .. w_span``."""
        w = np.zeros(self.span + 1)
        np.add.at(w, self.index, self.weight)
        for g in self.segments:
            w[g.start: g.stop + 1] += g.weights()
        return w

    @property
    def total(self) -> float:
        return float(self.weight.sum()) + sum(float(g.weights().sum()) for g in self.segments)


def _fit(k: np.ndarray, w: np.ndarray, degree: int, scale: float, omega: float = 0.0) -> Segment | None:
    """The constant, line (degree 0, 1) or constant plus sinusoid of ``omega`` (degree -1) through the
    taps ``w`` at samples ``k``, if it fits to FIT_TOL."""
    s, e = int(k[0]), int(k[-1])
    if degree == 0:
        g = Segment(s, e, float(np.mean(w)))
    else:
        probe = Segment(s, e, 0.0, omega=omega if degree < 0 else 0.0)
        X = np.vstack([np.ones(k.size), probe.basis()]).T
        c = np.linalg.lstsq(X, w, rcond=None)[0]
        g = Segment(s, e, float(c[0]), float(c[1]), float(c[2]) if degree < 0 else 0.0, probe.omega)
    if np.max(np.abs(g.weights() - w)) > FIT_TOL * scale:
        return None
    return g


def sparse_from_parts(entries: list[tuple[int, float]], parts: list[tuple[int, np.ndarray, object, float]],
                      target: float) -> SparseTaps:
    """Sparse taps from impulse taps ``entries`` and distributed ``parts`` ``(k0, w, part, Ts)``.

    Runs of at least :data:`MIN_SEGMENT` taps inside a polynomial piece of a single
    uniform, decreasing or triangular kernel (two samples clear of its breakpoints,
    and from sample 1 on, so the undelayed tap stays a sparse one) become segments;
    the rest are sparse taps.  The largest tap absorbs the rounding so that the
    taps sum to ``target`` (the static gain), as :func:`discretize` does.
    """
    idx = [k for k, _ in entries]
    val = [w for _, w in entries]
    segs: list[Segment] = []
    for k0, w, part, Ts in parts:
        used = np.zeros(w.size, dtype=bool)
        kernels = getattr(part, "kernels")
        if len(kernels) == 1 and kernels[0].shape in _DEGREE:
            pts = sorted({b / Ts for b in _pieces(part)})
            scale = float(np.max(np.abs(w))) if w.size else 0.0
            for a, b in zip(pts[:-1], pts[1:]):
                lo, hi = max(math.ceil(a) + 2, 1, k0), min(math.floor(b) - 2, k0 + w.size - 1)
                if hi - lo + 1 < MIN_SEGMENT:
                    continue
                k = np.arange(lo, hi + 1)
                g = _fit(k, w[k - k0], _DEGREE[kernels[0].shape], scale, 2.0 * math.pi * Ts / kernels[0].T)
                if g is not None:
                    segs.append(g)
                    used[k - k0] = True
        rest = np.flatnonzero(~used & (w != 0))
        idx += (rest + k0).tolist()
        val += w[rest].tolist()
    index, inv = np.unique(np.asarray(idx, dtype=np.int64), return_inverse=True)
    weight = np.bincount(inv.ravel(), weights=np.asarray(val, dtype=float), minlength=index.size)
    keep = weight != 0.0
    index, weight = index[keep], weight[keep]
    out = SparseTaps(index, weight, tuple(segs))
    err = target - out.total
    if err != 0.0 and index.size:
        weight[int(np.argmax(np.abs(weight)))] += err
    index.flags.writeable = False
    weight.flags.writeable = False
    return out


def _pieces(part: object) -> list[float]:
    delay, end = getattr(part, "delay"), getattr(part, "end")
    k = getattr(part, "kernels")[0]
    return [delay, end] + ([delay + k.T / 2.0] if k.shape == "triangular" else [])


# ---------------------------------------------------------------------- stability of the inverse
class InverseStability(NamedTuple):
    """Stability of the inverse recursion ``1 / S_d(z)``: the zeros of ``S_d`` are its poles."""

    verdict: str              #: "stable", "marginal" (zeros on |z| = 1 to MARGINAL_TOL) or "unstable"
    spectral_radius: float    #: largest |zero| of S_d(z) = sum_k w_k z^-k
    sample_rate: float
    resolution: float = 0.0   #: the radius is known to this (nonzero where the FFT grid limits it)

    @property
    def decay_per_second(self) -> float:
        """``ln(spectral_radius) * sample_rate``: the inverse's slowest decay rate (>0 grows) [1/s]."""
        return math.log(self.spectral_radius) * self.sample_rate if self.spectral_radius > 0 else -math.inf

    def __str__(self) -> str:
        res = f" +- {self.resolution:.1g}" if self.resolution else ""
        return (f"inverse {self.verdict}: spectral radius {self.spectral_radius:.12g}{res} at {self.sample_rate:g} Hz "
                f"(decay {self.decay_per_second:.4g} 1/s)")


def _outside(w: np.ndarray, r: float) -> int | None:
    """Zeros of ``sum_k w_k z^-k`` with ``|z| > r`` (winding number on ``|z| = r``), None if unresolved.

    The FFT grid is refined until the phase moves by less than pi/4 between points
    (up to :data:`_FFT_MAX` points); a zero at rounding distance from the circle is unresolved.
    """
    K = w.size - 1
    with np.errstate(over="ignore", under="ignore"):
        a = w * np.exp(-np.arange(K + 1) * math.log(r))  # w_k r^-k
    if not np.all(np.isfinite(a)):
        return None
    n = 1 << max(12, int(math.ceil(math.log2(8 * (K + 1)))))
    while n <= _FFT_MAX:
        f = np.fft.fft(a, n)
        if np.min(np.abs(f)) <= 1e-13 * np.sum(np.abs(a)):
            return None
        ph = np.unwrap(np.angle(np.append(f, f[0])))
        if np.max(np.abs(np.diff(ph))) < math.pi / 4:
            # f(w) = sum a_k e^{-j w k} = S_d(r e^{jw}): its winding number is (#zeros inside r) - K
            return -int(round((ph[-1] - ph[0]) / (2 * math.pi)))
        n *= 4
    return None


def inverse_stability(taps: np.ndarray, sample_rate: float) -> InverseStability:
    """Spectral radius of ``1 / S_d(z)`` for the dense FIR taps ``w_0 .. w_K`` (``w_0 != 0``).

    Up to degree 400 the zeros come from ``np.roots``.  Above (long shapers at high
    rates) the radius is bracketed by winding numbers of ``S_d`` on circles ``|z| = r``
    (FFT; bisection from the geometric mean of the zero moduli to 1e-9 relative) until
    a circle passes closer to a zero than the finest grid resolves (``resolution``
    1.2e-5, a few steps of a 2^22-point grid).  Zeros that close to the unit circle
    (an inverse that forgets slower than about ``1.2e-5 fs`` per second, e.g. a
    0.05 Hz mode at 10 kHz) give the verdict "marginal".

    >>> round(inverse_stability(np.array([0.5, 0.0, 0.5]), 100.0).spectral_radius, 12)   # ZV, zeta = 0
    1.0
    >>> inverse_stability(np.array([0.5, 0.0, 0.5]), 100.0).verdict
    'marginal'
    """
    w = v.strict_real_array(taps, "taps", allow_empty=True)
    if w.ndim != 1:
        raise ValueError(f"taps must be 1-D, got shape {w.shape}")
    v.positive(sample_rate, "sample_rate")
    w = np.trim_zeros(w, "b")
    if w.size == 0 or w[0] == 0.0:
        raise ValueError("taps must start with a nonzero undelayed tap w_0 (the inverse needs it: 1/S is not causal)")
    if w.size == 1:
        return InverseStability("stable", 0.0, sample_rate)
    if w.size - 1 <= _ROOTS_MAX:
        rho = float(np.max(np.abs(np.roots(w))))
    else:
        K = w.size - 1
        # the product of the K zero moduli is |w_K / w_0|: the largest is at least their geometric mean
        lo = max(math.exp((math.log(abs(w[-1])) - math.log(abs(w[0]))) / K), math.exp(-600.0 / K))
        hi = 1.0 + float(np.sum(np.abs(w[1:])) / abs(w[0]))        # Cauchy bound: every zero below it
        at_one = _outside(w, 1.0)
        res = 0.0
        if at_one is None:   # a zero on the unit circle to the grid's resolution: marginal for this filter
            lo = hi = 1.0
            res = _RESOLUTION
        elif at_one == 0:
            hi = 1.0
        else:
            lo = max(lo, 1.0)
        while hi - lo > 1e-9 * hi:
            mid = 0.5 * (lo + hi)
            out = _outside(w, mid)
            if out is None:   # a zero on (or closer than the grid resolves to) the circle |z| = mid
                lo = hi = mid
                res = _RESOLUTION
                break
            if out == 0:
                hi = mid
            else:
                lo = mid
        rho = hi
        tol = max(MARGINAL_TOL, res)
        verdict = "marginal" if abs(rho - 1.0) <= tol else ("stable" if rho < 1.0 else "unstable")
        return InverseStability(verdict, rho, sample_rate, res)
    verdict = "marginal" if abs(rho - 1.0) <= MARGINAL_TOL else ("stable" if rho < 1.0 else "unstable")
    return InverseStability(verdict, rho, sample_rate)


# ---------------------------------------------------------------------- the filter
class SparseEngine:
    """The streaming arithmetic: forward ``y = S x`` or inverse ``m = x / S`` on sparse taps and segments.

    Samples are numbered from 0; the history before sample 0 is ``initial`` (the
    input for the forward filter, the steady output ``initial / S_d(1)`` for the
    inverse).  Output depends only on the input, never on how it is chunked.
    """

    def __init__(self, sp: SparseTaps, inverse: bool, initial: float, resync: int | None = None) -> None:
        self.sp = sp
        self.inverse = inverse
        span = sp.span + 1
        self.size = 1 << int(math.ceil(math.log2(2 * span + 2 + 8192)))  # blocks of >= 8192 samples
        self.mask = self.size - 1
        self.resync = resync or max(65536, 4 * span)
        k = sp.index
        if inverse:
            if k.size == 0 or k[0] != 0:
                raise ValueError("the inverse needs a nonzero undelayed tap w_0 (1/S is not causal)")
            self.w0 = float(sp.weight[0])
            self.taps = list(zip(k[1:].tolist(), sp.weight[1:].tolist()))
            firsts = [t for t, _ in self.taps] + [g.start for g in sp.segments]
            self.block = min(firsts) if firsts else self.size
        else:
            self.taps = list(zip(k.tolist(), sp.weight.tolist()))
            self.block = self.size - span
        self.reset(initial)

    def reset(self, initial: float) -> None:
        hist = initial / self.sp.total if self.inverse else initial
        self.ring = np.full(self.size, hist)
        self.n = 0
        self.M = [self._exact(g, -1) for g in self.sp.segments]
        self._rot = [complex(np.exp(1j * g.omega)) for g in self.sp.segments]
        self._rot_end = [complex(np.exp(1j * g.omega * (g.stop - g.start + 1))) for g in self.sp.segments]
        self._zrot: list[Any] = [None] * len(self.sp.segments)

    def _exact(self, g: Segment, n: int) -> tuple[float, Any]:
        """``(M0, M1)`` (``M1`` complex, the rotating sum, for a sinusoidal segment) summed exactly."""
        vals = self.ring[(n - np.arange(g.start, g.stop + 1)) & self.mask]
        b = g.basis()
        if g.omega:
            return math.fsum(vals), complex(math.fsum(b[0] * vals), math.fsum(b[1] * vals))
        return math.fsum(vals), (math.fsum(b[0] * vals) if g.c1 != 0.0 else 0.0)

    def _segments(self, n0: int, B: int) -> np.ndarray:
        """Sum of the segments' outputs for samples ``n0 .. n0 + B - 1`` (ring holds what they read)."""
        y = np.zeros(B)
        pos = n0 + np.arange(B)
        cut = [j for j in range((-n0) % self.resync, B, self.resync) if n0 + j > 0]
        bounds = [0] + cut + [B]
        for gi, g in enumerate(self.sp.segments):
            m0, m1 = self.M[gi]
            M0, M1 = np.empty(B), np.empty(B)
            for a, b in zip(bounds[:-1], bounds[1:]):
                if a == b:
                    continue
                if a in cut:  # exact resynchronisation at an absolute multiple of `resync`
                    m0, m1 = self._exact(g, n0 + a)
                    M0[a] = m0
                    if g.omega:
                        M1[a] = g.c1 * m1.real + g.c2 * m1.imag
                        self._zrot[gi] = None  # restart the rotation from the exact sum
                    else:
                        M1[a] = m1
                    a += 1
                    if a == b:
                        continue
                p = pos[a:b]
                xs = self.ring[(p - g.start) & self.mask]
                xe = self.ring[(p - g.stop - 1) & self.mask]
                M0[a:b] = np.cumsum(np.concatenate(([m0], xs - xe)))[1:]
                if g.omega:  # Mc[n] = r Mc[n-1] + x[n-s] - r^(L+1) x[n-1-e]; the state is lfilter's own
                    r = self._rot[gi]
                    u = xs - self._rot_end[gi] * xe
                    zi = self._zrot[gi] if self._zrot[gi] is not None else np.array([r * m1])
                    Mc, self._zrot[gi] = signal.lfilter([1.0], [1.0, -r], u, zi=zi)
                    M1[a:b] = g.c1 * Mc.real + g.c2 * Mc.imag
                    m1 = Mc[-1]
                elif g.c1 != 0.0:
                    prev = np.concatenate(([m0], M0[a: b - 1]))
                    M1[a:b] = np.cumsum(np.concatenate(([m1], (prev - xe) / g.length - xe)))[1:]
                else:
                    M1[a:b] = 0.0
                m0, m1 = float(M0[b - 1]), float(M1[b - 1])
            self.M[gi] = (m0, m1)
            y = y + (g.c0 * M0 + M1) if g.omega else y + (g.c0 * M0 + g.c1 * M1)
        return y

    def _delayed(self, n0: int, B: int) -> np.ndarray:
        pos = n0 + np.arange(B)
        y = np.zeros(B)
        for k, w in self.taps:
            y = y + w * self.ring[(pos - k) & self.mask]
        return y + self._segments(n0, B) if self.sp.segments else y

    def process(self, x: np.ndarray) -> np.ndarray:
        out = np.empty(x.size)
        i = 0
        while i < x.size:
            B = min(self.block, x.size - i)
            n0 = self.n
            slots = (n0 + np.arange(B)) & self.mask
            if self.inverse:
                m = (x[i: i + B] - self._delayed(n0, B)) / self.w0   # seed 000 eq. 19-20 on the grid
                self.ring[slots] = m
                out[i: i + B] = m
            else:
                self.ring[slots] = x[i: i + B]
                out[i: i + B] = self._delayed(n0, B)
            self.n += B
            i += B
        return out
