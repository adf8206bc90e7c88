"""``posicast tune``: robust PD/PI design for a loop with a shaper (H-infinity regions, seed 001)."""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import TYPE_CHECKING, Any

from .. import _validate as v
from ..shapers import registry  # registry.design at call time: the suite patches it to test status 70
from ..tune import TuningResult, tune_pd, tune_pi
from ..tune.constraints import sensitivity_constraint
from ..tune.family import pd_family
from .figures import pyplot, save_atomic
from .progress import working
from .systems import plant_of

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["run"]


def run(args: argparse.Namespace) -> int:
    _check_tune_options(args)  # every option first, before any design work
    G, F, mode, _ = plant_of(args)
    S = None
    if args.shaper is not None:
        if mode is None:
            raise ValueError("--shaper needs the mode: --omega and --zeta (or --case)")
        S = registry.design(args.shaper.lower(), mode)
    with working(f"tuning the {args.controller.upper()} controller (H-infinity regions)", args.quiet):
        if args.controller == "pd":
            r = tune_pd(G, S, _architecture(args), ms=args.ms, derivative_filter=args.derivative_filter,
                        kp_range=args.kp_range, kd_range=args.kd_range, F=F)
        else:
            r = tune_pi(G, S, _architecture(args), ms=args.ms, kp_range=args.kp_range, ki_range=args.ki_range,
                        F=F)
    figures = _tune_figures(args, r)
    for fig, out, opt in figures:  # everything computed: only now write
        save_atomic(fig, out, opt)
    if args.json:
        print(json.dumps(_tune_json(args, r), indent=2))
    else:
        print(r.summary())
        for _, out, _opt in figures:
            print(f"wrote {out}")
    return 0 if r.gains is not None else 1  # 1: ran, but no controller (empty or unbounded region)


def _check_tune_options(args: argparse.Namespace) -> None:
    """Every ``tune`` option that needs no design work, before any design work."""
    sensitivity_constraint(args.ms)  # ms range (ValueError naming ms)
    if args.derivative_filter is not None:
        try:
            pd_family(args.derivative_filter)  # 0 or a time constant in the tuner's range
        except ValueError as exc:
            raise ValueError(f"--derivative-filter: {exc}") from None
    for g in ("kp", "ki", "kd"):
        r = getattr(args, f"{g}_range")
        if r is not None:
            lo, hi = (v.real_in_range(x, f"--{g}-range", -1e12, 1e12) for x in r)
            if not lo < hi:
                raise ValueError(f"--{g}-range: {g}_range must have low < high, got ({lo:g}, {hi:g})")
    if args.controller == "pd" and args.ki_range is not None:
        raise ValueError("--ki-range does not apply to a pd controller")
    if args.controller == "pi" and (args.kd_range is not None or args.derivative_filter is not None):
        raise ValueError("--kd-range and --derivative-filter do not apply to a pi controller")


def _tune_figures(args: argparse.Namespace, r: TuningResult) -> list[tuple[Figure, str, str]]:
    """The requested figures of a tuning result as ``(figure, path, option)``, not yet written."""
    figures: list[tuple[Figure, str, str]] = []
    if (args.plot or args.nyquist) and not r.empty:
        pyplot()  # the Agg backend before the tuner draws
        if args.plot:
            figures.append((r.plot()[0], args.plot, "--plot"))
        if args.nyquist and r.loop is not None:
            figures.append((r.nyquist_plot()[0], args.nyquist, "--nyquist"))
    written = {opt for _, _, opt in figures}
    for opt, out in (("--plot", args.plot), ("--nyquist", args.nyquist)):
        if out and opt not in written:  # said, not silently skipped
            print(f"posicast: warning: {opt} {out} not written: no controller to draw", file=sys.stderr)
    return figures


def _json_number(x: Any) -> float | None:
    """JSON has no NaN or inf: null (and no -0.0: 0.0)."""
    return float(x) + 0.0 if x is not None and math.isfinite(x) else None


def _tune_json(args: argparse.Namespace, r: TuningResult) -> dict[str, Any]:
    ext = r.region.extent()
    num = _json_number
    return {
        "controller": r.family.describe(), "architecture": r.architecture, "structure": r.architecture,
        "shaper": args.shaper,
        "empty": r.empty, "unbounded": r.unbounded,
        "gains": None if r.gains is None else {k: r._gain(k) for k in ("kp", "ki", "kd")},
        "ms": num(r.ms), "omega_ms": num(r.omega_ms), "stable": r.stable, "reason": r.reason,
        "region": None if ext is None else {r.family.x: [num(ext[0]), num(ext[1])],
                                            r.family.y: [num(ext[2]), num(ext[3])]},
    }


def _architecture(args: argparse.Namespace) -> str:
    """``--architecture``, or the 0.1 spelling ``--structure`` (with a one-line warning on stderr)."""
    if args.structure is not None:
        if args.architecture is not None:
            raise ValueError("give --architecture only (--structure is its old name)")
        print("posicast: warning: --structure is now --architecture", file=sys.stderr)
        return args.structure
    return args.architecture or "control_action"
