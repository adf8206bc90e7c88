"""A shaper as it runs on a controller: discrete taps at a sample rate, streaming and batch filtering.

A continuous-time shaper ``S`` (lumped impulses, distributed delays, optionally an
IIR remainder) is turned into a discrete filter at the sample period ``Ts``:

* **lumped impulses** ``A_i delta(t - t_i)`` with ``t_i = (n_i + f_i) Ts``:

  - ``fractional="linear"`` (default): split between samples ``n_i`` and
    ``n_i + 1`` with weights ``A_i (1 - f_i)`` and ``A_i f_i`` (linear-interpolation
    fractional delay; keeps the DC gain and, to first order, the zero);
  - ``fractional="lagrange3"``: cubic Lagrange fractional delay, 4 taps per impulse
    at ``n_i - 1 .. n_i + 2`` (exact for cubic inputs; the zero moves by
    ``O((|p| Ts)^4)`` instead of ``O((|p| Ts)^2)``);
  - ``fractional="round"``: the whole impulse on the nearest sample (for comparison).

* **distributed parts** ``w k(t - t0)``: tap ``k`` is the exact integral of the delay
  density against the linear-interpolation hat function centred on ``k Ts``
  (``"round"``: against the box ``[k Ts - Ts/2, k Ts + Ts/2)``), so a linearly
  interpolated input is reproduced exactly and the taps sum to ``w``.  The
  integrals are taken piecewise between the grid points and the kernel's
  breakpoints with 16-point Gauss-Legendre rules (exact for the polynomial
  kernels, to rounding for the cosine kernel).

* an **IIR remainder** (``S.continuous``, e.g. the notch of seed 001 eq. 13) is
  discretised with the bilinear (Tustin) transform prewarped at the shaper's mode
  frequency (``scipy.signal.cont2discrete`` with the prewarped step
  ``2 tan(omega Ts / 2) / omega``) and runs in parallel with the FIR part.

The FIR taps are corrected at rounding level so that taps plus IIR DC gain equal
``S.dc_gain``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import signal

from posicast import _validate as v
from posicast.shapers.base import Shaper

from .sparse import InverseStability, SparseEngine, SparseTaps, inverse_stability, sparse_from_parts
from .taps import GRID_TOL, impulse_taps, iir_section, part_taps, prewarped_step

__all__ = [
    "DiscreteShaper",
    "ShaperFilter",
    "discretize",
    "shape_signal",
    "shortest_delay",
    "prewarped_step",
    "FRACTIONAL",
]

FRACTIONAL = ("linear", "lagrange3", "round")

# Most FIR taps a discretisation may produce (80 MB of taps; the filter state is as long).
MAX_TAPS = 10_000_000


@dataclass(frozen=True, eq=False)
class DiscreteShaper:
    """A shaper discretised at ``sample_rate``: FIR taps plus an optional parallel IIR section.

    ``y[n] = sum_k taps[k] x[n - k] + (b / a)(z) x[n]`` (``b``, ``a`` in powers of
    ``z^-1``, ``a[0] = 1``; both None for a shaper without IIR part).

    Attributes
    ----------
    shaper : Shaper
        The continuous-time design.
    sample_rate : float
        Samples per second.
    fractional : str
        How lumped delays between samples were realised (see :data:`FRACTIONAL`).
    taps : ndarray
        FIR weights ``w_k``, ``k = 0 .. N-1``.
    b, a : ndarray or None
        The IIR section.
    sparse : SparseTaps
        The same FIR part as sparse taps ``(index, weight)`` plus running-sum segments
        (:mod:`posicast.simulation.sparse`): what :class:`ShaperFilter` runs.
    """

    shaper: Shaper
    sample_rate: float
    fractional: str
    taps: np.ndarray
    b: np.ndarray | None = None
    a: np.ndarray | None = None
    sparse: SparseTaps | None = None

    def __post_init__(self) -> None:
        if self.sparse is None:  # built from bare taps: every nonzero tap is a sparse one
            k = np.flatnonzero(self.taps)
            object.__setattr__(self, "sparse", SparseTaps(k.astype(np.int64), np.asarray(self.taps, float)[k]))

    def inverse_stability(self) -> InverseStability:
        """Stability of the inverse ``1 / S_d(z)`` on this grid (the zeros of ``S_d``), see
        :func:`posicast.simulation.sparse.inverse_stability`."""
        if self.b is not None:
            raise ValueError(f"the inverse of {self.shaper.name!r} is not a delay recursion (it has an IIR part)")
        return inverse_stability(self.taps, self.sample_rate)

    @property
    def sample_period(self) -> float:
        return 1.0 / self.sample_rate

    @property
    def n_taps(self) -> int:
        return int(self.taps.size)

    @property
    def dc_gain(self) -> float:
        """``sum(taps)`` plus the IIR section's DC gain ``sum(b) / sum(a)``."""
        g = float(self.taps.sum())
        if self.b is not None and self.a is not None:
            g += float(self.b.sum() / self.a.sum())
        return g

    @property
    def residual(self) -> float:
        """Residual vibration left by the discretisation: ``max |S_d(exp(p Ts))| / |S_d(1)|`` over the design modes.

        0 for a z-plane design on this grid (seed 002 eq. 8); for a continuous design
        whose delays fall between samples the fractional taps leave this much (``nan``
        for a shaper without modes).

        >>> import posicast as pc
        >>> m = pc.Mode.from_hz(28.0, 0.05)
        >>> round(discretize(pc.design("zv", m), 100.0).residual, 4)     # seed 002's mode at 10 ms
        0.1277
        """
        if not self.shaper.modes:
            return math.nan
        dc = abs(complex(self._eval(np.array([1.0 + 0j]))[0]))
        vals = [abs(complex(self._eval(np.array([np.exp(m.pole * self.sample_period)]))[0])) for m in self.shaper.modes]
        return max(vals) / dc if dc > 0 else math.inf

    def __call__(self, z: Any) -> Any:
        """The discrete transfer function ``S_d(z)`` at complex ``z`` (``z = exp(s Ts)``, nonzero, finite).

        >>> import posicast as pc
        >>> complex(discretize(pc.design("zv", pc.Mode(10.0, 0.0)), 100.0)(1.0))   # DC gain
        (1+0j)
        """
        z_arr = v.complex_array(z, "z")
        if np.any(z_arr == 0):
            raise ValueError("z must be nonzero (S_d has its poles at z = 0)")
        return self._finish(self._eval(z_arr), z_arr, "z")

    def _eval(self, z_arr: np.ndarray) -> np.ndarray:
        with np.errstate(all="ignore"):
            zi = 1.0 / z_arr
            out = np.polynomial.polynomial.polyval(zi, self.taps)
            if self.b is not None and self.a is not None:
                out = out + np.polynomial.polynomial.polyval(zi, self.b) / np.polynomial.polynomial.polyval(zi, self.a)
        return out

    @staticmethod
    def _finish(out: Any, arg: np.ndarray, name: str) -> Any:
        if not np.all(np.isfinite(out)):
            bad = complex(arg.reshape(-1)[int(np.flatnonzero(~np.isfinite(np.reshape(out, -1)))[0])])
            raise ValueError(f"{name} = {bad:.6g}: S_d overflows the float range there ({name} too far from |z| = 1)")
        return out if arg.ndim else complex(out)

    def at_s(self, s: Any) -> Any:
        """``S_d(exp(s Ts))``: e.g. the residual vibration ``|S_d(p)|`` of a mode pole ``p``."""
        s_arr = v.complex_array(s, "s")
        with np.errstate(all="ignore"):
            z = np.exp(s_arr * self.sample_period)
            out = self._eval(z)
        return self._finish(out, s_arr, "s")

    def __repr__(self) -> str:
        iir = f", IIR order {self.a.size - 1}" if self.a is not None else ""
        return (
            f"DiscreteShaper({self.shaper.name!r}, {self.sample_rate:g} Hz, {self.fractional}, "
            f"{self.n_taps} taps{iir}, residual {self.residual:.3g})"
        )


# ---------------------------------------------------------------------- validation
def _check_shaper(S: Any) -> Shaper:
    if not isinstance(S, Shaper):
        raise TypeError(f"S must be a posicast Shaper (from posicast.design), got {type(S).__name__}")
    return S


def _check_fractional(fractional: Any) -> str:
    return v.choice(fractional, "fractional", FRACTIONAL)


def shortest_delay(S: Shaper) -> float:
    """The shaper's first nonzero delay: smallest positive impulse time, part delay or kernel length.

    ``inf`` for a shaper without any delay (e.g. the pure IIR notch).

    >>> import posicast as pc
    >>> round(shortest_delay(pc.design("zv", pc.Mode(10.0, 0.0))), 6)     # pi / 10
    0.314159
    """
    S = _check_shaper(S)
    cands = [float(t) for t in S.times if t > 0]
    for p in S.distributed:
        if p.delay > 0:
            cands.append(p.delay)
        cands += [k.T for k in p.kernels]
    return min(cands) if cands else math.inf


def _fir_span(S: Shaper) -> float:
    """Length [s] of the FIR part: the last impulse or the end of the last distributed part."""
    return max([float(t) for t in S.times] + [float(p.end) for p in S.distributed] + [0.0])


def _check_rate(S: Shaper, sample_rate: Any) -> float:
    fs = v.positive(sample_rate, "sample_rate")
    n_taps = _fir_span(S) * fs + 4
    v.refuse_large(n_taps, MAX_TAPS, f"discretising the {S.name} shaper ({_fir_span(S):.4g} s long) at "
                   f"sample_rate = {fs:g} Hz", f"use a lower sample_rate (at most {MAX_TAPS / max(_fir_span(S), 1e-300):.4g} Hz)",
                   "taps")
    nyq = fs / 2.0
    for m in S.modes:
        if m.freq_hz >= nyq:
            raise ValueError(
                f"sample_rate = {fs:g} Hz is too low for the shaper's mode at {m.freq_hz:.6g} Hz "
                f"(above the Nyquist frequency {nyq:g} Hz); sample_rate must be > {2.0 * m.freq_hz:.6g} Hz"
            )
    d = shortest_delay(S)
    if d * fs < 1.0 - GRID_TOL:
        raise ValueError(
            f"sample_rate = {fs:g} Hz is too low for this shaper: its shortest delay {d:.6g} s is below one "
            f"sample ({1.0 / fs:.6g} s); sample_rate must be >= {1.0 / d:.6g} Hz"
        )
    return fs


def discretize(S: Shaper, sample_rate: float, fractional: str = "linear") -> DiscreteShaper:
    """Discretise a shaper at ``sample_rate`` (FIR taps plus an optional IIR section).

    Parameters
    ----------
    S : Shaper
        The continuous-time shaper.
    sample_rate : float
        Samples per second (> 0).  Must resolve the shaper: its shortest delay is at
        least one sample and every design mode lies below the Nyquist frequency.
    fractional : {"linear", "lagrange3", "round"}
        How a lumped delay between samples is realised (see the module docstring).

    Returns
    -------
    DiscreteShaper

    Raises
    ------
    ValueError
        ``sample_rate`` too low (the message names the limit), unknown ``fractional``,
        or an IIR part with delays.
    TypeError
        ``S`` is not a Shaper.

    Examples
    --------
    >>> import posicast as pc
    >>> D = discretize(pc.design("zv", pc.Mode(10.0, 0.0)), 100.0)
    >>> D.n_taps, [round(float(w), 4) for w in D.taps[[0, 31, 32]]]   # 0.5 at pi/10 s = 31.42 samples
    (33, [0.5, 0.292, 0.208])
    >>> round(D.dc_gain, 15)
    1.0
    """
    S = _check_shaper(S)
    fractional = _check_fractional(fractional)
    fs = _check_rate(S, sample_rate)
    Ts = 1.0 / fs
    entries: list[tuple[int, float]] = []
    for t, amp in zip(S.times, S.amplitudes):
        entries += impulse_taps(float(t) * fs, float(amp), fractional)
    parts = [part_taps(p, Ts, fractional) for p in S.distributed]
    n = max([k for k, _ in entries] + [k0 + w.size - 1 for k0, w in parts] + [0]) + 1
    taps = np.zeros(n)
    for k, w in entries:
        taps[k] += w
    for k0, w in parts:
        taps[k0 : k0 + w.size] += w
    b, a = iir_section(S, Ts)
    # DC gain: FIR taps + IIR DC equal S.dc_gain (fix the rounding on the largest tap)
    target = float(S.amplitudes.sum()) + sum(p.weight for p in S.distributed)
    err = target - float(taps.sum())
    if err != 0.0 and n:
        taps[int(np.argmax(np.abs(taps)))] += err
    while taps.size > 1 and taps[-1] == 0.0:
        taps = taps[:-1]
    taps.flags.writeable = False
    sp = sparse_from_parts(entries, [(k0, w, p, Ts) for (k0, w), p in zip(parts, S.distributed)], target)
    return DiscreteShaper(S, fs, fractional, taps, b, a, sp)


# ---------------------------------------------------------------------- filtering
def _check_chunk(x: Any, name: str) -> np.ndarray:
    if isinstance(x, (str, bytes)) or x is None:
        raise TypeError(f"{name} must be a 1-D array of real numbers, got {type(x).__name__}")
    try:
        arr = np.asarray(x)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be a 1-D array of real numbers") from exc
    if arr.dtype.kind not in "iuf":
        if arr.dtype.kind == "O":
            arr = v.strict_real_array(arr, name, allow_empty=True)
        else:
            raise TypeError(f"{name} must be a 1-D array of real numbers, got dtype {arr.dtype}")
    arr = np.asarray(arr, dtype=float)
    if arr.ndim != 1:
        raise ValueError(f"{name} must be 1-D, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = int(np.flatnonzero(~np.isfinite(arr))[0])
        raise ValueError(f"{name} must be finite (no NaN or inf); sample {bad} is {arr[bad]}")
    return arr


class ShaperFilter:
    """A stateful discrete shaper (or its inverse) for real-time use: feed samples, get shaped samples.

    Runs the sparse form of the discretised shaper (:mod:`posicast.simulation.sparse`):
    O(number of impulses) per sample for lumped shapers, O(1) per distributed kernel
    of uniform, decreasing or triangular shape (running sums, seed 000 eq. 20); the
    cost per sample does not grow with the shaper's duration.  Output equals
    :func:`shape_signal` on the concatenated input, however the input is split.

    Parameters
    ----------
    S : Shaper or DiscreteShaper
        The shaper (discretised here at ``sample_rate``), or an already discretised one.
    sample_rate : float
        Samples per second (ignored, but checked for agreement, for a DiscreteShaper).
    fractional : {"linear", "lagrange3", "round"}
        Realisation of fractional delays (see :func:`discretize`).
    initial : float
        The input is taken as constant ``initial`` before the first sample (steady
        state), so a machine resting at ``initial`` does not jump.
    inverse : bool
        Run ``1 / S_d(z)`` instead: ``m[n] = (x[n] - sum_{k>=1} w_k m[n-k]) / w_0``, seed
        000 eq. 19 (inverse ZV) and eq. 20 (inverse DZV) on the sample grid.  Its
        stability (the zeros of ``S_d``) is checked first, see :attr:`stability`.
    allow_marginal : bool
        Accept an inverse whose spectral radius is 1 to ``1e-9`` (the neutral inverse
        ZV of an undamped mode on the grid): it neither decays nor grows.

    Raises
    ------
    ValueError
        ``inverse=True`` for a shaper whose inverse is unstable (the message states the
        spectral radius), marginal (unless ``allow_marginal``), has an IIR part or no
        undelayed tap.

    Examples
    --------
    >>> import posicast as pc
    >>> f = ShaperFilter(pc.design("zv", pc.Mode(10.0, 0.0)), 100.0)
    >>> [round(f.push(1.0), 4) for _ in range(33)][-3:]
    [0.5, 0.792, 1.0]
    >>> f.reset(); f.process([0.0, 0.0]).tolist()
    [0.0, 0.0]
    >>> S = pc.design("zv", pc.Mode(10.0, 0.1))
    >>> g = ShaperFilter(S, 100.0, inverse=True)
    >>> x = [0.0, 1.0, 3.0, -2.0] * 10
    >>> g.stability.verdict, bool(np.allclose(g.process(shape_signal(S, x, 100.0)), x, atol=1e-13))   # 1/S undoes S
    ('stable', True)
    """

    def __init__(
        self,
        S: Shaper | DiscreteShaper,
        sample_rate: float,
        fractional: str = "linear",
        initial: float = 0.0,
        inverse: bool = False,
        allow_marginal: bool = False,
    ) -> None:
        _check_fractional(fractional)
        self._initial = v.finite_real(initial, "initial")
        self.inverse = v.instance_of(inverse, bool, "inverse", "True or False")
        v.instance_of(allow_marginal, bool, "allow_marginal", "True or False")
        if isinstance(S, DiscreteShaper):
            fs = v.positive(sample_rate, "sample_rate")
            if not math.isclose(fs, S.sample_rate, rel_tol=1e-12):
                raise ValueError(
                    f"sample_rate = {fs:g} Hz differs from the DiscreteShaper's {S.sample_rate:g} Hz"
                )
            self.discrete = S
        else:
            self.discrete = discretize(S, sample_rate, fractional)
        self.stability: InverseStability | None = None
        if self.inverse:
            st = self.discrete.inverse_stability()
            name = self.discrete.shaper.name
            if st.verdict == "unstable" or (st.verdict == "marginal" and not allow_marginal):
                hint = " (pass allow_marginal=True to run it anyway)" if st.verdict == "marginal" else ""
                raise ValueError(f"the inverse of the {name!r} shaper at {self.sample_rate:g} Hz is {st.verdict}: "
                                 f"S_d(z) has a zero of modulus {st.spectral_radius:.12g}{hint}")
            self.stability = st
        sp = self.discrete.sparse
        assert sp is not None
        self._engine = SparseEngine(sp, self.inverse, self._initial)
        self.reset()

    @property
    def sample_rate(self) -> float:
        return self.discrete.sample_rate

    @property
    def taps(self) -> np.ndarray:
        return self.discrete.taps

    def reset(self, initial: float | None = None) -> None:
        """Forget the past input (back to steady state at ``initial``, default the constructor's)."""
        x0 = self._initial if initial is None else v.finite_real(initial, "initial")
        d = self.discrete
        self._engine.reset(x0)
        if d.b is not None and d.a is not None:
            self._zi = signal.lfilter_zi(d.b, d.a) * x0
        else:
            self._zi = None

    def process(self, chunk: Any) -> np.ndarray:
        """Shape a chunk of consecutive samples (any length, including 0); returns the shaped chunk."""
        x = _check_chunk(chunk, "chunk")
        if x.size == 0:
            return np.zeros(0)
        y = self._engine.process(x)
        if self._zi is not None:
            d = self.discrete
            yi, self._zi = signal.lfilter(d.b, d.a, x, zi=self._zi)
            y = y + yi
        return np.asarray(y, dtype=float)

    def push(self, sample: float) -> float:
        """Shape one sample."""
        x = v.finite_real(sample, "sample")  # TypeError / ValueError (NaN, inf) naming "sample"
        return float(self.process(np.array([x]))[0])

    def __repr__(self) -> str:
        kind = "inverse " if self.inverse else ""
        return f"ShaperFilter({kind}{self.discrete!r})"


def _dense_shape(D: DiscreteShaper, x: np.ndarray) -> np.ndarray:
    """The dense convolution with every tap (the filter before issue #16; kept for the benchmark)."""
    y = signal.lfilter(D.taps, [1.0], x)
    return y + signal.lfilter(D.b, D.a, x) if D.b is not None and D.a is not None else y


def shape_signal(S: Shaper | DiscreteShaper, x: Any, sample_rate: float, fractional: str = "linear",
                 inverse: bool = False, allow_marginal: bool = False) -> np.ndarray:
    """Shape a whole sampled signal ``x`` (taken as zero before its first sample).

    The batch counterpart of :class:`ShaperFilter`: same discretisation, same
    arithmetic, so the streaming output equals this one however the input is chunked.

    Parameters
    ----------
    S : Shaper or DiscreteShaper
    x : array_like
        1-D finite samples at ``sample_rate``.
    sample_rate : float
    fractional : {"linear", "lagrange3", "round"}
    inverse, allow_marginal : bool
        Apply ``1 / S`` instead (see :class:`ShaperFilter`).

    Returns
    -------
    ndarray
        The shaped samples, same length as ``x``.

    Examples
    --------
    >>> import posicast as pc
    >>> y = shape_signal(pc.design("zv", pc.Mode(10.0, 0.0)), [1.0] * 40, 100.0)
    >>> float(y[0]), round(float(y[-1]), 12)
    (0.5, 1.0)
    """
    x = _check_chunk(x, "x")  # the input first: nothing is designed for a bad signal
    return ShaperFilter(S, sample_rate, fractional, inverse=inverse, allow_marginal=allow_marginal).process(x)
