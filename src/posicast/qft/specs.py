"""The QFT specifications of seed 003 evaluated over a plant set: margins, verification and Nichols bounds.

For a plant ``P_k``, controller ``G`` and prefilter ``F`` with ``L_k = P_k G``:

* robust stability (seed 003 eq. 2): ``|L_k / (1 + L_k)| <= gamma`` (3 dB = 1.413 in the paper);
* model matching (eq. 3): ``|L_k F / (1 + L_k) - F_m| <= delta`` (-20 dB = 0.1);
* optionally, output-disturbance rejection ``|1 / (1 + L_k)| <= sigma`` (up to ``omega_max``);
* every inner closed loop stable: the roots of ``D_P D_G + N_P N_G``, certified by
  :func:`posicast.spectra.stability` in :func:`verify`.

A **margin** is ``20 log10(bound / worst value)`` in dB over all plants and frequencies: >= 0
means the specification holds.

>>> from posicast import cases
>>> c = cases.ALL["two_mass"]
>>> chk = verify(PlantSet.two_mass(), c.extras["G_qft"], c.extras["F_m"], c.extras["F_m"], 1.413, 0.1)
>>> chk.ok, round(chk.worst["matching"], 2)        # the paper's own design misses eq. 3
(False, 0.3)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from .. import _validate as v
from ..core.transfer import TransferFunction, as_transfer
from ..spectra.rootfinder import RootFindingError
from ..spectra.systems import stability
from .plantset import PlantSet

__all__ = ["SpecData", "Verification", "verify", "nichols_bounds", "dense_grid", "disturbance_spec"]


@dataclass(frozen=True)
class SpecData:
    """Everything the specifications need at a frequency grid ``w``: plants, reference, prefilter."""

    w: np.ndarray
    P: np.ndarray  # (plants, frequencies)
    Fm: np.ndarray
    F: np.ndarray | None  # None: the prefilter is the reference model

    @classmethod
    def at(cls, plants: PlantSet, reference: TransferFunction, prefilter: TransferFunction | None,
           w: np.ndarray) -> SpecData:
        s = 1j * w
        P = np.array([np.polyval(n, s) / np.polyval(d, s) for n, d in plants.polynomials()])
        return cls(w, P, reference.freqresp(w), None if prefilter is None else prefilter.freqresp(w))

    def values(self, Gw: np.ndarray, Fw: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``|T_k|``, ``|T_k F - F_m|`` and ``|S_k| = |1 / (1 + L_k)|`` for the controller's response ``Gw``.

        Three ``(plants, w)`` arrays; ``Fw`` overrides the prefilter's response.
        """
        L = self.P * Gw
        S = 1.0 / (1.0 + L)
        T = L * S
        F = Fw if Fw is not None else (self.Fm if self.F is None else self.F)
        return np.abs(T), np.abs(T * F - self.Fm), np.abs(S)


_NO_CONTROLLER = object()  # nichols_bounds has no controller to check


def _checked(plants: Any, G: Any, F: Any, reference: Any, gamma: Any, delta: Any, gname: str,
             dname: str) -> tuple[PlantSet, Any, Any, TransferFunction, float, float]:
    """The arguments of :func:`verify` and :func:`nichols_bounds`, checked (named errors)."""
    ps = plants if isinstance(plants, PlantSet) else PlantSet.from_list(v.sequence(plants, "plants"))
    out_G = None if G is _NO_CONTROLLER else as_transfer(G, "G")
    out_F = None if F is None else as_transfer(F, "F")
    ref = as_transfer(reference, "reference")
    for x, nm in ((out_G, "G"), (out_F, "F"), (ref, "reference")):
        if x is not None and x.has_delays:
            raise ValueError(f"{nm} must be delay-free (rational), got delay {x.max_delay:g} s")
    g, d = v.positive(gamma, gname), v.positive(delta, dname)
    return ps, out_G, out_F, ref, g, d


def dense_grid(lo: float, hi: float, per_decade: int = 2000) -> np.ndarray:
    """A log grid of ``per_decade`` points per decade over ``[lo, hi]``."""
    n = int(np.ceil(np.log10(hi / lo) * per_decade)) + 1
    return np.logspace(np.log10(lo), np.log10(hi), n)


@dataclass(frozen=True)
class Verification:
    """The check of a design on a dense grid over every plant.

    Attributes
    ----------
    margins : mapping
        ``"stability"``, ``"matching"`` [dB, >= 0 met] and ``"inner_loops"`` (the largest
        spectral abscissa of the inner closed loops, rad/s: < 0 met).
    worst : mapping
        The worst value of each bound (``|T|``, ``|T F - F_m|``) and where: ``*_omega``, ``*_plant``.
    stable : tuple of bool
        Certified stability of each inner closed loop (:func:`posicast.stability`).
    ok : bool
    violated : tuple of str
        The names of the failed bounds.
    """

    margins: Mapping[str, float]
    worst: Mapping[str, float]
    stable: tuple[bool, ...]
    violated: tuple[str, ...] = field(default=())

    @property
    def ok(self) -> bool:
        return not self.violated


def verify(plants: PlantSet, G: TransferFunction, F: TransferFunction | None, reference: TransferFunction,
           gamma: float, delta: float, w: np.ndarray | None = None, disturbance: Any = None) -> Verification:
    """Check ``G`` and ``F`` over every plant on a dense grid, with certified inner-loop stability.

    ``disturbance`` (optional): the output-disturbance bound ``|1 / (1 + P G)| <= sigma``, given as
    ``sigma`` (every frequency) or ``(sigma, omega_max)`` (up to ``omega_max`` rad/s).
    """
    plants, G, F, reference, gamma, delta = _checked(plants, G, F, reference, gamma, delta, "gamma", "delta")
    dist = disturbance_spec(disturbance)
    if w is None:
        w = dense_grid(1e-3, 1e4, 1000)
    data = SpecData.at(plants, reference, F, w)
    T, E, S = data.values(G.freqresp(w))
    worst: dict[str, float] = {}
    checks = [("stability", T), ("matching", E)]
    if dist is not None:
        checks.append(("disturbance", np.where(w <= dist[1], S, 0.0)))
    for name, arr in checks:
        k, i = np.unravel_index(int(np.argmax(arr)), arr.shape)
        worst[name], worst[f"{name}_omega"], worst[f"{name}_plant"] = float(arr[k, i]), float(w[i]), int(k)
    stable, abscissa = [], []
    for P in plants:
        loop = (P * G).feedback()
        stable.append(_certified_stable(loop))
        with np.errstate(all="ignore"):
            r = np.roots(loop.to_scipy().den)
        abscissa.append(float(r.real.max()) if r.size else -np.inf)
    with np.errstate(divide="ignore", over="ignore"):
        margins = {"stability": float(20 * (np.log10(gamma) - np.log10(worst["stability"]))),
                   "matching": float(20 * (np.log10(delta) - np.log10(worst["matching"]))),
                   "inner_loops": float(max(abscissa))}
        if dist is not None:
            margins["disturbance"] = float(20 * (np.log10(dist[0]) - np.log10(worst["disturbance"])))
    violated = tuple(n for n in ("stability", "matching", "disturbance") if n in margins and margins[n] < 0)
    if not all(stable):
        violated += ("inner_loops",)
    return Verification(margins, worst, tuple(stable), violated)


def _certified_stable(loop: TransferFunction) -> bool:
    """:func:`posicast.stability` of an inner closed loop; False when it cannot be certified.

    A characteristic polynomial whose coefficients span more than 1e60 (an absurd gain) is not
    certified (False), nor is one the root finder gives up on within its budget.
    """
    den = np.abs(np.asarray(loop.to_scipy().den, float))
    nz = den[den > 0]
    if nz.size == 0 or not np.all(np.isfinite(nz)) or nz.max() / nz.min() > 1e60:
        return False
    try:
        return bool(stability(loop, max_evaluations=2e6, timeout=2.0).stable)
    except (RootFindingError, ValueError):
        return False


def nichols_bounds(plants: PlantSet, frequencies: np.ndarray, reference: TransferFunction,
                   prefilter: TransferFunction | None, gamma: float, delta: float,
                   phases: np.ndarray | None = None, gains_db: np.ndarray | None = None,
                   disturbance: Any = None) -> np.ndarray:
    """QFT bounds on the nominal loop ``L_0 = P_0 G``: admissible ``(frequency, gain, phase)`` cells.

    Every cell of the Nichols grid (``phases`` in degrees, ``gains_db``) is checked exactly
    against every template point: ``L_k = L_0 P_k / P_0`` must meet both specifications.

    Returns
    -------
    ndarray of bool, shape ``(frequencies, gains, phases)``: True where ``L_0`` may lie.
    """
    plants, _, prefilter, reference, gamma, delta = _checked(plants, _NO_CONTROLLER, prefilter, reference, gamma, delta,
                                                             "gamma", "delta")
    dist = disturbance_spec(disturbance)
    frequencies = np.atleast_1d(v.strict_real_array(frequencies, "frequencies")).reshape(-1)
    if frequencies.size == 0 or frequencies.size > 1000:
        raise ValueError(f"frequencies must hold 1 to 1000 values, got {frequencies.size}")
    phases = np.linspace(-360.0, 0.0, 181) if phases is None else phases
    gains_db = np.linspace(-40.0, 60.0, 201) if gains_db is None else gains_db
    tmpl = plants.templates(frequencies)  # (w, k)
    ratio = tmpl / tmpl[:, [plants.nominal_index]]
    L0 = 10 ** (gains_db[:, None] / 20) * np.exp(1j * np.deg2rad(phases))[None, :]
    Fm = reference.freqresp(frequencies)
    F = Fm if prefilter is None else prefilter.freqresp(frequencies)
    out = np.ones((len(frequencies), len(gains_db), len(phases)), dtype=bool)
    for i in range(len(frequencies)):
        for k in range(ratio.shape[1]):
            L = L0 * ratio[i, k]
            T = L / (1 + L)
            out[i] &= (np.abs(T) <= gamma) & (np.abs(T * F[i] - Fm[i]) <= delta)
            if dist is not None and frequencies[i] <= dist[1]:
                out[i] &= np.abs(1.0 / (1 + L)) <= dist[0]
    return out


def disturbance_spec(value: Any) -> tuple[float, float] | None:
    """``sigma`` or ``(sigma, omega_max)`` as ``(sigma, omega_max)`` (``omega_max = inf`` by default), or None."""
    if value is None:
        return None
    if isinstance(value, (tuple, list)):
        sigma, wmax = v.pair(value, "disturbance", "sigma or a (sigma, omega_max) pair")
        if isinstance(wmax, (float, np.floating)) and wmax == np.inf:  # "every frequency"
            return v.positive(sigma, "disturbance sigma"), float("inf")
        return v.positive(sigma, "disturbance sigma"), v.positive(wmax, "disturbance omega_max")
    return v.positive(value, "disturbance"), float("inf")
