"""``posicast.design(kind, mode, **params)``: one entry point for every shaper of the seeds."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from .. import _validate as v
from ..modes import Mode
from . import lumped
from .base import _T_MAX, DistributedPart, Kernel, Shaper, check_resolution
from .distributed import _dzv as _dzv_weights
from .distributed import distributed_zv_part, notch_continuous
from .ei import ei_exact, ei_fit, ei_multi_hump
from .negative import um_shaper, um_si_shaper
from .optimal import si_shaper
from .sampled import SAMPLED_KINDS, multiplicity_of, zplane_shaper

__all__ = ["design", "KINDS", "ZERO_VIBRATION_KINDS"]


@dataclass(frozen=True)
class _Kind:
    build: Callable[..., Shaper]
    params: dict[str, Any]  # name -> default
    summary: str
    zero_vibration: bool
    multi_mode: bool = False  # takes a sequence of modes too
    # zero_vibration: S(p) = 0 with positive impulses for every zeta < 1 (UM shapers place the zero
    # too, with negative impulses and up to zeta ~ 0.9: they are not listed in ZERO_VIBRATION_KINDS)


def _shortest_interval(times: np.ndarray) -> float:
    """Shortest spacing of designed impulse times (times equal to rounding, as MIS-ZVD's coincident
    ones, are one impulse); ``inf`` for fewer than two distinct times."""
    t = np.sort(np.asarray(times, dtype=float))
    if t.size < 2:
        return math.inf
    d = np.diff(t)
    d = d[d > 1e-12 * t[-1]]
    return float(d.min()) if d.size else math.inf


def _check_duration(duration: float, mode: Mode, what: str) -> None:
    if not duration <= _T_MAX:
        raise ValueError(f"omega={mode.omega:g} rad/s is too slow for seconds as the time unit: {what} would last "
                         f"{duration:.4g} s, more than {_T_MAX:g} s; give omega in rad/ks or rad/Ms")


def _lumped(name: str, mode: Mode, times: np.ndarray, amps: np.ndarray, **params: Any) -> Shaper:
    _check_duration(float(np.max(times)), mode, f"a {name} shaper")
    # before the Shaper merges (numerically) equal times: a mode too fast for the time unit
    # would otherwise lose impulses silently
    check_resolution(_shortest_interval(times), float(np.max(times)), f"a {name} shaper for omega={mode.omega:g} rad/s")
    return Shaper(times, amps, name=name, modes=(mode,), params=params)


def _zvdk(mode: Mode, k: int) -> Shaper:
    t, a = lumped.zvdk_impulses(mode, k)
    names = {0: "zv", 1: "zvd", 2: "zvdd", 3: "zvddd"}
    return _lumped(names.get(k, f"zvd{k}"), mode, t, a, k=k)


def _ei(mode: Mode, vtol: float, method: str) -> Shaper:
    # "exact": hump exactly at the model frequency with height vtol (the standard EI meaning);
    #          the same shaper as ei_exact(mode, vtol), whose default definition is "hump";
    # "singhose": exact solution of the constraint set Singhose's fit approximates (t3 = T_d);
    # "fit": Singhose's published damped curve fit (seed 004 eq. 8, corrected).
    v.choice(method, "method", ("exact", "singhose", "fit"))
    if method == "exact":
        t, a = ei_exact(mode, vtol, definition="hump")
    elif method == "singhose":
        t, a = ei_exact(mode, vtol, definition="singhose")
    else:  # "fit"
        t, a = ei_fit(mode, vtol)
    return _lumped("ei", mode, t, a, vtol=vtol, method=method)


def _dzv(mode: Mode) -> Shaper:
    _check_duration(mode.damped_period, mode, "a dzv shaper")
    B, w, theta = _dzv_weights(mode)
    check_resolution(theta, theta, f"a dzv shaper for omega={mode.omega:g} rad/s")
    return Shaper(
        [0.0], [B], (DistributedPart(w, 0.0, (Kernel("uniform", theta),)),),
        name="dzv", modes=(mode,), params={"B": B, "theta": theta},
    )


def _dist(shape: str, name: str) -> Callable[..., Shaper]:
    def build(mode: Mode, T: float | None) -> Shaper:
        T = math.pi / mode.omega if T is None else T
        what = f"a {name} shaper with T={T:g} s for omega={mode.omega:g} rad/s"
        _check_duration(T + mode.damped_period, mode, what)
        check_resolution(T, T + mode.damped_period, what)
        A, part, tau = distributed_zv_part(mode, shape, T)
        if tau > 0:
            check_resolution(tau, part.end, what)
        return Shaper([0.0], [A], (part,), name=name, modes=(mode,), params={"A": A, "tau": tau, "T": T})

    return build


def _notch(mode: Mode) -> Shaper:
    return Shaper([0.0], [1.0], (), notch_continuous(mode), name="notch", modes=(mode,))


KINDS: dict[str, _Kind] = {
    "zv": _Kind(lambda m: _zvdk(m, 0), {}, "zero vibration, 2 impulses (seed 000 eq. 4)", True),
    "zvd": _Kind(lambda m: _zvdk(m, 1), {}, "zero vibration and derivative, 3 impulses (seed 004 eq. 5)", True),
    "zvdd": _Kind(lambda m: _zvdk(m, 2), {}, "ZVDD, 4 impulses (seed 004 eq. 6)", True),
    "zvddd": _Kind(lambda m: _zvdk(m, 3), {}, "ZVDDD, 5 impulses (seed 004 eq. 7)", True),
    "zvdk": _Kind(_zvdk, {"k": 1}, "ZVD^k, k + 2 impulses (seed 003 eq. 4)", True),
    "ei": _Kind(_ei, {"vtol": 0.05, "method": "exact"}, "extra insensitive, 3 impulses (seed 004 eq. 8)", False),
    "ei2": _Kind(
        lambda m, vtol: _lumped("ei2", m, *ei_multi_hump(m, vtol, 2), vtol=vtol),
        {"vtol": 0.05}, "two-hump extra insensitive, 4 impulses", False,
    ),
    "ei3": _Kind(
        lambda m, vtol: _lumped("ei3", m, *ei_multi_hump(m, vtol, 3), vtol=vtol),
        {"vtol": 0.05}, "three-hump extra insensitive, 5 impulses", False,
    ),
    "mzv": _Kind(lambda m: _lumped("mzv", m, *lumped.mzv_impulses(m)), {}, "3 impulses over 3/4 damped period", True),
    "mis_zv": _Kind(
        lambda m, n: _lumped("mis_zv", m, *lumped.mis_zv_impulses(m, n), n=n),
        {"n": 3}, "n-impulse modified ZV (seed 004 eq. 9)", True,
    ),
    "mis_zvd": _Kind(
        lambda m, n, m2: _lumped("mis_zvd", m, *lumped.mis_zvd_impulses(m, n, m2), n=n, m=m2),
        {"n": 2, "m": 3}, "n x m-impulse modified ZVD (seed 004 eq. 10)", True,
    ),
    "dzv": _Kind(_dzv, {}, "equally distributed delay ZV (seed 000 eq. 5-10)", True),
    "dezv": _Kind(_dist("uniform", "dezv"), {"T": None}, "A + (1-A) uniform delay (seed 001 G1)", True),
    "dtzv": _Kind(_dist("triangular", "dtzv"), {"T": None}, "A + (1-A) triangular delay (seed 001 G2)", True),
    "dczv": _Kind(_dist("cosine", "dczv"), {"T": None}, "A + (1-A) cosine delay (seed 001 G3)", True),
    "dtazv": _Kind(_dist("decreasing", "dtazv"), {"T": None}, "A + (1-A) decreasing-ramp delay (seed 001 G4)", True),
    "notch": _Kind(_notch, {}, "IIR notch (seed 001 eq. 13)", True),
    # issue #17: optimal and unity-magnitude shapers (shapers/optimal.py, shapers/negative.py)
    "si": _Kind(si_shaper, {"vtol": 0.05, "band": (0.9, 1.1), "damping": None, "max_impulses": None},
                "specified insensitivity: shortest with V <= vtol over a band (Singhose 1996)", False, True),
    "um_zv": _Kind(lambda m: um_shaper(m, "um_zv"), {}, "unity-magnitude ZV, impulses 1, -1, 1 (Singhose 1997)", False),
    "um_zvd": _Kind(lambda m: um_shaper(m, "um_zvd"), {}, "unity-magnitude ZVD, 5 impulses +-1 (Singhose 1997)",
                    False),
    "um_si": _Kind(um_si_shaper, {"vtol": 0.05, "band": (0.9, 1.1)},
                   "unity-magnitude SI: shortest 3 or 5 impulses +-1 with V <= vtol over a band", False),
}

ZERO_VIBRATION_KINDS = tuple(k for k, d in KINDS.items() if d.zero_vibration)


def _as_mode(mode: Any) -> Mode:
    if isinstance(mode, Mode):
        return mode
    if isinstance(mode, (tuple, list, np.ndarray)) and len(mode) == 2:
        return Mode(mode[0], mode[1])
    raise TypeError(f"mode must be a posicast.Mode or an (omega, zeta) pair, got {type(mode).__name__}"
                    + (f" of length {len(mode)}" if isinstance(mode, (tuple, list, np.ndarray)) else ""))


def _design_sampled(key: str, mode: Any, params: dict[str, Any]) -> Shaper:
    """``design(kind, mode, sample_period=T[, stride=n])``: the z-plane ZV family (seed 002 eq. 4-12)."""
    if key not in SAMPLED_KINDS:
        raise ValueError(f"sample_period is supported for kinds {', '.join(SAMPLED_KINDS)} (zeros on the sampled "
                         f"pole, seed 002 eq. 8); for {key!r} design the continuous shaper and discretise it "
                         "(posicast.simulation.streaming.discretize, which reports the residual)")
    T, stride = params.pop("sample_period"), params.pop("stride", "positive")
    unknown = set(params) - set(KINDS[key].params)
    if unknown:
        raise TypeError(f"kind {key!r} takes no parameter {sorted(unknown)[0]!r} with sample_period "
                        f"(parameters: {', '.join(KINDS[key].params) or 'none'}, stride)")
    return zplane_shaper(mode, T, multiplicity_of(key, params.get("k", 1)), stride, name=key)


def design(kind: str, mode: Mode | tuple[float, float], **params: Any) -> Shaper:
    """Design a shaper for one damped mode.

    Parameters
    ----------
    kind : str
        One of ``zv, zvd, zvdd, zvddd, zvdk, ei, ei2, ei3, mzv, mis_zv, mis_zvd,
        dzv, dezv, dtzv, dczv, dtazv, notch, si, um_zv, um_zvd, um_si`` (see ``posicast.KINDS``).
    mode : Mode or (omega, zeta)
        The mode to cancel (``si``: also a sequence of Modes).
    **params
        ``k`` (zvdk, integer >= 0, default 1); ``vtol`` (ei/ei2/ei3, in (0, 1),
        default 0.05); ``sample_period`` (zv, zvd, zvdd, zvddd, zvdk: the z-plane design of
        seed 002 eq. 8, impulses on the grid ``k T``, zeros of multiplicity 1, 2, 3, 4, ``k + 1``
        on the sampled pole ``exp(p T)``; ``mode`` may then be a sequence of modes) with
        ``stride`` (samples between taps; default ``"positive"``, the smallest stride with
        nonnegative taps, which is seed 002's adjacent taps (stride 1) whenever those are
        nonnegative; ``stride=1`` always gives the seed's taps, which alternate in sign and
        grow like ``(|p| T)^(-2m)`` at short periods; see
        :func:`posicast.shapers.sampled.zplane_shaper`); ``method`` (ei: ``"exact"`` (hump of height vtol exactly at the
        model frequency: the shaper ``ei_exact(mode, vtol)`` returns), ``"singhose"``
        (t3 = T_d, ``ei_exact(..., definition="singhose")``) or ``"fit"``); ``n`` (mis_zv,
        integer >= 2, default 3); ``n``, ``m`` (mis_zvd, integers >= 2, default
        2 and 3); ``T`` (dezv/dtzv/dczv/dtazv, kernel length > 0, default
        ``pi / omega``); ``vtol``, ``band`` (ratios ``(low, high)``, default
        ``(0.9, 1.1)``), ``damping`` (``(low, high)``, default the mode's) and
        ``max_impulses`` (si: see :func:`~posicast.shapers.optimal.shortest_shaper`;
        the result carries ``.optimality``); ``vtol``, ``band`` (um_si, impulses +-1:
        :func:`~posicast.shapers.negative.um_si_shaper`).  Impulse counts are limited to
        :data:`~posicast.shapers.base.MAX_IMPULSES` (``k <= 99998``, ``n <= 100000``,
        ``n * m <= 100000``); the EI solvers need ``vtol >= 1e-6``.

    Returns
    -------
    Shaper

    Raises
    ------
    ValueError
        Unknown ``kind`` or a parameter out of range (the message names it and
        gives the range).  Also when the shaper cannot be represented in double
        precision: ``zeta`` so close to 1 that the mode decays by more than
        ``e^600`` over the shaper (the message gives the largest ``zeta`` for
        the kind), or a time interval shorter than ``1e-9 x max(1 s, duration)``
        (a mode too fast for seconds as the time unit, or an extreme ``T``).
    TypeError
        A parameter the kind does not take, or of the wrong type.

    Examples
    --------
    >>> S = design("zv", Mode(1.0, 0.0))
    >>> S.impulses[1].tolist(), round(S.duration, 6)
    ([0.5, 0.5], 3.141593)
    >>> abs(S(Mode(1.0, 0.0).pole)) < 1e-15
    True
    """
    v.instance_of(kind, str, "kind", "a string")
    key = kind.lower()
    if key not in KINDS:
        raise ValueError(f"kind must be one of {', '.join(KINDS)}; got {kind!r}")
    spec = KINDS[key]
    if params.get("sample_period") is not None:
        return _design_sampled(key, mode, dict(params))
    params.pop("sample_period", None)
    several = spec.multi_mode and isinstance(mode, (list, tuple)) and bool(mode) and isinstance(mode[0], Mode)
    m = tuple(mode) if several else _as_mode(mode)
    unknown = set(params) - set(spec.params)
    if unknown:
        allowed = ", ".join(spec.params) or "none"
        raise TypeError(f"kind {key!r} takes no parameter {sorted(unknown)[0]!r} (parameters: {allowed})")
    args = {**spec.params, **params}
    if "k" in args:
        args["k"] = v.integer(args["k"], "k", 0)
    if "n" in args:
        args["n"] = v.integer(args["n"], "n", 2)
    if "m" in args:
        args["m2"] = v.integer(args.pop("m"), "m", 2)
    if "vtol" in args:
        args["vtol"] = v.real_in_range(args["vtol"], "vtol", 0.0, 1.0, lo_open=True, hi_open=True)
    if "T" in args and args["T"] is not None:
        args["T"] = v.positive(v.finite_real(args["T"], "T"), "T")
    return spec.build(m, **args)
