"""Results persisted as they arrive: a Zarr group, one chunk per batch of points.

Layout of a store (a directory ``*.zarr``, or zarr's in-memory store when no path
is given)::

    attrs            posicast_sweep (format 1), function, fingerprint of the points, batch_size,
                     values {name: "float" | "bool" | "str"}
    parameters/<p>   a grid's axis, or the draws (so a store describes its own points)
    status           int8 per point: 0 missing, 1 ok, 2 error          (chunk = one batch)
    error            the message of each failed point                   (chunk = one batch)
    seconds          each point's evaluation time                       (chunk = one batch)
    values/<v>       one array per value the function returned          (chunk = one batch)

A batch's chunks are written values first and ``status`` last; zarr writes each
chunk file atomically (a temporary file renamed), so a sweep killed at any moment
leaves every batch either fully stored or marked missing: resuming recomputes
exactly the missing batches and loses nothing.  One process writes a store at a
time (the one that called :func:`posicast.sweep`; the workers only compute).
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from .. import _validate as v
from .result import STATUS, SweepResult
from .space import Space

__all__ = ["Store", "open_store", "load", "StoreMismatch"]

FORMAT = 1
_KINDS = {"float": ("f8", np.nan), "bool": ("bool", False), "str": (str, "")}


class StoreMismatch(ValueError):
    """The store holds another sweep (other points, another function or batch size)."""


def _zarr() -> Any:
    import zarr  # lazy: a quarter of a second that only sweeps with a store need

    return zarr


def _strings(arr: Any) -> np.ndarray:
    """Zarr's variable-length strings as a fixed-width numpy str array."""
    return np.asarray(arr).astype(object).astype(str)


def _kind(x: Any) -> str:
    return "bool" if isinstance(x, (bool, np.bool_)) else "str" if isinstance(x, str) else "float"


class Store:
    """One sweep's Zarr group: create or reopen it, write batches, read the result."""

    def __init__(self, group: Any, space: Space, path: str | None) -> None:
        self.group = group
        self.space = space
        self.path = path
        self.batch_size = int(group.attrs["batch_size"])
        self.kinds: dict[str, str] = dict(group.attrs.get("values", {}))
        # array handles opened once (each lookup in the group reads metadata again)
        self.arrays = {name: group[name] for name in ("status", "error", "seconds")}
        self.values = {name: group["values"][name] for name in self.kinds} if self.kinds else {}

    # ------------------------------------------------------------------ batches
    @property
    def n_batches(self) -> int:
        return -(-self.space.n_points // self.batch_size)

    def bounds(self, b: int) -> tuple[int, int]:
        return b * self.batch_size, min((b + 1) * self.batch_size, self.space.n_points)

    def pending(self) -> list[int]:
        """The batches with at least one missing point (all of a batch is recomputed: it is one chunk)."""
        status = self.arrays["status"][:]
        n = self.n_batches
        padded = np.zeros(n * self.batch_size, dtype=np.int8)
        padded[: status.size] = status
        padded[status.size:] = 1
        return [int(b) for b in np.flatnonzero(np.any(padded.reshape(n, self.batch_size) == 0, axis=1))]

    def write(self, b: int, status: np.ndarray, errors: list[str], values: list[dict[str, Any] | None],
              seconds: np.ndarray) -> None:
        """Store batch ``b``: the values and messages first, the status last (the commit)."""
        start, stop = self.bounds(b)
        status = status.copy()
        errors = list(errors)
        columns: dict[str, list[Any]] = {}
        for j, vals in enumerate(values):
            if vals is None:
                continue
            for name, x in vals.items():
                kind = self.kinds.get(name) or _kind(x)
                if _kind(x) != kind and not (kind == "float" and x is None):
                    status[j] = 2
                    errors[j] = f"TypeError: value {name!r} is {_kind(x)} here, {kind} at other points"
                    continue
                self.kinds.setdefault(name, kind)
                columns.setdefault(name, [_KINDS[kind][1]] * (stop - start))[j] = x
        for name, col in columns.items():
            if name not in self.values:
                self._create_value(name)
            arr = self.values[name]
            arr[start:stop] = np.array([np.nan if x is None else x for x in col],
                                       dtype=arr.dtype if self.kinds[name] != "str" else str)
        if any(errors):  # the fill value is ''
            self.arrays["error"][start:stop] = np.array(errors, dtype=str)
        self.arrays["seconds"][start:stop] = seconds
        self.arrays["status"][start:stop] = status

    def _create_value(self, name: str) -> None:
        dtype, fill = _KINDS[self.kinds[name]]
        # overwrite: an array left by a kill between its creation and the attrs' update holds no data yet
        # (a batch's values are written after both)
        self.values[name] = self.group.require_group("values").create_array(
            name, shape=(self.space.n_points,), chunks=(self.batch_size,), dtype=dtype, fill_value=fill,
            overwrite=True)
        self.group.attrs["values"] = dict(self.kinds)

    # ------------------------------------------------------------------ reading
    def result(self, computed: int = 0, timing: Any = None) -> SweepResult:
        shape = self.space.shape
        codes = self.arrays["status"][:]
        vals = {}
        for name, handle in self.values.items():
            arr = handle[:]
            vals[name] = (_strings(arr) if self.kinds[name] == "str" else arr).reshape(shape)
        return SweepResult(self.space, str(self.group.attrs["function"]), vals,
                           np.array(STATUS)[codes].reshape(shape), _strings(self.arrays["error"][:]).reshape(shape),
                           self.arrays["seconds"][:].reshape(shape), self.path, computed, timing)


def _check_path(store: Any) -> str:
    path = v.path_text(store, "store", "directory path")
    if os.path.exists(path) and not os.path.isdir(path):
        raise ValueError(f"store {path!r} is a file, not a Zarr directory")
    parent = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(parent):
        raise ValueError(f"store {path!r}: the directory {parent!r} does not exist")
    return path


def open_store(store: Any, space: Space, function: str, batch_size: int, overwrite: bool = False) -> Store:
    """Create the store of a sweep, or reopen it to resume (same points, function and batch size)."""
    zarr = _zarr()
    if store is None:
        root, path = zarr.storage.MemoryStore(), None
    else:
        path = _check_path(store)
        root = path
        if os.path.isdir(path) and os.listdir(path) and not overwrite:
            group = _open_existing(path)
            attrs = group.attrs
            if attrs.get("fingerprint") != space.fingerprint():
                raise StoreMismatch(f"store {path!r} holds a sweep over other points ({describe(attrs)}); "
                                    "use another store, or overwrite=True to discard it")
            if attrs.get("function") != function:
                raise StoreMismatch(f"store {path!r} holds a sweep of {attrs.get('function')}, not {function}; "
                                    "use another store, or overwrite=True to discard it")
            return Store(group, space, path)
    group = zarr.open_group(root, mode="w")
    group.attrs.update({"posicast_sweep": FORMAT, "function": function, "fingerprint": space.fingerprint(),
                        "batch_size": int(batch_size), "kind": space.kind, "names": list(space.names),
                        "shape": list(space.shape), "seed": space.seed, "values": {}})
    params = group.require_group("parameters")
    for name, ax in zip(space.names, space.axes):
        if ax.dtype.kind == "U":  # variable-length strings (zarr's fixed-width ones have no v3 specification)
            params.create_array(name, shape=ax.shape, dtype=str, fill_value="")[:] = ax
        else:
            params.create_array(name, data=ax)
    n, chunk = space.n_points, (int(batch_size),)
    group.create_array("status", shape=(n,), chunks=chunk, dtype="int8", fill_value=0)
    group.create_array("error", shape=(n,), chunks=chunk, dtype=str, fill_value="")
    group.create_array("seconds", shape=(n,), chunks=chunk, dtype="f8", fill_value=np.nan)
    return Store(group, space, path)


def describe(attrs: Any) -> str:
    return f"{attrs.get('kind')} of shape {tuple(attrs.get('shape', ()))} over {', '.join(attrs.get('names', []))}"


def _open_existing(path: str) -> Any:
    zarr = _zarr()
    try:
        group = zarr.open_group(path, mode="r+")
    except Exception as exc:  # zarr raises several kinds for a directory that is not a group
        raise StoreMismatch(f"store {path!r} is not a posicast sweep store ({type(exc).__name__}: "
                            f"{str(exc).splitlines()[0] if str(exc) else ''})") from None
    if group.attrs.get("posicast_sweep") != FORMAT:
        raise StoreMismatch(f"store {path!r} is not a posicast sweep store (format {FORMAT})")
    return group


def load(store: str | os.PathLike[str]) -> SweepResult:
    """The result stored at ``store`` (complete or not), without computing anything.

    Raises
    ------
    ValueError
        No such store, or not a posicast sweep store.
    """
    path = _check_path(store)
    if not os.path.isdir(path):
        raise ValueError(f"store {path!r} does not exist")
    group = _open_existing(path)
    attrs = group.attrs
    names = tuple(attrs["names"])
    axes = tuple(np.asarray(group["parameters"][nm][:]) for nm in names)
    axes = tuple(_strings(ax) if ax.dtype.kind not in "fiub" else ax for ax in axes)
    space = Space(str(attrs["kind"]), names, axes, tuple(attrs["shape"]), attrs.get("seed"))
    return Store(group, space, path).result()
