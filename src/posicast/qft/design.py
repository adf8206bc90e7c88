"""Automatic QFT loop shaping (seed 003 eq. 2-3): the least high-frequency gain meeting every bound.

The user fixes the controller's structure (:class:`~posicast.qft.structure.Structure`); the
design minimises QFT's cost, the high-frequency gain of ``G`` (its leading-coefficient ratio),
subject to

* the robust stability bound ``|P_k G / (1 + P_k G)| <= gamma`` (eq. 2) and
* the model-matching bound ``|P_k G F / (1 + P_k G) - F_m| <= delta`` (eq. 3)

for every plant ``P_k`` of the set at every design frequency, and to a stable inner closed loop
for every plant (spectral abscissa ``<= -stability_margin``).  The problem is solved by SLSQP
on the log-parameters from a few deterministic starts; the best feasible design is then checked
on a dense grid (:func:`~posicast.qft.specs.verify`, certified stability by
:func:`posicast.stability`).  A frequency where the dense check fails is added to the design
grid and the design repeated (at most ``refinements`` times).  An infeasible specification is a
result with ``feasible = False`` and the violated bounds named, never an exception.

An optional output-disturbance bound ``|1 / (1 + P_k G)| <= sigma`` (up to ``omega_max``) joins them.

The prefilter is the reference model (``F = F_m``, the paper's choice: eq. 3 becomes the
output-disturbance bound ``|F_m / (1 + L_k)| <= delta``) unless a fixed one is given or its
correction ``F_c`` (``F = F_m F_c``, unit DC gain) is synthesised with ``G`` (``prefilter_structure``).
SLSQP finds a local optimum: the cost is the best of the starts, not a certified global minimum.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np
from scipy.optimize import minimize

from .. import _validate as v
from ..core.transfer import TransferFunction, as_transfer
from .plantset import PlantSet
from .specs import SpecData, Verification, dense_grid, disturbance_spec, nichols_bounds, verify
from .structure import SECTIONS, Structure

__all__ = ["QFTResult", "qft_design", "DEFAULT_STRUCTURE"]

#: The design meets every bound with 0.1 dB to spare on its grid (the dense check sees between the points).
_BACKOFF = 10 ** (-0.1 / 20)

#: Three real zeros (the paper's phase lead of +270 deg), made proper by three real poles.
DEFAULT_STRUCTURE = ("lead", "lead", "lead")


@dataclass(frozen=True)
class QFTResult:
    """A QFT design: the controller ``G``, the prefilter ``F`` and their check over the plant set.

    Attributes
    ----------
    controller, prefilter : TransferFunction
        ``G`` and ``F``.
    feasible : bool
        Every bound met on the dense grid and every inner loop certified stable.
    margins : mapping
        Per bound: ``"stability"``, ``"matching"`` (and ``"disturbance"``) in dB (>= 0 met), ``"inner_loops"``
        the largest spectral abscissa [rad/s] (< 0 met).
    violated : tuple of str
        The names of the failed bounds (empty when feasible).
    high_frequency_gain : float
        QFT's cost (the leading-coefficient ratio of ``G``).
    parameters : mapping
        The structure's parameters.
    verification : Verification
    """

    controller: TransferFunction
    prefilter: TransferFunction
    feasible: bool
    margins: Mapping[str, float]
    violated: tuple[str, ...]
    high_frequency_gain: float
    parameters: Mapping[str, float]
    verification: Verification
    plants: PlantSet = field(repr=False)
    reference: TransferFunction = field(repr=False)
    specs: tuple[float, float] = (1.413, 0.1)
    frequencies: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    disturbance: tuple[float, float] | None = None

    @classmethod
    def check(cls, plants: Any, reference: Any, G: Any, F: Any = None, *, stability: float, matching: float,
              frequencies: Any = None, disturbance: Any = None) -> QFTResult:
        """The result for a given controller ``G`` and prefilter ``F`` (default ``F = F_m``), checked like a design.

        For a printed design (seed 003's ``G``): its margins, violated bounds and Nichols chart.
        The high-frequency gain of an improper ``G`` is infinite.

        >>> from posicast import cases
        >>> c = cases.ALL["two_mass"]
        >>> r = QFTResult.check(PlantSet.two_mass(), c.extras["F_m"], c.extras["G_qft"], stability=1.413, matching=0.1)
        >>> r.feasible, r.violated, r.high_frequency_gain
        (False, ('matching',), inf)
        """
        ps = plants if isinstance(plants, PlantSet) else PlantSet.from_list(v.sequence(plants, "plants"))
        ref = as_transfer(reference, "reference")
        Gt = as_transfer(G, "G")
        Ft = None if F is None else as_transfer(F, "F")
        gamma, delta = _check_spec(stability, "stability"), _check_spec(matching, "matching")
        freqs = _frequencies(frequencies)
        lo, hi = _feature_range(ps, ref)
        dense = dense_grid(min(lo, freqs.min()) / 30, max(hi, freqs.max()) * 30, 1000)
        dist = disturbance_spec(disturbance)
        chk = verify(ps, Gt, Ft, ref, gamma, delta, dense, dist)
        num, den = (np.trim_zeros(np.asarray(x, float), "f") for x in (Gt.to_scipy().num, Gt.to_scipy().den))
        hf = float("inf") if num.size > den.size else (abs(num[0] / den[0]) if num.size == den.size else 0.0)
        return cls(Gt, ref if Ft is None else Ft, chk.ok, chk.margins, chk.violated, hf, {}, chk, ps, ref,
                   (gamma, delta), freqs, dist)

    def summary(self) -> str:
        """A few lines: feasibility, margins, cost and parameters."""
        state = "feasible" if self.feasible else f"INFEASIBLE (violated: {', '.join(self.violated)})"
        lines = [f"QFT design over {len(self.plants)} plants: {state}",
                 f"  margins: stability {self.margins['stability']:+.2f} dB, matching "
                 f"{self.margins['matching']:+.2f} dB, "
                 + (f"disturbance {self.margins['disturbance']:+.2f} dB, " if "disturbance" in self.margins else "")
                 + f"inner loops abscissa {self.margins['inner_loops']:.3g} rad/s",
                 f"  high-frequency gain {self.high_frequency_gain:.6g}",
                 "  " + ", ".join(f"{k} = {x:.5g}" for k, x in self.parameters.items())]
        return "\n".join(lines)

    def plot(self, ax: Any = None) -> Any:
        """Nichols chart: the bounds at the design's template frequencies and the nominal open loop.

        Returns ``(fig, ax)``.
        """
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 5)) if ax is None else (v.axes(ax).figure, ax)
        phases = np.linspace(-360.0, 0.0, 181)
        gains = np.linspace(-40.0, 80.0, 161)
        F = None if self.prefilter is self.reference else self.prefilter
        ok = nichols_bounds(self.plants, self.frequencies, self.reference, F, *self.specs, phases, gains,
                            disturbance=self.disturbance)
        colors = plt.cm.viridis(np.linspace(0, 0.9, len(self.frequencies)))
        for i, w in enumerate(self.frequencies):
            if ok[i].all() or not ok[i].any():
                continue
            cs = ax.contour(phases, gains, ok[i].astype(float), levels=[0.5], colors=[colors[i]])
            ax.plot([], [], color=colors[i], label=f"bound {w:g} rad/s")
            del cs
        w = dense_grid(self.frequencies.min() / 10, self.frequencies.max() * 10, 400)
        L0 = self.plants.nominal.freqresp(w) * self.controller.freqresp(w)
        ph = np.rad2deg(np.unwrap(np.angle(L0)))
        ph -= 360.0 * np.floor((ph.max()) / 360.0) if ph.max() > 0 else 0.0
        ax.plot(ph, 20 * np.log10(np.abs(L0)), "k-", lw=1.5, label="nominal L0 = P0 G")
        L0t = self.plants.nominal.freqresp(self.frequencies) * self.controller.freqresp(self.frequencies)
        pht = np.interp(self.frequencies, w, ph)
        ax.plot(pht, 20 * np.log10(np.abs(L0t)), "ko", ms=4)
        ax.set_xlabel("open-loop phase [deg]")
        ax.set_ylabel("open-loop gain [dB]")
        ax.set_title("QFT bounds (seed 003 eq. 2-3) and the nominal loop")
        ax.legend(fontsize=7, loc="lower right")
        return fig, ax


def _check_spec(value: Any, name: str) -> float:
    x = v.real(value, name)
    if x <= 0:
        raise ValueError(f"{name} must be a bound > 0 on a magnitude (absolute, not dB), got {x:g}")
    return x


def _abscissae(polys: Sequence[tuple[np.ndarray, np.ndarray]], num: np.ndarray, den: np.ndarray) -> np.ndarray:
    """The spectral abscissa of every inner loop ``D_P D_G + N_P N_G``: one batched eigenvalue call.

    (Fast and uncertified, for the optimiser; the result is certified by :func:`verify`.)
    """
    chars = []
    for pn, pd in polys:
        a, b = np.convolve(pd, den), np.convolve(pn, num)
        n = max(a.size, b.size)
        c = np.zeros(n)
        c[n - a.size:] += a
        c[n - b.size:] += b
        chars.append(np.trim_zeros(c, "f"))
    deg = {c.size for c in chars}
    if len(deg) != 1 or not all(np.all(np.isfinite(c)) for c in chars):
        return np.array([float(np.roots(c).real.max()) if np.all(np.isfinite(c)) and c.size > 1 else
                         (1e6 if not np.all(np.isfinite(c)) else -1e6) for c in chars])
    m = deg.pop() - 1
    if m < 1:
        return np.full(len(chars), -1e6)
    comp = np.zeros((len(chars), m, m))
    lead = np.array([c[0] for c in chars])
    comp[:, 0, :] = -np.array([c[1:] for c in chars]) / lead[:, None]
    comp[:, np.arange(1, m), np.arange(m - 1)] = 1.0
    if not np.all(np.isfinite(comp)):
        return np.full(len(chars), 1e6)
    return np.linalg.eigvals(comp).real.max(axis=1)


def _frequencies(frequencies: Any) -> np.ndarray:
    """The QFT template frequencies (default: 8 from 0.05 to 20 rad/s, as in seed 003's Fig. 3)."""
    if frequencies is None:
        return np.array([0.05, 0.1, 0.5, 1.0, 2.0, 3.2, 5.0, 20.0])
    freqs = np.unique(v.strict_real_array(frequencies, "frequencies"))
    if freqs.size == 0 or np.any(freqs <= 0) or freqs.size > 1000 or freqs.max() / freqs.min() > 1e12:
        raise ValueError(f"frequencies must be 1 to 1000 values > 0 [rad/s] spanning at most 12 decades, got "
                         f"{freqs.size} values")
    return freqs


def _feature_range(plants: PlantSet, reference: TransferFunction) -> tuple[float, float]:
    mags = []
    for num, den in plants.polynomials() + ((reference.to_scipy().num, reference.to_scipy().den),):
        for poly in (num, den):
            r = np.abs(np.roots(poly))
            mags.extend(r[r > 1e-9])
    if not mags:
        return 0.1, 10.0
    return float(min(mags)), float(max(mags))


def _starts(structure: Structure, lo: float, hi: float, center: float,
            prefilter: Structure | None = None) -> list[np.ndarray]:
    """Deterministic starting points: zeros spread about the reference's mode, poles far above.

    A prefilter correction starts as the identity (its zeros and poles at the same frequencies).
    """
    kinds = [n.split(".")[-1] for n in structure.names[1:]]
    zeros = [i for i, k in enumerate(kinds) if k in ("z", "w", "wz")]
    out = []
    for spread, pole_factor in ((20.0, 600.0), (10.0, 300.0), (40.0, 1000.0)):
        zs = np.geomspace(center / np.sqrt(spread), center * np.sqrt(spread), max(1, len(zeros)))
        x = [np.log(1e3)]
        for i, k in enumerate(kinds):
            if k in ("zeta", "zz"):
                x.append(np.log(0.3))
            elif k == "zp":
                x.append(np.log(0.7))
            elif i in zeros:
                x.append(np.log(np.clip(zs[zeros.index(i)], lo, hi)))
            else:
                x.append(np.log(min(hi, center * pole_factor)))
        if prefilter is not None:
            x += [np.log(0.7) if n.split(".")[-1] in ("zeta", "zz", "zp") else np.log(center)
                  for n in prefilter.names]
            x[len(structure.names)] = 0.0  # F_c's gain: 1
        out.append(np.array(x))
    return out


def _sections(value: Any, name: str) -> Structure:
    secs = tuple(v.sequence(value, name))
    for sec in secs:
        v.choice(sec, f"{name} section", tuple(SECTIONS))
    return Structure(secs)


def _controller_structure(structure: Any) -> Structure:
    st = _sections(structure, "structure")
    if st.relative_degree < 0:
        raise ValueError(f"structure must give a proper controller (relative degree >= 0), got "
                         f"{st.relative_degree} for {st.sections}: add poles")
    return st


def _prefilter_parts(prefilter: Any, prefilter_structure: Any) -> tuple[TransferFunction | None, Structure | None]:
    """The fixed prefilter ``F`` or the structure of a synthesised ``F_c`` (at most one of them)."""
    F = None if prefilter is None else as_transfer(prefilter, "prefilter")
    stF = None
    if prefilter_structure is not None:
        if prefilter is not None:
            raise ValueError("prefilter_structure must not be given with a fixed prefilter")
        stF = _sections(prefilter_structure, "prefilter_structure")
        if stF.relative_degree < 0:
            raise ValueError(f"prefilter_structure must be proper (relative degree >= 0), got {stF.relative_degree}")
    if F is not None:
        num, den = F.to_scipy().num, F.to_scipy().den
        if F.has_delays or len(np.trim_zeros(num, "f")) > len(np.trim_zeros(den, "f")):
            raise ValueError("prefilter must be a proper, delay-free transfer function")
    return F, stF


@dataclass(frozen=True)
class _QFTProblem:
    """The checked specification of :func:`qft_design` and the grids, bounds and starts' scale built from it."""

    ps: PlantSet
    ref: TransferFunction
    gamma: float
    delta: float
    st: Structure
    F: TransferFunction | None
    stF: Structure | None
    freqs: np.ndarray
    dist: Any
    margin: float
    refinements: int
    maxiter: int
    w_lo: float
    w_hi: float
    grid: np.ndarray    # the first design grid
    dense: np.ndarray   # the check's grid
    polys: Any
    center: float       # the reference's pole scale
    bounds: Any
    nG: int             # the controller's parameters (then F_c's)


def _qft_problem(plants: Any, reference: Any, stability: Any, matching: Any, frequencies: Any, structure: Any,
                 prefilter: Any, prefilter_structure: Any, disturbance: Any, stability_margin: Any,
                 refinements: Any, maxiter: Any) -> _QFTProblem:
    ps = plants if isinstance(plants, PlantSet) else PlantSet.from_list(v.sequence(plants, "plants"))
    ref = as_transfer(reference, "reference")
    if ref.has_delays:
        raise ValueError("reference must be delay-free (rational)")
    gamma = _check_spec(stability, "stability")
    delta = _check_spec(matching, "matching")
    st = _controller_structure(structure)
    F, stF = _prefilter_parts(prefilter, prefilter_structure)
    freqs = _frequencies(frequencies)
    dist = disturbance_spec(disturbance)
    margin = v.nonnegative(stability_margin, "stability_margin")
    refinements = v.integer_in_range(refinements, "refinements", 0, 20)
    maxiter = v.integer_in_range(maxiter, "maxiter", 1, 100_000)
    return _QFTProblem(ps, ref, gamma, delta, st, F, stF, freqs, dist, margin, refinements, maxiter,
                       *_grids(ps, ref, freqs, st, stF))


def _grids(ps: PlantSet, ref: TransferFunction, freqs: np.ndarray, st: Structure,
           stF: Structure | None) -> tuple[Any, ...]:
    """``(w_lo, w_hi, grid, dense, polys, center, bounds, nG)`` of :class:`_QFTProblem`."""
    lo, hi = _feature_range(ps, ref)
    w_lo, w_hi = min(lo, freqs.min()) / 30, max(hi, freqs.max()) * 30
    grid = np.union1d(dense_grid(w_lo, w_hi, 60), freqs)
    polys = ps.polynomials()
    rden = np.trim_zeros(np.asarray(ref.to_scipy().den, float), "f")
    center = float(abs(rden[-1] / rden[0]) ** (1.0 / max(1, rden.size - 1)))  # the reference's pole scale
    if not (np.isfinite(center) and center > 0):
        center = float(np.sqrt(lo * hi))
    bounds = st.bounds(w_lo / 10, w_hi * 10)
    nG = st.n_params
    if stF is not None:  # F_c's gain is fixed at 1 (unit DC gain: the reference model's)
        bounds = bounds + [(0.0, 0.0)] + stF.bounds(w_lo / 10, w_hi * 10)[1:]
    dense = dense_grid(w_lo, w_hi, 1000)
    return w_lo, w_hi, grid, dense, polys, center, bounds, nG


def _prefilter_at(p: _QFTProblem, x: np.ndarray, s_: np.ndarray) -> np.ndarray | None:
    if p.stF is None:
        return None
    fn, fd = p.stF.polynomials(x[p.nG:])
    return p.ref.freqresp(s_.imag) * np.polyval(fn, s_) / np.polyval(fd, s_)


def _constraints(p: _QFTProblem, data: SpecData, grid_: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The bounds as ``>= 0`` constraints (log margins on ``grid_``, then the inner loops' abscissae)."""
    s = 1j * grid_
    num, den = p.st.polynomials(x[:p.nG])
    T, E, S = data.values(np.polyval(num, s) / np.polyval(den, s), _prefilter_at(p, x, s) if p.stF else None)
    ab = -p.margin - _abscissae(p.polys, num, den)
    # the worst plant at each frequency, with a back-off so that the dense check passes between points
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        parts = [np.log(p.gamma * _BACKOFF) - np.log(T.max(0)), np.log(p.delta * _BACKOFF) - np.log(E.max(0))]
        if p.dist is not None:
            parts.append((np.log(p.dist[0] * _BACKOFF) - np.log(S.max(0)))[grid_ <= p.dist[1]])
        out = np.concatenate(parts + [np.atleast_1d(ab)])
    return np.nan_to_num(out, nan=-1e6, posinf=1e6, neginf=-1e6)


def _gain_raised(cons: Any, x0: np.ndarray, n_grid: int) -> np.ndarray:
    """The gain that meets the matching bound at the nominal plant, a feasible-leaning start."""
    x0 = x0.copy()
    for _ in range(60):
        with np.errstate(all="ignore"):
            ok = np.min(cons(x0)[: 2 * n_grid]) > -0.5
        if ok or x0[0] > 25:
            break
        x0[0] += 0.5
    return x0


def _solve(p: _QFTProblem, grid_: np.ndarray, starts: list[np.ndarray]) -> tuple[np.ndarray | None, float]:
    """The lowest-cost feasible SLSQP result over ``starts`` on ``grid_`` (None if none is feasible)."""
    data = SpecData.at(p.ps, p.ref, p.F, grid_)

    def cons(x: np.ndarray) -> np.ndarray:
        return _constraints(p, data, grid_, x)

    def cost(x: np.ndarray) -> float:
        return float(np.log(p.st.high_frequency_gain(x[:p.nG])))

    best, best_cost = None, np.inf
    for x0 in starts:
        x0 = _gain_raised(cons, x0, grid_.size)
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore", RuntimeWarning)
            res = minimize(cost, x0, method="SLSQP", bounds=p.bounds,
                           constraints=[{"type": "ineq", "fun": cons}],
                           options={"maxiter": p.maxiter, "ftol": 1e-9})
        if np.all(np.isfinite(res.x)) and np.min(cons(res.x)) >= -1e-6 and cost(res.x) < best_cost:
            best, best_cost = res.x, cost(res.x)
    return best, best_cost


def _dense_violations(p: _QFTProblem, x: np.ndarray) -> np.ndarray:
    """Where on the dense grid a bound fails for the design ``x``."""
    G = p.st.transfer(x[:p.nG])
    data = SpecData.at(p.ps, p.ref, p.F, p.dense)
    T, E, S = data.values(G.freqresp(p.dense), _prefilter_at(p, x, 1j * p.dense) if p.stF else None)
    bad = (T.max(0) > p.gamma) | (E.max(0) > p.delta)
    if p.dist is not None:
        bad |= (S.max(0) > p.dist[0]) & (p.dense <= p.dist[1])
    return bad


def _refined(p: _QFTProblem) -> np.ndarray:
    """The design, redesigned with the dense check's failing frequencies added (``refinements`` times at most)."""
    grid = p.grid
    x_best = None
    for _ in range(p.refinements + 1):  # a refinement starts from the previous design
        x_new, _c = _solve(p, grid, _starts(p.st, p.w_lo, p.w_hi, p.center, p.stF) if x_best is None else [x_best])
        if x_new is None:
            break
        x_best = x_new
        bad = _dense_violations(p, x_best)
        if not bad.any():
            break
        grid = np.union1d(grid, p.dense[bad][:: max(1, int(bad.sum()) // 40)])
    if x_best is None:  # no start converged to a feasible point: report the closest attempt
        x_best = _starts(p.st, p.w_lo, p.w_hi, p.center, p.stF)[0]
    return x_best


def _qft_result(p: _QFTProblem, x_best: np.ndarray) -> QFTResult:
    st, stF, nG, ref, F = p.st, p.stF, p.nG, p.ref, p.F
    G = st.transfer(x_best[:nG])
    if stF is not None:
        F = ref * stF.transfer(x_best[nG:])
    Ffin = ref if F is None else F
    chk = verify(p.ps, G, F, ref, p.gamma, p.delta, p.dense, p.dist)
    params = st.parameters(x_best[:nG])
    if stF is not None:
        params.update({f"F.{k}": val for k, val in stF.parameters(x_best[nG:]).items() if k != "K"})
    return QFTResult(G, Ffin, chk.ok, chk.margins, chk.violated, st.high_frequency_gain(x_best[:nG]),
                     params, chk, p.ps, ref, (p.gamma, p.delta), p.freqs, p.dist)


def qft_design(
    plants: Any,
    reference: Any,
    *,
    stability: float,
    matching: float,
    frequencies: Any = None,
    structure: Sequence[str] = DEFAULT_STRUCTURE,
    prefilter: Any = None,
    prefilter_structure: Sequence[str] | None = None,
    disturbance: Any = None,
    stability_margin: float = 0.05,
    refinements: int = 3,
    maxiter: int = 300,
) -> QFTResult:
    """Design the inner-loop controller ``G`` (and prefilter ``F``) of seed 003 automatically.

    Parameters
    ----------
    plants : PlantSet or sequence of plants
        The uncertain plant set (seed 003: :meth:`PlantSet.two_mass`, 27 plants).
    reference : plant-like
        The reference model ``F_m`` (eq. 1).
    stability : float
        ``gamma`` of eq. 2, a bound on ``|P G / (1 + P G)|`` (the paper: 1.413, 3 dB).
    matching : float
        ``delta`` of eq. 3, a bound on ``|P G F / (1 + P G) - F_m|`` (the paper: 0.1, -20 dB).
    frequencies : array_like, optional
        The QFT template frequencies [rad/s] (for the bounds of :meth:`QFTResult.plot`; they
        join the design grid).  Default: 8 frequencies from 0.05 to 20 rad/s, as in the paper.
    structure : sequence of str
        The controller's sections (:class:`~posicast.qft.structure.Structure`).
    prefilter : plant-like, optional
        A fixed prefilter ``F``; default ``F = F_m`` (the paper's choice).
    prefilter_structure : sequence of str, optional
        Synthesise the prefilter too: ``F = F_m F_c`` with ``F_c`` of these sections at unit DC
        gain, designed jointly with ``G`` (excludes ``prefilter``).
    disturbance : float or (float, float), optional
        Output-disturbance rejection ``|1 / (1 + P G)| <= sigma``: ``sigma``, or ``(sigma, omega_max)``
        for frequencies up to ``omega_max`` rad/s.
    stability_margin : float
        Every inner closed loop's poles at ``Re s <= -stability_margin`` during the design.
    refinements : int
        How often the dense check may add its failing frequencies and redesign.
    maxiter : int
        SLSQP iterations per start.

    Returns
    -------
    QFTResult

    Examples
    --------
    >>> from posicast import cases
    >>> r = qft_design(PlantSet.two_mass(), cases.ALL["two_mass"].extras["F_m"], stability=1.413, matching=0.1)
    >>> r.feasible, r.margins["matching"] >= 0.0
    (True, True)
    """
    p = _qft_problem(plants, reference, stability, matching, frequencies, structure, prefilter,
                     prefilter_structure, disturbance, stability_margin, refinements, maxiter)
    return _qft_result(p, _refined(p))
