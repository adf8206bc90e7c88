"""What a sweep runs over: a grid of parameter values or seeded draws from distributions.

A :class:`Space` numbers its points ``0 .. n_points - 1``; point ``i`` is a dict of
keyword arguments for the swept function.  A **grid** is the Cartesian product of
one 1-D axis per parameter (the first parameter varies slowest, numpy's C order);
**draws** are ``n`` points sampled once, up front, from one distribution per
parameter (anything with scipy.stats' ``rvs(size=, random_state=)``) with a
``numpy.random.Generator`` seeded by ``seed``: the points do not depend on how the
sweep is batched or on how many workers run it.

>>> s = make_space({"gain": [0.1, 0.2, 0.3], "delay_error": [-0.1, 0.1]})
>>> s.kind, s.shape, s.n_points
('grid', (3, 2), 6)
>>> s.point(3)
{'gain': 0.2, 'delay_error': 0.1}
>>> from scipy import stats
>>> d = make_space({"c1": stats.uniform(25, 50)}, n=4, seed=1)
>>> d.kind, d.shape, bool(25 <= d.point(0)["c1"] <= 75)
('draws', (4,), True)
"""

from __future__ import annotations

import hashlib
import inspect
import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping

import numpy as np

from .. import _validate as v

__all__ = ["Space", "make_space", "check_arguments", "function_name", "MAX_POINTS"]

#: The largest sweep accepted (points): a 10^4 x 10^4 chart.  Beyond it the store's status array alone
#: passes 100 MB and a sweep should be split.
MAX_POINTS = 10**8


@dataclass(frozen=True, eq=False)
class Space:
    """The points of a sweep.

    Attributes
    ----------
    kind : {"grid", "draws"}
    names : tuple of str
        The parameters, in the order given (a grid's axis order).
    axes : tuple of ndarray
        A grid's axis values per parameter, or the ``n`` draws per parameter (float or str arrays).
    shape : tuple of int
        A grid's shape, or ``(n,)`` for draws.
    seed : int or None
        The draws' seed.
    """

    kind: str
    names: tuple[str, ...]
    axes: tuple[np.ndarray, ...]
    shape: tuple[int, ...]
    seed: int | None = None

    @property
    def n_points(self) -> int:
        return int(math.prod(self.shape))

    def columns(self, start: int, stop: int) -> dict[str, np.ndarray]:
        """The parameter values of points ``start .. stop - 1``, one array per parameter."""
        idx = np.arange(start, stop)
        if self.kind == "draws":
            return {nm: ax[idx] for nm, ax in zip(self.names, self.axes)}
        sub = np.unravel_index(idx, self.shape)
        return {nm: ax[k] for nm, ax, k in zip(self.names, self.axes, sub)}

    def point(self, i: int) -> dict[str, Any]:
        """Point ``i`` as keyword arguments (Python floats and strings)."""
        cols = self.columns(i, i + 1)
        return {nm: c[0].item() for nm, c in cols.items()}

    def fingerprint(self) -> str:
        """A hash of the points (kind, names, values, seed): a store holds the results of one space only."""
        h = hashlib.sha256()
        h.update(repr((self.kind, self.names, self.shape, self.seed)).encode())
        for ax in self.axes:
            if ax.dtype.kind in "UOT":
                h.update("\x00".join(map(str, ax.tolist())).encode())
            else:
                h.update(np.ascontiguousarray(ax, dtype=float).tobytes())
        return h.hexdigest()[:16]


def _axis(values: Any, name: str) -> np.ndarray:
    """One grid axis: a 1-D sequence of finite reals or of strings, not empty."""
    if isinstance(values, (str, bytes)) or not hasattr(values, "__len__"):
        raise TypeError(f"parameters[{name!r}] must be a 1-D sequence of values (a grid axis) or a "
                        f"distribution with .rvs (e.g. scipy.stats.uniform(0, 1)), got {type(values).__name__}")
    if len(values) == 0:
        raise ValueError(f"parameters[{name!r}] is empty: a grid axis needs at least one value")
    items = list(values)
    if all(isinstance(x, str) for x in items):
        return np.array(items, dtype=str)
    arr = v.strict_real_array(items, f"parameters[{name!r}]")
    if arr.ndim != 1:
        raise ValueError(f"parameters[{name!r}] must be 1-D, got shape {arr.shape}")
    return arr


def make_space(parameters: Mapping[str, Any], n: int | None = None, seed: int | None = None) -> Space:
    """The :class:`Space` of ``parameters`` (see :func:`posicast.sweep`).

    Raises
    ------
    TypeError, ValueError
        Not a mapping, no parameter, an empty axis, non-finite values, grid axes mixed with
        distributions, draws without ``n`` or with ``n`` for a grid, too many points.
    """
    if not isinstance(parameters, Mapping):
        raise TypeError(f"parameters must be a mapping of names to grid axes or distributions, "
                        f"got {type(parameters).__name__}")
    if not parameters:
        raise ValueError("parameters is empty: give at least one parameter, e.g. {'gain': [0.1, 0.2]}")
    for name in parameters:
        if not isinstance(name, str) or not name.isidentifier():
            raise ValueError(f"parameter names must be Python identifiers (keyword arguments), got {name!r}")
    names = tuple(parameters)
    random = [callable(getattr(val, "rvs", None)) for val in parameters.values()]
    if any(random) and not all(random):
        grid = [nm for nm, r in zip(names, random) if not r]
        raise ValueError(f"parameters mixes grid axes ({', '.join(grid)}) with distributions: sweep one kind "
                         "(fix the grid values with functools.partial, or sweep the grid and draw inside)")
    if all(random):
        if n is None:
            raise ValueError("n must be given for a sweep over distributions (the number of draws)")
        n = v.integer_in_range(n, "n", 1, MAX_POINTS)
        if seed is None:
            raise ValueError("seed must be given for a sweep over distributions (the draws must be repeatable)")
        seed = v.integer(seed, "seed", 0)
        rng = np.random.default_rng(seed)
        axes = []
        for name, dist in parameters.items():
            try:
                draws = np.asarray(dist.rvs(size=n, random_state=rng), dtype=float).reshape(n)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"parameters[{name!r}]: drawing {n} values failed: {exc}") from None
            if not np.all(np.isfinite(draws)):
                raise ValueError(f"parameters[{name!r}] drew non-finite values")
            axes.append(draws)
        return Space("draws", names, tuple(axes), (n,), seed)
    if n is not None or seed is not None:
        raise ValueError("n and seed apply to a sweep over distributions only; a grid's points are its axes")
    axes = [_axis(val, name) for name, val in parameters.items()]
    shape = tuple(ax.size for ax in axes)
    v.refuse_large(math.prod(shape), MAX_POINTS, f"a grid of shape {shape}", "use fewer values per axis "
                   "or split the sweep", "points")
    return Space("grid", names, tuple(axes), shape)


def check_arguments(function: Callable[..., Any], names: tuple[str, ...]) -> None:
    """Every parameter is a keyword argument of ``function``: a ValueError naming the unknown ones."""
    if not callable(function):
        raise TypeError(f"function must be callable, got {type(function).__name__}")
    try:
        sig = inspect.signature(function)
    except (TypeError, ValueError):  # a builtin without a signature: the points will say
        return
    params = sig.parameters
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values()):
        return
    accepted = [nm for nm, p in params.items()
                if p.kind in (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)]
    unknown = [nm for nm in names if nm not in accepted]
    if unknown:
        raise ValueError(f"unknown parameter{'s' if len(unknown) > 1 else ''} {', '.join(map(repr, unknown))}: "
                         f"{function_name(function)} accepts {', '.join(accepted) or 'no keyword argument'}")


def function_name(function: Callable[..., Any]) -> str:
    """The qualified name a store records (``functools.partial`` shows its function)."""
    inner = getattr(function, "func", function)
    return str(getattr(inner, "__qualname__", type(inner).__qualname__))
