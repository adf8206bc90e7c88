"""Frequency data of a tuning problem: ``1 + L`` and every constraint, affine in the two gains.

With the controller ``C = c0 + kx cx + ky cy`` (a :class:`ControllerFamily`) and
the loop ``L = C P``, at every frequency

* ``1 + L = u + kx a + ky b`` with ``u = 1 + c0 P``, ``a = cx P``, ``b = cy P``;
* a constraint channel ``X = (alpha + beta C) / (1 + L)``
  (:meth:`~posicast.loops.Loop.controller_factor`) has numerator
  ``nu + kx na + ky nb``, and ``|W X| < gamma`` reads
  ``|u + kx a + ky b|^2 - w2 |nu + kx na + ky nb|^2 > 0`` with ``w2 = |W|^2 / gamma^2``.

:class:`FrequencyData` holds these on a grid built for the problem: a log grid
over the features of every block, refined until the exact derivative of each
quantity times the local spacing is small against its size (this resolves
every resonance, including those of a shaper's quasi-polynomial zeros in
``1 / S``), plus *limit columns*: the ``omega -> infinity`` behaviour, which for
a neutral loop is an almost-periodic function of ``omega`` (ratio of the leading
exponential sums), sampled over one period of the commensurate delays.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple, Sequence

import numpy as np

from ..core.quasipoly import QuasiPolynomial, horner
from ..core.transfer import TransferFunction
from ..loops import Loop, feature_frequencies
from ..spectra.difference import common_step as _spectra_common_step
from .axis import OnAxis
from .constraints import Constraint
from .family import ControllerFamily

__all__ = ["FrequencyData", "Asymptote", "Columns", "ConstraintColumns", "columns_of", "grid_subset", "thin_columns",
           "thinnable", "with_frequencies"]

_MAX_POINTS = 400_000  # frequency grid size cap
_REFINE_ROUNDS = 24
_LIMIT_SAMPLES = 1024


# ---------------------------------------------------------------------- asymptotes
@dataclass(frozen=True)
class Asymptote:
    """``H(j omega) ~ (j omega)^m h(omega)`` as ``omega -> infinity``.

    ``h`` is the ratio of the leading exponential sums: ``num_coef . exp(-j omega num_delay)``
    over ``den_coef . exp(-j omega den_delay)``.
    """

    m: int
    num_coef: np.ndarray
    num_delay: np.ndarray
    den_coef: np.ndarray
    den_delay: np.ndarray

    @classmethod
    def of(cls, tf: TransferFunction) -> Asymptote:
        if tf.num.is_zero:
            return cls(-(10**6), np.zeros(1), np.zeros(1), np.ones(1), np.zeros(1))
        n, d = tf.num, tf.den
        nl, dl = n.coeffs[:, n.degree], d.coeffs[:, d.degree]
        kn, kd = nl != 0, dl != 0
        return cls(n.degree - d.degree, nl[kn], n.delays[kn], dl[kd], d.delays[kd])

    def __mul__(self, other: Asymptote) -> Asymptote:
        return Asymptote(
            self.m + other.m,
            np.multiply.outer(self.num_coef, other.num_coef).ravel(),
            np.add.outer(self.num_delay, other.num_delay).ravel(),
            np.multiply.outer(self.den_coef, other.den_coef).ravel(),
            np.add.outer(self.den_delay, other.den_delay).ravel(),
        )

    @property
    def delays(self) -> np.ndarray:
        return np.concatenate([self.num_delay, self.den_delay])

    @cached_property
    def peak(self) -> float | None:
        """``sup |h|`` over the phase parameters when ``|h|`` oscillates (two or more distinct delays in its
        numerator or denominator: a lumped shaper's ``S``, its inverse), sampled over one period of the
        commensurate delays (64 periods of the shortest one otherwise); None when ``|h|`` is constant.
        (Summed delay by delay, not as a matrix product: a BLAS call here would wake its worker threads,
        which then spin through the scan.)"""
        if self.m <= -(10**6) or (np.unique(self.num_delay).size < 2 and np.unique(self.den_delay).size < 2):
            return None
        delays = self.delays[self.delays > 0]
        step = _common_step(delays)
        theta = (np.linspace(0.0, 2.0 * math.pi / step, 4 * _LIMIT_SAMPLES, endpoint=False) if step is not None
                 else np.linspace(0.0, 64 * 2.0 * math.pi / float(delays.min()), 16 * _LIMIT_SAMPLES))

        def exponential_sum(coef: np.ndarray, delay: np.ndarray) -> np.ndarray:
            out = np.zeros(theta.shape, dtype=complex)
            for c, d in zip(coef, delay):
                out += c * np.exp(-1j * d * theta)
            return out

        with np.errstate(divide="ignore", invalid="ignore"):
            h = exponential_sum(self.num_coef, self.num_delay) / exponential_sum(self.den_coef, self.den_delay)
        return float(np.max(np.abs(h)))

    def values(self, theta: np.ndarray) -> np.ndarray:
        """The limit at phase parameters ``theta`` (0 for ``m < 0``; requires ``m <= 0``)."""
        if self.m < 0:
            return np.zeros(theta.shape, dtype=complex)
        if self.m > 0:
            raise ValueError("improper term: no finite limit")
        num = np.exp(-1j * np.multiply.outer(theta, self.num_delay)) @ self.num_coef
        den = np.exp(-1j * np.multiply.outer(theta, self.den_delay)) @ self.den_coef
        with np.errstate(divide="ignore", invalid="ignore"):
            return num / den


def _poly_tf(num_desc: np.ndarray, den_desc: np.ndarray) -> TransferFunction:
    n = np.trim_zeros(np.asarray(num_desc, dtype=float), "f")
    return TransferFunction.from_poly(n if n.size else [0.0], np.trim_zeros(np.asarray(den_desc, dtype=float), "f"))


def _common_step(delays: np.ndarray) -> float | None:
    return _spectra_common_step(np.unique(delays))


class _Term:
    """A transfer function evaluated with its exact derivative along the imaginary axis."""

    def __init__(self, tf: TransferFunction) -> None:
        self.tf = tf
        self.zero = tf.num.is_zero
        self.axis = OnAxis(tf)
        self.dnum = tf.num.derivative()
        self.dden = tf.den.derivative()
        self._dnum, self._dden = OnAxis.quasi(self.dnum), OnAxis.quasi(self.dden)

    def __call__(self, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(H(j omega), H'(j omega))`` at the real frequencies ``w``."""
        if self.zero:
            z = np.zeros(w.shape, dtype=complex)
            return z, z
        s = 1j * w
        val, _, D = self.axis.parts(w)
        dN, dD = self._dnum(s), self._dden(s)
        if not (np.all(np.isfinite(dN)) and np.all(np.isfinite(dD))):  # the checked call names the overflow
            dN, dD = np.asarray(self.dnum(s)).reshape(s.shape), np.asarray(self.dden(s)).reshape(s.shape)
        with np.errstate(divide="ignore", invalid="ignore"):
            der = (dN - val * dD) / D
        der = np.where(np.isfinite(der), der, 0.0)
        # dH/d omega = j H'(j omega): only the magnitude is used
        return val, der


# ---------------------------------------------------------------------- the data
class FrequencyData:
    """``u, a, b`` and every constraint's ``nu, na, nb, w2`` on a refined grid plus limit columns.

    Parameters
    ----------
    loop0 : Loop
        The loop with any controller (only its structure, plant and shaper are used).
    family : ControllerFamily
    constraints : sequence of Constraint
    scale : (float, float)
        Magnitudes of the gains ``(|kx|, |ky|)`` over which the grid must be
        accurate (it is refined where ``L`` changes by more than a small fraction
        of ``max(|1 + L|, r)`` between two points for gains of this size).
    delta : float
        That fraction.
    limit_for_delays : bool
        Stop the grid at :attr:`delay_ceiling` (see :meth:`refine`).

    Attributes
    ----------
    omega : ndarray
        The finite grid [rad/s] (increasing, > 0, possibly with 0 first).
    n_grid : int
        Number of finite columns; the remaining columns are limits.
    capped : bool
        The grid reached its size cap (:data:`_MAX_POINTS`) with intervals still coarser than the
        refinement rule accepts: it resolves the loop less finely than stated, at the largest gains.
    u, a, b : ndarray of complex
    cons : list of dict with ``nu, na, nb, w2`` arrays
    """

    def __init__(self, loop0: Loop, family: ControllerFamily, constraints: Sequence[Constraint],
                 scale: tuple[float, float], delta: float = 0.03, limit_for_delays: bool = False) -> None:
        self.family = family
        self.constraints = tuple(constraints)
        self.capped = False
        Pg = loop0.plant_gain
        self.plant = Pg
        self._plant_axis = OnAxis(Pg)
        self._plant_term = _Term(Pg)
        Cs = {k: _poly_tf(getattr(family, "n" + k), family.dC) for k in ("0", "x", "y")}
        one = TransferFunction.constant(1.0)
        tfs = {"u": one + Cs["0"] * Pg, "a": Cs["x"] * Pg, "b": Cs["y"] * Pg}
        asym = {k: Asymptote.of(t) for k, t in tfs.items()}
        _refuse_improper_loop(asym, family, loop0.architecture)
        self._cpolys = tuple((np.trim_zeros(np.asarray(getattr(family, "n" + k), dtype=float), "f"),
                              np.trim_zeros(np.asarray(family.dC, dtype=float), "f")) for k in ("0", "x", "y"))
        cons_tfs = self._constraint_terms(loop0, Cs)
        self._terms = {k: _Term(t) for k, t in tfs.items()}
        self._cterms = [{k: _Term(t) for k, t in d.items()} for d in cons_tfs]
        self._asym = asym
        self._casym = [{k: Asymptote.of(t) for k, t in d.items()} for d in cons_tfs]
        self.r_min = float(min((1.0 / c.gamma for c in self.constraints if c.kind == "S"), default=0.5))
        self.delta = float(delta)
        self._initial_grid(Pg, tfs, cons_tfs, list(Cs.values()))
        self.refine(scale, ceiling=self.delay_ceiling if limit_for_delays else None)
        self._limit_columns()

    def _constraint_terms(self, loop0: Loop, Cs: dict[str, TransferFunction]) -> list[dict[str, TransferFunction]]:
        """Each constraint's ``nu, na, nb`` (the channel's numerator parts) and weight ``W``.

        Also records ``(R, through the controller, W)`` per constraint: :meth:`values`
        builds every term from ``P``, ``R``, ``W`` and ``C``'s parts.
        """
        family = self.family
        cons_tfs: list[dict[str, TransferFunction]] = []
        self._factors: list[tuple[OnAxis, bool, OnAxis]] = []
        self._factor_terms: list[tuple[_Term, bool, _Term]] = []
        for c in self.constraints:
            src, dst = c.channel
            try:
                R, through = loop0.controller_factor(src, dst)
            except ValueError as exc:
                raise ValueError(f"constraint {c.label}: {exc}") from exc
            zero = TransferFunction(QuasiPolynomial.zero(), QuasiPolynomial.constant(1.0))
            if through:
                d = {"nu": Cs["0"] * R, "na": Cs["x"] * R, "nb": Cs["y"] * R}
            else:
                d = {"nu": R, "na": zero, "nb": zero}
            d["W"] = c.weight_tf
            for k in ("nu", "na", "nb"):
                if not d[k].num.is_zero and (Asymptote.of(d[k]) * Asymptote.of(c.weight_tf)).m > 0:
                    raise ValueError(
                        f"constraint {c.label}: the channel {src} -> {dst} grows without bound at high "
                        f"frequency for {family.describe()} (an ideal derivative); set derivative_filter"
                    )
            cons_tfs.append(d)
            self._factors.append((OnAxis(R), through, OnAxis(c.weight_tf)))
            self._factor_terms.append((_Term(R), through, _Term(c.weight_tf)))
        return cons_tfs

    def _initial_grid(self, Pg: TransferFunction, tfs: dict[str, TransferFunction],
                      cons_tfs: list[dict[str, TransferFunction]], controller_tfs: list[TransferFunction]) -> None:
        """A log grid from 1/30 of the lowest to 30 times the highest feature of every block (and 0 when
        every term is finite there), with its values; sets :attr:`top_feature` and :attr:`delay_ceiling`."""
        feats = feature_frequencies([Pg] + [t for d in cons_tfs for t in d.values()] + controller_tfs)
        feats = [f for f in feats if 1e-8 < f < 1e9] or [1.0]
        #: the highest feature frequency [rad/s] of the loop's blocks
        self.top_feature = max(feats)
        # A delay needs a uniform grid (spacing ~ delta / tau) wherever the loop's terms are large, so a
        # grid for huge gains costs ~ omega_max tau / delta points: a delay loop's grid stops at
        # max(1e3 / tau_max, 100 x the top feature) when asked (the scan keeps the gains it verifies).
        tau_max = max((float(q.delays.max()) for t in tfs.values() for q in (t.num, t.den) if not q.is_zero),
                      default=0.0)
        #: where a delay loop's grid stops when ``limit_for_delays`` (None: no delay)
        self.delay_ceiling = max(1e3 / tau_max, 100.0 * self.top_feature) if tau_max > 0 else None
        lo = min(feats) / 30.0
        hi = max(feats) * 30.0
        grid = np.geomspace(lo, hi, max(300, int(100 * math.log10(hi / lo)) + 1))
        self._lo, self._hi = lo, hi
        self._has_zero = bool(np.all(np.isfinite([_safe_eval(t, 0.0) for t in tfs.values()])))
        if self._has_zero:
            grid = np.concatenate([[0.0], grid])
        self.omega = grid
        self._vals = self._evaluate(grid)

    # ------------------------------------------------------------------ evaluation
    def _evaluate(self, w: np.ndarray) -> dict[str, np.ndarray]:
        """Every quantity and its derivative ``d/ds`` at the frequencies ``w``: as :meth:`values`, from the
        plant ``P``, each constraint's ``R`` and ``W`` (with their derivatives) and the controller's parts,
        so that ``P`` is evaluated once, not once per term; ``omega = 0`` through the combined terms."""
        w = np.asarray(w, dtype=float)
        s = 1j * w
        z = np.zeros(s.shape, dtype=complex)
        P, dP = self._plant_term(w)
        out: dict[str, np.ndarray] = {}
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            c: list[tuple[np.ndarray, np.ndarray] | None] = []  # each part and its derivative (None: 0)
            for n, d in self._cpolys:
                if not n.size:
                    c.append(None)
                    continue
                nv, dv = np.polyval(n, s), np.polyval(d, s)
                c.append((nv / dv, (np.polyval(np.polyder(n), s) * dv - nv * np.polyval(np.polyder(d), s)) / (dv * dv)))

            def times(part: tuple[np.ndarray, np.ndarray] | None, h: np.ndarray,
                      dh: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
                return (z, z) if part is None else (part[0] * h, part[1] * h + part[0] * dh)

            for k, part in zip(("u", "a", "b"), c):
                out[k], out["d" + k] = times(part, P, dP)
            out["u"] = out["u"] + 1.0
            for i, (R, through, W) in enumerate(self._factor_terms):
                r, dr = R(w)
                for k, part in zip(("nu", "na", "nb"), c):
                    out[f"{k}{i}"], out[f"d{k}{i}"] = times(part, r, dr) if through else (
                        (r, dr) if k == "nu" else (z, z))
                out[f"W{i}"], out[f"dW{i}"] = W(w)
        for k in out:
            if k.startswith("d"):
                out[k] = np.where(np.isfinite(out[k]), out[k], 0.0)
        at0 = np.flatnonzero(w == 0.0)
        if at0.size:
            for k, t in self._terms.items():
                out[k][at0], out["d" + k][at0] = t(w[at0])
            for i, ct in enumerate(self._cterms):
                for k, t in ct.items():
                    out[f"{k}{i}"][at0], out[f"d{k}{i}"][at0] = t(w[at0])
        return out

    def values(self, w: np.ndarray) -> dict[str, np.ndarray]:
        """Every quantity (values only) at the frequencies ``w`` (exact).

        For ``omega > 0`` the plant ``P``, each constraint's ``R`` and ``W`` are
        evaluated once and combined with the controller's parts ``c0, cx, cy``
        (``u = 1 + c0 P``, ``a = cx P``, ``b = cy P``; ``nu, na, nb = (c0, cx, cy) R``
        or ``R, 0, 0``): the same numbers as the combined transfer functions, at a
        third of the cost.  ``omega = 0`` goes through the combined transfer
        functions, which resolve a pole of ``C`` cancelled by a zero of ``P``.
        """
        w = np.asarray(w, dtype=float)
        s = 1j * w
        z = np.zeros(s.shape, dtype=complex)
        P = self._plant_axis(w)
        with np.errstate(divide="ignore", invalid="ignore"):  # s = 0 is replaced below
            c0, cx, cy = (horner(s, n[::-1]) / horner(s, d[::-1]) if n.size else z for n, d in self._cpolys)
            out = {"u": 1.0 + c0 * P, "a": cx * P, "b": cy * P}
            for i, (R, through, W) in enumerate(self._factors):
                r = R(w)
                out[f"nu{i}"], out[f"na{i}"], out[f"nb{i}"] = (c0 * r, cx * r, cy * r) if through else (r, z, z)
                out[f"W{i}"] = W(w)
        at0 = np.flatnonzero(w == 0.0)
        if at0.size:
            s0 = s[at0]
            for k, t in self._terms.items():
                out[k][at0] = np.asarray(t.tf(s0), dtype=complex) if not t.zero else 0j
            for i, ct in enumerate(self._cterms):
                for k, t in ct.items():
                    out[f"{k}{i}"][at0] = np.asarray(t.tf(s0), dtype=complex) if not t.zero else 0j
        return out

    def point(self, w: float) -> dict[str, complex]:
        """Every quantity (values only) at one frequency: exact, for the final refinement."""
        return {k: complex(v[0]) for k, v in self.values(np.array([float(w)])).items()}

    def refine(self, scale: tuple[float, float], small: tuple[float, float] | None = None,
               ceiling: float | None = None) -> None:
        """Extend and refine the grid until every quantity is resolved for gains up to ``scale``
        (and, at low frequency, for gains down to ``small``).

        The grid first grows upward, a decade at a time, until the decaying
        terms of ``L`` times these gains are below 1e-4 at its end (beyond, ``L``
        only decays further and the limit columns take over), or until it
        reaches ``ceiling`` [rad/s]; then points are inserted wherever the exact
        derivative says the grid is too coarse.  A grid that stops at its
        ceiling is valid for smaller gains only (``_Engine.x_valid``, ``y_valid``).
        """
        X, Y = (max(float(abs(x)), 1e-300) for x in scale)
        self._scale = (X, Y)
        # the smallest gains scanned: the low-frequency end of the D-decomposition curve must be resolved
        # at their scale too (for small gains the crossover, and the boundaries, move to omega -> 0)
        if small is not None:
            self._small = (min(X, max(float(abs(small[0])), 1e-300)), min(Y, max(float(abs(small[1])), 1e-300)))
        elif not hasattr(self, "_small"):
            self._small = (X, Y)
        self._grow_upward(X, Y, ceiling)
        self._grow_downward(*self._small)
        self._insert_points(X, Y)
        self.n_grid = self.omega.size
        if hasattr(self, "_limit"):
            self._limit_columns()

    def _append(self, new: np.ndarray, at: int | None = None) -> None:
        """Evaluate the frequencies ``new`` and insert them at column ``at`` (None: at the end)."""
        nv = self._evaluate(new)
        if at is None:
            self.omega = np.concatenate([self.omega, new])
            self._vals = {k: np.concatenate([self._vals[k], nv[k]]) for k in self._vals}
        else:
            self.omega = np.concatenate([self.omega[:at], new, self.omega[at:]])
            self._vals = {k: np.concatenate([self._vals[k][:at], nv[k], self._vals[k][at:]]) for k in self._vals}

    def _grow_upward(self, X: float, Y: float, ceiling: float | None) -> None:
        """Extend the grid a decade at a time until the decaying terms of ``L`` times the gains ``X, Y``
        are below 1e-4 at its end, or it reaches ``ceiling`` (or 1e9) rad/s."""
        for _ in range(12):
            v = self._vals
            lim = {k: self._asym[k] for k in ("a", "b")}
            tail = sum(g * abs(v[k][-1]) for g, k in ((X, "a"), (Y, "b")) if lim[k].m < 0)
            if not tail > 1e-4 or self.omega[-1] >= min(1e9, ceiling or math.inf):
                break
            top = min(10.0, max(1.0 + 1e-9, (ceiling or math.inf) / self.omega[-1]))  # not past the ceiling
            self._append(self.omega[-1] * np.geomspace(1.0, top, max(3, int(100 * math.log10(top)) + 1))[1:])

    def _grow_downward(self, Xs: float, Ys: float) -> None:
        """Extend the grid downward until the D-decomposition curve (1 + L = 0) has settled at its
        low-frequency end for gains ``Xs, Ys`` (for small gains the crossover, and the boundaries, move
        to omega -> 0)."""
        for _ in range(12):
            w0 = self.omega[1] if self._has_zero else self.omega[0]
            if w0 <= 1e-12 or not self._curve_moves(0 if not self._has_zero else 1, Xs, Ys):
                break
            self._append(w0 * np.geomspace(1e-1, 1.0, 101)[:-1], at=1 if self._has_zero else 0)

    def _insert_points(self, X: float, Y: float) -> None:
        """Insert midpoints wherever the exact derivative says the grid is too coarse (:meth:`_bad_intervals`).

        Each round bisects every interval that fails the test; only the two halves of a bisected
        interval are tested again (the test of an interval uses its two ends alone), and the new
        points are merged into the grid once, at the end.  The same points, evaluated in the same
        batches, as bisecting the whole grid round by round (issue #15: on a lumped shaper's grid of
        ~10^5 columns, testing and merging the whole grid every round cost as much as evaluating it).
        """
        omega = self.omega
        n_total = omega.size
        ends, finite = self._interval_ends(self._vals, X, Y)
        # the intervals under test: left and right frequencies and each test quantity at both ends
        wl, wr = omega[:-1], omega[1:]
        el = [(d[:-1], z[:-1]) for d, z in ends]
        er = [(d[1:], z[1:]) for d, z in ends]
        fl, fr = finite[:-1], finite[1:]
        new_w: list[np.ndarray] = []
        new_v: list[dict[str, np.ndarray]] = []
        for _ in range(_REFINE_ROUNDS):
            bad = self._bad_intervals(wl, wr, el, er, fl, fr)
            if not np.any(bad):
                break
            if n_total >= _MAX_POINTS:  # intervals still too coarse: said in the design's reason
                self.capped = True
                break
            idx = np.flatnonzero(bad)
            if n_total + idx.size > _MAX_POINTS:
                idx = idx[: _MAX_POINTS - n_total]
            mid = 0.5 * (wl[idx] + wr[idx])
            nv = self._evaluate(mid)
            new_w.append(mid)
            new_v.append(nv)
            n_total += mid.size
            m_ends, m_fin = self._interval_ends(nv, X, Y)

            def halves(left: np.ndarray, middle: np.ndarray, right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
                """The (left, right) ends of the two halves of each bisected interval, in grid order."""
                lo = np.empty(2 * idx.size, dtype=left.dtype)
                hi = np.empty(2 * idx.size, dtype=left.dtype)
                lo[0::2], lo[1::2] = left[idx], middle
                hi[0::2], hi[1::2] = middle, right[idx]
                return lo, hi

            wl, wr = halves(wl, mid, wr)
            pairs = [(halves(a, md, b), halves(c, mz, e)) for (a, c), (md, mz), (b, e) in zip(el, m_ends, er)]
            el = [(d[0], z[0]) for d, z in pairs]
            er = [(d[1], z[1]) for d, z in pairs]
            fl, fr = halves(fl, m_fin, fr)
        if new_w:
            w_all = np.concatenate([omega] + new_w)
            order = np.argsort(w_all, kind="stable")
            self.omega = w_all[order]
            self._vals = {k: np.concatenate([self._vals[k]] + [nv[k] for nv in new_v])[order] for k in self._vals}

    def _interval_ends(self, v: dict[str, np.ndarray], X: float, Y: float) -> tuple[list[tuple[np.ndarray, np.ndarray]],
                                                                                 np.ndarray]:
        """Per point, what the spacing test (:meth:`_bad_intervals`) reads at an interval's end: for ``1 + L``
        and for each constraint, the bound of the derivative (``|du| + X |da| + Y |db|``, and
        ``|W'| |N| + |W| |N'|`` with ``|N| = |nu| + X |na| + Y |nb|``) and the size (``max(|u| + X |a| + Y |b|, r)``,
        and ``max(|W| |N|, that, r)``); and whether ``|1 + L|`` is finite there."""
        mag = np.abs(v["u"]) + X * np.abs(v["a"]) + Y * np.abs(v["b"])
        der = np.abs(v["du"]) + X * np.abs(v["da"]) + Y * np.abs(v["db"])
        out = [(der, np.maximum(mag, self.r_min))]
        for i, c in enumerate(self.constraints):
            W = np.abs(v[f"W{i}"]) / c.gamma
            dW = np.abs(v[f"dW{i}"]) / c.gamma
            nmag = np.abs(v[f"nu{i}"]) + X * np.abs(v[f"na{i}"]) + Y * np.abs(v[f"nb{i}"])
            nder = np.abs(v[f"dnu{i}"]) + X * np.abs(v[f"dna{i}"]) + Y * np.abs(v[f"dnb{i}"])
            wn = W * nmag
            out.append((dW * nmag + W * nder, np.maximum(np.maximum(wn, mag), self.r_min)))
        return out, np.isfinite(mag)

    def _bad_intervals(self, wl: np.ndarray, wr: np.ndarray, el: list[tuple[np.ndarray, np.ndarray]],
                       er: list[tuple[np.ndarray, np.ndarray]], fl: np.ndarray, fr: np.ndarray) -> np.ndarray:
        """The grid's spacing test on intervals given by their ends (:meth:`_interval_ends`): too coarse where, for
        ``1 + L`` or a constraint, the larger derivative bound at the two ends times the spacing exceeds ``delta``
        times the smaller size (and both ends are finite, and the interval is not at rounding level)."""
        h = wr - wl
        bad = np.zeros(h.shape, dtype=bool)
        for (dl, zl), (dr, zr) in zip(el, er):
            bad |= np.maximum(dl, dr) * h / np.minimum(zl, zr) > self.delta
        return bad & fl & fr & (h > 1e-12 * wr)

    def _curve_point(self, vals: dict[str, np.ndarray], i: int) -> tuple[float, float] | None:
        u, a, b = vals["u"][i], vals["a"][i], vals["b"][i]
        det = a.real * b.imag - a.imag * b.real
        if not (np.isfinite(det) and det != 0 and np.isfinite(u)):
            return None
        return ((-u.real * b.imag + u.imag * b.real) / det, (-a.real * u.imag + a.imag * u.real) / det)

    def _curve_moves(self, i: int, X: float, Y: float) -> bool:
        """Does the D-decomposition curve (1 + L = 0) move by more than 1e-3 of the box in the decade
        below grid column ``i``?  (Below, it has converged to its low-frequency end point, and a
        boundary crossing there is within that distance of it.)"""
        here = self._curve_point(self._vals, i)
        lower = self._curve_point(self._evaluate(np.array([self.omega[i] / 10.0])), 0)
        if here is None or lower is None:
            return False
        return bool(abs(here[0] - lower[0]) > 1e-3 * X or abs(here[1] - lower[1]) > 1e-3 * Y)

    def _magnitudes(self) -> dict[str, np.ndarray]:
        """``|v|`` of every value and derivative on the current grid (made once per grid)."""
        cached = getattr(self, "_mag_cache", None)
        if cached is None or cached[0] is not self._vals:
            cached = (self._vals, {k: np.abs(v) for k, v in self._vals.items()})
            self._mag_cache = cached
        return cached[1]

    def allowed_spacing(self, X: float, Y: float) -> np.ndarray:
        """Per grid column, the spacing :meth:`refine` accepts there for gains up to ``X, Y``:
        ``delta`` times the size of ``1 + L`` (and of each constraint's terms) over their exact
        derivative, as in :meth:`_bad_intervals` (``inf`` where nothing changes)."""
        v = self._magnitudes()
        mag = v["u"] + X * v["a"] + Y * v["b"]
        der = v["du"] + X * v["da"] + Y * v["db"]
        with np.errstate(divide="ignore", invalid="ignore"):
            h = self.delta * np.maximum(mag, self.r_min) / der
            finite = math.isfinite(X) and math.isfinite(Y)
            for i, (W, dW, zero_gains, zero_dgains) in enumerate(self._constraint_magnitudes()):
                # a term free of the gains (an S bound: na = nb = 0) is |nu| itself: |nu| + X 0 + Y 0 = |nu|
                zero_gains, zero_dgains = zero_gains and finite, zero_dgains and finite
                nmag = v[f"nu{i}"] if zero_gains else v[f"nu{i}"] + X * v[f"na{i}"] + Y * v[f"nb{i}"]
                nder = v[f"dnu{i}"] if zero_dgains else v[f"dnu{i}"] + X * v[f"dna{i}"] + Y * v[f"dnb{i}"]
                h = np.fmin(h, self.delta * np.maximum(np.maximum(W * nmag, mag), self.r_min) / (dW * nmag + W * nder))
        return np.where(np.isnan(h), np.inf, h)

    def _constraint_magnitudes(self) -> list[tuple[np.ndarray, np.ndarray, bool, bool]]:
        """Per constraint, on the current grid: ``|W| / gamma``, ``|W'| / gamma``, and whether the gains'
        terms of its numerator (``na, nb``) and of their derivatives vanish at every column (made once per
        grid, for :meth:`allowed_spacing`)."""
        v = self._magnitudes()
        cached = getattr(self, "_cmag_cache", None)
        if cached is None or cached[0] is not v:
            rows = []
            for i, c in enumerate(self.constraints):
                rows.append((v[f"W{i}"] / c.gamma, v[f"dW{i}"] / c.gamma,
                             not (np.any(v[f"na{i}"]) or np.any(v[f"nb{i}"])),
                             not (np.any(v[f"dna{i}"]) or np.any(v[f"dnb{i}"]))))
            cached = (v, rows)
            self._cmag_cache = cached
        return cached[1]

    def _limit_columns(self) -> None:
        asyms = list(self._asym.values()) + [a for d in self._casym for a in d.values()]
        delays = np.concatenate([a.delays for a in asyms if a.m >= 0] or [np.zeros(1)])
        delays = delays[delays > 0]
        if delays.size == 0:
            theta = np.zeros(1)
        else:
            step = _common_step(delays)
            if step is not None:
                theta = np.linspace(0.0, 2.0 * math.pi / step, _LIMIT_SAMPLES, endpoint=False)
            else:
                theta = np.linspace(0.0, 64 * 2.0 * math.pi / float(delays.min()), 16 * _LIMIT_SAMPLES)
        lim: dict[str, np.ndarray] = {}
        for k, a in self._asym.items():
            lim[k] = a.values(theta)
        for i, d in enumerate(self._casym):
            for k, a in d.items():
                lim[f"{k}{i}"] = a.values(theta)
        self._limit = lim
        self.theta = theta

    def asymptote(self, name: str) -> Asymptote:
        """High-frequency form of ``'u'``, ``'a'`` or ``'b'``."""
        return self._asym[name]

    # ------------------------------------------------------------------ columns
    def columns(self) -> dict[str, np.ndarray]:
        """Grid and limit columns: ``u, a, b`` and ``nu{i}, na{i}, nb{i}, w2{i}`` per constraint."""
        out: dict[str, np.ndarray] = {}
        for k in ("u", "a", "b"):
            out[k] = np.concatenate([self._vals[k], self._limit[k]])
        for i, c in enumerate(self.constraints):
            for k in ("nu", "na", "nb"):
                out[f"{k}{i}"] = np.concatenate([self._vals[f"{k}{i}"], self._limit[f"{k}{i}"]])
            out[f"w2{i}"] = _weight_squared(np.concatenate([self._vals[f"W{i}"], self._limit[f"W{i}"]]), c)
        return out

    @property
    def n_columns(self) -> int:
        return self.n_grid + self.theta.size


# ---------------------------------------------------------------------- columns of one grid
class ConstraintColumns(NamedTuple):
    """One constraint ``|W X| < gamma`` on the columns: ``X``'s numerator ``nu + kx na + ky nb`` and
    ``w2 = |W|^2 / gamma^2``."""

    nu: np.ndarray
    na: np.ndarray
    nb: np.ndarray
    w2: np.ndarray


@dataclass(frozen=True)
class Columns:
    """The frequency data of one grid as arrays: ``1 + L = u + kx a + ky b`` and each constraint.

    Columns ``0 .. n_grid - 1`` are the finite grid ``omega``; the rest are limit
    columns (``omega -> infinity``).  A new grid (:meth:`FrequencyData.refine`)
    needs new columns (:func:`columns_of`).

    Attributes
    ----------
    data : FrequencyData
        The exact frequency response, for refinements between columns.
    omega : ndarray
        The finite grid [rad/s].
    n_grid : int
    u, a, b : ndarray of complex
    constraints : tuple of ConstraintColumns
    """

    data: FrequencyData
    omega: np.ndarray
    n_grid: int
    u: np.ndarray
    a: np.ndarray
    b: np.ndarray
    constraints: tuple[ConstraintColumns, ...]
    #: what the scan derives from these columns alone (per constraint, per line), made once
    cache: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def n_constraints(self) -> int:
        return len(self.constraints)


def _weight_squared(W: np.ndarray, c: Constraint) -> np.ndarray:
    """A constraint's column ``w2 = |W|^2 / gamma^2`` (``|W X| < gamma`` as ``w2 |X|^2 < 1``)."""
    return np.abs(W) ** 2 / c.gamma**2


def columns_of(fd: FrequencyData) -> Columns:
    """The columns of ``fd``'s current grid."""
    cols = fd.columns()
    cons = tuple(ConstraintColumns(cols[f"nu{i}"], cols[f"na{i}"], cols[f"nb{i}"], cols[f"w2{i}"])
                 for i in range(len(fd.constraints)))
    return Columns(fd, fd.omega, fd.n_grid, cols["u"], cols["a"], cols["b"], cons)


#: a grid smaller than this is never thinned (a distributed shaper's or a rational loop's grid is not)
_THIN_ABOVE = 8000


def thinnable(cols: Columns) -> bool:
    """Can :func:`thin_columns` keep fewer than all columns (a large grid, and the frequency data's current one)?"""
    return cols.n_grid >= _THIN_ABOVE and cols.data.omega.size == cols.n_grid


def thin_columns(cols: Columns, X: float, Y: float) -> tuple[Columns, np.ndarray | None]:
    """The grid columns that lines with ``|kx| <= X`` need for ``|ky| <= Y``: ``(columns, their indices)``,
    or ``(cols, None)`` for all of them.

    The grid is refined for the largest gains scanned (:meth:`FrequencyData.refine`).
    A lumped shaper (or any pure delay) in the loop keeps ``|L|`` from decaying, so
    for large ``kx`` the grid must follow the delay's phase ``e^{-j omega tau}``
    with spacing ``~ delta / tau`` up to its ceiling: tens of thousands of columns.
    Lines with smaller ``|kx|`` need that spacing only where ``|kx a| + |ky b|`` is
    not small against ``max(|1 + L|, r)``.  The columns kept here make every step
    shorter than what :meth:`~FrequencyData.refine` accepts for the gains ``X, Y``
    (:meth:`FrequencyData.allowed_spacing`): measured in units of the accepted
    spacing along it (each grid step over the smaller accepted spacing at its two
    ends, summed), a kept step that skips columns is below one unit: the grid
    :meth:`~FrequencyData.refine` would build for those gains, up to the placement
    of its points.  The first and last grid columns and every limit column are kept.  Grids below ``_THIN_ABOVE`` columns are used whole.
    """
    n = cols.n_grid
    if not thinnable(cols):  # small, or columns of an older grid: all of them
        return cols, None
    memo = cols.cache.setdefault("thin", {})  # the optimum's lines ask for the same gains again and again
    key = (float(X), float(Y))
    if key not in memo:
        if len(memo) >= 8:
            memo.pop(next(iter(memo)))
        memo[key] = _thin(cols, *key)
    return memo[key]


def _thin(cols: Columns, X: float, Y: float) -> tuple[Columns, np.ndarray | None]:
    n = cols.n_grid
    h = cols.data.allowed_spacing(float(X), float(Y))
    step = np.diff(cols.omega) / np.fmin(h[:-1], h[1:])
    measure = np.concatenate([[0.0], np.cumsum(np.where(np.isfinite(step), step, 0.0))])
    keep = np.zeros(n, dtype=bool)
    keep[[0, n - 1]] = True
    # a column wherever the measure passes an integer, and the one before: every kept step is < 1 unit
    cross = np.flatnonzero(np.diff(np.floor(measure)) > 0) + 1
    keep[cross] = True
    keep[cross - 1] = True
    if keep.sum() > 0.7 * n:
        return cols, None
    sel = np.flatnonzero(keep)
    return grid_subset(cols, sel), sel


def grid_subset(cols: Columns, sel: np.ndarray) -> Columns:
    """The grid columns ``sel`` (increasing indices below ``n_grid``) and every limit column of ``cols``."""
    full = np.concatenate([sel, np.arange(cols.n_grid, cols.u.size)])
    cons = tuple(ConstraintColumns(c.nu[full], c.na[full], c.nb[full], c.w2[full]) for c in cols.constraints)
    return Columns(cols.data, cols.omega[sel], sel.size, cols.u[full], cols.a[full], cols.b[full], cons)


def with_frequencies(cols: Columns, w: np.ndarray) -> Columns:
    """``cols`` with exact columns at the frequencies ``w`` (> every grid frequency, increasing) added after
    its grid columns (:meth:`FrequencyData.values`; for probes beyond the grid's end)."""
    v = cols.data.values(np.asarray(w, dtype=float))
    n = cols.n_grid

    def join(old: np.ndarray, new: np.ndarray) -> np.ndarray:
        return np.concatenate([old[:n], new, old[n:]])

    cons = tuple(ConstraintColumns(join(c.nu, v[f"nu{i}"]), join(c.na, v[f"na{i}"]), join(c.nb, v[f"nb{i}"]),
                                   join(c.w2, _weight_squared(v[f"W{i}"], con)))
                 for i, (c, con) in enumerate(zip(cols.constraints, cols.data.constraints)))
    return Columns(cols.data, np.concatenate([cols.omega[:n], w]), n + w.size, join(cols.u, v["u"]),
                   join(cols.a, v["a"]), join(cols.b, v["b"]), cons)


def _refuse_improper_loop(asym: dict[str, Asymptote], family: ControllerFamily, architecture: str) -> None:
    """ValueError when ``C P`` grows without bound (an ideal derivative on a plant of relative degree 0)."""
    for k in ("a", "b"):
        if asym[k].m > 0:
            raise ValueError(
                f"the loop gain C P is improper for this controller ({family.describe()}): P = "
                f"{'G' if architecture == 'feedforward' else 'G S' if architecture == 'control_action' else 'G / S'}"
                " needs more poles than zeros (a PD needs relative degree >= 1, a PID with ideal "
                "derivative too; or set derivative_filter)"
            )


def _safe_eval(tf: TransferFunction, s: float) -> complex:
    try:
        return complex(tf(s))
    except (ZeroDivisionError, OverflowError, ValueError):
        return complex(np.inf)
