"""``posicast design``, ``posicast kinds`` and ``posicast sensitivity``: shapers from the command line."""

from __future__ import annotations

import argparse
import json
import math
from typing import Any

from .. import _validate as v
from ..analysis import insensitivity, sensitivity_curve, sensitivity_plot
from ..modes import Mode
from ..shapers import registry  # registry.design at call time: the suite patches it to test status 70
from ..shapers.base import Shaper
from .figures import pyplot, save_atomic

__all__ = ["run"]


def run(args: argparse.Namespace) -> int:
    """Run ``kinds``, ``design`` or ``sensitivity`` (``args.command``)."""
    if args.command == "kinds":
        return _kinds(args)
    if args.command == "sensitivity":  # the tolerance and the output before any design work
        v.real_in_range(args.tol, "--tol", 0.0, 1.0, lo_open=True, hi_open=True)
        if args.out is None and not args.json:
            raise ValueError("--out is required (the figure), unless --json")
    mode = mode_of(args)
    if args.command == "design":
        return _design(args, mode)
    return _sensitivity(args, mode)


def _kinds(args: argparse.Namespace) -> int:
    if args.json:
        print(json.dumps([{"kind": name, "summary": spec.summary, "params": dict(spec.params)}
                          for name, spec in registry.KINDS.items()], indent=2, default=str))
        return 0
    for name, spec in registry.KINDS.items():
        params = ", ".join(f"{k}={v}" for k, v in spec.params.items())
        print(f"{name:8s} {spec.summary}" + (f"  [{params}]" if params else ""))
    return 0


def _design(args: argparse.Namespace, mode: Mode) -> int:
    kind = args.kind.lower()
    S = registry.design(kind, mode, **shaper_params(args, kind))
    if args.json:
        print(json.dumps(S.to_dict(), indent=2))
    else:
        _print_shaper(S)
    return 0


def _sensitivity(args: argparse.Namespace, mode: Mode) -> int:
    """Design each kind, analyse, draw; the figure is written last."""
    shapers = [registry.design(k.lower(), mode, **shaper_params(args, k.lower())) for k in args.kinds]
    ref = "unshaped" if any(not math.isfinite(S.duration) for S in shapers) else "end"
    rows = []
    for S in shapers:
        ins = insensitivity(S, args.tol, reference=ref)
        curve = sensitivity_curve(S, reference=ref)
        rows.append({"kind": S.name, "duration": S.duration if math.isfinite(S.duration) else None,
                     "insensitivity": ins.width, "band": [ins.low, ins.high],
                     "ratio": curve.ratio.tolist(), "vibration": curve.vibration.tolist()})
    if args.out is not None:
        pyplot()  # the Agg backend before sensitivity_plot draws
        fig, ax = sensitivity_plot(shapers, vtol=args.tol, reference=ref)
        ax.set_title(f"omega = {mode.omega:.4g} rad/s, zeta = {mode.zeta:.4g}")
        save_atomic(fig, args.out, "--out")
    if args.json:
        print(json.dumps({"omega": mode.omega, "zeta": mode.zeta, "tol": args.tol, "reference": ref,
                          "shapers": rows, "out": args.out}, indent=2))
        return 0
    for r in rows:
        dur = "infinite" if r["duration"] is None else f"{r['duration']:.6g} s"
        print(f"{r['kind']:8s} duration {dur}, insensitivity at {args.tol:g}: {r['insensitivity']:.4f}")
    print(f"wrote {args.out}")
    return 0


def shaper_params(args: argparse.Namespace, kind: str) -> dict[str, Any]:
    accepted = registry.KINDS[kind].params if kind in registry.KINDS else {}
    out = {}
    for name in ("vtol", "k", "n", "m", "T", "method"):
        val = getattr(args, name)
        if val is None:
            continue
        if name not in accepted:
            raise ValueError(f"--{name} does not apply to kind {kind!r}")
        out[name] = val
    return out


def mode_of(args: argparse.Namespace) -> Mode:
    if args.omega is not None:
        return Mode(args.omega, args.zeta)
    return Mode.from_hz(args.freq_hz, args.zeta)


def _print_shaper(S: Shaper) -> None:
    m = S.modes[0]
    print(f"{S.name} shaper for omega = {m.omega:.6g} rad/s ({m.freq_hz:.6g} Hz), zeta = {m.zeta:.6g}")
    if S.params:
        print("parameters: " + ", ".join(f"{k} = {v:.10g}" if isinstance(v, float) else f"{k} = {v}"
                                         for k, v in S.params.items()))
    print(f"{'t [s]':>14}  {'amplitude':>14}")
    for t, a in zip(*S.impulses):
        print(f"{t:14.10f}  {a:14.10f}")
    for p in S.distributed:
        shapes = " * ".join(f"{k.shape}(T={k.T:.10g})" for k in p.kernels)
        print(f"distributed: weight {p.weight:.10f} on [{p.delay:.10f}, {p.end:.10f}] s, kernel {shapes}")
    if S.continuous is not None:
        print(f"IIR part: {S.continuous}")
    dur = S.duration
    print(f"duration: {dur:.10f} s" if math.isfinite(dur) else "duration: infinite (IIR)")
