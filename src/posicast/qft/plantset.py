"""Uncertain plant sets: the plants a QFT design must cover (seed 003 "Inner-loop controllers").

A :class:`PlantSet` is an ordered, non-empty tuple of delay-free transfer
functions with one **nominal** member.  It is built

* from a list of plants (:meth:`PlantSet.from_list`; the nominal given by index),
* from parameter ranges of a plant model (:meth:`PlantSet.from_ranges`): the full
  grid of ``n`` values per parameter (seed 003: c1, c2, k2 at -50 %, 0, +50 %, the
  27 plants), the vertices only (2 values per parameter), or ``samples`` random
  parameter vectors drawn uniformly with a given ``seed`` (reproducible);
* or, for seed 003's two-mass plant (eq. 1), by :meth:`PlantSet.two_mass` with any
  uncertainty level.

:meth:`PlantSet.templates` gives the QFT templates: the plants' frequency responses
at chosen frequencies (a ``(frequencies, plants)`` complex array).

>>> ps = PlantSet.two_mass()
>>> len(ps), ps.nominal_index
(27, 13)
>>> ps.templates([1.0, 3.0]).shape
(2, 27)
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any, Callable, Iterator, Mapping, NamedTuple, Sequence

import numpy as np

from .. import _validate as v
from ..cases import two_mass_plant
from ..core.transfer import TransferFunction, as_transfer

__all__ = ["PlantSet"]

_METHODS = ("grid", "vertices", "random")


class _Box(NamedTuple):
    """Checked parameter ranges of :meth:`PlantSet.from_ranges` and the nominal point."""

    names: tuple[str, ...]
    lows: dict[str, float]
    highs: dict[str, float]
    nominal: dict[str, float]


def _box(ranges: Any, nominal: Any) -> _Box:
    lows, highs = {}, {}
    for name, rng in ranges.items():
        lo, hi = v.pair(rng, f"ranges[{name!r}]")
        lows[name] = v.real(lo, f"ranges[{name!r}] low")
        highs[name] = v.real(hi, f"ranges[{name!r}] high")
        if lows[name] > highs[name]:
            raise ValueError(f"ranges[{name!r}] must have low <= high, got ({lo:g}, {hi:g})")
    names = tuple(ranges)
    nom = {k: 0.5 * (lows[k] + highs[k]) for k in names}
    if nominal is not None:
        if not isinstance(nominal, Mapping):
            raise TypeError(f"nominal must be a mapping name -> value, got {type(nominal).__name__}")
        for k, val in dict(nominal).items():
            v.choice(k, "nominal parameter", names)
            nom[k] = v.real(val, f"nominal[{k!r}]")
    return _Box(names, lows, highs, nom)


def _draws(box: _Box, method: str, n: Any, samples: Any, seed: Any) -> list[dict[str, float]]:
    """The parameter sets: the nominal and uniform draws (``"random"``), else the grid or the vertices."""
    names, lows, highs = box.names, box.lows, box.highs
    if method == "random":
        count = v.integer(samples, "samples", 1)
        v.refuse_large(count, 10_000, "random plants", "samples")
        rng_ = np.random.default_rng(v.integer(seed, "seed", 0))
        return [dict(box.nominal)] + [{k: float(lows[k] + (highs[k] - lows[k]) * rng_.random()) for k in names}
                                      for _ in range(count)]
    m = 2 if method == "vertices" else v.integer(n, "n", 2)
    v.refuse_large(float(m) ** len(names), 10_000, "grid plants", "n or the number of parameters")
    axes = [np.linspace(lows[k], highs[k], m) for k in names]
    return [dict(zip(names, map(float, p))) for p in itertools.product(*axes)]


def _nearest_nominal(box: _Box, draws: list[dict[str, float]]) -> int:
    """The draw nearest to the nominal point, each parameter scaled by its range."""
    scale = {k: (box.highs[k] - box.lows[k]) or 1.0 for k in box.names}
    dist = [sum(((p[k] - box.nominal[k]) / scale[k]) ** 2 for k in box.names) for p in draws]
    return int(np.argmin(dist))


@dataclass(frozen=True)
class PlantSet:
    """An uncertain plant set: an ordered tuple of rational transfer functions and its nominal member.

    Parameters
    ----------
    plants : tuple of TransferFunction
        The plants (non-empty, delay-free).
    nominal_index : int
        Which plant is the nominal one.
    parameters : tuple of dict, optional
        The parameter values of each plant when built from ranges (else empty).

    Examples
    --------
    >>> ps = PlantSet.from_list([(1, [1, 1]), (2, [1, 1])], nominal=1)
    >>> float(ps.nominal.dc_gain)
    2.0
    >>> [round(float(P.dc_gain), 1) for P in ps]
    [1.0, 2.0]
    """

    plants: tuple[TransferFunction, ...]
    nominal_index: int = 0
    parameters: tuple[Mapping[str, float], ...] = ()

    def __post_init__(self) -> None:
        plants = tuple(v.sequence(self.plants, "plants"))
        if not plants:
            raise ValueError("plants must be a non-empty set of transfer functions, got an empty set")
        checked = []
        for i, P in enumerate(plants):
            tf = as_transfer(P, f"plants[{i}]")
            if tf.num.is_zero:
                raise ValueError(f"plants[{i}] must not be identically zero (no loop can be closed), got 0")
            if tf.has_delays:
                raise ValueError(f"plants[{i}] must be delay-free (rational) for a QFT design, got delays "
                                 f"{tf.max_delay:g} s")
            checked.append(tf)
        object.__setattr__(self, "plants", tuple(checked))
        object.__setattr__(self, "nominal_index", v.index(self.nominal_index, "nominal_index", len(checked)))
        if self.parameters and len(self.parameters) != len(checked):
            raise ValueError(f"parameters must have one entry per plant ({len(checked)}), got {len(self.parameters)}")

    # ------------------------------------------------------------------ container
    def __iter__(self) -> Iterator[TransferFunction]:
        return iter(self.plants)

    def __len__(self) -> int:
        return len(self.plants)

    def __getitem__(self, i: int) -> TransferFunction:
        return self.plants[i]

    @property
    def nominal(self) -> TransferFunction:
        """The nominal plant."""
        return self.plants[self.nominal_index]

    def __repr__(self) -> str:
        return f"PlantSet({len(self)} plants, nominal #{self.nominal_index})"

    # ------------------------------------------------------------------ builders
    @classmethod
    def from_list(cls, plants: Sequence[Any], nominal: int = 0) -> PlantSet:
        """A set from a list of plants (anything :func:`posicast.as_transfer` accepts)."""
        items = tuple(v.sequence(plants, "plants"))
        if items:
            v.index(nominal, "nominal", len(items))
        return cls(items, nominal)

    @classmethod
    def from_ranges(
        cls,
        model: Callable[..., Any],
        ranges: Mapping[str, tuple[float, float]],
        nominal: Mapping[str, float] | None = None,
        *,
        method: str = "grid",
        n: int = 3,
        samples: int = 20,
        seed: int = 0,
    ) -> PlantSet:
        """A set from parameter ranges of ``model(**params) -> plant``.

        Parameters
        ----------
        model : callable
            Keyword parameters to a plant (e.g. :func:`posicast.cases.two_mass_plant`).
        ranges : mapping of str to (low, high)
            The uncertain parameters and their intervals (``low <= high``).
        nominal : mapping of str to float, optional
            The nominal parameters (default: the middle of each range); the nominal
            plant is the member nearest to it (it is added when ``method="random"``).
        method : {"grid", "vertices", "random"}
            ``n`` values per parameter (``n >= 2``, the middle included when ``n`` is
            odd: seed 003's 27 plants are ``n = 3``), the ``2^p`` vertices, or
            ``samples`` uniform draws with the seed ``seed`` (plus the nominal).

        Examples
        --------
        >>> r = {"c1": (25.0, 75.0), "c2": (0.05, 0.15), "k2": (5.0, 15.0)}
        >>> len(PlantSet.from_ranges(two_mass_plant, r, method="vertices"))
        8
        >>> ps = PlantSet.from_ranges(two_mass_plant, r)
        >>> len(ps), ps.nominal_index, dict(ps.parameters[13])
        (27, 13, {'c1': 50.0, 'c2': 0.1, 'k2': 10.0})
        """
        if not callable(model):
            raise TypeError(f"model must be a callable returning a plant, got {type(model).__name__}")
        if not isinstance(ranges, Mapping) or not ranges:
            raise ValueError(f"ranges must be a non-empty mapping name -> (low, high), got {ranges!r}")
        method = v.choice(method, "method", _METHODS)
        box = _box(ranges, nominal)
        draws = _draws(box, method, n, samples, seed)
        plants = tuple(as_transfer(model(**p), "model(...)") for p in draws)
        return cls(plants, _nearest_nominal(box, draws), tuple(draws))

    @classmethod
    def two_mass(cls, uncertainty: float = 50.0, **kwargs: Any) -> PlantSet:
        """Seed 003's two-mass plant with ``c1, c2, k2`` at ``nominal * (1 +/- uncertainty / 100)``.

        ``uncertainty = 50`` (default, 3 values each) is the paper's 27-plant set,
        in the order of :func:`posicast.cases.two_mass_plants` (index 13 nominal).
        Extra keywords go to :meth:`from_ranges` (``method``, ``n``, ``samples``, ``seed``).
        """
        u = v.real_in_range(uncertainty, "uncertainty", 0.0, 100.0, hi_open=True) / 100.0
        base = {"c1": 50.0, "c2": 0.1, "k2": 10.0}
        ranges = {k: (x * (1 - u), x * (1 + u)) for k, x in base.items()}
        return cls.from_ranges(two_mass_plant, ranges, base, **kwargs)

    # ------------------------------------------------------------------ frequency data
    def templates(self, frequencies: Any) -> np.ndarray:
        """The QFT templates: ``P_k(j omega)`` for every frequency (rows) and plant (columns)."""
        w = np.atleast_1d(v.strict_real_array(frequencies, "frequencies"))
        if w.ndim != 1 or np.any(w <= 0):
            raise ValueError("frequencies must be a 1-D array of values > 0 [rad/s]")
        return np.stack([P.freqresp(w) for P in self.plants], axis=1)

    def polynomials(self) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
        """Each plant's ``(num, den)`` in descending powers (for fast evaluation and closed-loop roots)."""
        out = []
        for P in self.plants:
            sc = P.to_scipy()
            out.append((np.asarray(sc.num, float), np.asarray(sc.den, float)))
        return tuple(out)


