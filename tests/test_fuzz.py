"""Hostile-input fuzz harness (issue #13): every public entry point and every CLI subcommand.

Each public callable of ``posicast.__all__`` and of every subpackage's ``__all__``
(plus the public methods of the objects they return) is called with valid base
arguments in which ONE argument at a time is replaced by an invalid or extreme
value: NaN, +-inf, 0, negative numbers, 1e300, 1e-300, huge integers, wrong types,
None, strings, complex numbers, empty arrays, wrong shapes.  The values come from
a fixed pool per kind of argument (swept completely; for the few expensive entries,
its first values) and from hypothesis strategies (derandomised, so a run is
reproducible).  Every call must end in

* a named ``ValueError``/``TypeError`` (or a posicast ``RootFindingError``) raised
  by posicast itself, whose message names the argument; or
* a result without NaN (and passing the entry's own invariant check, if any);

never an exception from numpy/scipy/pathlib or of another type, a NaN, a
RuntimeWarning, a hang (a per-call CPU time limit, and a wall-clock one four times longer) or unbounded
memory (the address space is limited during each call; a MemoryError is a failure).

The command line (``posicast.cli.main``, in-process, with ``tmp_path`` as the
working directory) gets the same treatment per subcommand: an error is exactly
one line on stderr with exit status 2 and no file written; a success writes
its figure at the user's exact path and nothing else.  A few real subprocess
runs prove that no traceback reaches stderr, the memory-hungry ones under an
``RLIMIT_AS`` limit.

Failures are collected, not raised at the first one: each failing test lists
one line per entry and input, with the owning area (from where the exception
was raised), and the module prints the count of generated inputs and the clean
percentage per area at the end of the run.
"""

from __future__ import annotations

import copy
import functools
import importlib
import inspect
import json
import math
import os
import pkgutil
import re
import resource
import signal
import subprocess
import sys
import time
import traceback
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field, fields, is_dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest

from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import posicast  # noqa: E402
from posicast.cli import main as cli_main  # noqa: E402

PKG_DIR = Path(posicast.__file__).resolve().parent
# Every subpackage (found, not listed: a new one is fuzzed too) and the modules posicast.__all__ exports.
SUBPACKAGES = tuple(sorted(
    [m.name for m in pkgutil.iter_modules(posicast.__path__) if m.ispkg]
    + [n for n in posicast.__all__ if inspect.ismodule(getattr(posicast, n, None))]
))
# Modules whose __all__ is public although their package's __init__ does not re-export it.
EXTRA_MODULES = ("posicast.io.export",)

CALL_SECONDS = 3.0  # per-call CPU time limit (see call_limits); the tuner and the identification get 6 s
MEMORY_HEADROOM = 2 << 30  # address space a single call may add (RLIMIT_AS)
HYPOTHESIS_EXAMPLES = 3  # generated inputs per entry and argument, on top of the fixed pools

# Where a failure is routed: the first matching path (relative to the package) names the owner.
OWNERS = (
    ("spectra/", "spectra owner"),
    ("shapers/", "shapers+analysis owner"),
    ("analysis/", "shapers+analysis owner"),
    ("modes.py", "shapers+analysis owner"),
    ("identification/data.py", "identification.data owner"),
    ("identification/", "lead (identification)"),
    ("firmware/", "lead (firmware)"),
    ("cases.py", "lead (cases)"),
    ("_validate.py", "shared (_validate)"),
    ("", "core/loops/simulate/tune/io/cli owner"),
)


def owner_of(path: str) -> str:
    rel = str(Path(path).resolve().relative_to(PKG_DIR)) if Path(path).resolve().is_relative_to(PKG_DIR) else path
    for prefix, who in OWNERS:
        if rel.startswith(prefix):
            return who
    return OWNERS[-1][1]


# ====================================================================== hostile values
class _Opaque:
    """An object of no expected type."""

    def __repr__(self) -> str:
        return "<opaque object>"


NAN, INF = math.nan, math.inf
OPAQUE = _Opaque()

REAL_POOL: list[Any] = [
    NAN, INF, -INF, 0.0, -0.0, -1.0, -1e300, 1e300, 1e-300, 5e-324, 10**30, -(2**64), True, None, "1.0", "abc",
    1j, complex(1.0, 1.0), [], [1.0, 2.0], np.array([NAN]), np.zeros((2, 2)), np.float32("inf"), OPAQUE,
]
INT_POOL: list[Any] = [
    0, -1, -(10**20), 10**20, 2**63, 10**12, 1.5, NAN, INF, 1e300, None, "3", True, 3j, [3], np.int64(-5), OPAQUE,
]
ARRAY_POOL: list[Any] = [
    [], np.zeros(0), [NAN], [INF, 1.0], [-INF], np.zeros((2, 2)), np.zeros((2, 1, 1)), "abc", None, 1.0, NAN,
    1j * np.ones(3), [[1.0, 2.0], [3.0]], [1e300, -1e300], [1e-300] * 3, np.array(["a", "b"]), [None], OPAQUE,
    {"a": 1.0},
]
STR_POOL: list[Any] = ["", "nonexistent", " ", "ZV\x00", None, 1, 1.0, b"zv", ["zv"], NAN, "\u00e9\u00e9", OPAQUE]
BOOL_POOL: list[Any] = [None, "yes", 2, NAN, 1.0, [True], OPAQUE]
SYSTEM_POOL: list[Any] = [
    None, "abc", 1j, NAN, INF, (1.0, [0.0]), (1.0, [NAN, 1.0]), (1.0, [INF, 1.0]), ([1.0, 0.0, 0.0], [1.0, 1.0]),
    ((), ()), ([], []), (1.0,), (1.0, 2.0, 3.0), ([1e300], [1e-300, 1.0]), ([1.0], [1e300, 1e-300, 1.0]),
    (np.zeros((2, 2)), [1.0, 1.0]), ([1.0], [0.0, 0.0, 0.0]), (["a"], [1.0]), OPAQUE, [1.0, 2.0], True,
]
MODE_POOL: list[Any] = [
    None, (NAN, 0.1), (1.0, 1.0), (1.0, -0.1), (0.0, 0.1), (-1.0, 0.1), (1e300, 0.1), (1e-300, 0.1),
    (1.0, 0.999999999), (1.0, 1e-300), (INF, 0.0), "zv", 5.0, (1.0,), (1.0, 2.0, 3.0), (1j, 0.1), OPAQUE,
]
PAIR_POOL: list[Any] = [
    (NAN, 1.0), (1.0, 0.0), (1.0, 1.0), (0.0, INF), (-INF, 0.0), (1.0,), "ab", (1e300, -1e300), (-1e300, 1e300),
    (0.0, 1e-300), [1.0, 2.0, 3.0], 1.0, ("a", "b"), (None, 1.0), OPAQUE,
]
REGION_POOL: list[Any] = [
    (NAN, 0.0, 0.0, 1.0), (0.0, -1.0, 0.0, 1.0), (-1e300, 1e300, -1e300, 1e300), (0.0, 0.0, 0.0, 0.0),
    (1.0, 2.0, 3.0), "abcd", None, (-1.0, 1.0, 0.0, 1e12), (-1e6, 1.0, 0.0, 1e6), (INF, 0.0, 0.0, 1.0),
    ((1, 2), (3, 4)), OPAQUE,
]
OBJECT_POOL: list[Any] = [None, 1.0, NAN, "x", OPAQUE, [], (1.0, 2.0), np.zeros(3), 1j]
QP_POOL: list[Any] = [
    None, "abc", [[NAN]], [], np.zeros((0, 0)), [[1e300, 1e300, 1e300]], [[1e-300, 1.0]], np.zeros((2, 2, 2)),
    (1.0, [0.0]), 0.0, 1j, OPAQUE, [[0.0]],
]


def real_strategy() -> st.SearchStrategy:
    return st.one_of(
        st.floats(allow_nan=True, allow_infinity=True),
        st.floats(min_value=-1e-6, max_value=1e-6),
        st.integers(min_value=-(2**80), max_value=2**80),
        st.complex_numbers(allow_nan=True, allow_infinity=True),
        st.text(max_size=4),
        st.sampled_from(REAL_POOL),
    )


def int_strategy() -> st.SearchStrategy:
    return st.one_of(
        st.integers(min_value=-(2**70), max_value=2**70),
        st.integers(min_value=-3, max_value=20),
        st.floats(allow_nan=True, allow_infinity=True),
        st.sampled_from(INT_POOL),
    )


def array_strategy() -> st.SearchStrategy:
    return st.one_of(
        hnp.arrays(np.float64, hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=4),
                   elements=st.floats(allow_nan=True, allow_infinity=True)),
        st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=5),
        st.lists(st.one_of(st.floats(), st.text(max_size=2), st.none()), max_size=4),
        st.sampled_from(ARRAY_POOL),
    )


def str_strategy() -> st.SearchStrategy:
    return st.one_of(st.text(max_size=12), st.sampled_from(STR_POOL), st.integers(), st.none())


def system_strategy() -> st.SearchStrategy:
    coeffs = st.lists(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0.0, 1.0, 1e300])),
                      min_size=0, max_size=5)
    return st.one_of(st.tuples(coeffs, coeffs), st.sampled_from(SYSTEM_POOL), real_strategy())


def mode_strategy() -> st.SearchStrategy:
    x = st.floats(allow_nan=True, allow_infinity=True)
    return st.one_of(st.tuples(x, x), st.tuples(st.floats(1e-3, 1e3), st.floats(-0.5, 1.5)), st.sampled_from(MODE_POOL))


def pair_strategy() -> st.SearchStrategy:
    x = st.floats(allow_nan=True, allow_infinity=True)
    return st.one_of(st.tuples(x, x), st.lists(x, max_size=4), st.sampled_from(PAIR_POOL))


def region_strategy() -> st.SearchStrategy:
    x = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(-1e4, 1e4))
    return st.one_of(st.tuples(x, x, x, x), st.lists(x, max_size=5), st.sampled_from(REGION_POOL))


def object_strategy() -> st.SearchStrategy:
    return st.one_of(st.sampled_from(OBJECT_POOL), real_strategy(), st.text(max_size=3))


def qp_strategy() -> st.SearchStrategy:
    return st.one_of(
        hnp.arrays(np.float64, hnp.array_shapes(min_dims=1, max_dims=3, min_side=0, max_side=4),
                   elements=st.floats(allow_nan=True, allow_infinity=True)),
        st.sampled_from(QP_POOL),
    )


# Kinds of argument: the fixed pool and the hypothesis strategy.  Paths are added per run (they need a directory).
KINDS: dict[str, tuple[list[Any], Callable[[], st.SearchStrategy]]] = {
    "real": (REAL_POOL, real_strategy),
    "int": (INT_POOL, int_strategy),
    "array": (ARRAY_POOL, array_strategy),
    "str": (STR_POOL, str_strategy),
    "bool": (BOOL_POOL, lambda: st.one_of(st.sampled_from(BOOL_POOL), st.integers(), st.text(max_size=3))),
    "system": (SYSTEM_POOL, system_strategy),
    "mode": (MODE_POOL, mode_strategy),
    "pair": (PAIR_POOL, pair_strategy),
    "region": (REGION_POOL, region_strategy),
    "object": (OBJECT_POOL, object_strategy),
    "qp": (QP_POOL, qp_strategy),
}


def short(value: Any, limit: int = 60) -> str:
    if isinstance(value, np.ndarray):
        body = np.array2string(value.ravel()[:4], precision=3, separator=",", threshold=4)
        txt = f"array(shape={value.shape}, dtype={value.dtype}, {body})"
    else:
        try:
            txt = repr(value)
        except Exception:  # pragma: no cover - repr of a hostile value
            txt = f"<{type(value).__name__}>"
    txt = txt.replace("\n", " ")
    return txt if len(txt) <= limit else txt[: limit - 3] + "..."


# ====================================================================== per-call limits
class CallTimeout(BaseException):
    """Raised inside a call that exceeds its time limit (BaseException: no library catches it)."""


def _vm_size() -> int:
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmSize:"):
                    return int(line.split()[1]) * 1024
    except OSError:  # pragma: no cover - not Linux
        pass
    return 0


#: the wall-clock limit of a call, in multiples of its CPU limit (a call blocked without using the CPU)
WALL_FACTOR = 4.0


@contextmanager
def call_limits(seconds: float):
    """Time limits and address-space limit (RLIMIT_AS = current size + headroom) for one call.

    The limit is on the process's CPU time (SIGPROF), so that a loaded machine (CI on 2 cores shared with
    other jobs) does not fail a call that is merely slowed down; a call that waits without computing is
    stopped by a wall-clock limit ``WALL_FACTOR`` times longer (SIGALRM)."""

    def on_alarm(signum: int, frame: Any) -> None:
        raise CallTimeout()

    old_handler = signal.signal(signal.SIGALRM, on_alarm)
    old_prof = signal.signal(signal.SIGPROF, on_alarm)
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    vm = _vm_size()
    limited = vm > 0
    if limited:
        cap = vm + MEMORY_HEADROOM
        if hard != resource.RLIM_INFINITY:
            cap = min(cap, hard)
        resource.setrlimit(resource.RLIMIT_AS, (cap, hard))
    signal.setitimer(signal.ITIMER_PROF, seconds)
    signal.setitimer(signal.ITIMER_REAL, WALL_FACTOR * seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0.0)
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, old_handler)
        signal.signal(signal.SIGPROF, old_prof)
        if limited:
            resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


# ====================================================================== result checks


def _library_errors() -> tuple[type[BaseException], ...]:
    """Clean refusals: ValueError/TypeError, and the spectra's public RootFindingError (its BudgetExceeded
    is the up-front refusal of a root search too large, with the estimate)."""
    from posicast.spectra import RootFindingError

    return (ValueError, TypeError, RootFindingError)


def nan_paths(obj: Any, path: str = "result", depth: int = 0, seen: set[int] | None = None) -> list[str]:
    """Where a result holds a NaN (floats, complex, arrays, containers, dataclasses, posicast objects)."""
    seen = set() if seen is None else seen
    if depth > 5 or id(obj) in seen:
        return []
    if isinstance(obj, (bool, np.bool_, str, bytes, type(None))):
        return []
    if isinstance(obj, (float, np.floating)):
        return [path] if math.isnan(obj) else []
    if isinstance(obj, (complex, np.complexfloating)):
        return [path] if (math.isnan(obj.real) or math.isnan(obj.imag)) else []
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind in "fc" and obj.size and np.isnan(obj).any():
            return [f"{path}[{int(np.flatnonzero(np.isnan(obj.ravel()))[0])}]"]
        return []
    seen.add(id(obj))
    mod = type(obj).__module__ or ""
    if mod.startswith("matplotlib"):
        return []
    out: list[str] = []
    if isinstance(obj, (list, tuple)):
        for i, item in enumerate(obj[:64]):
            out += nan_paths(item, f"{path}[{i}]", depth + 1, seen)
        return out
    if isinstance(obj, dict) or type(obj).__name__ == "mappingproxy":
        for k, item in list(obj.items())[:64]:
            out += nan_paths(item, f"{path}[{k!r}]", depth + 1, seen)
        return out
    if is_dataclass(obj):
        for f in fields(obj):
            out += nan_paths(getattr(obj, f.name, None), f"{path}.{f.name}", depth + 1, seen)
        return out
    name = type(obj).__name__
    if name == "QuasiPolynomial":
        return nan_paths(obj.coeffs, f"{path}.coeffs", depth + 1, seen) + nan_paths(obj.delays, f"{path}.delays",
                                                                                      depth + 1, seen)
    if name == "TransferFunction":
        return nan_paths(obj.num, f"{path}.num", depth + 1, seen) + nan_paths(obj.den, f"{path}.den", depth + 1, seen)
    if name == "Loop":
        return nan_paths(obj.characteristic, f"{path}.characteristic", depth + 1, seen)
    if name == "ShaperFilter":
        return nan_paths(obj.taps, f"{path}.taps", depth + 1, seen)
    return []


def allow_nan(*suffixes: str) -> Callable[[list[str]], list[str]]:
    """A filter dropping NaN paths that are documented as 'not available' (e.g. ``Margins.omega_gm``)."""

    def keep(paths: list[str]) -> list[str]:
        return [p for p in paths if not any(p.endswith(s) for s in suffixes)]

    return keep


# ====================================================================== the entry table
@dataclass
class Entry:
    """One public entry point: how to call it validly and which arguments to replace."""

    label: str
    call: Callable[..., Any]
    base: Callable[[], dict[str, Any]]
    params: dict[str, str]
    check: Callable[[Any, dict[str, Any]], str | None] | None = None
    nan_filter: Callable[[list[str]], list[str]] | None = None
    aliases: dict[str, tuple[str, ...]] = field(default_factory=dict)
    timeout: float = CALL_SECONDS
    examples: int = HYPOTHESIS_EXAMPLES
    area: str = ""
    pool_limit: int | None = None  # sweep only the first values of each pool (expensive entries)
    writes: bool = False  # writes files: an error must leave none behind


# ---- shared valid objects (built once)
@functools.lru_cache(maxsize=None)
def ZV():
    return posicast.design("zv", posicast.Mode(10.0, 0.03))


@functools.lru_cache(maxsize=None)
def DZV():
    return posicast.design("dzv", posicast.Mode(10.0, 0.03))


def PLANT():
    return ([1.0], [1.0, 1.0, 0.0])


def CTRL():
    return ([10.0, 10.0], [0.01, 1.0])


def LOAD():
    return ([1.0, 0.0], [1.0, 0.6, 100.0])


@functools.lru_cache(maxsize=None)
def LOOP():
    return posicast.control_action(G=PLANT(), C=CTRL(), F=LOAD(), S=ZV())


@functools.lru_cache(maxsize=None)
def TIME():
    return np.arange(0.0, 2.0, 1e-3)


@functools.lru_cache(maxsize=None)
def SIM():
    t = TIME()
    return posicast.simulate(LOOP(), t, w=np.ones_like(t))


@functools.lru_cache(maxsize=None)
def TUNED():
    return posicast.tune_pi(([1.0], [1.0, 2.0, 1.0]), ms=1.4, n_lines=21)


@functools.lru_cache(maxsize=None)
def SYNTH():
    testing = importlib.import_module("posicast.testing")
    return testing.synthetic(posicast.Mode(2 * math.pi * 5.0, 0.05), "random_binary", sample_rate=200.0, n=400, seed=1,
                           noise=0.001)


@functools.lru_cache(maxsize=None)
def IDENT():
    d = SYNTH()
    return posicast.identify(d.t, d.u, d.y)


@functools.lru_cache(maxsize=None)
def QP():
    return posicast.QuasiPolynomial([[1.0, 1.0], [0.5, 0.0]], [0.0, 1.0])


@functools.lru_cache(maxsize=None)
def TF():
    return posicast.TransferFunction.from_poly([1.0], [1.0, 1.0, 0.0], 0.1)


def DATA_DIR() -> Path:
    return _DATA_DIR[0]


_DATA_DIR: list[Path] = [Path(".")]


def shaper_check(S: Any, kw: dict[str, Any]) -> str | None:
    """A designed shaper passes a unit step unchanged in the end: DC gain 1 (every kind, seed 000 eq. 3)."""
    g = S.dc_gain
    if not (math.isfinite(g) and abs(g - 1.0) < 1e-6):
        return f"dc_gain = {g!r}, not 1"
    if not np.all(np.isfinite(S.times)) or np.any(S.times < 0):
        return "impulse times not finite and >= 0"
    return None


def delay_check(D: Any, kw: dict[str, Any]) -> str | None:
    float(kw["tau"])  # a real delay was drawn
    v = D(1j)  # |exp(-j tau)| = 1
    return None if abs(abs(v) - 1.0) < 1e-12 else f"|delay(tau)(j)| = {abs(v)!r}, not 1"


def tuning_check(r: Any, kw: dict[str, Any]) -> str | None:
    """A returned controller is certified stable and meets every constraint; NaN marks only an empty result."""
    if r.gains is None:
        return None
    if not (math.isfinite(r.ms) and math.isfinite(r.sm) and all(math.isfinite(n) for n in r.norms)):
        return f"a controller was returned with a NaN or infinite Ms ({r.ms!r}) or norm ({r.norms!r})"
    if not r.stable:
        return "a controller was returned but the loop is not certified stable"
    for c, nrm in zip(r.constraints, r.norms):
        if not nrm <= c.gamma * (1 + 1e-6):
            return f"achieved {c.label.split('<')[0].strip()} = {nrm!r} exceeds gamma {c.gamma!r}"
    return None


# An empty or unbounded TuningResult documents ms, omega_ms, sm and the norms as NaN (tuning_check
# requires them finite whenever a controller is returned).
TUNING_NAN = allow_nan(".ms", ".omega_ms", ".sm", ".norms[0]", ".norms[1]", ".abscissa")


def _tune_nan_filter(paths: list[str]) -> list[str]:
    return TUNING_NAN(paths)


def entry_table() -> list[Entry]:
    """Every public entry with its valid base call and the kinds of its arguments."""
    pc = posicast
    ident = importlib.import_module("posicast.identification")
    spectra = importlib.import_module("posicast.spectra")
    tune = importlib.import_module("posicast.tune")
    loops = importlib.import_module("posicast.loops")
    simulate = importlib.import_module("posicast.simulation")
    cases = importlib.import_module("posicast.cases")
    export = importlib.import_module("posicast.io.export")
    firmware = importlib.import_module("posicast.firmware")
    testing = importlib.import_module("posicast.testing")
    E = Entry
    csv_path = lambda: str(DATA_DIR() / "data.csv")  # noqa: E731
    mode = lambda: pc.Mode(10.0, 0.03)  # noqa: E731
    table = [
        # ---------------------------------------------------------------- modes, shapers, analysis
        E("Mode", lambda **k: pc.Mode(**k), lambda: {"omega": 10.0, "zeta": 0.03}, {"omega": "real", "zeta": "real"}),
        E("Mode.from_hz", lambda **k: pc.Mode.from_hz(**k), lambda: {"freq_hz": 2.0, "zeta": 0.03},
          {"freq_hz": "real", "zeta": "real"}),
        E("Mode.scaled", lambda **k: mode().scaled(**k), lambda: {"ratio": 1.1}, {"ratio": "real"}),
        E("design", lambda **k: pc.design(**k), lambda: {"kind": "zvd", "mode": mode()},
          {"kind": "str", "mode": "mode"}, check=shaper_check, aliases={"mode": ("omega", "zeta")}),
        E("design[ei]", lambda **k: pc.design("ei", mode(), **k), lambda: {"vtol": 0.05}, {"vtol": "real"},
          check=shaper_check),
        E("design[zvdk]", lambda **k: pc.design("zvdk", mode(), **k), lambda: {"k": 2}, {"k": "int"},
          check=shaper_check),
        E("design[mis_zvd]", lambda **k: pc.design("mis_zvd", mode(), **k), lambda: {"n": 2, "m": 3},
          {"n": "int", "m": "int"}, check=shaper_check),
        E("design[dezv]", lambda **k: pc.design("dezv", mode(), **k), lambda: {"T": 0.3}, {"T": "real"},
          check=shaper_check),
        E("design[si]", lambda **k: pc.design("si", mode(), **k), lambda: {"vtol": 0.05, "band": (0.95, 1.05)},
          {"vtol": "real", "band": "pair", "damping": "pair", "max_impulses": "int"}, check=shaper_check,
          timeout=6.0, pool_limit=12),
        E("design[um_si]", lambda **k: pc.design("um_si", mode(), **k), lambda: {"vtol": 0.05, "band": (0.95, 1.05)},
          {"vtol": "real", "band": "pair"}, check=shaper_check, timeout=6.0, pool_limit=12),
        E("design[um_zvd]", lambda **k: pc.design("um_zvd", pc.Mode(10.0, k.pop("zeta"))), lambda: {"zeta": 0.1},
          {"zeta": "real"}, check=shaper_check),
        E("shortest_shaper", lambda **k: pc.shortest_shaper(**k),
          lambda: {"modes": [mode()], "vtol": 0.05, "band": (0.95, 1.05), "max_impulses": 4},
          {"modes": "object", "vtol": "real", "band": "pair", "damping": "pair", "max_impulses": "int",
           "sample_period": "real", "max_duration": "real", "certify": "bool", "name": "str"},
          check=shaper_check, timeout=6.0, pool_limit=12),
        E("design[zeta]", lambda **k: pc.design(k.pop("kind"), pc.Mode(10.0, k.pop("zeta"))),
          lambda: {"kind": "dezv", "zeta": 0.5}, {"zeta": "real"}, check=shaper_check),
        E("Shaper", lambda **k: pc.Shaper(**k), lambda: {"times": np.array([0.0, 0.5]), "amplitudes": np.array([0.5, 0.5])},
          {"times": "array", "amplitudes": "array", "distributed": "object", "continuous": "object", "name": "str",
           "modes": "object"}),
        E("Kernel", lambda **k: pc.Kernel(**k), lambda: {"shape": "rectangular", "T": 0.3}, {"shape": "str", "T": "real"}),
        E("DistributedPart", lambda **k: pc.DistributedPart(**k),
          lambda: {"weight": 0.5, "delay": 0.1, "kernels": (pc.Kernel("rectangular", 0.3),)},
          {"weight": "real", "delay": "real", "kernels": "object"}),
        E("residual_vibration", lambda **k: pc.residual_vibration(**k),
          lambda: {"shaper": ZV(), "omega": 10.0, "zeta": 0.03, "reference": "end"},
          {"shaper": "object", "omega": "array", "zeta": "real", "reference": "str"}),
        E("sensitivity_curve", lambda **k: pc.sensitivity_curve(**k),
          lambda: {"shaper": ZV(), "ratio": np.linspace(0.5, 1.5, 11), "mode": None, "reference": "end"},
          {"shaper": "object", "ratio": "array", "mode": "object", "reference": "str"}),
        E("insensitivity", lambda **k: pc.insensitivity(**k),
          lambda: {"shaper": ZV(), "vtol": 0.05, "mode": None, "reference": "end", "max_ratio": 10.0},
          {"shaper": "object", "vtol": "real", "mode": "object", "reference": "str", "max_ratio": "real"}),
        E("sensitivity_plot", lambda **k: pc.sensitivity_plot(**k),
          lambda: {"items": [ZV()], "vtol": 0.05, "reference": "end", "ratio": None},
          {"items": "object", "vtol": "real", "reference": "str", "ratio": "array", "labels": "object"}),
        E("impulse_plot", lambda **k: pc.impulse_plot(**k), lambda: {"shaper": DZV(), "n_points": 200},
          {"shaper": "object", "n_points": "int", "ax": "object"}),
        # ---------------------------------------------------------------- core
        E("QuasiPolynomial", lambda **k: pc.QuasiPolynomial(**k),
          lambda: {"coeffs": [[1.0, 1.0], [0.5, 0.0]], "delays": [0.0, 1.0]}, {"coeffs": "qp", "delays": "array"}),
        E("QuasiPolynomial.__call__", lambda **k: QP()(**k), lambda: {"s": 1j}, {"s": "array"}),
        E("QuasiPolynomial.derivative", lambda **k: QP().derivative(**k), lambda: {"order": 2}, {"order": "int"}),
        E("QuasiPolynomial.taylor", lambda **k: QP().taylor(**k), lambda: {"s0": 0.5j, "order": 4},
          {"s0": "real", "order": "int"}),
        E("QuasiPolynomial.shift", lambda **k: QP().shift(**k), lambda: {"delay": 0.5}, {"delay": "real"}),
        E("QuasiPolynomial.scaled", lambda **k: QP().scaled(**k), lambda: {"factor": 2.0}, {"factor": "real"}),
        E("QuasiPolynomial.from_poly", lambda **k: pc.QuasiPolynomial.from_poly(**k),
          lambda: {"poly_desc": [1.0, 2.0], "delay": 0.5}, {"poly_desc": "array", "delay": "real"}),
        E("QuasiPolynomial.from_terms", lambda **k: pc.QuasiPolynomial.from_terms(**k),
          lambda: {"terms": [([1.0, 2.0], 0.0), ([1.0], 0.5)]}, {"terms": "object"}),
        E("QuasiPolynomial.constant", lambda **k: pc.QuasiPolynomial.constant(**k), lambda: {"value": 2.0},
          {"value": "real"}),
        E("QuasiPolynomial.equals", lambda **k: QP().equals(**k), lambda: {"other": QP(), "rtol": 1e-12},
          {"other": "object", "rtol": "real"}),
        E("TransferFunction", lambda **k: pc.TransferFunction(**k),
          lambda: {"num": pc.QuasiPolynomial([[1.0]]), "den": pc.QuasiPolynomial([[1.0, 1.0]])},
          {"num": "object", "den": "object"}),
        E("TransferFunction.from_poly", lambda **k: pc.TransferFunction.from_poly(**k),
          lambda: {"num_desc": [1.0], "den_desc": [1.0, 1.0], "delay": 0.1},
          {"num_desc": "array", "den_desc": "array", "delay": "real"}, aliases={"num_desc": ("num",),
                                                                              "den_desc": ("den",)}),
        E("TransferFunction.constant", lambda **k: pc.TransferFunction.constant(**k), lambda: {"value": 2.0},
          {"value": "real"}),
        E("TransferFunction.__call__", lambda **k: TF()(**k), lambda: {"s": 1j}, {"s": "array"}),
        E("TransferFunction.freqresp", lambda **k: TF().freqresp(**k), lambda: {"omega": [0.1, 1.0]},
          {"omega": "array"}),
        E("TransferFunction.feedback", lambda **k: TF().feedback(**k), lambda: {"other": 2.0, "sign": -1},
          {"other": "system", "sign": "int"}),
        E("TransferFunction.series", lambda **k: TF().series(k["other"]), lambda: {"other": 2.0}, {"other": "system"}),
        E("TransferFunction.parallel", lambda **k: TF().parallel(k["other"]), lambda: {"other": 2.0},
          {"other": "system"}),
        E("as_transfer", lambda **k: pc.as_transfer(**k), lambda: {"obj": PLANT(), "name": "G"},
          {"obj": "system", "name": "str"}, aliases={"obj": ("G",)}),
        E("delay", lambda **k: pc.delay(**k), lambda: {"tau": 0.5}, {"tau": "real"}, check=delay_check),
        # ---------------------------------------------------------------- loops
        *[E(name, lambda _f=f, **k: _f(**k), lambda: {"G": PLANT(), "C": CTRL(), "F": LOAD(), "S": ZV()},
            {"G": "system", "C": "system", "F": "system", "S": "system"})
          for name, f in (("feedforward", pc.feedforward), ("control_action", pc.control_action),
                          ("inverse_shaper", pc.inverse_shaper))],
        E("Loop", lambda **k: pc.Loop(k.pop("architecture"), **k),
          lambda: {"architecture": "inverse_shaper", "G": PLANT(), "C": CTRL(), "S": DZV()},
          {"architecture": "str", "G": "system", "C": "system", "S": "system"}),
        E("Loop.transfer", lambda **k: LOOP().transfer(**k), lambda: {"src": "w", "dst": "y"},
          {"src": "str", "dst": "str"}),
        E("Loop.controller_factor", lambda **k: LOOP().controller_factor(**k), lambda: {"src": "n", "dst": "u"},
          {"src": "str", "dst": "str"}),
        E("Loop.channel_cancelled", lambda **k: LOOP().channel_cancelled(**k), lambda: {"src": "w", "dst": "z"},
          {"src": "str", "dst": "str"}),
        E("Loop.frequency_response", lambda **k: LOOP().frequency_response(**k),
          lambda: {"src": "w", "dst": "z", "omega": [0.5, 5.0]}, {"src": "str", "dst": "str", "omega": "array"}),
        E("Loop.nyquist", lambda **k: LOOP().nyquist(**k), lambda: {"omega": [0.5, 5.0]}, {"omega": "array"}),
        E("Loop.margins", lambda **k: LOOP().margins(**k), lambda: {"omega": np.linspace(0.1, 50, 400)},
          {"omega": "array"}, nan_filter=allow_nan(".omega_gm", ".omega_pm")),
        E("Loop.poles", lambda **k: LOOP().poles(**k), lambda: {"region": (-5.0, 1.0, 0.0, 20.0)},
          {"region": "region"}),
        E("Loop.zeros", lambda **k: LOOP().zeros(**k), lambda: {"region": (-5.0, 1.0, 0.0, 20.0), "channel": ("w", "z")},
          {"region": "region", "channel": "object"}),
        E("Loop.stability", lambda **k: LOOP().stability(**k), lambda: {"max_evaluations": 1e6, "timeout": 10.0},
          {"max_evaluations": "real", "timeout": "real"}),
        E("removable_points", lambda **k: loops.removable_points(**k), lambda: {"num": DZV().num, "den": DZV().den},
          {"num": "object", "den": "object"}),
        E("feature_frequencies", lambda **k: loops.feature_frequencies(**k), lambda: {"tfs": [TF()]},
          {"tfs": "object"}),
        E("bode_plot", lambda **k: loops.bode_plot(**k), lambda: {"items": LOOP(), "src": "w", "dst": "y",
                                                                   "omega": np.logspace(-1, 2, 50)},
          {"items": "object", "src": "str", "dst": "str", "omega": "array", "labels": "object", "ax": "object"}),
        E("nyquist_plot", lambda **k: loops.nyquist_plot(**k), lambda: {"loop": LOOP(), "omega": np.linspace(0.1, 50, 50),
                                                                         "ms": 2.0},
          {"loop": "object", "omega": "array", "ms": "real", "labels": "object", "ax": "object"}),
        E("spectrum_plot", lambda **k: loops.spectrum_plot(**k), lambda: {"loop": LOOP(), "region": (-5.0, 1.0, 0.0, 20.0)},
          {"loop": "object", "region": "region", "labels": "object", "ax": "object"}),
        # ---------------------------------------------------------------- simulate
        E("simulate", lambda **k: pc.simulate(**k), lambda: {"loop": LOOP(), "t": TIME(), "w": np.ones(TIME().size)},
          {"loop": "object", "t": "array", "w": "array", "d": "array", "n": "array", "di": "array",
           "sample_rate": "real", "substeps": "int", "controller_method": "str", "saturation": "pair",
           "rate_limit": "real", "divergence_limit": "real"}),
        E("SimulationResponse.residual_vibration", lambda **k: SIM().residual_vibration(**k),
          lambda: {"after": 1.0, "signal": "y"}, {"after": "real", "signal": "str"}),
        E("SimulationResponse.settling_time", lambda **k: SIM().settling_time(**k),
          lambda: {"signal": "z", "tol": 0.02, "start": None}, {"signal": "str", "tol": "real", "start": "real"},
          nan_filter=allow_nan("result")),
        E("SimulationResponse.overshoot", lambda **k: SIM().overshoot(**k), lambda: {"signal": "z", "start": None},
          {"signal": "str", "start": "real"}),
        E("SimulationResponse.peak", lambda **k: SIM().peak(**k), lambda: {"signal": "u"}, {"signal": "str"}),
        E("SimulationResponse.plot", lambda **k: SIM().plot(**k), lambda: {"signals": ("w", "y")},
          {"signals": "object", "axes": "object", "label": "object"}),
        E("ShaperFilter", lambda **k: pc.ShaperFilter(**k),
          lambda: {"S": ZV(), "sample_rate": 100.0, "fractional": "linear", "initial": 0.0},
          {"S": "object", "sample_rate": "real", "fractional": "str", "initial": "real"}),
        E("ShaperFilter.process", lambda **k: pc.ShaperFilter(ZV(), 100.0).process(**k), lambda: {"chunk": [1.0, 1.0]},
          {"chunk": "array"}),
        E("ShaperFilter.push", lambda **k: pc.ShaperFilter(ZV(), 100.0).push(**k), lambda: {"sample": 1.0},
          {"sample": "real"}),
        E("ShaperFilter.reset", lambda **k: pc.ShaperFilter(ZV(), 100.0).reset(**k), lambda: {"initial": 1.0},
          {"initial": "real"}),
        E("shape_signal", lambda **k: pc.shape_signal(**k),
          lambda: {"S": ZV(), "x": np.ones(50), "sample_rate": 100.0, "fractional": "linear"},
          {"S": "object", "x": "array", "sample_rate": "real", "fractional": "str"}),
        E("discretize", lambda **k: simulate.discretize(**k), lambda: {"S": DZV(), "sample_rate": 100.0,
                                                                       "fractional": "lagrange3"},
          {"S": "object", "sample_rate": "real", "fractional": "str"}),
        E("DiscreteShaper.__call__", lambda **k: simulate.discretize(ZV(), 100.0)(**k), lambda: {"z": 1j},
          {"z": "array"}),
        E("DiscreteShaper.at_s", lambda **k: simulate.discretize(ZV(), 100.0).at_s(**k), lambda: {"s": 1j},
          {"s": "array"}),
        E("shortest_delay", lambda **k: simulate.shortest_delay(**k), lambda: {"S": ZV()}, {"S": "object"}),
        E("export_shaper", lambda **k: export.export_shaper(**k),
          lambda: {"S": ZV(), "sample_rate": 100.0, "format": "c", "name": "zv", "fractional": "linear",
                   "form": "sparse", "inverse": True, "precision": "float"},
          {"S": "object", "sample_rate": "real", "format": "str", "name": "str", "fractional": "str",
           "form": "str", "inverse": "object", "precision": "str"}),
        # ---------------------------------------------------------------- issue #16: the sample period
        E("zplane_shaper", lambda **k: pc.zplane_shaper(**k),
          lambda: {"modes": mode(), "sample_period": 0.01, "multiplicity": 2, "stride": "positive"},
          {"modes": "mode", "sample_period": "real", "multiplicity": "int", "stride": "object"},
          aliases={"modes": ("omega", "zeta", "mode")}),
        E("highest_multiplicity", lambda **k: pc.highest_multiplicity(**k),
          lambda: {"modes": mode(), "actuator_period": 0.01, "rise_time": 2.0, "stride": "positive"},
          {"modes": "mode", "actuator_period": "real", "rise_time": "real", "stride": "object"},
          aliases={"modes": ("omega", "zeta", "mode"), "actuator_period": ("actuator_period", "sample_period")}),
        E("sampled_loop", lambda **k: pc.sampled_loop(**k), lambda: {"loop": LOOP(), "sample_rate": 100.0},
          {"loop": "object", "sample_rate": "real"}),
        E("SampledLoop", lambda **k: pc.SampledLoop(**k).spectral_radius,
          lambda: {"loop": LOOP(), "sample_rate": 100.0, "computation_delay": 1, "controller_method": "zoh",
                   "fractional": "linear"},
          {"loop": "object", "sample_rate": "real", "computation_delay": "int", "controller_method": "str",
           "fractional": "str"}),
        E("inverse_stability", lambda **k: simulate.inverse_stability(**k),
          lambda: {"taps": [0.6, 0.0, 0.4], "sample_rate": 100.0}, {"taps": "array", "sample_rate": "real"}),
        # ---------------------------------------------------------------- spectra
        E("roots", lambda **k: pc.roots(**k), lambda: {"h": QP(), "region": (-5.0, 1.0, 0.0, 20.0)},
          {"h": "qp", "region": "region", "ignore": "array", "max_evaluations": "real", "timeout": "real"}),
        E("stability", lambda **k: pc.stability(**k), lambda: {"h": QP()},
          {"h": "qp", "ignore": "array", "max_evaluations": "real", "timeout": "real"}),
        E("spectral_abscissa", lambda **k: pc.spectral_abscissa(**k), lambda: {"h": QP()},
          {"h": "qp", "ignore": "array", "max_radius": "real"}),
        E("rightmost", lambda **k: pc.rightmost(**k), lambda: {"h": QP(), "n": 2},
          {"h": "qp", "n": "int", "ignore": "array", "max_alpha_steps": "int"}),
        E("poles", lambda **k: pc.poles(**k), lambda: {"system": PLANT(), "region": (-5.0, 1.0, 0.0, 20.0)},
          {"system": "system", "region": "region", "max_evaluations": "real", "timeout": "real"}),
        E("zeros", lambda **k: pc.zeros(**k), lambda: {"system": ZV(), "region": (-5.0, 1.0, 0.0, 20.0)},
          {"system": "system", "region": "region", "channel": "object", "max_evaluations": "real",
           "timeout": "real"}),
        E("characteristic_of", lambda **k: spectra.characteristic_of(**k), lambda: {"system": PLANT()},
          {"system": "system"}),
        E("difference_spectrum", lambda **k: pc.difference_spectrum(**k),
          lambda: {"h": pc.QuasiPolynomial([[1.0, 1.0], [0.0, 0.5]], [0.0, 1.0])}, {"h": "qp"}),
        E("root_bound", lambda **k: spectra.root_bound(**k), lambda: {"h": QP(), "alpha": -1.0},
          {"h": "qp", "alpha": "real"}),
        E("unstable_count", lambda **k: spectra.unstable_count(**k), lambda: {"h": QP()},
          {"h": "qp", "ignore": "array", "max_evaluations": "real"}),
        # ---------------------------------------------------------------- tune
        E("tune_pd", lambda **k: pc.tune_pd(**k), lambda: {"G": PLANT(), "ms": 2.0, "n_lines": 21},
          {"G": "system", "S": "system", "architecture": "str", "ms": "real", "F": "system", "constraints": "object",
           "derivative_filter": "real", "kp_range": "pair", "kd_range": "pair", "n_lines": "int"},
          check=tuning_check, nan_filter=_tune_nan_filter, timeout=6.0, examples=3, pool_limit=14),
        E("tune_pi", lambda **k: pc.tune_pi(**k), lambda: {"G": ([1.0], [1.0, 2.0, 1.0]), "ms": 1.4, "n_lines": 21},
          {"G": "system", "ms": "real", "kp_range": "pair", "ki_range": "pair", "n_lines": "int"},
          check=tuning_check, nan_filter=_tune_nan_filter, timeout=6.0, examples=3, pool_limit=14),
        E("tune_pid", lambda **k: pc.tune_pid(**k),
          lambda: {"G": ([1.0], [1.0, 3.0, 3.0, 1.0]), "ms": 1.6, "fixed": {"kd": 0.5}, "derivative_filter": 0.01,
                   "n_lines": 21},
          {"fixed": "object", "maximize": "str", "derivative_filter": "real", "ms": "real"},
          check=tuning_check, nan_filter=_tune_nan_filter, timeout=6.0, examples=3, pool_limit=14),
        E("tune", lambda **k: tune.tune(**k),
          lambda: {"G": PLANT(), "family": tune.pd_family(), "constraints": [tune.Constraint("S", 2.0)], "n_lines": 21},
          {"family": "object", "constraints": "object", "x_range": "pair", "y_range": "pair"},
          aliases={"x_range": ("kd_range",), "y_range": ("kp_range",)},  # the PD family's names
          check=tuning_check, nan_filter=_tune_nan_filter, timeout=6.0, examples=3, pool_limit=14),
        E("Constraint", lambda **k: tune.Constraint(**k), lambda: {"kind": "S", "gamma": 2.0, "weight": None},
          {"kind": "object", "gamma": "real", "weight": "system"}),
        E("ControllerFamily", lambda **k: tune.ControllerFamily(**k),
          lambda: {"name": "pd", "x": "kd", "y": "kp", "dC": np.array([1.0]), "n0": np.array([0.0]),
                   "nx": np.array([1.0, 0.0]), "ny": np.array([1.0])},
          {"name": "str", "x": "str", "y": "str", "dC": "array", "n0": "array", "nx": "array", "ny": "array",
           "derivative_filter": "real"}),
        E("pd_family", lambda **k: tune.pd_family(**k), lambda: {"derivative_filter": 0.01},
          {"derivative_filter": "real"}),
        E("pi_family", lambda **k: tune.pi_family(**k), lambda: {}, {}),
        E("pid_family", lambda **k: tune.pid_family(**k), lambda: {"fixed": {"kd": 0.5}, "maximize": "ki",
                                                                    "derivative_filter": 0.01},
          {"fixed": "object", "maximize": "str", "derivative_filter": "real"}),
        E("sample_check", lambda **k: testing.sample_check(**k), lambda: {"result": TUNED(), "n": 20, "seed": 0,
                                                                       "margin": 0.3, "n_uniform": 2000},
          {"result": "object", "n": "int", "seed": "int", "margin": "real", "n_uniform": "int"}, timeout=6.0,
          pool_limit=12),
        E("Region.contains", lambda **k: TUNED().region.contains(**k), lambda: {"kx": 1.0, "ky": 1.0},
          {"kx": "array", "ky": "array"}),
        E("Region.mask", lambda **k: TUNED().region.mask(**k), lambda: {"y": np.linspace(0, 5, 5), "what": "hinf"},
          {"y": "array", "what": "str", "constraint": "int"}),
        E("TuningResult.plot", lambda **k: TUNED().plot(**k), lambda: {}, {"ax": "object"}),
        E("region_plot", lambda **k: tune.region_plot(**k), lambda: {"item": TUNED()},
          {"item": "object", "ax": "object", "label": "object"}),
        E("regions_plot", lambda **k: tune.regions_plot(**k), lambda: {"items": [TUNED()]},
          {"items": "object", "labels": "object", "ax": "object", "title": "object"}),
        E("tuning_nyquist_plot", lambda **k: tune.tuning_nyquist_plot(**k), lambda: {"items": TUNED()},
          {"items": "object", "ax": "object", "labels": "object", "omega": "array"}),
        # ---------------------------------------------------------------- identify
        E("identify", lambda **k: pc.identify(**k), lambda: {"t": SYNTH().t, "u": SYNTH().u, "y": SYNTH().y},
          {"t": "array", "u": "array", "y": "array", "n_modes": "int", "method": "str", "covariance": "str",
           "max_modes": "int", "band": "pair", "excitation_slope": "real", "nk": "int"},
          nan_filter=allow_nan(".fit_percent", ".whiteness_p", ".sample_rate"), timeout=6.0, pool_limit=12),
        E("whiteness", lambda **k: ident.whiteness(**k), lambda: {"e": np.sin(np.arange(100.0)), "lags": 10},
          {"e": "array", "lags": "int"}),
        E("synthetic", lambda **k: testing.synthetic(**k), lambda: {"modes": mode(), "input": "step", "n": 200},
          {"modes": "mode", "input": "str", "sample_rate": "real", "n": "int", "noise": "real", "bits": "int",
           "density": "real", "seed": "int", "delay": "int", "period": "real"}),
        E("simulate_modes", lambda **k: testing.simulate_modes(**k), lambda: {"modes": mode(), "u": np.ones(100), "sample_rate": 200.0},
          {"modes": "mode", "u": "array", "sample_rate": "real", "output": "str", "gains": "array"}),
        E("excitation", lambda **k: testing.excitation(**k), lambda: {"kind": "chirp", "n": 100, "sample_rate": 200.0},
          {"kind": "str", "n": "int", "sample_rate": "real", "seed": "int", "delay": "int", "freq": "real", "period": "real"}),
        E("klipper_log", lambda **k: testing.klipper_log(**k),
          lambda: {"path": str(DATA_DIR() / "out" / "k.csv"), "modes": pc.Mode(2 * math.pi * 40.0, 0.05),
                   "sample_rate": 800.0, "min_freq": 20.0, "max_freq": 60.0, "hz_per_sec": 40.0},
          {"path": "path_out", "modes": "mode", "sample_rate": "real", "min_freq": "real", "max_freq": "real",
           "hz_per_sec": "real", "direction": "array", "jitter": "real", "density": "real", "lead": "real"},
          pool_limit=12, writes=True),
        E("load_csv", lambda **k: ident.load_csv(**k), lambda: {"path": csv_path(), "resample": "auto"},
          {"path": "path_in", "resample": "str"}),
        E("Dataset.column", lambda **k: ident.load_csv(csv_path()).column(**k), lambda: {"name": "y"},
          {"name": "str"}),
        E("calibrate", lambda **k: pc.calibrate(**k), lambda: {"paths": csv_path(), "input": "u", "output": "y"},
          {"paths": "path_in", "input": "str", "output": "str", "firmware": "str", "axis": "str", "n_modes": "int",
           "method": "str", "vtol": "real", "margin": "real", "max_smoothing": "real", "klipper_version": "str"},
          timeout=6.0, pool_limit=10, examples=2),
        E("mode_boxes", lambda **k: ident.mode_boxes(**k),
          lambda: {"modes": [pc.Mode(31.4, 0.05)], "intervals": [ident.Interval((30.0, 32.0), (0.04, 0.06))],
                   "shares": None, "margin": 0.05},
          {"modes": "object", "intervals": "object", "shares": "array", "margin": "real"}),
        E("recommend_setting", lambda **k: ident.recommend_setting(**k),
          lambda: {"fw": firmware.Klipper(), "boxes": ident.mode_boxes([pc.Mode(31.4, 0.05)],
                                                                        [ident.Interval((30.0, 32.0), (0.04, 0.06))]),
                   "vtol": 0.05, "margin": 0.05},
          {"fw": "object", "boxes": "object", "vtol": "real", "max_smoothing": "real", "axis": "str",
           "margin": "real"}, timeout=6.0, pool_limit=12),
        E("ResonanceTest", lambda **k: ident.ResonanceTest(**k), lambda: {},
          {"method": "str", "min_freq": "real", "max_freq": "real", "hz_per_sec": "real", "accel_per_hz": "real",
           "sweeping_accel": "real", "sweeping_period": "real"}),
        E("Klipper", lambda **k: firmware.Klipper(**k), lambda: {"version": "v0.13"}, {"version": "str"}),
        E("RepRapFirmware", lambda **k: firmware.RepRapFirmware(**k), lambda: {"version": "3.6"}, {"version": "str"}),
        E("Prusa", lambda **k: firmware.Prusa(**k), lambda: {"printer": "mk4"}, {"printer": "str"}),
        E("MarlinFT", lambda **k: firmware.MarlinFT(**k), lambda: {}, {}),
        E("smoothing_offsets", lambda **k: firmware.smoothing_offsets(**k),
          lambda: {"A": np.array([0.5, 0.5]), "T": np.array([0.0, 0.01])}, {"A": "array", "T": "array"}),
        E("vibration_grid", lambda **k: firmware.vibration_grid(**k),
          lambda: {"A": np.array([0.5, 0.5]), "T": np.array([0.0, 0.01]), "bins": np.array([40.0, 50.0]),
                   "zetas": np.array([0.05])},
          {"A": "array", "T": "array", "bins": "array", "zetas": "array"}),
        E("klipper_smoothing", lambda **k: ident.klipper_smoothing(**k), lambda: {"shaper": ZV(), "accel": 5000.0,
                                                                                   "scv": 5.0},
          {"shaper": "object", "accel": "real", "scv": "real"}),
        # ---------------------------------------------------------------- cases
        # (the report writer is posicast_reports.html.Report now, outside posicast: not a posicast entry)
        E("modes_of", lambda **k: cases.modes_of(**k), lambda: {"system": LOAD()}, {"system": "system"}),
        E("two_mass_plant", lambda **k: cases.two_mass_plant(**k), lambda: {},
          {"c1": "real", "c2": "real", "k2": "real", "m1": "real", "m2": "real"}),
        E("Case", lambda **k: cases.Case(**k),
          lambda: {"name": "x", "source": "s", "G": pc.as_transfer(PLANT()), "F": pc.as_transfer(LOAD()), "C": None,
                   "mode": mode()},
          {"name": "str", "G": "object", "F": "object", "mode": "object", "sample_rate": "real"}),
    ]
    # ---------------------------------------------------------------- qft (issue #18)
    from posicast import qft

    qplants = lambda: [([1.0], [1.0, 1.0, 0.0]), ([1.5], [1.0, 1.0, 0.0])]  # noqa: E731
    qmodes = lambda: [([100.0], [1.0, 0.6, 100.0]), ([121.0], [1.0, 0.66, 121.0])]  # noqa: E731
    qref = ([1.0], [1.0, 1.4, 1.0])
    table += [
        E("PlantSet", lambda **k: qft.PlantSet(**k), lambda: {"plants": qplants(), "nominal_index": 0},
          {"plants": "object", "nominal_index": "int"}),
        E("PlantSet.from_ranges", lambda **k: qft.PlantSet.from_ranges(**k),
          lambda: {"model": cases.two_mass_plant, "ranges": {"c1": (25.0, 75.0)}, "method": "grid", "n": 3},
          {"model": "object", "ranges": "object", "nominal": "object", "method": "str", "n": "int",
           "samples": "int", "seed": "int"}),
        E("PlantSet.two_mass", lambda **k: qft.PlantSet.two_mass(**k), lambda: {"uncertainty": 30.0},
          {"uncertainty": "real"}),
        E("PlantSet.templates", lambda **k: qft.PlantSet.from_list(qplants()).templates(**k),
          lambda: {"frequencies": [0.5, 2.0]}, {"frequencies": "array"}),
        E("percent_vibration", lambda **k: qft.percent_vibration(**k),
          lambda: {"S": ZV(), "plants": qmodes(), "per_plant": False, "damping": "model"},
          {"S": "object", "plants": "object", "per_plant": "bool", "damping": "str"}),
        E("zvdk", lambda **k: qft.zvdk(**k), lambda: {"mode": posicast.Mode(3.0, 0.05), "k": 2},
          {"mode": "object", "k": "int"}),
        E("shortest_zvdk", lambda **k: qft.shortest_zvdk(**k),
          lambda: {"plants": qmodes(), "mode": posicast.Mode(10.0, 0.03), "vtol": 10.0, "kmax": 5},
          {"plants": "object", "mode": "object", "vtol": "real", "kmax": "int"}, timeout=6.0, pool_limit=14),
        E("length_vs_vibration", lambda **k: qft.length_vs_vibration(**k),
          lambda: {"plants": qmodes(), "mode": posicast.Mode(10.0, 0.03), "ks": [0, 1, 2]},
          {"plants": "object", "mode": "object", "inner": "object", "ks": "object"}),
        E("length_vs_uncertainty", lambda **k: qft.length_vs_uncertainty(**k),
          lambda: {"levels": [0.0, 50.0], "vtol": 10.0},
          {"levels": "object", "mode": "object", "vtol": "real"}, timeout=6.0, pool_limit=8, examples=2),
        E("bandwidth", lambda **k: qft.bandwidth(**k), lambda: {"T": ([1.0], [1.0, 1.0])},
          {"T": "system", "omega": "array"}),
        E("qft_design", lambda **k: qft.qft_design(**k),
          lambda: {"plants": qplants(), "reference": qref, "stability": 2.0, "matching": 0.5,
                   "structure": ("lead",)},
          {"plants": "object", "reference": "system", "stability": "real", "matching": "real",
           "frequencies": "array", "structure": "object", "prefilter": "system", "stability_margin": "real",
           "prefilter_structure": "object", "disturbance": "object",
           "refinements": "int", "maxiter": "int"}, timeout=10.0, pool_limit=8, examples=1),
        E("verify", lambda **k: qft.verify(**k),
          lambda: {"plants": qft.PlantSet.from_list(qplants()), "G": posicast.as_transfer(3.0), "F": None,
                   "reference": posicast.as_transfer(qref), "gamma": 2.0, "delta": 0.5},
          {"plants": "object", "G": "object", "F": "object", "gamma": "real", "delta": "real",
           "disturbance": "object"}, timeout=6.0),
        E("nichols_bounds", lambda **k: qft.nichols_bounds(**k),
          lambda: {"plants": qft.PlantSet.from_list(qplants()), "frequencies": np.array([0.5, 2.0]),
                   "reference": posicast.as_transfer(qref), "prefilter": None, "gamma": 2.0, "delta": 0.5},
          {"plants": "object", "frequencies": "array", "gamma": "real", "delta": "real", "disturbance": "object"}),
        E("Structure", lambda **k: qft.Structure(**k), lambda: {"sections": ("lead", "notch")},
          {"sections": "object"}),
        E("model_matching", lambda **k: qft.model_matching(**k),
          lambda: {"P": PLANT(), "G": 3.0, "F": qref, "C": CTRL(), "S": ZV()},
          {"P": "system", "G": "system", "F": "system", "C": "system", "S": "object"}),
        E("inner_loop", lambda **k: qft.inner_loop(**k), lambda: {"P": PLANT(), "G": 3.0, "F": qref},
          {"P": "system", "G": "system", "F": "system"}),
        E("inner_closed_loop", lambda **k: qft.inner_closed_loop(**k), lambda: {"P": PLANT(), "G": 3.0, "F": qref},
          {"P": "system", "G": "system", "F": "system"}),
        E("deviated_two_mass", lambda **k: qft.deviated_two_mass(**k), lambda: {"uncertainty": 35.0},
          {"uncertainty": "real"}),
        E("root_locus", lambda **k: qft.root_locus(**k), lambda: {"plants": qplants(), "C": CTRL(), "gains": [0.5, 2.0]},
          {"plants": "object", "C": "system", "gains": "array"}),
        E("control_effort", lambda **k: qft.control_effort(**k),
          lambda: {"P": PLANT(), "G": ([5.0, 5.0], [0.05, 1.0]), "F": ([4.0], [1.0, 0.4, 4.0]),
                   "C": ([0.5, 1.0], [1.0, 0.0]), "S": posicast.design("zv", posicast.Mode(2.0, 0.1)),
                   "t": np.arange(0.0, 5.0, 0.01)},
          {"P": "system", "G": "system", "F": "system", "C": "system", "S": "object", "t": "array", "w": "array"},
          timeout=6.0, pool_limit=10, examples=2),
    ]
    for name in ("simulation_example", "flexible_link", "gantry_crane", "two_mass", "flexible_joint_robot",
                 "sampled_28hz", "two_mass_plants"):
        table.append(E(name, lambda _f=getattr(cases, name), **k: _f(**k), lambda: {}, {}))
    table += _sweep_entries(E)  # issue #19
    table += _report_entries(E)  # issue #20
    return table


# ---- issue #19: posicast.sweep (serial here: a LocalCluster per call would not fit the per-call limit)
def _vibration_sweep(store: Any = None) -> Any:
    sweep = importlib.import_module("posicast.sweeps").sweep
    return sweep(functools.partial(posicast.residual_vibration, ZV()), {"omega": [9.0, 10.0], "zeta": [0.0, 0.03]},
                 client="serial", store=store, progress=False)


@functools.lru_cache(maxsize=None)
def SWEPT():
    return _vibration_sweep()


@functools.lru_cache(maxsize=None)
def SWEEP_STORE() -> str:
    path = str(DATA_DIR() / "swept.zarr")
    _vibration_sweep(path)
    return path


def _sweep_entries(E: Callable[..., Entry]) -> list[Entry]:
    sweeps = importlib.import_module("posicast.sweeps")
    no_nan_but_failed_points = lambda paths: [p for p in paths if ".values[" not in p and ".seconds[" not in p]  # noqa: E731
    return [
        E("sweep", lambda **k: sweeps.sweep(**k),
          lambda: {"function": functools.partial(posicast.residual_vibration, ZV()),
                   "parameters": {"omega": [9.0, 10.0], "zeta": [0.03]}, "client": "serial", "progress": False,
                   "connect_timeout": 0.3},
          {"function": "object", "parameters": "object", "n": "int", "seed": "int", "workers": "int",
           "batch_size": "int", "progress": "object", "overwrite": "bool", "connect_timeout": "real",
           "store": "path_out"}, nan_filter=no_nan_but_failed_points, writes=True, timeout=6.0),
        E("load", lambda **k: sweeps.load(**k), lambda: {"store": SWEEP_STORE()}, {"store": "path_in"}),
        E("make_space", lambda **k: sweeps.make_space(**k), lambda: {"parameters": {"x": [1.0, 2.0]}},
          {"parameters": "object", "n": "int", "seed": "int"}),
        E("default_batch_size", lambda **k: sweeps.default_batch_size(**k), lambda: {"n_points": 400, "workers": 2},
          {"n_points": "int", "workers": "int"}),
        E("SweepResult.parameter", lambda **k: SWEPT().parameter(**k), lambda: {"name": "omega"}, {"name": "str"}),
        E("SweepResult.plot", lambda **k: SWEPT().plot(**k), lambda: {"value": "value"},
          {"value": "str", "ax": "object"}),
    ]


def _plant_file(data: dict[str, Any]) -> str:
    path = DATA_DIR() / "plant.json"
    if not path.exists():
        path.write_text(json.dumps(data))
    return str(path)


# ---- issue #20: posicast report (a real Klipper file from the repository: the report's own example)
def _report_entries(E: Callable[..., Entry]) -> list[Entry]:
    report = importlib.import_module("posicast.report")
    log = str(Path(__file__).resolve().parent / "data" / "real" / "iconoclastxyz_v24_resonances_y_20220507.csv")
    plant = {"plant": {"num": [1.0], "den": [1.0, 0.4, 4.0, 0.0]}, "tune": {"controller": "pd", "ms": 2.0},
             "horizon": 20.0}
    return [
        E("write_report", lambda **k: report.write_report(**k),
          lambda: {"data": log, "out": str(DATA_DIR() / "report_out")},
          {"data": "path_in", "out": "path_dir", "firmware": "str", "axis": "str"}, writes=True, timeout=6.0,
          pool_limit=8, examples=1),
        E("load_plant", lambda **k: report.load_plant(**k), lambda: {"path": _plant_file(plant)}, {"path": "path_in"}),
        E("plant_spec", lambda **k: report.plant_spec(**k), lambda: {"data": dict(plant)}, {"data": "object"}),
        E("analyse_plant", lambda **k: report.analyse_plant(**k), lambda: {"spec": report.plant_spec(plant)},
          {"spec": "object"}, timeout=6.0, examples=1),
        E("is_plant_file", lambda **k: report.is_plant_file(**k), lambda: {"path": "p.json"}, {"path": "str"}),
        E("format_number", lambda **k: report.format_number(**k), lambda: {"value": 0.5},
          {"value": "real", "style": "str", "digits": "int", "zero": "str"}),
        E("format_column", lambda **k: report.format_column(**k), lambda: {"values": [0.5, 1e-17]},
          {"values": "array", "digits": "int"}),
    ]


# Public names that are not callables taking arguments, or result types built by the library, with the
# entries above that drive their methods.  test_every_public_name_is_covered keeps this honest.
NOT_CALLED = {
    "KINDS": "data (dict of kinds)",
    "ZERO_VIBRATION_KINDS": "data",
    "METHODS": "data",
    "INPUTS": "data",
    "EXCITATIONS": "data",
    "ARCHITECTURES": "data",
    "Ring": "data type: Loop.ring (built by the architectures; its checks tested in tests/test_loops.py)",
    "Block": "data type: the blocks of Loop.ring",
    "Tap": "data type: Ring.inputs/outputs entries",
    "LoopBlocks": "data type: what an architecture's builder receives",
    "register_architecture": "mutates the process-wide registry: driven in tests/test_loops.py (with cleanup)",
    "unregister_architecture": "mutates the process-wide registry: driven in tests/test_loops.py",
    "REQUIREMENTS": "data (posicast.serve: the serve extra's packages)",
    "missing_requirements": "no arguments (posicast.serve; tests/test_serve_api.py patches it)",
    "serve": "starts a blocking web server: run as `posicast serve` in a subprocess by tests/test_serve_api.py",
    "FRACTIONAL": "data",
    "NAMED_CHANNELS": "data",
    "EXPORT_FORMATS": "data",
    "ALL": "data (the cases)",
    "TWO_MASS_UNCERTAINTY": "data",
    "CRANE_TABLE1": "data",
    "DEFAULT_STRUCTURE": "data (qft: the default controller sections)",
    "SECTIONS": "data (qft: the section names and their parameters)",
    "QFTResult": "result of qft_design: .plot and .summary driven in tests/test_qft.py",
    "Verification": "result of verify",
    "Bandwidth": "result of bandwidth",
    "ShaperLengths": "result of length_vs_vibration",
    "ShortestShaper": "result of shortest_zvdk",
    "UncertaintyLengths": "result of length_vs_uncertainty",
    "RootLocus": "result of root_locus (plot driven in tests/test_qft_loop.py)",
    "ControlEffort": "result of control_effort",
    "cases": "module: its __all__ is walked",
    "DivergenceWarning": "warning class",
    "OptimalShaper": "result of design('si' | 'um_zv' | 'um_zvd') and shortest_shaper (a Shaper: driven there)",
    "Optimality": "result: OptimalShaper.optimality",
    "ActiveConstraint": "result: Optimality.active entries",
    "RootFindingError": "exception class",
    "BudgetExceeded": "exception class",
    "TuningResult": "result of tune_*: plot driven as TuningResult.plot",
    "Region": "result: Region.contains, Region.mask",
    "RegionCheck": "result of sample_check",
    "Roots": "result of roots",
    "Characteristic": "result of characteristic_of",
    "Stability": "result of stability",
    "DifferenceSpectrum": "result of difference_spectrum",
    "SimulationResponse": "result of simulate: its methods are driven",
    "Margins": "result of Loop.margins",
    "NyquistResponse": "result of Loop.nyquist",
    "SensitivityCurve": "result of sensitivity_curve",
    "Insensitivity": "result of insensitivity",
    "Identification": "result of identify",
    "Interval": "result of identify",
    "Calibration": "result of calibrate",
    "Candidate": "result of recommend_setting",
    "Recommendation": "result of recommend_setting",
    "ModeBox": "result of mode_boxes",
    "FileResult": "result of calibrate",
    "Schedule": "result of calibrate",
    "ModeTest": "result of identify's significance test",
    "NoModeFound": "exception class",
    "SpectralAbscissa": "result of spectral_abscissa",
    "Firmware": "abstract base of the firmware classes (Klipper, ... are driven)",
    "Setting": "result of a firmware's setting()",
    "ShaperType": "data: a firmware's shaper types",
    "FIRMWARES": "data",
    "SyntheticData": "result of synthetic",
    "Dataset": "result of load_csv: Dataset.column driven",
    "DiscreteShaper": "result of discretize: __call__ and at_s driven",
    "EXPORT_FORMS": "data",
    "EXPORT_PRECISIONS": "data",
    "InverseStability": "result of inverse_stability",
    "OrderChoice": "result of highest_multiplicity",
    "SparseTaps": "result of discretize (DiscreteShaper.sparse)",
    "SweepResult": "result of sweep: SweepResult.parameter and .plot driven",
    "local_cluster": "starts worker processes (seconds): driven in tests/test_sweep.py, its workers checked there",
    "Space": "result of make_space",
    "Failure": "result: SweepResult.failures entries",
    "Timing": "result: SweepResult.timing",
    "SchedulerUnreachable": "exception class",
    "WorkerFailure": "exception class",
    "StoreMismatch": "exception class",
    "ReportSummary": "result of write_report",
    "PlantSpec": "result of load_plant / plant_spec",
    "PlantAnalysis": "result of analyse_plant",
}
ALIASES: dict[str, tuple[str, ...]] = {}


def public_names() -> dict[str, set[str]]:
    """``{name: {module, ...}}`` over posicast.__all__, every subpackage's __all__ and EXTRA_MODULES."""
    out: dict[str, set[str]] = {}
    mods = ["posicast"] + [f"posicast.{s}" for s in SUBPACKAGES] + list(EXTRA_MODULES)
    for mn in mods:
        m = importlib.import_module(mn)
        for n in getattr(m, "__all__", ()):
            out.setdefault(n, set()).add(mn)
    return out


ENTRIES = entry_table()
ENTRY_LABELS = {e.label for e in ENTRIES}


def _entry_module(entry: Entry) -> str:
    """The module defining an entry's callable (``posicast.tune.design`` for ``tune_pd``)."""
    head = entry.label.split(".")[0].split("[")[0]
    for mn in ("posicast",) + tuple(f"posicast.{s}" for s in SUBPACKAGES) + EXTRA_MODULES:
        m = importlib.import_module(mn)
        if head in getattr(m, "__all__", ()) and hasattr(m, head):
            obj = getattr(m, head)
            return getattr(obj, "__module__", None) or mn
    return "posicast"


def area_of(entry: Entry) -> str:
    """The area an entry belongs to, for the clean-percentage summary (its defining subpackage)."""
    if entry.area:
        return entry.area
    parts = _entry_module(entry).split(".")
    return parts[1] if len(parts) > 1 else "posicast"


def entry_owner(entry: Entry) -> str:
    mod = importlib.import_module(_entry_module(entry))
    return owner_of(getattr(mod, "__file__", "") or "")


STATS: dict[str, list[int]] = {}  # area -> [calls, clean]
SECONDS: dict[str, float] = {}  # entry -> seconds spent
FAILURES: list[tuple[str, str]] = []  # (owner, line)


def record(area: str, clean: bool) -> None:
    s = STATS.setdefault(area, [0, 0])
    s[0] += 1
    s[1] += int(clean)


# ====================================================================== running one call
def _listing(root: Path) -> set[str]:
    """Every path below ``root`` (relative), to see what a call wrote."""
    return {str(p.relative_to(root)) for p in root.rglob("*")}


def _deepest_posicast_frame(tb: Any) -> traceback.FrameSummary | None:
    frames = traceback.extract_tb(tb)
    for fr in reversed(frames):
        p = Path(fr.filename).resolve()
        if p.is_relative_to(PKG_DIR):
            return fr
    return None


def _where(fr: traceback.FrameSummary | None) -> str:
    if fr is None:
        return "?"
    return f"{Path(fr.filename).resolve().relative_to(PKG_DIR)}:{fr.lineno}"


def _names_argument(msg: str, names: tuple[str, ...]) -> bool:
    for n in names:
        if len(n) <= 2:
            if re.search(rf"(?<![A-Za-z_]){re.escape(n)}(?![A-Za-z_])", msg):
                return True
        elif n.lower() in msg.lower():
            return True
    return False


def run_call(entry: Entry, param: str | None, value: Any, timeout: float | None = None) -> tuple[bool, str | None, str]:
    """Call ``entry`` with ``param`` replaced by ``value``: (clean, problem line, owner)."""
    limit = entry.timeout if timeout is None else timeout
    kwargs = entry.base()
    if param is not None:
        kwargs[param] = value
    try:
        kwargs = copy.deepcopy(kwargs)
    except Exception:  # some hostile values do not deep-copy: use them as they are
        pass
    shown = "()" if param is None else f"({param}={short(value)})"
    head = f"{entry.label}{shown}"
    own_area_owner = entry_owner(entry)
    before = _listing(DATA_DIR()) if entry.writes else set()
    caught: list[warnings.WarningMessage] = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            with call_limits(limit):
                result = entry.call(**kwargs)
    except CallTimeout as exc:
        fr = _deepest_posicast_frame(exc.__traceback__)
        return False, f"{head}: no answer within {limit:g} s of CPU (at {_where(fr)})", \
            owner_of(fr.filename) if fr else own_area_owner
    except MemoryError as exc:
        fr = _deepest_posicast_frame(exc.__traceback__)
        return False, f"{head}: MemoryError past {MEMORY_HEADROOM >> 30} GiB, no up-front estimate (at {_where(fr)})", \
            owner_of(fr.filename) if fr else own_area_owner
    except BaseException as exc:  # noqa: BLE001 - everything is judged here
        if isinstance(exc, (KeyboardInterrupt, SystemExit)):
            raise
        if param is None:  # the valid base call itself must succeed
            fr = _deepest_posicast_frame(exc.__traceback__)
            return False, f"{head}: the valid base call raised {type(exc).__name__}: {short(str(exc), 100)} " \
                          f"(at {_where(fr)}; the fuzz table may be stale)", owner_of(fr.filename) if fr else own_area_owner
        tb = traceback.extract_tb(exc.__traceback__)
        last = tb[-1] if tb else None
        fr = _deepest_posicast_frame(exc.__traceback__)
        owner = owner_of(fr.filename) if fr else own_area_owner
        msg = str(exc).splitlines()[0] if str(exc) else ""
        desc = f"{type(exc).__name__}: {short(msg, 110)}"
        if not isinstance(exc, _library_errors()):
            return False, f"{head}: {desc} (at {_where(fr)})", owner
        if last is not None and not Path(last.filename).resolve().is_relative_to(PKG_DIR):
            return False, f"{head}: {desc} raised inside {Path(last.filename).name}:{last.lineno} " \
                          f"(called from {_where(fr)})", owner
        if param is not None:
            names = (param,) + entry.aliases.get(param, ())
            # naming the argument, or quoting the bad value itself (a file path, a column name), is clean
            quoted = isinstance(value, (str, os.PathLike)) and (repr(os.fspath(value)) in msg or (
                len(os.fspath(value)) >= 3 and os.fspath(value) in msg))
            if not msg or not (quoted or _names_argument(msg, names)):
                return False, f"{head}: {desc} does not name {param!r} (at {_where(fr)})", owner
        left = sorted(_listing(DATA_DIR()) - before) if entry.writes else []
        if left:
            return False, f"{head}: {desc}, but it left {left} behind", owner
        return True, None, owner
    finally:
        plt.close("all")
    bad_warn = [w for w in caught if issubclass(w.category, RuntimeWarning)]
    if bad_warn:
        w = bad_warn[0]
        inside = Path(w.filename).resolve().is_relative_to(PKG_DIR)
        return False, f"{head}: RuntimeWarning {short(str(w.message), 80)} at {Path(w.filename).name}:{w.lineno}", \
            owner_of(w.filename) if inside else own_area_owner
    paths = nan_paths(result)
    if entry.nan_filter is not None:
        paths = entry.nan_filter(paths)
    if paths:
        return False, f"{head}: returned NaN at {paths[0]}", own_area_owner
    if entry.check is not None:
        try:
            problem = entry.check(result, kwargs)
        except Exception as exc:  # noqa: BLE001 - a result that cannot even be checked
            problem = f"checking it raised {type(exc).__name__}: {short(str(exc), 80)}"
        if problem:
            return False, f"{head}: wrong result: {problem}", own_area_owner
    return True, None, own_area_owner


# ====================================================================== fixtures
@pytest.fixture(scope="module")
def data_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("fuzzdata")
    _DATA_DIR[0] = d
    s = SYNTH()
    np.savetxt(d / "data.csv", np.column_stack([s.t, s.u, s.y]), delimiter=",", header="t,u,y", comments="")
    (d / "empty.csv").write_text("")
    (d / "garbage.csv").write_bytes(bytes(range(256)) * 4)
    (d / "header_only.csv").write_text("t,u,y\n")
    (d / "nan.csv").write_text("t,u,y\n0,nan,1\n0.01,1,inf\n0.02,1,1\n")
    (d / "subdir").mkdir()
    (d / "out").mkdir()
    return d


def path_pool(kind: str, d: Path) -> list[Any]:
    common = ["", None, 1, NAN, b"\x00", "\x00", OPAQUE]
    if kind == "path_in":
        return common + [str(d / "missing.csv"), str(d / "subdir"), str(d / "empty.csv"), str(d / "garbage.csv"),
                         str(d / "header_only.csv"), str(d / "nan.csv"), d / "missing" / "x.csv"]
    if kind == "path_dir":
        return common + [str(d / "data.csv"), str(d / "data.csv" / "x")]
    return common + [str(d / "subdir"), str(d / "missing" / "k.csv"), str(d / "data.csv" / "x")]


def pool_for(kind: str, d: Path) -> list[Any]:
    if kind.startswith("path"):
        return path_pool(kind, d)
    return KINDS[kind][0]


def strategy_for(kind: str, d: Path) -> st.SearchStrategy:
    if kind.startswith("path"):
        return st.one_of(st.sampled_from(path_pool(kind, d)), st.text(max_size=8).map(lambda s: str(d / "out" / s)))
    return KINDS[kind][1]()


# ====================================================================== the library tests
def test_every_public_name_is_covered() -> None:
    """Each public name is driven by an entry above, or listed in NOT_CALLED with the reason."""
    missing = []
    for name, mods in sorted(public_names().items()):
        if name in NOT_CALLED:
            continue
        labels = ALIASES.get(name, (name,))
        for lab in labels:
            if lab not in ENTRY_LABELS and not any(e.startswith(lab + ".") or e.startswith(lab + "[") for e in ENTRY_LABELS):
                missing.append(f"{name} (from {', '.join(sorted(mods))}) has no fuzz entry")
    assert not missing, "\n".join(missing)


@pytest.mark.parametrize("entry", ENTRIES, ids=[e.label for e in ENTRIES])
def test_public_entry_hostile_inputs(entry: Entry, data_dir: Path) -> None:
    area = area_of(entry)
    problems: list[tuple[str, str]] = []
    t_entry = time.perf_counter()

    hangs = [0]

    def one(param: str | None, value: Any) -> None:
        # after two hangs, an entry's further calls get 0.5 s: a known hang is reported, not waited for again
        clean, line, owner = run_call(entry, param, value, timeout=0.5 if hangs[0] >= 2 else None)
        record(area, clean)
        if not clean:
            problems.append((owner, line or ""))
            if "no answer within" in (line or ""):
                hangs[0] += 1

    one(None, None)  # the valid base call itself must be clean
    if problems and not any(k in problems[0][1] for k in ("returned NaN", "wrong result", "RuntimeWarning")):
        # the base call raised, hung or ran out of memory: every variation would fail for the same reason
        SECONDS[entry.label] = time.perf_counter() - t_entry
        FAILURES.extend(problems)
        pytest.fail(f"[{problems[0][0]}] {problems[0][1]}\n(the hostile sweep of {entry.label} needs a working "
                    f"valid call; it was not run)", pytrace=False)
    for param, kind in entry.params.items():
        pool = pool_for(kind, data_dir)
        if entry.pool_limit is not None:
            pool = pool[: entry.pool_limit]
        for value in pool:
            one(param, value)
    if entry.params and entry.examples:
        names = sorted(entry.params)
        strategies = {p: strategy_for(entry.params[p], data_dir) for p in names}

        @settings(max_examples=entry.examples * len(names), deadline=None, database=None, derandomize=True,
                  phases=[Phase.generate], suppress_health_check=list(HealthCheck))
        @given(data=st.data())
        def generated(data: Any) -> None:
            p = data.draw(st.sampled_from(names), label="param")
            one(p, data.draw(strategies[p], label=p))

        generated()
    SECONDS[entry.label] = time.perf_counter() - t_entry
    FAILURES.extend(problems)
    if problems:
        lines = sorted({f"[{o}] {ln}" for o, ln in problems})
        pytest.fail(f"{len(lines)} unclean call(s) of {entry.label}:\n" + "\n".join(lines), pytrace=False)


# ====================================================================== the command line
IMAGE_MAGIC = {".png": b"\x89PNG", ".pdf": b"%PDF", ".svg": b"<?xml", ".eps": b"%!PS", ".ps": b"%!PS",
               ".jpg": b"\xff\xd8", ".jpeg": b"\xff\xd8", ".tif": b"II", ".tiff": b"II"}

NUM_TEXT = ["nan", "NaN", "inf", "-inf", "0", "-0", "-1", "1e300", "-1e300", "1e-300", "4.9e-324",
            "99999999999999999999999", "abc", "", " ", "1j", "0x10", "1,5", "1e", "\u221e", "1_000"]
INT_TEXT = ["0", "-1", "1000000000000", "100000000", "99999999999999999999", "1.5", "nan", "abc", "", "1e3"]
WORD_TEXT = ["", "nonexistent", "ZV", " zv", "zv\u00e9", "-", "1", "nan"]


def cli_cases(d: Path) -> dict[str, list[list[str]]]:
    """Per subcommand: argument lists with one value replaced by a hostile one."""
    csv = str(d / "data.csv")
    out: dict[str, list[list[str]]] = {}

    def subst(base: list[str], opt: str, values: list[str]) -> list[list[str]]:
        return [base + [f"{opt}={v}"] for v in values]

    design = ["design", "zvd", "--omega=5", "--zeta=0.05"]
    cases = [["design", k, "--omega=5", "--zeta=0.05"] for k in WORD_TEXT]
    cases += [["design", "zvd", f"--omega={v}", "--zeta=0.05"] for v in NUM_TEXT]
    cases += [["design", "zvd", "--omega=5", f"--zeta={v}"] for v in NUM_TEXT + ["0.999999999", "0.9999999999999"]]
    cases += [["design", "zvd", f"--freq-hz={v}", "--zeta=0.05"] for v in NUM_TEXT[:12]]
    cases += subst(["design", "ei", "--omega=5", "--zeta=0.05"], "--vtol", NUM_TEXT[:12])
    cases += subst(["design", "zvdk", "--omega=5", "--zeta=0.05"], "--k", INT_TEXT)
    cases += subst(["design", "mis_zv", "--omega=5", "--zeta=0.05"], "--n", INT_TEXT)
    cases += subst(["design", "mis_zvd", "--omega=5", "--zeta=0.05"], "--m", INT_TEXT)
    cases += subst(["design", "dezv", "--omega=5", "--zeta=0.05"], "--T", NUM_TEXT[:12])
    cases += subst(["design", "ei", "--omega=5", "--zeta=0.05"], "--method", WORD_TEXT[:4])
    cases += [design + ["--json", "--k=2"], design + ["extra"], ["design"], design[:2]]
    out["design"] = cases

    sens = ["sensitivity", "zv", "zvd", "--omega=5", "--zeta=0.05"]
    cases = [sens + [f"--out={d / 'cli' / 'fig.png'}", f"--tol={v}"] for v in NUM_TEXT[:14] + ["1", "0.999"]]
    plots = ["fig", "fig.txt", "fig.PNG", ".png", "fig.png/", str(d / "cli"), str(d / "missing" / "f.png"),
             "", "fig.svg", "fig.pdf", str(d / "data.csv" / "x.png"), "dir.png"]
    cases += [sens + [f"--out={p}"] for p in plots]
    cases += [["sensitivity", k, "--omega=5", "--zeta=0.05", "--out=f.png"] for k in WORD_TEXT[:4]]
    cases += [["sensitivity", "zv", f"--omega={v}", "--zeta=0.05", "--out=f.png"] for v in NUM_TEXT[:10]]
    out["sensitivity"] = cases

    out["kinds"] = [["kinds"], ["kinds", "extra"], ["kinds", "--json"]]

    tune_base = ["tune", "--num=1", "--den=1 1 0"]
    cases = [["tune", f"--num={v}", "--den=1 1 0"] for v in NUM_TEXT[:12] + ["1 0 0 0", "1e300 1"]]
    cases += [["tune", "--num=1", f"--den={v}"] for v in NUM_TEXT[:12] + ["0 0", "1e300 1 1e-300", "1 nan 0"]]
    cases += subst(tune_base, "--ms", NUM_TEXT[:12])
    cases += subst(tune_base, "--delay", NUM_TEXT[:10])
    cases += subst(tune_base, "--derivative-filter", NUM_TEXT[:10])
    cases += [tune_base + ["--kp-range", a, b] for a, b in (("nan", "1"), ("1", "0"), ("0", "inf"), ("-1e300", "1e300"))]
    # the shaper's arguments with the shaper outside the loop (feedforward): a valid design then costs
    # what the shaper-free loop costs, not the seconds of a delay loop's region
    ff = tune_base + ["--architecture=feedforward"]
    cases += [ff + ["--shaper=zv", f"--omega={v}", "--zeta=0.05"] for v in NUM_TEXT[:8]]
    cases += [ff + ["--shaper=zv", "--omega=5", f"--zeta={v}"] for v in NUM_TEXT[:8]]
    cases += [ff + [f"--shaper={k}", "--omega=5", "--zeta=0.05"] for k in WORD_TEXT[:4]]
    cases += [["tune", f"--case={k}"] for k in WORD_TEXT[:4]]
    cases += [["tune", "--case=gantry_crane", f"--ms={v}"] for v in ("1e300", "1e-300", "inf", "100")]
    cases += [tune_base + [f"--plot={p}"] for p in plots]
    cases += [tune_base + [f"--nyquist={p}"] for p in ("fig", str(d / "cli"), "n.png")]
    cases += [tune_base + ["--architecture=nowhere"], tune_base + ["--structure=nowhere"], tune_base + ["--controller=pid"]]
    out["tune"] = cases

    ident = ["identify", csv, "--input=u", "--output=y"]
    cases = [["identify", p, "--input=u", "--output=y"] for p in
             [str(d / "missing.csv"), str(d / "subdir"), str(d / "empty.csv"), str(d / "garbage.csv"),
              str(d / "header_only.csv"), str(d / "nan.csv"), ""]]
    cases += [["identify", csv, f"--input={c}", "--output=y"] for c in WORD_TEXT[:4]]
    cases += [["identify", csv, "--input=u", f"--output={c}"] for c in WORD_TEXT[:4]]
    cases += subst(ident, "--modes", INT_TEXT[:8])
    cases += subst(ident, "--method", WORD_TEXT[:3])
    cases += [["identify", csv, "--output=y"], ["identify", csv]]
    out["identify"] = cases

    cal = ["calibrate", csv, "--input=u", "--output=y"]
    cases = subst(cal, "--vtol", NUM_TEXT[:10])
    cases += subst(cal, "--margin", NUM_TEXT[:8])
    cases += [cal + [f"--plot={p}"] for p in ("fig", str(d / "cli"), str(d / "missing" / "f.png"), "cal.png")]
    cases += [["calibrate", p] for p in (str(d / "missing.csv"), str(d / "empty.csv"), str(d / "garbage.csv"))]
    out["calibrate"] = cases

    loop = ["--num=1", "--den=1 1 0", "--kp=10", "--kd=10", "--derivative-filter=0.01"]
    cases = [["stability", f"--num={v}", "--den=1 1"] for v in NUM_TEXT[:12]]
    cases += [["stability", "--num=1", f"--den={v}"] for v in NUM_TEXT[:12] + ["1; 1 @", "1 @1 @2", "; ;", "@"]]
    cases += [["stability", *loop, f"--kp={v}"] for v in NUM_TEXT[:8]]
    cases += [["stability", *loop, f"--plot={p}"] for p in ("fig", str(d / "cli"), "s.png")]
    cases += [["stability", *loop, f"--roots={v}"] for v in INT_TEXT[:6]]
    out["stability"] = cases
    sim = ["simulate", *loop, "--t-end=1"]
    cases = [sim + [f"--dt={v}"] for v in NUM_TEXT[:10]]
    cases += [sim + [f"--step-time={v}"] for v in NUM_TEXT[:6]]
    cases += [sim + [f"--out={p}"] for p in ("run", "run.png", str(d / "cli"), "run.csv")]
    cases += [sim + [f"--input={p}"] for p in (str(d / "missing.csv"), str(d / "empty.csv"), str(d / "garbage.csv"),
                                                str(d / "nan.csv"), str(d / "data.csv"))]
    cases += [sim + [f"--signals={v}"] for v in WORD_TEXT[:4]]
    out["simulate"] = cases
    return out


def _cli_check(argv: list[str], rc: Any, out: str, err: str, before: set[str], after: set[str], root: Path,
               exc: BaseException | None) -> str | None:
    """The problem with one CLI run, or None."""
    if exc is not None:
        return f"main() raised {type(exc).__name__}: {short(str(exc), 100)} (a traceback for the user)"
    new = sorted(after - before)
    if rc == 2:
        lines = err.splitlines()
        if len(lines) != 1 or not err.endswith("\n") or not lines[0].startswith("posicast: error: "):
            return f"exit 2 but stderr is not one 'posicast: error:' line: {short(err, 120)!r}"
        if new:
            return f"exit 2 but wrote {new}"
        return None
    if rc not in (0, 1) or (rc == 1 and argv[0] not in ("tune", "identify", "calibrate")):
        return f"exit status {rc!r}; stderr {short(err, 120)!r}"
    if rc == 1 and argv[0] in ("identify", "calibrate"):  # no resonance in the data: one line, nothing written
        if err.count("\n") != 1 or not err.startswith("posicast: ") or out.strip() or after - before:
            return f"exit 1 (no resonance) but stderr {short(err, 120)!r}, stdout {short(out, 60)!r}"
        return None
    # progress lines (commands/progress.py) and the CLI's one-line warnings
    progress = [ln for ln in err.splitlines() if re.match(r"\[\s*[0-9.]+ s\] |posicast: warning: ", ln)]
    if len(progress) != len(err.splitlines()):
        return f"exit {rc} with stderr {short(err, 120)!r}"
    if re.search(r"(?<![A-Za-z])nan(?![A-Za-z])", out, flags=re.I):
        return f"exit {rc} but the output shows NaN: {short(out, 120)!r}"
    wanted = []
    for a in argv:
        for opt in ("--out=", "--plot=", "--nyquist="):  # (simulate's --out is a CSV table)
            if a.startswith(opt):
                wanted.append(a[len(opt):])
    expected = set()
    for w in wanted:
        p = Path(w) if Path(w).is_absolute() else root / w
        if not p.is_file():
            if rc == 1:  # tune found no controller: a figure is drawn only when there is a region
                continue
            return f"exit 0 but {w!r} was not written"
        magic = IMAGE_MAGIC.get(p.suffix.lower())
        head = p.read_bytes()[:64]
        if magic is not None and magic not in head and not (p.suffix.lower() == ".svg" and b"<svg" in head):
            return f"exit 0 but {w!r} is not a {p.suffix} file (starts {head[:8]!r})"
        if p.resolve().is_relative_to(root.resolve()):
            expected.add(str(p.resolve().relative_to(root.resolve())))
    stray = [n for n in new if n not in expected and not any(e.startswith(n + os.sep) for e in expected)]
    if stray:
        return f"exit {rc} but also wrote {stray}"
    return None


CLI_SUBCOMMANDS = ("design", "sensitivity", "kinds", "tune", "identify", "calibrate", "stability", "simulate")


def _cli_owner(argv: list[str], exc: BaseException | None, err: str) -> str:
    """Who fixes a CLI failure: where the exception was raised (main's 'internal error' line names the
    place), else the owner of the subcommand's library area."""
    if exc is not None:
        fr = _deepest_posicast_frame(exc.__traceback__)
        if fr is not None:
            return owner_of(fr.filename)
    m = re.search(r"\(at posicast/([^:]+):\d+", err)
    if m:
        return owner_of(str(PKG_DIR / m.group(1)))
    if argv[0] in ("identify", "calibrate"):
        return owner_of(str(PKG_DIR / "identification" / "estimators.py"))
    return OWNERS[-1][1]


@pytest.mark.parametrize("sub", CLI_SUBCOMMANDS)
def test_cli_hostile_arguments(sub: str, data_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                               capsys: pytest.CaptureFixture[str]) -> None:
    work = tmp_path / "cwd"
    work.mkdir()
    (work / "cli").mkdir()
    (work / "dir.png").mkdir()
    monkeypatch.chdir(work)
    d = work  # CLI paths are relative to, or inside, the working directory
    (d / "data.csv").write_bytes((data_dir / "data.csv").read_bytes())
    for name in ("empty.csv", "garbage.csv", "header_only.csv", "nan.csv"):
        (d / name).write_bytes((data_dir / name).read_bytes())
    (d / "subdir").mkdir()
    argvs = cli_cases(d)[sub]
    problems: list[tuple[str, str]] = []
    hangs = [0]

    def one(argv: list[str]) -> None:
        before = _listing(work)
        exc = None
        rc = None
        capsys.readouterr()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                slow = argv[0] in ("tune", "calibrate", "identify", "stability", "simulate")
                with call_limits(0.5 if hangs[0] >= 2 else 6.0 if slow else CALL_SECONDS):
                    rc = cli_main(list(argv))
        except CallTimeout as e:
            exc = e
        except MemoryError as e:
            exc = e
        except BaseException as e:  # noqa: BLE001
            if isinstance(e, KeyboardInterrupt):
                raise
            exc = e
        finally:
            plt.close("all")
        out, err = capsys.readouterr()
        after = _listing(work)
        if isinstance(exc, CallTimeout):
            problem = "no answer within the time limit"
            hangs[0] += 1
        else:
            problem = _cli_check(argv, rc, out, err, before, after, work, exc)
        record("cli", problem is None)
        if problem:
            shown = " ".join(a.replace(str(work) + os.sep, "") for a in argv)
            problems.append((_cli_owner(argv, exc, err), f"posicast {shown}: {problem}"))
        # a success may leave its figure; remove new files so the next run starts from the same tree
        for n in sorted(after - before, reverse=True):
            p = work / n
            if p.is_file() or p.is_symlink():
                p.unlink()
            elif p.is_dir():
                try:
                    p.rmdir()
                except OSError:
                    pass

    for argv in argvs:
        one(argv)
    # generated: one value of the first numeric option replaced by arbitrary text
    templates = {
        "design": (["design", "ei", "--omega=5", "--zeta=0.05"], "--vtol"),
        "sensitivity": (["sensitivity", "zv", "--omega=5", "--zeta=0.05", "--out=g.png"], "--tol"),
        "kinds": (["kinds"], None),
        "tune": (["tune", "--num=1", "--den=1 1 0"], "--ms"),
        "identify": (["identify", str(d / "data.csv"), "--input=u", "--output=y"], "--modes"),
        "calibrate": (["calibrate", str(d / "data.csv"), "--input=u", "--output=y"], "--vtol"),
        "stability": (["stability", "--num=1", "--den=1 1 0", "--kp=1"], "--kd"),
        "simulate": (["simulate", "--num=1", "--den=1 1 0", "--kp=1", "--t-end=1"], "--t-end"),
    }
    base, opt = templates[sub]
    if opt is not None:
        n_ex = 8 if sub in ("tune", "calibrate", "identify", "stability", "simulate") else 30

        @settings(max_examples=n_ex, deadline=None, database=None, derandomize=True, phases=[Phase.generate],
                  suppress_health_check=list(HealthCheck))
        @given(text=st.one_of(st.text(max_size=10), st.floats(allow_nan=True, allow_infinity=True).map(repr),
                              st.integers().map(str)))
        def generated(text: str) -> None:
            if "\x00" in text:  # an argv entry cannot hold NUL: the OS refuses it before posicast runs
                text = text.replace("\x00", "")
            one(base + [f"{opt}={text}"])

        generated()
    FAILURES.extend(problems)
    if problems:
        lines = sorted({f"[{o}] {ln}" for o, ln in problems})
        pytest.fail(f"{len(lines)} unclean run(s) of 'posicast {sub}':\n" + "\n".join(lines), pytrace=False)


def _limit_memory() -> None:  # pragma: no cover - runs in the child
    resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))


SUBPROCESS_CASES = [
    ["design", "dezv", "--omega", "1", "--zeta", "0.999999999"],
    ["tune", "--case", "gantry_crane", "--ms", "1e300"],
    ["design", "zvdk", "--omega", "1", "--zeta", "0.1", "--k", "1000000000000"],
    ["design", "mis_zvd", "--omega", "1", "--zeta", "0.1", "--n", "100000000"],
    ["sensitivity", "zv", "--omega", "1", "--zeta", "0.1", "--tol", "nan", "--out", "fig.png"],
    ["sensitivity", "zv", "--omega", "1", "--zeta", "0.1", "--out", "fig"],
]


@pytest.mark.parametrize("argv", SUBPROCESS_CASES, ids=[" ".join(a[:2] + a[-2:]) for a in SUBPROCESS_CASES])
def test_cli_subprocess_no_traceback(argv: list[str], tmp_path: Path) -> None:
    """The installed command under a 3 GiB address-space limit: one line, exit 2, no traceback, no file."""
    r = subprocess.run([sys.executable, "-m", "posicast", *argv], capture_output=True, text=True, cwd=tmp_path,
                       preexec_fn=_limit_memory, timeout=60, env={**os.environ, "MPLBACKEND": "Agg"})
    problem = None
    if "Traceback" in r.stderr:
        problem = f"traceback on stderr: {short(r.stderr.strip().splitlines()[-1], 120)}"
    elif r.returncode != 2 or r.stderr.count("\n") != 1 or not r.stderr.startswith("posicast: error: "):
        problem = f"exit {r.returncode}, stderr {short(r.stderr, 150)!r}"
    elif list(tmp_path.iterdir()):
        problem = f"wrote {[p.name for p in tmp_path.iterdir()]}"
    record("cli", problem is None)
    if problem:
        FAILURES.append(("?", f"posicast {' '.join(argv)} (subprocess): {problem}"))
        pytest.fail(f"posicast {' '.join(argv)}: {problem}", pytrace=False)


def _limit_memory_small() -> None:  # pragma: no cover - runs in the child
    resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))


def test_simulate_refuses_huge_work_before_allocating(tmp_path: Path) -> None:
    """10^8 samples: refused with the estimate and the parameter to change, under a 1 GiB address-space
    limit.  The time grid is a zero-stride view (16 bytes), so any allocation proportional to its length
    (800 MB per signal) would be a MemoryError: the refusal must come first."""
    code = (
        "import numpy as np, posicast as pc\n"
        "loop = pc.control_action(G=([1.0], [1.0, 1.0, 0.0]), C=([10.0, 10.0], [0.01, 1.0]),"
        " S=pc.design('zv', pc.Mode(10.0, 0.03)))\n"
        "t = np.lib.stride_tricks.as_strided(np.arange(1.0), shape=(10**8,), strides=(0,))\n"
        "try:\n"
        "    pc.simulate(loop, t, w=t)\n"
        "except ValueError as exc:\n"
        "    print('refused:', exc)\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path,
                       preexec_fn=_limit_memory_small, timeout=120, env={**os.environ, "MPLBACKEND": "Agg"})
    ok = "MemoryError" not in r.stderr and r.returncode == 0 and "refused:" in r.stdout and "samples in t" in r.stdout
    record("simulate", ok)
    assert ok, (r.stdout + r.stderr)[-600:]


# ====================================================================== the summary
@pytest.fixture(scope="module", autouse=True)
def _summary(request: pytest.FixtureRequest):
    yield
    if not STATS:
        return
    tr = request.config.pluginmanager.get_plugin("terminalreporter")
    total = sum(s[0] for s in STATS.values())
    clean = sum(s[1] for s in STATS.values())
    lines = [f"fuzz: {total} calls with generated invalid or extreme inputs, {clean} clean "
             f"({100.0 * clean / total:.1f} %)"]
    for area in sorted(STATS):
        n, c = STATS[area]
        lines.append(f"fuzz:   {area:10s} {c:5d}/{n:<5d} clean ({100.0 * c / n:5.1f} %)")
    by_owner: dict[str, int] = {}
    for owner, _ in FAILURES:
        by_owner[owner] = by_owner.get(owner, 0) + 1
    for owner in sorted(by_owner):
        lines.append(f"fuzz:   failures routed to {owner}: {by_owner[owner]}")
    slow = sorted(SECONDS.items(), key=lambda kv: -kv[1])[:12]
    lines.append("fuzz:   slowest entries: " + ", ".join(f"{k} {v:.1f} s" for k, v in slow))
    out = os.environ.get("POSICAST_FUZZ_REPORT")
    if out:
        Path(out).write_text("\n".join(lines + [f"[{o}] {ln}" for o, ln in FAILURES]) + "\n")
    if tr is not None:
        tr.write_line("")
        for ln in lines:
            tr.write_line(ln)
