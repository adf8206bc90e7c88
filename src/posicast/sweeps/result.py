"""What a sweep returns: every point labelled with its parameters, its values and its status.

A :class:`SweepResult` holds one array per value, shaped like the sweep (a grid's
shape, or ``(n,)`` for draws), a status per point (``'ok'``, ``'error'`` or
``'missing'``: not computed yet) and, for a failed point, the error message (the
exception's type and first line).  ``result["gain"]`` is a parameter's value at
every point, ``result["stable"]`` a value; :meth:`SweepResult.table` flattens
everything into columns, :meth:`SweepResult.to_csv` writes them.
"""

from __future__ import annotations

import csv
import io
import os
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, Mapping, NamedTuple

import numpy as np

from .. import _validate as v
from .._files import atomic_write
from .plots import value_map
from .space import Space

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["SweepResult", "Failure", "Timing", "STATUS"]

#: Status codes as stored (int8) and as shown.
STATUS = ("missing", "ok", "error")


class Failure(NamedTuple):
    """A point whose evaluation raised: its flat index, its parameters and the message."""

    index: int
    point: dict[str, Any]
    message: str


class Timing(NamedTuple):
    """The cost of one :func:`posicast.sweep` call.

    ``wall`` [s] from the first task submitted to the last result stored; ``compute`` [s] the
    evaluations' own time (summed over the points computed by this call); ``tasks`` batches run,
    ``workers`` processes (1 serial).  ``overhead_per_task`` [s]: the workers' time not spent in
    the function, per task (scheduling, transfer, storing), ``(wall * workers - compute) / tasks``.
    """

    wall: float
    compute: float
    tasks: int
    workers: int

    @property
    def overhead_per_task(self) -> float:
        return (self.wall * self.workers - self.compute) / self.tasks if self.tasks else 0.0


@dataclass(frozen=True, eq=False)
class SweepResult:
    """A labelled sweep result (see the module docstring).

    Attributes
    ----------
    space : Space
        The points: ``space.names``, ``space.axes``, ``space.shape``.
    function : str
        The swept function's qualified name.
    values : Mapping[str, ndarray]
        One array per value the function returned (shape ``space.shape``; NaN, False or ``''``
        where a point failed or is missing).
    status : ndarray of str
        ``'ok'``, ``'error'`` or ``'missing'`` per point.
    errors : ndarray of str
        The error message of each failed point (``''`` elsewhere).
    seconds : ndarray
        Each point's evaluation time [s] (NaN where missing).
    store : str or None
        Where the results are persisted (None: in memory only).
    computed : int
        Points evaluated by the call that returned this (the rest came from the store).
    timing : Timing or None
    """

    space: Space
    function: str
    values: Mapping[str, np.ndarray]
    status: np.ndarray
    errors: np.ndarray
    seconds: np.ndarray
    store: str | None = None
    computed: int = 0
    timing: Timing | None = None
    _grids: dict[str, np.ndarray] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "values", MappingProxyType(dict(self.values)))

    # ------------------------------------------------------------------ access
    @property
    def names(self) -> tuple[str, ...]:
        return self.space.names

    @property
    def shape(self) -> tuple[int, ...]:
        return self.space.shape

    @property
    def axes(self) -> Mapping[str, np.ndarray]:
        """A grid's axes (for draws: the drawn values), by parameter name."""
        return MappingProxyType(dict(zip(self.space.names, self.space.axes)))

    @property
    def ok(self) -> np.ndarray:
        return self.status == "ok"

    @property
    def complete(self) -> bool:
        """Every point has a result (a value or an error)."""
        return not bool(np.any(self.status == "missing"))

    def parameter(self, name: str) -> np.ndarray:
        """The parameter ``name`` at every point (shape ``shape``)."""
        v.choice(name, "name", self.space.names)
        if name not in self._grids:
            self._grids[name] = self.space.columns(0, self.space.n_points)[name].reshape(self.shape)
        return self._grids[name]

    def __getitem__(self, name: str) -> np.ndarray:
        """A value (``result["stable"]``) or a parameter at every point (``result["gain"]``)."""
        if name in self.values:
            return self.values[name]
        if name in self.space.names:
            return self.parameter(name)
        raise KeyError(f"{name!r} is neither a value ({', '.join(self.values) or 'none yet'}) nor a parameter "
                       f"({', '.join(self.space.names)})")

    @property
    def failures(self) -> list[Failure]:
        """Every failed point with its message."""
        idx = np.flatnonzero(self.status.ravel() == "error")
        return [Failure(int(i), self.space.point(int(i)), str(self.errors.ravel()[i])) for i in idx]

    def same_as(self, other: SweepResult) -> bool:
        """Identical points, statuses, error messages and values (NaN equal to NaN); timings are ignored."""
        if self.space.fingerprint() != other.space.fingerprint() or set(self.values) != set(other.values):
            return False
        if not (np.array_equal(self.status, other.status) and np.array_equal(self.errors, other.errors)):
            return False
        for k, a in self.values.items():
            b = other.values[k]
            if a.dtype.kind == "f" and b.dtype.kind == "f":
                if not np.array_equal(a, b, equal_nan=True):
                    return False
            elif not np.array_equal(a, b):
                return False
        return True

    # ------------------------------------------------------------------ tables
    def table(self) -> dict[str, np.ndarray]:
        """Flat columns, one row per point: the parameters, the values, ``status`` and ``error``."""
        out = {nm: col for nm, col in self.space.columns(0, self.space.n_points).items()}
        for k, a in self.values.items():
            out[k] = a.ravel()
        out["status"] = self.status.ravel()
        out["error"] = self.errors.ravel()
        return out

    def to_csv(self, path: str | os.PathLike[str]) -> None:
        """Write :meth:`table` as CSV at exactly ``path``, atomically (a temporary file renamed): a header
        row, one row per point, floats with ``repr`` precision."""
        cols = self.table()

        def write(fh: Any) -> None:
            text = io.TextIOWrapper(fh, encoding="utf-8", newline="")
            w = csv.writer(text)
            w.writerow(list(cols))
            for row in zip(*cols.values()):
                w.writerow([repr(float(x)) if isinstance(x, np.floating) else
                            str(bool(x)) if isinstance(x, np.bool_) else str(x) for x in row])
            text.flush()
            text.detach()  # the temporary file is closed by atomic_write

        atomic_write(path, write, name="path")

    def summary(self) -> str:
        """One paragraph: points, statuses, values, the first failures and the cost."""
        n = self.status.size
        counts = {s: int(np.count_nonzero(self.status == s)) for s in STATUS}
        dims = " x ".join(f"{nm} ({len(ax)})" for nm, ax in zip(self.space.names, self.space.axes)) \
            if self.space.kind == "grid" else f"{n} draws of {', '.join(self.space.names)} (seed {self.space.seed})"
        lines = [f"sweep of {self.function} over {dims}: {counts['ok']} ok, {counts['error']} failed, "
                 f"{counts['missing']} missing" + (f"; store {self.store}" if self.store else "")]
        for k, a in self.values.items():
            sel = a[self.ok]
            if a.dtype.kind == "f" and sel.size and np.any(np.isfinite(sel)):
                lines.append(f"  {k}: min {np.nanmin(sel):.6g}, median {np.nanmedian(sel):.6g}, max {np.nanmax(sel):.6g}")
            elif a.dtype.kind == "b" and sel.size:
                lines.append(f"  {k}: true at {int(np.count_nonzero(sel))} of {sel.size} points")
            elif sel.size:
                uniq, cnt = np.unique(sel.astype(str), return_counts=True)
                top = sorted(zip(cnt, uniq), reverse=True)[:4]
                lines.append(f"  {k}: " + ", ".join(f"{u} ({c})" for c, u in top))
        for f in self.failures[:3]:
            lines.append(f"  failed at {f.point}: {f.message}")
        if self.timing is not None and self.timing.tasks:
            t = self.timing
            lines.append(f"  computed {self.computed} points in {t.tasks} tasks on {t.workers} worker"
                         f"{'s' if t.workers > 1 else ''}: {t.wall:.3g} s wall, {t.compute:.3g} s in the function, "
                         f"{t.overhead_per_task * 1e3:.3g} ms overhead per task")
        return "\n".join(lines)

    def plot(self, value: str, ax: Axes | None = None, **kwargs: Any) -> tuple[Figure, Axes]:
        """A 2-D grid's ``value`` as an image over its two axes (failed points hatched grey).

        Returns ``(fig, ax)``; ``kwargs`` go to ``pcolormesh``.
        """
        return value_map(self, value, ax, **kwargs)

    def __repr__(self) -> str:
        counts = ", ".join(f"{int(np.count_nonzero(self.status == s))} {s}" for s in STATUS)
        return (f"SweepResult({self.function}, {self.space.kind} {self.shape} over {', '.join(self.space.names)}; "
                f"values {', '.join(self.values) or 'none'}; {counts})")
