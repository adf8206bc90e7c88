"""Command line: ``posicast design``, ``sensitivity``, ``kinds``, ``identify``, ``calibrate``, ``tune``.

Every error (bad argument, out-of-range value) prints one line to stderr and
exits with status 2; no traceback.  ``posicast tune`` exits with status 1 when
it ran but found no controller (an empty or unbounded region, printed as such).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any, Sequence

__all__ = ["main"]


class _OneLineError(Exception):
    pass


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> Any:  # argparse prints usage + message; we want one line
        raise _OneLineError(message)


def _add_mode_args(p: argparse.ArgumentParser) -> None:
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--omega", type=float, help="natural frequency [rad/s]")
    g.add_argument("--freq-hz", type=float, help="natural frequency [Hz]")
    p.add_argument("--zeta", type=float, required=True, help="damping ratio, 0 <= zeta < 1")


def _add_param_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--vtol", type=float, help="tolerable vibration for ei/ei2/ei3, in (0, 1)")
    p.add_argument("--k", type=int, help="derivative order for zvdk (>= 0)")
    p.add_argument("--n", type=int, help="impulses for mis_zv / first factor of mis_zvd (>= 2)")
    p.add_argument("--m", type=int, help="second factor of mis_zvd (>= 2)")
    p.add_argument("--T", type=float, help="kernel length for dezv/dtzv/dczv/dtazv [s], default pi/omega")
    p.add_argument("--method", choices=("exact", "singhose", "fit"), help="ei: exact (default), singhose (t3 = T_d) or Singhose's fit")


def _build_parser() -> _Parser:
    parser = _Parser(prog="posicast", description="Time-delay signal shapers for flexible machines.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    d = sub.add_parser("design", help="design a shaper and print it")
    d.add_argument("kind", help="shaper kind (see 'posicast kinds')")
    _add_mode_args(d)
    _add_param_args(d)
    d.add_argument("--json", action="store_true", help="machine-readable output")

    s = sub.add_parser("sensitivity", help="plot residual vibration against omega/omega_model")
    s.add_argument("kinds", nargs="+", help="one or more shaper kinds")
    _add_mode_args(s)
    _add_param_args(s)
    s.add_argument("--out", required=True, help="output image (png, pdf, svg)")
    s.add_argument("--tol", type=float, default=0.05, help="tolerance line and insensitivity level (default 0.05)")

    sub.add_parser("kinds", help="list the shaper kinds")

    i = sub.add_parser("identify", help="identify lightly damped modes in a CSV or Klipper file")
    i.add_argument("file", help="CSV with a time column, Klipper accelerometer log or PSD file")
    i.add_argument("--input", help="input column (omit for output-only data)")
    i.add_argument("--output", help="output column (Klipper logs: see --axis)")
    i.add_argument("--axis", default="auto", choices=("auto", "x", "y", "z", "all"), help="Klipper log axis")
    i.add_argument("--modes", default="auto", help="number of modes or 'auto' (default)")
    i.add_argument("--method", choices=("oe", "arx", "freq", "decay", "psd"), help="estimator (default oe / psd)")
    i.add_argument("--json", action="store_true", help="machine-readable output")

    c = sub.add_parser("calibrate", help="identify modes and recommend a shaper with firmware config lines")
    c.add_argument("file", help="CSV with a time column, Klipper accelerometer log or PSD file")
    c.add_argument("--input", help="input column (omit for output-only data)")
    c.add_argument("--output", help="output column")
    c.add_argument("--axis", default="auto", choices=("auto", "x", "y", "z", "all"), help="Klipper log axis")
    c.add_argument("--modes", default="auto", help="number of modes or 'auto' (default)")
    c.add_argument("--vtol", type=float, default=0.05, help="tolerable worst-case vibration (default 0.05)")
    c.add_argument("--margin", type=float, default=0.05, help="extra frequency uncertainty (default 0.05)")
    c.add_argument("--plot", help="write the calibration plot (png, pdf, svg)")

    t = sub.add_parser("tune", help="robust PD/PI for a loop with a shaper (H-infinity regions, seed 001)")
    src = t.add_mutually_exclusive_group(required=True)
    src.add_argument("--case", help="a seed plant from posicast.cases (e.g. gantry_crane)")
    src.add_argument("--num", help="plant numerator, descending powers, e.g. '1'")
    t.add_argument("--den", help="plant denominator, descending powers, e.g. '1 1 0' (with --num)")
    t.add_argument("--delay", type=float, default=0.0, help="plant dead time [s] (default 0)")
    t.add_argument("--shaper", help="shaper kind (see 'posicast kinds'); default: none")
    t.add_argument("--omega", type=float, help="shaper mode frequency [rad/s] (default: the case's mode)")
    t.add_argument("--zeta", type=float, help="shaper mode damping (default: the case's mode)")
    t.add_argument("--structure", default="control_action",
                   choices=("control_action", "inverse_shaper", "feedforward"), help="where the shaper sits")
    t.add_argument("--controller", default="pd", choices=("pd", "pi"), help="controller structure (default pd)")
    t.add_argument("--ms", type=float, default=2.0, help="peak sensitivity bound (default 2)")
    t.add_argument("--derivative-filter", type=float, help="Tf of Kd s / (Tf s + 1) (pd only)")
    for g in ("kp", "ki", "kd"):
        t.add_argument(f"--{g}-range", type=float, nargs=2, metavar=("LOW", "HIGH"), help=f"bounds of {g}")
    t.add_argument("--json", action="store_true", help="machine-readable output")
    t.add_argument("--plot", help="write the region in the gain plane (png, pdf, svg)")
    t.add_argument("--nyquist", help="write the Nyquist plot with the Ms circle")
    return parser


def _coeffs(text: str, name: str) -> list[float]:
    try:
        vals = [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        raise ValueError(f"{name} must be numbers separated by spaces, got {text!r}") from None
    if not vals:
        raise ValueError(f"{name} must not be empty")
    return vals


def _tune_cmd(args: argparse.Namespace) -> int:
    from .core.transfer import TransferFunction, delay
    from .modes import Mode
    from .shapers.design import design
    from .tune import tune_pd, tune_pi

    F = None
    mode = None
    if args.case is not None:
        from .cases import ALL

        if args.case not in ALL:
            raise ValueError(f"--case must be one of {', '.join(ALL)}; got {args.case!r}")
        case = ALL[args.case]
        G, F, mode = case.G, case.F, case.mode
        if args.den is not None:
            raise ValueError("--den goes with --num, not with --case")
    else:
        if args.den is None:
            raise ValueError("--den is required with --num")
        G = TransferFunction.from_poly(_coeffs(args.num, "--num"), _coeffs(args.den, "--den"))
    if args.delay != 0.0:
        if not (math.isfinite(args.delay) and args.delay > 0):
            raise ValueError(f"--delay must be a finite number >= 0 [s], got {args.delay:g}")
        G = G * delay(args.delay)
    if args.omega is not None or args.zeta is not None:
        if args.omega is None or args.zeta is None:
            raise ValueError("--omega and --zeta go together")
        mode = Mode(args.omega, args.zeta)
    S = None
    if args.shaper is not None:
        if mode is None:
            raise ValueError("--shaper needs the mode: --omega and --zeta (or --case)")
        S = design(args.shaper.lower(), mode)
    common = {"F": F}
    if args.controller == "pd":
        if args.ki_range is not None:
            raise ValueError("--ki-range does not apply to a pd controller")
        r = tune_pd(G, S, args.structure, ms=args.ms, derivative_filter=args.derivative_filter,
                    kp_range=args.kp_range, kd_range=args.kd_range, **common)
    else:
        if args.kd_range is not None or args.derivative_filter is not None:
            raise ValueError("--kd-range and --derivative-filter do not apply to a pi controller")
        r = tune_pi(G, S, args.structure, ms=args.ms, kp_range=args.kp_range, ki_range=args.ki_range, **common)
    figures = []
    if (args.plot or args.nyquist) and not r.empty:
        import matplotlib

        matplotlib.use("Agg")
        if args.plot:
            figures.append((r.plot()[0], args.plot))
        if args.nyquist and r.loop is not None:
            figures.append((r.nyquist_plot()[0], args.nyquist))
    for fig, out in figures:  # everything computed: only now write
        _save_atomic(fig, out)
    if args.json:
        ext = r.region.extent()

        def num(v: Any) -> Any:  # JSON has no NaN or inf: null
            return float(v) if v is not None and math.isfinite(v) else None

        print(json.dumps({
            "controller": r.family.describe(), "structure": r.structure, "shaper": args.shaper,
            "empty": r.empty, "unbounded": r.unbounded,
            "gains": None if r.gains is None else {k: r._gain(k) for k in ("kp", "ki", "kd")},
            "ms": num(r.ms), "omega_ms": num(r.omega_ms), "stable": r.stable, "reason": r.reason,
            "region": None if ext is None else {r.family.x: [num(ext[0]), num(ext[1])],
                                                r.family.y: [num(ext[2]), num(ext[3])]},
        }, indent=2))
    else:
        print(r.summary())
        for _, out in figures:
            print(f"wrote {out}")
    return 0 if r.gains is not None else 1  # 1: ran, but no controller (empty or unbounded region)


def _n_modes(text: str) -> Any:
    if text == "auto":
        return "auto"
    try:
        n = int(text)
    except ValueError:
        raise ValueError(f"--modes must be a positive integer or 'auto', got {text!r}") from None
    if n < 1:
        raise ValueError(f"--modes must be a positive integer or 'auto', got {n}")
    return n


def _identify_cmd(args: argparse.Namespace) -> int:
    from .identify import calibrate, load_csv
    from .identify.estimators import identify

    if args.command == "calibrate":
        cal = calibrate(args.file, input=args.input, output=args.output, axis=args.axis,
                        n_modes=_n_modes(args.modes), vtol=args.vtol, margin=args.margin)
        if args.plot:  # everything computed: only now write
            import matplotlib

            matplotlib.use("Agg")
            from .identify.plots import calibration_plot

            fig = calibration_plot(cal)
            _save_atomic(fig, args.plot)
        print(cal.summary())
        if args.plot:
            print(f"wrote {args.plot}")
        return 0
    ds = load_csv(args.file)
    nm = _n_modes(args.modes)
    if args.input is not None:
        if args.output is None:
            raise ValueError("--output is required with --input")
        r = identify(ds.t, ds.column(args.input), ds.column(args.output), n_modes=nm, method=args.method or "oe")
    else:
        if ds.kind == "klipper_raw":
            y, slope = ds.projection(args.axis), 2.0
        elif args.output is not None:
            y, slope = ds.column(args.output), 0.0
        else:
            raise ValueError("--output is required (or --input and --output) for CSV data")
        method = args.method or "psd"
        nm = (2 if method == "psd" else 1) if nm == "auto" else nm
        r = identify(ds.t, None, y, n_modes=nm, method=method, excitation_slope=slope,
                     band=(5.0, min(133.0, 0.45 * ds.fs)) if method == "psd" else None)
    if args.json:
        print(json.dumps({"method": r.method, "modes": [
            {"omega": m.omega, "freq_hz": m.freq_hz, "zeta": m.zeta, "omega_95": list(iv.omega), "zeta_95": list(iv.zeta)}
            for m, iv in zip(r.modes, r.intervals)], "fit_percent": r.fit_percent, "whiteness_p": r.whiteness_p}, indent=2))
    else:
        print(r.summary())
    return 0


def _save_atomic(fig: Any, out: str) -> None:
    import os
    import tempfile
    from pathlib import Path

    import matplotlib.pyplot as plt

    target = Path(out)
    fd, tmp = tempfile.mkstemp(suffix=target.suffix, dir=target.parent if str(target.parent) else ".")
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=110, bbox_inches="tight")
        os.replace(tmp, target)
    finally:
        plt.close(fig)
        if os.path.exists(tmp):
            os.unlink(tmp)


def _params(args: argparse.Namespace, kind: str) -> dict[str, Any]:
    from .shapers.design import KINDS

    accepted = KINDS[kind].params if kind in KINDS else {}
    out = {}
    for name in ("vtol", "k", "n", "m", "T", "method"):
        val = getattr(args, name)
        if val is None:
            continue
        if name not in accepted:
            raise ValueError(f"--{name} does not apply to kind {kind!r}")
        out[name] = val
    return out


def _mode(args: argparse.Namespace) -> Any:
    from .modes import Mode

    if args.omega is not None:
        return Mode(args.omega, args.zeta)
    return Mode.from_hz(args.freq_hz, args.zeta)


def _print_shaper(S: Any) -> None:
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


def _run(argv: Sequence[str] | None) -> int:
    args = _build_parser().parse_args(argv)
    from .shapers.design import KINDS, design

    if args.command in ("identify", "calibrate"):
        return _identify_cmd(args)
    if args.command == "tune":
        return _tune_cmd(args)
    if args.command == "kinds":
        for name, spec in KINDS.items():
            params = ", ".join(f"{k}={v}" for k, v in spec.params.items())
            print(f"{name:8s} {spec.summary}" + (f"  [{params}]" if params else ""))
        return 0
    mode = _mode(args)
    if args.command == "design":
        kind = args.kind.lower()
        S = design(kind, mode, **_params(args, kind))
        if args.json:
            print(json.dumps(S.to_dict(), indent=2))
        else:
            _print_shaper(S)
        return 0
    # sensitivity
    import matplotlib

    matplotlib.use("Agg")
    from .analysis import insensitivity, sensitivity_plot

    shapers = [design(k.lower(), mode, **_params(args, k.lower())) for k in args.kinds]
    ref = "unshaped" if any(not math.isfinite(S.duration) for S in shapers) else "end"
    fig, ax = sensitivity_plot(shapers, vtol=args.tol, reference=ref)
    ax.set_title(f"omega = {mode.omega:.4g} rad/s, zeta = {mode.zeta:.4g}")
    fig.savefig(args.out, dpi=120, bbox_inches="tight")
    for S in shapers:
        ins = insensitivity(S, args.tol, reference=ref)
        print(f"{S.name:8s} duration {S.duration:.6g} s, insensitivity at {args.tol:g}: {ins.width:.4f}")
    print(f"wrote {args.out}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``posicast`` command."""
    try:
        return _run(argv)
    except (_OneLineError, ValueError, TypeError, OSError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        print(f"posicast: error: {msg}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
