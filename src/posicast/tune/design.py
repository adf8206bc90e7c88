"""One-call robust fixed-structure controller design for loops with shapers (seed 001, Algorithm 1).

``tune_pd``, ``tune_pi`` and ``tune_pid`` follow seed 001 section 3:

1. the shaper ``S`` is given (step 1 of Algorithm 1);
2. the loop of the chosen architecture is formed, ``L = C P`` with ``P = G``,
   ``S G`` or ``G / S`` (eq. 5; step 2);
3. the requirements are H-infinity constraints ``||W X||_inf < gamma``
   (eq. 6-7), by default ``||S||_inf < Ms`` (eq. 14-15; step 3);
4. their regions in the gain plane are computed exactly per scan line and
   intersected with the stability region of the infinite-dimensional loop
   (D-decomposition plus one certified spectrum check per component; steps 4-5);
5. the point with the largest integral gain is chosen (eq. 8: minimum integral
   error; for a PD, maximum ``Kp`` through eq. 16; step 6) and verified
   independently: spectrum (:meth:`Loop.stability`) and peak sensitivity from
   the loop's own channels.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Mapping, Sequence

import numpy as np

from .. import _validate as v
from ..core.quasipoly import QuasiPolynomial
from ..core.transfer import TransferFunction, as_transfer
from ..loops import ARCHITECTURES, Loop
from .constraints import Constraint, sensitivity_constraint
from . import family as family_mod
from .family import ControllerFamily, pd_family, pi_family, pid_family
from .frequency import FrequencyData
from .regions import LineData, Region, _Components, _Engine, _interval_point, join_lines

__all__ = ["TuningResult", "tune", "tune_pd", "tune_pi", "tune_pid"]

_PASS1_LINES = 41
_SWEEP_DECADES = 4  # pass 1 sweeps kx over +/- 10^(+/-4) times the natural gain scale


@dataclass(frozen=True)
class TuningResult:
    """A fixed-structure controller chosen from its admissible region, with its checks.

    Attributes
    ----------
    family : ControllerFamily
        The controller structure (``family.describe()``).
    structure : str
        ``'feedforward'``, ``'control_action'`` or ``'inverse_shaper'``.
    gains : Mapping[str, float] or None
        ``{'kp', 'ki', 'kd'}`` of the chosen controller (None if the region is empty).
    controller : TransferFunction or None
    loop : Loop or None
        The closed loop with the chosen controller (and ``F``, if given).
    ms : float
        Achieved peak sensitivity ``||1 / (1 + L)||_inf`` (from the loop's own
        sensitivity, refined in frequency); ``nan`` when empty.
    omega_ms : float
        Where it peaks [rad/s] (``inf``: the high-frequency limit).
    sm : float
        Stability margin ``1 / ms``: the least distance of the Nyquist curve to -1.
    stable : bool
        Certified spectrum check of the chosen loop (issue #3).
    stability : Stability or None
    abscissa : float
        Spectral abscissa of the chosen loop (its exponential decay rate is
        ``-abscissa``); computed on first access.
    norms : tuple of float
        Achieved ``||W X||_inf`` for each constraint, in order.
    active : tuple of bool
        Which constraints hold with equality (to 1e-6 relative) at the chosen point.
    constraints : tuple of Constraint
    region : Region
    empty, unbounded : bool
        No admissible controller; or the maximised gain is not bounded by the
        constraints within the ranges (the point returned is then the best one
        inside them, on a range edge).
    reason : str
        One sentence: why this point, or why nothing.
    timings : Mapping[str, float]
        Seconds spent per stage.
    """

    family: ControllerFamily
    structure: str
    gains: Mapping[str, float] | None
    controller: TransferFunction | None
    loop: Loop | None
    ms: float
    omega_ms: float
    sm: float
    stable: bool
    stability: Any
    norms: tuple[float, ...]
    active: tuple[bool, ...]
    constraints: tuple[Constraint, ...]
    region: Region
    empty: bool
    unbounded: bool
    reason: str
    timings: Mapping[str, float] = field(default_factory=dict)

    @cached_property
    def abscissa(self) -> float:
        """Spectral abscissa of the chosen loop (certified search; ``nan`` if empty or not resolved)."""
        from ..spectra.rootfinder import RootFindingError

        if self.loop is None:
            return math.nan
        try:
            return float(self.loop.spectral_abscissa())
        except (RootFindingError, ValueError):
            return math.nan

    def _gain(self, name: str) -> float | None:
        if self.gains is None:
            return None
        present = name in (self.family.x, self.family.y) or name in self.family.fixed
        return float(self.gains[name]) if present else None

    @property
    def kp(self) -> float | None:
        """Proportional gain (None if the family has none or the region is empty)."""
        return self._gain("kp")

    @property
    def ki(self) -> float | None:
        """Integral gain (None if the family has none or the region is empty)."""
        return self._gain("ki")

    @property
    def kd(self) -> float | None:
        """Derivative gain (None if the family has none or the region is empty)."""
        return self._gain("kd")

    @property
    def point(self) -> tuple[float, float] | None:
        """The chosen ``(kx, ky)`` in the region's plane."""
        if self.gains is None:
            return None
        return float(self.gains[self.family.x]), float(self.gains[self.family.y])

    def plot(self, ax: Any = None, **kwargs: Any) -> tuple[Any, Any]:
        """Regions in the gain plane with the chosen point (seed 001 Fig. 5-6); returns ``(fig, ax)``."""
        from .plots import region_plot

        return region_plot(self, ax=ax, **kwargs)

    def nyquist_plot(self, ax: Any = None, **kwargs: Any) -> tuple[Any, Any]:
        """Nyquist curve of the chosen loop with the Ms circle (seed 001 Fig. 7); returns ``(fig, ax)``."""
        from .plots import tuning_nyquist_plot

        return tuning_nyquist_plot(self, ax=ax, **kwargs)

    def summary(self) -> str:
        """A few lines: controller, achieved norms, stability, region."""
        if self.gains is None:
            what = "unbounded, no design returned" if self.unbounded else "no admissible controller"
            return f"{self.family.describe()} in {self.structure}: {what}. {self.reason}"
        g = ", ".join(f"{k} = {self.gains[k]:.6g}" for k in ("kp", "ki", "kd") if self._gain(k) is not None)
        cons = "; ".join(f"{c.label}: {n:.6g}{' (active)' if a else ''}"
                         for c, n, a in zip(self.constraints, self.norms, self.active))
        return (f"{self.family.describe()} in {self.structure}: {g}\n"
                f"  Ms = {self.ms:.6g} at {self.omega_ms:.4g} rad/s (stability margin {self.sm:.4g}); {cons}\n"
                f"  {'stable' if self.stable else 'UNSTABLE'} (spectral abscissa {self.abscissa:.4g}); {self.reason}")

    def __repr__(self) -> str:
        if self.gains is None:
            return f"TuningResult({self.structure}, {self.family.name}: empty)"
        g = ", ".join(f"{k}={self.gains[k]:.5g}" for k in ("kp", "ki", "kd") if self._gain(k) is not None)
        return f"TuningResult({self.structure}, {self.family.name}: {g}, ms={self.ms:.5g}, stable={self.stable})"


# ---------------------------------------------------------------------- helpers
def _check_structure(structure: Any) -> str:
    return v.choice(structure, "structure", ARCHITECTURES)


def _check_range(r: Any, name: str) -> tuple[float, float] | None:
    if r is None:
        return None
    if isinstance(r, (str, bytes)) or not hasattr(r, "__len__") or len(r) != 2:
        raise TypeError(f"{name} must be a (low, high) pair of numbers, got {type(r).__name__}")
    lo, hi = r
    lo = v.real_in_range(lo, f"{name}[0]", -family_mod.MAX_GAIN, family_mod.MAX_GAIN)
    hi = v.real_in_range(hi, f"{name}[1]", -family_mod.MAX_GAIN, family_mod.MAX_GAIN)
    if not lo < hi:
        raise ValueError(f"{name} must have low < high, got ({lo:g}, {hi:g})")
    return lo, hi


# Coefficients of G, S and F, relative to the largest of their denominator, must lie within these
# magnitudes: the region computation squares and multiplies them over wide frequency grids.
_COEFF_RANGE = (1e-100, 1e100)
# Scan lines: at most MAX_LINES (memory), and pass 2 is refused when its time, estimated from the measured
# cost of a pass-1 line (5 ms to 100 ms a line, depending on the frequency grid the loop's delays need),
# would exceed MAX_SECONDS.
MAX_LINES = 100_001
MAX_SECONDS = 60.0


def _check_scale(tf: TransferFunction, name: str) -> None:
    """Refuse a block whose coefficients span beyond :data:`_COEFF_RANGE` (rescale time or gain units)."""
    scale = max(float(np.max(np.abs(tf.den.coeffs))), 1e-300)
    lo, hi = _COEFF_RANGE
    for q in (tf.num, tf.den):
        if q.is_zero:
            continue
        mags = np.abs(q.coeffs[q.coeffs != 0]) / scale
        if mags.size and (mags.min() < lo or mags.max() > hi):
            raise ValueError(
                f"{name}: its coefficients span {mags.min():.3g} to {mags.max():.3g} relative to the largest "
                f"denominator coefficient, beyond [{lo:g}, {hi:g}]; rescale the time or gain units"
            )


# Largest loop delay times the fastest pole/zero magnitude of the delay-free blocks: beyond this the
# frequency grid cannot resolve the delay's phase over the blocks' dynamics (measured for 1/(s(s+1))
# e^{-s tau}: tau = 1e3 designs in ~35 s, 1e4 ends in ~35 s with a failed independent verification,
# 1e5 runs for minutes, 1e6 and beyond return nonsense).
MAX_DELAY_RATIO = 1e4


def _check_delays(blocks: list[tuple[str, TransferFunction]]) -> None:
    from ..loops import feature_frequencies

    tau = max(tf.max_delay for _, tf in blocks)
    if tau <= 0:
        return
    rates = []
    for _, tf in blocks:
        no_delay = TransferFunction(QuasiPolynomial(tf.num.coeffs), QuasiPolynomial(tf.den.coeffs)) \
            if tf.num.coeffs.shape[0] == 1 and tf.den.coeffs.shape[0] == 1 else None
        if no_delay is not None:
            rates += feature_frequencies([no_delay])
    if not rates:
        return
    ratio = tau * max(rates)
    if ratio > MAX_DELAY_RATIO:
        name = next(n for n, tf in blocks if tf.max_delay == tau)
        raise ValueError(
            f"{name}: its delay {tau:.4g} s is {ratio:.3g} times the fastest time constant of the loop's blocks "
            f"(1 / {max(rates):.4g} rad/s); the frequency grid cannot resolve more than {MAX_DELAY_RATIO:g}: "
            f"use a smaller delay or rescale time"
        )


def _check_blocks(G: Any, S: Any, structure: str, F: Any = None) -> tuple[TransferFunction, Any]:
    Gt = as_transfer(G, "G")
    _check_scale(Gt, "G")
    if Gt.num.is_zero:
        raise ValueError("G is identically zero: nothing to control")
    if Gt.num.degree > Gt.den.degree:
        raise ValueError(
            f"G must be proper (a physical plant): its numerator has degree {Gt.num.degree} > "
            f"denominator degree {Gt.den.degree}"
        )
    if S is not None:
        St = as_transfer(S, "S")
        _check_scale(St, "S")
        if St.num.is_zero:
            raise ValueError("S is identically zero: no signal passes the shaper")
        if St.num.degree > St.den.degree:
            raise ValueError("S must be proper (a shaper is a realisable filter)")
        if structure == "inverse_shaper" and St.num.degree < St.den.degree:
            raise ValueError(
                "the inverse_shaper structure needs 1/S proper: S must be biproper "
                "(every delay shaper and the notch are); this S is strictly proper"
            )
        if structure == "feedforward":
            _check_open_loop_stable(St, "S", "in the feedforward structure it filters w outside the loop")
    if F is not None:
        Ft = as_transfer(F, "F")
        _check_scale(Ft, "F")
        if Ft.num.degree > Ft.den.degree:
            raise ValueError("F must be proper (the flexible load is a physical system)")
        _check_open_loop_stable(Ft, "F", "it acts on the plant output outside the loop")
    _check_delays([("G", Gt)] + ([("S", as_transfer(S, "S"))] if S is not None else []))
    return Gt, S


def _check_open_loop_stable(tf: TransferFunction, name: str, why: str) -> None:
    """Raise if ``tf`` has a pole with ``Re s >= 0`` (removable singularities excepted): a block
    outside the loop that no controller can stabilise."""
    from ..loops import removable_points
    from ..spectra import stability
    from ..spectra.rootfinder import RootFindingError

    if tf.den.degree < 1 and tf.den.is_polynomial:  # a constant (times a delay): no pole
        return
    try:
        st = stability(tf.den, ignore=removable_points(tf.num, tf.den))
    except (RootFindingError, ValueError) as exc:
        raise ValueError(f"{name}: its poles could not be certified ({exc})") from None
    if not st.stable:
        raise ValueError(f"{name} is unstable ({st.reason}); {why}, so no controller can make it stable")


def _scale_estimate(loop0: Loop, family: ControllerFamily) -> tuple[float, float]:
    """Gain magnitudes at which ``|kx a| ~ 1`` and ``|ky b| ~ 1`` near the plant's phase crossover."""
    from ..loops import feature_frequencies
    from .frequency import _poly_tf

    P = loop0.plant_gain
    feats = [f for f in feature_frequencies([P]) if 1e-8 < f < 1e9] or [1.0]
    w = np.geomspace(min(feats) / 30, max(feats) * 30, 600)
    p = np.asarray(P.freqresp(w))
    cx = np.asarray(_poly_tf(family.nx, family.dC).freqresp(w))
    cy = np.asarray(_poly_tf(family.ny, family.dC).freqresp(w))
    a, b = np.abs(cx * p), np.abs(cy * p)
    ph = np.unwrap(np.angle(cy * p))
    ok = np.isfinite(ph) & np.isfinite(a) & np.isfinite(b) & (a > 0) & (b > 0)
    if not np.any(ok):
        return 1.0, 1.0
    w, a, b, ph = w[ok], a[ok], b[ok], ph[ok]
    target = ph[0] - math.pi
    k = np.flatnonzero(ph <= target)
    i = int(k[0]) if k.size else int(np.argmin(np.abs(np.log(b))))
    return 1.0 / a[i], 1.0 / b[i]


class _Tuner:
    def __init__(self, G: TransferFunction, S: Any, structure: str, family: ControllerFamily,
                 constraints: tuple[Constraint, ...], F: Any) -> None:
        self.G, self.S, self.structure, self.family, self.F = G, S, structure, family, F
        self.constraints = constraints
        self.loop0 = Loop(structure, G=G, C=1.0, F=F, S=S)
        P = self.loop0.plant_gain
        dC = QuasiPolynomial.from_poly(np.trim_zeros(family.dC, "f"))

        def qp(desc: np.ndarray) -> QuasiPolynomial:
            t = np.trim_zeros(desc, "f")
            return QuasiPolynomial.from_poly(t) if t.size else QuasiPolynomial.zero()

        self.char_terms = (dC * P.den + qp(family.n0) * P.num, qp(family.nx) * P.num, qp(family.ny) * P.num)
        self.m0 = int(np.count_nonzero(self.loop0.cancelled == 0))

    def loop(self, kx: float, ky: float) -> Loop:
        return Loop(self.structure, G=self.G, C=self.family.controller(kx, ky), F=self.F, S=self.S)


def _hinf_wanted(lines: list[LineData]) -> Any:
    """Mask of the segments of line ``i`` that meet an H-infinity-admissible interval."""

    def wanted(i: int) -> np.ndarray:
        ln = lines[i]
        iv = ln.hinf
        if not iv.size:
            return np.zeros(ln.n_segments, dtype=bool)
        edges = np.concatenate([[-math.inf], ln.breaks, [math.inf]])
        return np.any((iv[None, :, 0] < edges[1:, None]) & (iv[None, :, 1] > edges[:-1, None]), axis=1)

    return wanted


def _build_region(engine: _Engine, family: ControllerFamily, xs: np.ndarray,
                  y_range: tuple[float, float], previous: Region | None = None) -> Region:
    """Scan ``xs``; the cells of ``previous`` whose checked point connects to a new segment
    without crossing a boundary pass their stability label on (no second spectrum check)."""
    lines = engine.lines(xs)
    comps = _Components()
    join_lines(engine, lines, comps, _hinf_wanted(lines))
    if previous is not None and lines:
        old = previous._comps
        seeds = [(old.point[r], lab) for r, lab in old.label.items() if lab is not None and r in old.point]
        if seeds:
            px = np.array([p[0] for p, _ in seeds])
            py = np.array([p[1] for p, _ in seeds])
            idx = np.abs(xs[None, :] - px[:, None]).argmin(axis=1)
            hit = engine.horizontal_crossing(px, xs[idx], py)
            for (_, lab), i, y, h in zip(seeds, idx, py, hit):
                ln = lines[int(i)]
                if h or np.any(ln.breaks == y):
                    continue
                root = comps.find(int(ln.comp[int(np.searchsorted(ln.breaks, y))]))
                if root not in comps.label:
                    comps.label[root] = lab
                    comps.point[root] = (float(xs[int(i)]), float(y))
    return Region(engine, family, lines, comps, y_range)


# ---------------------------------------------------------------------- the design
def tune(
    G: Any,
    family: ControllerFamily,
    S: Any = None,
    structure: str = "control_action",
    constraints: Sequence[Constraint] = (),
    *,
    F: Any = None,
    x_range: Any = None,
    y_range: Any = None,
    n_lines: int = 161,
) -> TuningResult:
    """Generic H-infinity-region design for any :class:`ControllerFamily` (see :func:`tune_pd`).

    ``x_range`` / ``y_range`` bound the scanned and the maximised gain.
    """
    t_start = time.perf_counter()
    structure = _check_structure(structure)
    if not isinstance(family, ControllerFamily):
        raise TypeError(f"family must be a ControllerFamily, got {type(family).__name__}")
    cons = _constraint_tuple(constraints)
    if not cons:
        raise ValueError("no constraint: give ms (e.g. ms=2.0) or constraints=[Constraint(...)]")
    n_lines = v.integer_in_range(n_lines, "n_lines", 11, MAX_LINES)
    Gt, S = _check_blocks(G, S, structure, F)
    xr = _check_range(x_range, f"{family.x}_range")
    yr = _check_range(y_range, f"{family.y}_range")
    tuner = _Tuner(Gt, S, structure, family, cons, F)
    sx, sy = _scale_estimate(tuner.loop0, family)
    # Without a ky_range the maximised gain is searched within +/- 10^4 times its natural scale (the
    # ultimate gain near the plant's phase crossover), as the scan sweeps kx: far beyond every optimum
    # seen, and a region that reaches this window's top is reported as unbounded, not as a design.
    auto_y = yr is None
    if yr is None:
        yr = (-(10.0**_SWEEP_DECADES) * sy, (10.0**_SWEEP_DECADES) * sy)
    timings: dict[str, float] = {}

    # ---- frequency data and pass 1: locate the admissible set on a logarithmic sweep
    # kx = 0 and +/- sx 10^k over eight decades (each line is exact in ky), so a region is found at
    # whatever scale it lies; the grid is made valid for the largest gains scanned.
    t0 = time.perf_counter()
    auto = xr is None
    mags = sx * np.logspace(-_SWEEP_DECADES, _SWEEP_DECADES, 8 * _SWEEP_DECADES + 1)
    sweep = np.concatenate([-mags[::-1], [0.0], mags])
    if auto:
        xs1 = sweep
    else:
        xs1 = np.union1d(np.linspace(xr[0], xr[1], _PASS1_LINES), sweep[(sweep > xr[0]) & (sweep < xr[1])])
    fd = FrequencyData(tuner.loop0, family, cons, scale=(float(np.max(np.abs(xs1))), 4 * sy), limit_for_delays=True)
    nonzero = np.abs(xs1[xs1 != 0])
    fd.refine(fd._scale, small=(float(nonzero.min()) if nonzero.size else sx, sy * 10.0 ** -_SWEEP_DECADES),
              ceiling=fd.delay_ceiling)
    engine = _Engine(fd, tuner.loop, tuner.char_terms, tuner.m0)
    engine.y_window = yr
    weak = _weakly_neutral(engine)
    if weak is not None:  # no gain of this family can help: say so at once, with the reason
        region = Region(engine, family, [], _Components(), yr)
        timings["total"] = time.perf_counter() - t_start
        return _with_timings(_empty(tuner, engine, region, weak), timings)
    # a delay loop's pass-1 grid stops at fd.delay_ceiling (else e^{-s} / (s + 1) would stretch it to
    # 1e9 rad/s for hopeless huge gains): the sweep keeps the lines the grid verifies
    xs1 = xs1[np.abs(xs1) <= engine.x_valid]
    timings["frequency grid"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    region = _build_region(engine, family, xs1, yr)
    best = region.best()
    timings["pass 1"] = time.perf_counter() - t0
    per_line = timings["pass 1"] / max(xs1.size, 1)
    v.refuse_large(per_line * n_lines, MAX_SECONDS, f"scanning n_lines = {n_lines} lines (measured {per_line * 1e3:.3g} ms "
                   f"a line for this loop)", f"use n_lines <= {max(11, int(MAX_SECONDS / per_line))}", "s")

    # ---- pass 2: the best component at full resolution, between the sweep lines around it
    t0 = time.perf_counter()
    unbounded_x = False
    if best is not None:
        comp = region.component_lines(best[0], _interval_point(best[1], best[2]))
        unbounded_x = bool(auto and (comp.min() == 0 or comp.max() == region.x.size - 1))
        a = float(region.x[max(comp.min() - 1, 0)])
        b = float(region.x[min(comp.max() + 1, region.x.size - 1)])
        if xr is not None:
            a, b = max(a, xr[0]), min(b, xr[1])
        ytop = abs(best[2]) if math.isfinite(best[2]) else sy
        fd.refine((max(abs(a), abs(b)), max(ytop, sy)))
        engine.reload()
        region = _build_region(engine, family, np.linspace(a, b, n_lines), yr, region)
    timings["pass 2"] = time.perf_counter() - t0

    # ---- the optimum
    t0 = time.perf_counter()
    result = _optimum(tuner, engine, region, yr, unbounded_x, auto_y)
    timings["optimum and checks"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_start
    return _with_timings(result, timings)


def _with_timings(r: TuningResult, timings: dict[str, float]) -> TuningResult:
    object.__setattr__(r, "timings", dict(timings))
    return r


def _empty(tuner: _Tuner, engine: _Engine, region: Region, reason: str) -> TuningResult:
    nan = math.nan
    return TuningResult(tuner.family, tuner.structure, None, None, None, nan, nan, nan, False, None,
                        tuple(nan for _ in tuner.constraints), tuple(False for _ in tuner.constraints),
                        tuner.constraints, region, True, False, reason)


def _empty_reason(tuner: _Tuner, engine: _Engine, region: Region) -> str:
    fam = tuner.family
    if engine.real_structural:
        return ("every gain leaves a closed-loop pole at s = 0 (the controller's integrator meets a plant "
                "zero at s = 0, or similar): no stabilising controller of this structure exists")
    any_hinf = any(ln.hinf.size and _intersect_any(ln.hinf, region.y_range) for ln in region._lines)
    span = f"{fam.x} in [{region.x[0]:.4g}, {region.x[-1]:.4g}]"
    if not any_hinf:
        return f"no gain with {span} meets {', '.join(c.label for c in tuner.constraints)}"
    fails = f"; {len(engine.stability_failures)} spectrum checks failed" if engine.stability_failures else ""
    return f"gains with {span} meet the constraints, but none of them gives a stable loop{fails}"


def _intersect_any(iv: np.ndarray, yr: tuple[float, float]) -> bool:
    return bool(np.any((iv[:, 0] < yr[1]) & (iv[:, 1] > yr[0])))


def _optimum(tuner: _Tuner, engine: _Engine, region: Region, yr: tuple[float, float],
             unbounded_x: bool, auto_y: bool = False) -> TuningResult:
    """The design: the best admissible piece, refined exactly, and verified independently.

    A point that fails its verification (its own loop's spectrum check, or a
    constraint's norm above its bound) is never returned: the next best lines'
    exact optima are tried instead, and if none verifies, the result is empty
    with that reason.
    """
    fam = tuner.family
    best = region.best()
    if best is None:
        return _empty(tuner, engine, region, _empty_reason(tuner, engine, region))
    i, _, y_top = best
    y_cap = min(yr[1], engine.y_valid)  # the largest ky searched and verified
    if y_top == math.inf or ((auto_y or y_cap < yr[1]) and y_top >= y_cap):
        if y_top == math.inf:
            window = None
        elif y_cap < yr[1]:
            window = f"{y_cap:.4g}, the largest gain the frequency grid verifies"
        else:
            window = f"{y_cap:.4g}, the top of the searched window (10^{_SWEEP_DECADES} x the loop's ultimate-gain scale)"
        return _unbounded(tuner, engine, region, i, window)
    x_best = float(region.x[i])
    y_best, end, bottom = _probe_top(engine, region, i, x_best, with_bottom=True)
    if end is not None and not _is_cut(end):
        x_best, y_best, end = _exact_optimum(engine, region, i, x_best, y_best, bottom, end)

    def candidates() -> Any:
        yield x_best, y_best, end, bottom, i
        # fall-backs, only if the best point fails its verification: the next best lines' tops
        tops = np.array([region.top(k) for k in range(region.x.size)])
        for k in [int(k) for k in np.argsort(-tops) if np.isfinite(tops[k]) and int(k) != i][:8]:
            yield float(region.x[k]), None, None, None, k

    last = None
    for x, y, e, b, line in candidates():
        if y is None:
            y_p, e_p, b = _probe_top(engine, region, line, x, with_bottom=True)
            if not math.isfinite(y_p):
                continue
            y, e = y_p, e_p
            if e is not None and not _is_cut(e):
                y_x, _, e_x = engine.exact_top(x, y_p, b)
                if math.isfinite(y_x) and y_x > b:
                    y, e = y_x, (e_x if e_x is not None else e_p)
        note = ""
        if e is None and y < yr[1]:
            # the supremum lies on a stability boundary: not attained, step into the open set
            depth = (y - b) if math.isfinite(b) else max(abs(y), 1.0)
            y = y - 1e-3 * depth
            note = "; the boundary there is a stability boundary (not attained): the point is 0.1 % inside"
        reason = _reason_for(fam, e, engine, y, yr, unbounded_x) + note
        result = _finish(tuner, engine, region, x, y, reason, unbounded_x, e)
        if result.stable and all(n <= c.gamma * (1 + 1e-6) for n, c in zip(result.norms, tuner.constraints)):
            return result
        last = result
    why = "the best admissible points did not pass the independent verification"
    if last is not None:
        bad = [f"{c.label}: {n:.6g}" for n, c in zip(last.norms, tuner.constraints) if n > c.gamma * (1 + 1e-6)]
        why += f" (e.g. {fam.x} = {last.point[0]:.6g}, {fam.y} = {last.point[1]:.6g}: " + (
            "unstable" if not last.stable else "; ".join(bad)) + ")"
    return _empty(tuner, engine, region, why + "; please report this case")


def _weakly_neutral(engine: _Engine) -> str | None:
    """Why no controller of the family can stabilise the loop robustly, or None.

    When the gains do not reach the highest power of ``s`` in the characteristic
    quasi-polynomial, its difference operator ``sum_k d_k e^{-s theta_k}`` is the
    same for every controller.  If it is not strongly stable (Hale:
    ``sum_{k>0} |d_k| >= |d_0|`` for a scalar operator), arbitrarily small changes
    of the delays put root chains in the right half-plane, so no gain gives a loop
    that :func:`posicast.stability` (issue #3) calls stable: e.g. an inverse ZVD or
    EI shaper in the loop (impulses 1/4, 1/2, 1/4: 0.75 >= 0.25).
    """
    if not engine.neutral_possible or engine.lead_varies:
        return None
    d = np.abs(engine.lead[0])
    if d.size < 2 or float(np.sum(d[1:])) < float(d[0]):
        return None
    return (f"the loop is neutral for every controller of this family, and its difference operator is not "
            f"strongly stable (sum of |d_k| = {float(np.sum(d[1:])):.4g} >= |d_0| = {float(d[0]):.4g}, delays "
            f"{', '.join(f'{t:.4g}' for t in engine.lead_delays)} s): arbitrarily small delay errors make it "
            "unstable, so no gain is admissible; a shaper whose first impulse dominates (ZV) or a "
            "distributed-delay shaper (seed 001 eq. 12) avoids this")


def _is_cut(end: Any) -> bool:
    """An interval end computed exactly at a refined crossing frequency (see ``_Engine.lines``)."""
    return isinstance(end, tuple) and len(end) == 3 and end[0] == "cut"


def _exact_interval(engine: _Engine, region: Region, i: int, x: float) -> tuple[float, float, float, Any]:
    """The best admissible interval on a fresh line at ``x``, both ends refined exactly.

    Returns ``(top, bottom, omega, end)``; ``top <= bottom`` when the interval
    is empty exactly (a sliver the grid resolved as open).
    """
    y_probe, end, bot = _probe_top(engine, region, i, x, with_bottom=True)
    if not math.isfinite(y_probe):
        return -math.inf, math.inf, math.nan, None
    if end is None or _is_cut(end):  # a stability break, the range, or an exact cut: exact already
        return y_probe, bot, (end[2] if end is not None else math.nan), end
    y, w, end_exact = engine.exact_top(x, y_probe, bot)
    if not math.isfinite(y):
        y, end_exact = y_probe, end
    b = engine.exact_bottom(x, y_probe, bot)
    return y, b, w, end_exact if end_exact is not None else end


def _new_branches(engine: _Engine, x: float, found: list, trackers: list, upper: bool) -> list:
    """The branches of ``found`` that no tracker follows yet (see :meth:`_Engine.tracked`)."""
    del x, upper
    return [br for br in found if not engine.tracked(br, trackers)]


def _exact_optimum(engine: _Engine, region: Region, i: int, x0: float, y0: float, bottom: float,
                   end: Any) -> tuple[float, float, Any]:
    """Refine the best line's top ``(x0, y0)`` to the exact optimum between the neighbouring lines.

    The optimum usually sits where two frequency branches of the boundary cross
    (a kink); a small error of either branch on the grid moves it.  Here the
    branches bounding the admissible interval (from above, and from below: a
    thin region can close from below; and the real-root line ``t(kx, ky) = 0``)
    are followed exactly in frequency while ``x`` moves (adaptive local grids),
    and every move is verified on a freshly computed line with both interval
    ends exact (:func:`_exact_interval`).  A branch that shows up there is
    added and the search repeated; where the region turns out closed, the
    bracket is cut back to the open side.  If the interval at ``x0`` is empty
    exactly (a sliver thinner than the grid error), the scan lines are tried
    best first.
    """
    from scipy.optimize import minimize_scalar

    def open_at(x: float, line: int) -> tuple[float, float, Any] | None:
        y, b_, _, e = _exact_interval(engine, region, line, x)
        return (y, b_, e) if math.isfinite(y) and y > b_ else None

    anchor = None
    got = open_at(x0, i)
    if got is not None:
        anchor = (i, x0, *got)
    else:
        tops = np.array([region.top(k) for k in range(region.x.size)])
        for line in [int(k) for k in np.argsort(-tops) if np.isfinite(tops[k]) and int(k) != i][:12]:
            got = open_at(float(region.x[line]), line)
            if got is not None:
                anchor = (line, float(region.x[line]), *got)
                break
    if anchor is None:
        return x0, y0, end
    line, xa, ya, ba, ea = anchor
    lo_x = float(region.x[max(line - 1, 0)])
    hi_x = float(region.x[min(line + 1, region.x.size - 1)])
    best = (xa, ya, ea)
    # branches that may bind anywhere in the bracket: local extrema near the anchor's interval,
    # discovered at five positions across it (a branch can be far from binding at the anchor itself)
    if ea is None or _is_cut(ea):
        return best  # bounded by a stability break, the range, or an exact cut: nothing to track
    uppers: list = [ea]
    lowers: list = []
    for xs in np.unique(np.concatenate([np.linspace(lo_x, hi_x, 5), [xa]])):
        ys, _, bs = _probe_top(engine, region, line, float(xs), with_bottom=True)
        if not (math.isfinite(ys) and ys > bs):
            continue  # closed here: the branches that close it are found where it is open
        for br in engine.active_branches(float(xs), ys, bs, band=0.5):
            if br not in uppers:
                uppers.append(br)
        if math.isfinite(bs):
            for br in engine.active_branches(float(xs), ys, bs, band=0.5, upper=False):
                if br not in lowers:
                    lowers.append(br)
    # one tracker per branch (neighbouring columns of one branch are one tracker)
    def dedup(brs: list, upper: bool) -> list:
        kept: list = []
        trk: list = []
        for br in sorted(brs):
            if not engine.tracked(br, trk):
                kept.append(br)
                trk.append(engine.branch_tracker(br, upper=upper))
        return trk

    rc = engine.real_coeffs
    real_floor = rc is not None and rc[2] != 0 and math.isfinite(ba) and abs(engine.real_value(xa, ba)) <= 1e-9 * (
        abs(rc[0]) + abs(rc[1] * xa) + abs(rc[2] * ba) + 1e-300)
    up_t = dedup(uppers, True)
    lo_t = dedup(lowers, False)
    for _ in range(8):
        if not up_t or not hi_x > lo_x:
            break

        def top(x: float) -> float:
            ups = [v for v in (f(x) for f in up_t) if math.isfinite(v)]
            floors = [v for v in (f(x) for f in lo_t) if math.isfinite(v)]
            if real_floor:
                floors.append(-(rc[0] + x * rc[1]) / rc[2])
            t = min(ups) if ups else -math.inf
            return t if not floors or max(floors) < t else -math.inf

        penalty = 10.0 * (abs(best[1]) + 1.0)  # where the trackers say closed (finite: Brent's parabolas)

        def objective(x: float) -> float:
            t = top(x)
            return -t if math.isfinite(t) else penalty

        res = minimize_scalar(objective, bounds=(lo_x, hi_x), method="bounded",
                              options={"xatol": 1e-7 * max(abs(lo_x), abs(hi_x), 1e-300)})
        if not np.isfinite(res.fun) or res.fun >= penalty:
            break
        x_try = float(res.x)
        got = open_at(x_try, line)
        if got is None:
            # closed at x_try although the trackers say open: cut the bracket halfway back to the best point
            mid = 0.5 * (best[0] + x_try)
            if x_try > best[0]:
                hi_x = mid
            else:
                lo_x = mid
            continue
        y_try, b_try, e_try = got
        if y_try > best[1]:
            best = (x_try, y_try, e_try if e_try is not None else ea)
        new_up = _new_branches(engine, x_try, engine.active_branches(x_try, y_try, b_try), up_t, True)
        new_lo = _new_branches(engine, x_try, engine.active_branches(x_try, y_try, b_try, upper=False), lo_t, False)
        if not (new_up or new_lo) and abs(y_try + res.fun) <= 1e-6 * max(1.0, abs(y_try)):
            break
        up_t += [engine.branch_tracker(br) for br in new_up]
        lo_t += [engine.branch_tracker(br, upper=False) for br in new_lo]
        if not (new_up or new_lo):
            # the trackers disagree with the exact line without a new branch: trust the exact value
            if x_try > best[0]:
                hi_x = 0.5 * (best[0] + x_try) if y_try < best[1] else hi_x
            else:
                lo_x = 0.5 * (best[0] + x_try) if y_try < best[1] else lo_x
    return best


def _probe_top(engine: _Engine, region: Region, i: int, x: float, with_bottom: bool = False) -> Any:
    """Largest admissible ``ky`` on a fresh line at ``x``, joined to line ``i`` for its stability labels.

    Pieces are taken best-first; the first stable one decides.
    """
    ln = engine.lines(np.array([x]))[0]
    ref = region._lines[i]
    comps = region._comps
    for j in range(ln.n_segments):
        ln.comp[j] = comps.new()
    cand = []
    for r, (lo, hi) in enumerate(ln.hinf):
        lo, hi = max(lo, region.y_range[0]), min(hi, region.y_range[1])
        if not lo < hi:
            continue
        inner = ln.breaks[(ln.breaks > lo) & (ln.breaks < hi)]
        edges = np.concatenate([[lo], inner, [hi]])
        for k, (a, b) in enumerate(zip(edges[:-1], edges[1:])):
            top_piece = k == len(edges) - 2 and hi == ln.hinf[r][1]
            cand.append((float(b), float(a), ln.ends[r][1] if top_piece else None))
    cand.sort(key=lambda t: -t[0])
    if cand:
        ys = np.array([_interval_point(a, b) for b, a, _ in cand])
        js = np.searchsorted(ln.breaks, ys)
        jr = np.searchsorted(ref.breaks, ys)
        hit = engine.horizontal_crossing(ref.x, x, ys)
        for (b, a, end), y, j, jref, h in zip(cand, ys, js, jr, hit):
            if not h:
                comps.union(int(ref.comp[int(jref)]), int(ln.comp[int(j)]))
            if region._label(int(ln.comp[int(j)]), x, float(y)):
                return (b, end, a) if with_bottom else (b, end)
    return (-math.inf, None, -math.inf) if with_bottom else (-math.inf, None)


def _reason_for(fam: ControllerFamily, end: Any, engine: _Engine, y: float, yr: tuple[float, float],
                unbounded: bool) -> str:
    if end is not None:
        col, ci, _ = end
        c = engine.fd.constraints[ci]
        if _is_cut(end):
            where = f"{end[2]:.4g} rad/s, exact"
        else:
            where = "its high-frequency limit" if col >= engine.ng else f"{engine.omega[col]:.4g} rad/s"
        text = f"largest {fam.y} on the boundary of {c.label} (active near {where})"
    elif y >= yr[1]:
        text = f"largest {fam.y} allowed by {fam.y}_range (the constraints are not active there)"
    else:
        text = f"largest {fam.y} on a stability boundary (the constraints are not active there)"
    if unbounded:
        text += f"; the admissible set reaches the {fam.x} range edge, so a larger {fam.y} may exist beyond it"
    return text


def _unbounded(tuner: _Tuner, engine: _Engine, region: Region, i: int, window: str | None = None) -> TuningResult:
    fam = tuner.family
    where = f"every larger {fam.y} is admissible" if window is None else f"every {fam.y} up to {window} is admissible"
    reason = (f"{fam.y} is not bounded by the constraints (at {fam.x} = {region.x[i]:.4g} {where}): "
              f"give {fam.y}_range to bound it")
    r = _empty(tuner, engine, region, reason)
    object.__setattr__(r, "empty", False)
    object.__setattr__(r, "unbounded", True)
    return r


def _peak(tf: TransferFunction, omega: np.ndarray, limit: np.ndarray | None) -> tuple[float, float]:
    """``max |tf(j omega)|``: every grid local maximum within 2 % of the top is refined between its
    neighbours (an optimal design often has two equal peaks); limit values count as omega = inf."""
    from scipy.optimize import minimize_scalar

    mag = np.abs(np.asarray(tf.freqresp(omega)))
    mag = np.where(np.isfinite(mag), mag, 0.0)
    top = float(mag.max())
    left = np.concatenate([[-np.inf], mag[:-1]])
    right = np.concatenate([mag[1:], [-np.inf]])
    best, where = top, float(omega[int(np.argmax(mag))])
    for i in np.flatnonzero((mag >= 0.98 * top) & (mag >= left) & (mag >= right)):
        lo, hi = omega[max(i - 1, 0)], omega[min(i + 1, omega.size - 1)]
        if hi <= lo:
            continue
        res = minimize_scalar(lambda w: -abs(tf(1j * w)), bounds=(lo, hi), method="bounded",
                              options={"xatol": 1e-12 * max(hi, 1.0)})
        if -res.fun > best:
            best, where = float(-res.fun), float(res.x)
    if limit is not None and limit.size:
        lm = float(np.max(np.abs(limit)))
        if lm > best * (1 + 1e-9):
            best, where = lm, math.inf
    return best, where


def _active_frequency(engine: _Engine, kx: float, end: Any) -> float:
    """Frequency of the interval end ``end`` at ``kx`` (exact), or nan."""
    if end is None:
        return math.nan
    if _is_cut(end):
        return float(end[2])
    if end[0] >= engine.ng:
        return math.nan
    return float(engine.exact_end(kx, end, upper=True)[1])


def _finish(tuner: _Tuner, engine: _Engine, region: Region, kx: float, ky: float, reason: str,
            unbounded: bool, end: Any = None) -> TuningResult:
    from ..spectra.rootfinder import RootFindingError

    fam = tuner.family
    C = fam.controller(kx, ky)
    loop = tuner.loop(kx, ky)
    fd = engine.fd
    w = fd.omega[fd.omega > 0]
    # the active frequency (where the constraint holds with equality) may be a resonance narrower than
    # the grid, which was refined for the open-loop terms: add it and a narrow neighbourhood
    w_act = _active_frequency(engine, kx, end)
    if math.isfinite(w_act) and w_act > 0:
        w = np.unique(np.concatenate([w, w_act * (1.0 + np.linspace(-1e-3, 1e-3, 21))]))
    lim = fd.n_grid
    Ulim = engine.u[lim:] + kx * engine.a[lim:] + ky * engine.b[lim:]
    with np.errstate(divide="ignore"):
        ms, w_ms = _peak(loop.sensitivity, w, 1.0 / Ulim)
    norms, active = [], []
    for ci, c in enumerate(tuner.constraints):
        src, dst = c.channel
        X = loop.transfer(src, dst) * c.weight_tf
        nu, na, nb, w2 = engine.cons[ci]
        Nlim = nu[lim:] + kx * na[lim:] + ky * nb[lim:]
        with np.errstate(divide="ignore", invalid="ignore"):
            Xlim = np.sqrt(w2[lim:]) * c.gamma * np.abs(Nlim) / np.abs(Ulim)
        n, _ = _peak(X, w, Xlim)
        norms.append(n)
        active.append(abs(n - c.gamma) <= 1e-6 * c.gamma)
    try:
        st = loop.stability()
        stable = bool(st.stable)
    except (RootFindingError, ValueError) as exc:
        st, stable = None, False
        reason += f"; the spectrum check of the chosen loop failed: {exc}"
    return TuningResult(fam, tuner.structure, fam.gains(kx, ky), C, loop, ms, w_ms, 1.0 / ms if ms > 0 else math.inf,
                        stable, st, tuple(norms), tuple(active), tuner.constraints, region, False, unbounded,
                        reason)


# ---------------------------------------------------------------------- public entry points
def _constraint_tuple(constraints: Any) -> tuple[Constraint, ...]:
    """None, one Constraint or a sequence of them, as a tuple (TypeError naming ``constraints``)."""
    if constraints is None:
        return ()
    if isinstance(constraints, Constraint):
        return (constraints,)
    out = tuple(v.sequence(constraints, "constraints"))
    for c in out:
        if not isinstance(c, Constraint):
            raise TypeError(f"constraints must be posicast.tune.Constraint objects, got {type(c).__name__}")
    return out


def _constraints(ms: Any, constraints: Any) -> tuple[Constraint, ...]:
    extra = _constraint_tuple(constraints)
    base = () if ms is None else (sensitivity_constraint(ms),)
    return base + extra


def tune_pd(
    G: Any,
    S: Any = None,
    structure: str = "control_action",
    ms: float | None = 2.0,
    *,
    F: Any = None,
    constraints: Sequence[Constraint] | Constraint | None = None,
    derivative_filter: float | None = None,
    kp_range: Any = None,
    kd_range: Any = None,
    n_lines: int = 161,
) -> TuningResult:
    """Robust PD ``C = Kp + Kd s`` for a loop with a shaper, by H-infinity regions (seed 001).

    Maximises ``Kp`` (the integral gain of the equivalent PI ``C / s = Kd + Kp / s``
    for ``s G``, seed 001 eq. 16, i.e. minimum integral error, eq. 8) subject to
    ``||S||_inf <= ms`` and any further constraints, over the stabilising gains.

    Parameters
    ----------
    G : plant-like
        Actuator-side plant, proper (a delay ``G e^{-s theta}`` is allowed).
    S : Shaper, plant-like or None
        The shaper (None: no shaper).
    structure : {'control_action', 'inverse_shaper', 'feedforward'}
        Where the shaper sits (seed 001 Fig. 1-3).
    ms : float or None
        Peak sensitivity bound (seed 001 eq. 14); None if ``constraints`` say it all.
    F : plant-like, optional
        Flexible load outside the loop (kept in ``result.loop`` for simulation).
    constraints : Constraint or sequence of Constraint, optional
        Further ``||W X||_inf < gamma`` requirements.
    derivative_filter : float, optional
        ``Tf``: design ``Kp + Kd s / (Tf s + 1)`` instead (realisable; simulable).
    kp_range, kd_range : (low, high), optional
        Bounds of the gains; default: found automatically.
    n_lines : int
        Scan lines in ``Kd`` over the admissible set (its resolution).

    Returns
    -------
    TuningResult
        ``.kp``, ``.kd``, ``.ms`` (achieved), ``.stable``, ``.region``, ``.plot()``.
        An empty region is a result (``.empty``, ``.reason``), not an exception.

    Raises
    ------
    ValueError, TypeError
        Improper plant or loop gain, ``ms`` outside ``[0.001, 100]``, a bad range or
        structure, coefficients or delays beyond what the frequency grid resolves, or
        ``n_lines`` whose scan would exceed :data:`MAX_SECONDS` (estimated from the
        measured cost of the first pass; the message says which ``n_lines`` fits).

    Examples
    --------
    A double integrator with a lag, PD for ``Ms = 1.6`` (a brute-force scan with
    the Routh-Hurwitz test gives max Kp = 12.992; the top is flat in Kd):

    >>> r = tune_pd(([1.0], [0.1, 1.0, 0.0, 0.0]), ms=1.6)
    >>> r.stable, abs(r.ms - 1.6) < 1e-6
    (True, True)
    >>> round(r.kp, 3), round(r.kd, 1)
    (12.992, 7.4)
    """
    fam = pd_family(derivative_filter)
    return tune(G, fam, S, structure, _constraints(ms, constraints), F=F, x_range=kd_range,
                y_range=kp_range, n_lines=n_lines)


def tune_pi(
    G: Any,
    S: Any = None,
    structure: str = "control_action",
    ms: float | None = 2.0,
    *,
    F: Any = None,
    constraints: Sequence[Constraint] | Constraint | None = None,
    kp_range: Any = None,
    ki_range: Any = None,
    n_lines: int = 161,
) -> TuningResult:
    """Robust PI ``C = Kp + Ki / s`` by H-infinity regions: maximum ``Ki`` (seed 001 eq. 8).

    Parameters are those of :func:`tune_pd`, with ``ki_range`` for the integral gain.

    Examples
    --------
    >>> r = tune_pi(([1.0], [1.0, 2.0, 1.0]), ms=1.4)     # 1 / (s + 1)^2
    >>> r.stable, abs(r.ms - 1.4) < 1e-6
    (True, True)
    >>> round(r.ki, 3), round(r.kp, 1)                    # brute force: 1.058 (flat in Kp)
    (1.058, 1.8)
    """
    return tune(G, pi_family(), S, structure, _constraints(ms, constraints), F=F, x_range=kp_range,
                y_range=ki_range, n_lines=n_lines)


def tune_pid(
    G: Any,
    S: Any = None,
    structure: str = "control_action",
    ms: float | None = 2.0,
    *,
    fixed: Mapping[str, float],
    maximize: str | None = None,
    F: Any = None,
    constraints: Sequence[Constraint] | Constraint | None = None,
    derivative_filter: float | None = None,
    kp_range: Any = None,
    ki_range: Any = None,
    kd_range: Any = None,
    n_lines: int = 161,
) -> TuningResult:
    """Robust PID ``Kp + Ki / s + Kd s / (Tf s + 1)`` with one gain fixed (``fixed={'kd': 0.5}``).

    The other two gains span the plane; ``maximize`` (default ``'ki'``, or
    ``'kp'`` when ``ki`` is fixed) is the secondary criterion.  Other
    parameters as :func:`tune_pd`.

    Examples
    --------
    ``1 / (s + 1)^3`` with ``Kd = 0.5`` fixed: the derivative action buys
    integral gain at the same robustness (the PI alone reaches ``Ki = 0.461``).
    A brute-force scan (Hurwitz test and ``||S||inf`` on a dense grid over
    ``Kp``, ``Ki``) gives max ``Ki`` 0.8107 and 0.4608:

    >>> G = ([1.0], [1.0, 3.0, 3.0, 1.0])
    >>> r = tune_pid(G, ms=1.6, fixed={"kd": 0.5}, derivative_filter=0.01)
    >>> r.stable, r.kd, abs(r.ms - 1.6) < 1e-6, r.active
    (True, 0.5, True, (True,))
    >>> round(r.ki, 3), round(tune_pi(G, ms=1.6).ki, 3)
    (0.811, 0.461)
    """
    fam = pid_family(fixed, maximize, derivative_filter)
    ranges = {"kp": kp_range, "ki": ki_range, "kd": kd_range}
    return tune(G, fam, S, structure, _constraints(ms, constraints), F=F, x_range=ranges[fam.x],
                y_range=ranges[fam.y], n_lines=n_lines)
