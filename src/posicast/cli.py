"""Command line: ``posicast design``, ``sensitivity``, ``kinds``, ``identify``, ``calibrate``, ``tune``, ``sweep``.

``posicast sweep ...`` (issue #19) is defined in :mod:`posicast.sweeps.command`.

``identify`` and ``calibrate`` exit with status 1 when the data show no resonance
(one line on stderr, no configuration printed).  Every error (bad argument,
out-of-range value, work too large, unreadable or unwritable file) prints one
line to stderr and exits with status 2; no traceback.  ``posicast tune`` exits
with status 1 when it ran but found no controller (an empty or unbounded
region, printed as such).  An unexpected
exception (a bug) also prints one line, ``posicast: internal error: ...`` with
where it was raised, and exits with status 70; set ``POSICAST_TRACEBACK=1`` to
see the traceback.

Figures (``--out``, ``--plot``, ``--nyquist``) are written at exactly the path
given, whose extension chooses the format (``.png``, ``.pdf``, ``.svg``, ``.eps``,
``.ps``, ``.jpg``, ``.jpeg``, ``.tif``, ``.tiff``): a path without one of these is
refused, as is a directory or a missing parent directory.  Every argument and
output path is checked before any computation, the file is written only after
everything else succeeded, atomically (a temporary file in the same directory,
renamed), and an error leaves no file behind.

The command line is posicast's top layer and imports what it runs at module level.
matplotlib alone is loaded lazily, through :func:`_pyplot`, the one place here that
imports it: only the subcommands that draw pay for it.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
import traceback
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any, Callable, Sequence

from . import _validate as v
from .analysis import insensitivity, sensitivity_plot
from .cases import ALL as CASES
from .core.transfer import TransferFunction, as_transfer, delay
from .identification import NoModeFound, calibrate, load_csv
from .identification.calibration import identify_resonances
from .identification.estimators import identify
from .identification.plots import calibration_plot
from .identification.resonance import resonance_data
from .identification.significance import MAX_MODES
from .modes import Mode
from .shapers.base import Shaper
from .shapers import registry  # registry.design at call time: the suite patches it to test status 70
from .spectra.rootfinder import RootFindingError
from .sweeps.command import add_sweep_parser, run_sweep
from .tune import TuningResult, tune_pd, tune_pi
from .tune.constraints import sensitivity_constraint
from .tune.family import pd_family

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["main"]


def _pyplot() -> ModuleType:
    """``matplotlib.pyplot`` on the file-only Agg backend, imported on first use (the CLI's one matplotlib import)."""
    import matplotlib  # lazy: about half a second that only the drawing subcommands need

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


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
    i.add_argument("--output", help="output column (not for Klipper files)")
    i.add_argument("--axis", choices=("x", "y", "z"), help="tested axis of a Klipper file whose name does not say")
    i.add_argument("--modes", default="auto", help="number of modes, 1 to 6, or 'auto' (default)")
    i.add_argument("--method", choices=("oe", "arx", "freq", "decay", "psd"), help="estimator (default oe / psd)")
    i.add_argument("--json", action="store_true", help="machine-readable output")

    c = sub.add_parser("calibrate", help="identify modes in resonance tests and recommend firmware settings")
    c.add_argument("files", nargs="+", metavar="FILE",
                   help="Klipper raw logs or PSD files (resonances_*, calibration_data_*), or CSV with --input/--output")
    c.add_argument("--firmware", default="klipper",
                   help="klipper, reprapfirmware, marlin, prusa, a comma-separated list, or all (default klipper)")
    c.add_argument("--klipper-version", default="v0.13", choices=("v0.13", "master", "kalico"),
                   help="the Klipper whose shapers and rules to use (default v0.13)")
    c.add_argument("--axis", choices=("x", "y", "z"), help="tested axis when the file names do not say it")
    c.add_argument("--at", help="one label per file for a frequency schedule: mass=0,100,200 (g) or z=0,50,100 (mm)")
    c.add_argument("--vtol", type=float,
                   help="worst-case vibration target, in (0, 1): least smoothing within it (default: the best "
                        "trade-off of vibration and smoothing)")
    c.add_argument("--margin", type=float, default=0.05, help="frequency drift of the modes, in [0, 0.5) (default 0.05)")
    c.add_argument("--max-smoothing", type=float, help="upper bound on Klipper's smoothing [mm]")
    c.add_argument("--slack", type=float, default=0.01,
                   help="remaining vibration (the firmware tool's measure) that may be traded for less smoothing "
                        "against the tool's own pick, in [0, 0.2] (default 0.01)")
    c.add_argument("--input", help="input column (input/output CSV)")
    c.add_argument("--output", help="output column (input/output CSV)")
    c.add_argument("--modes", default="auto", help="number of modes, 1 to 6, or 'auto' (default)")
    c.add_argument("--json", action="store_true", help="machine-readable output")
    c.add_argument("--plot", help="write the calibration figure (png, pdf, svg)")
    c.add_argument("--quiet", action="store_true", help="no progress lines on stderr")

    t = sub.add_parser("tune", help="robust PD/PI for a loop with a shaper (H-infinity regions, seed 001)")
    src = t.add_mutually_exclusive_group(required=True)
    src.add_argument("--case", help="a seed plant from posicast.cases (e.g. gantry_crane)")
    src.add_argument("--num", help="plant numerator, descending powers, e.g. '1'")
    t.add_argument("--den", help="plant denominator, descending powers, e.g. '1 1 0' (with --num)")
    t.add_argument("--delay", type=float, default=0.0, help="plant dead time [s] (default 0)")
    t.add_argument("--shaper", help="shaper kind (see 'posicast kinds'); default: none")
    t.add_argument("--omega", type=float, help="shaper mode frequency [rad/s] (default: the case's mode)")
    t.add_argument("--zeta", type=float, help="shaper mode damping (default: the case's mode)")
    t.add_argument("--architecture", default=None,
                   choices=("control_action", "inverse_shaper", "feedforward"),
                   help="where the shaper sits (default control_action)")
    t.add_argument("--structure", default=None, choices=("control_action", "inverse_shaper", "feedforward"),
                   help=argparse.SUPPRESS)  # the 0.1 spelling: still read, with a warning on stderr
    t.add_argument("--controller", default="pd", choices=("pd", "pi"), help="controller structure (default pd)")
    t.add_argument("--ms", type=float, default=2.0, help="peak sensitivity bound (default 2)")
    t.add_argument("--derivative-filter", type=float, help="Tf of Kd s / (Tf s + 1) (pd only)")
    for g in ("kp", "ki", "kd"):
        t.add_argument(f"--{g}-range", type=float, nargs=2, metavar=("LOW", "HIGH"), help=f"bounds of {g}")
    t.add_argument("--json", action="store_true", help="machine-readable output")
    t.add_argument("--plot", help="write the region in the gain plane (png, pdf, svg)")
    t.add_argument("--nyquist", help="write the Nyquist plot with the Ms circle")
    add_sweep_parser(sub)
    return parser


def _coeffs(text: str, name: str) -> list[float]:
    try:
        vals = [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        raise ValueError(f"{name} must be numbers separated by spaces, got {text!r}") from None
    if not vals:
        raise ValueError(f"{name} must not be empty")
    return vals


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
    v.nonnegative(args.delay, "--delay", " [s]")
    if (args.omega is None) != (args.zeta is None):
        raise ValueError("--omega and --zeta go together")


def _tune_plant(args: argparse.Namespace) -> tuple[TransferFunction, TransferFunction | None, Mode | None]:
    """``(G, F, mode)`` from ``--case`` or ``--num/--den`` (with ``--delay``); ``--omega/--zeta`` override the mode."""
    F = None
    mode = None
    if args.case is not None:
        v.choice(args.case, "--case", CASES)
        if args.den is not None:
            raise ValueError("--den goes with --num, not with --case")
        case = CASES[args.case]
        G, F, mode = case.G, case.F, case.mode
    else:
        if args.den is None:
            raise ValueError("--den is required with --num")
        G = as_transfer((_coeffs(args.num, "--num"), _coeffs(args.den, "--den")), "the plant --num/--den")
    if args.delay != 0.0:
        G = G * delay(args.delay)
    if args.omega is not None:
        mode = Mode(args.omega, args.zeta)
    return G, F, mode


def _tune_figures(args: argparse.Namespace, r: TuningResult) -> list[tuple[Figure, str, str]]:
    """The requested figures of a tuning result as ``(figure, path, option)``, not yet written."""
    figures: list[tuple[Figure, str, str]] = []
    if (args.plot or args.nyquist) and not r.empty:
        _pyplot()  # the Agg backend before the tuner draws
        if args.plot:
            figures.append((r.plot()[0], args.plot, "--plot"))
        if args.nyquist and r.loop is not None:
            figures.append((r.nyquist_plot()[0], args.nyquist, "--nyquist"))
    return figures


def _json_number(x: Any) -> float | None:
    """JSON has no NaN or inf: null."""
    return float(x) if x is not None and math.isfinite(x) else None


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


def _tune_cmd(args: argparse.Namespace) -> int:
    _check_tune_options(args)  # every option first, before any design work
    G, F, mode = _tune_plant(args)
    S = None
    if args.shaper is not None:
        if mode is None:
            raise ValueError("--shaper needs the mode: --omega and --zeta (or --case)")
        S = registry.design(args.shaper.lower(), mode)
    if args.controller == "pd":
        r = tune_pd(G, S, _architecture(args), ms=args.ms, derivative_filter=args.derivative_filter,
                    kp_range=args.kp_range, kd_range=args.kd_range, F=F)
    else:
        r = tune_pi(G, S, _architecture(args), ms=args.ms, kp_range=args.kp_range, ki_range=args.ki_range, F=F)
    figures = _tune_figures(args, r)
    for fig, out, opt in figures:  # everything computed: only now write
        _save_atomic(fig, out, opt)
    if args.json:
        print(json.dumps(_tune_json(args, r), indent=2))
    else:
        print(r.summary())
        for _, out, _opt in figures:
            print(f"wrote {out}")
    return 0 if r.gains is not None else 1  # 1: ran, but no controller (empty or unbounded region)


def _architecture(args: argparse.Namespace) -> str:
    """``--architecture``, or the 0.1 spelling ``--structure`` (with a one-line warning on stderr)."""
    if args.structure is not None:
        if args.architecture is not None:
            raise ValueError("give --architecture only (--structure is its old name)")
        print("posicast: warning: --structure is now --architecture", file=sys.stderr)
        return args.structure
    return args.architecture or "control_action"


def _n_modes(text: str) -> int | str:
    if text == "auto":
        return "auto"
    try:
        n = int(text)
    except ValueError:
        raise ValueError(f"--modes must be an integer in [1, {MAX_MODES}] or 'auto', got {text!r}") from None
    if not 1 <= n <= MAX_MODES:
        raise ValueError(f"--modes must be an integer in [1, {MAX_MODES}] or 'auto', got {n}")
    return n


def _progress(quiet: bool) -> Callable[[str], None]:
    """Progress lines on stderr, once the work has taken more than a second (quick runs stay silent)."""
    start = time.monotonic()

    def say(msg: str) -> None:
        elapsed = time.monotonic() - start
        if not quiet and elapsed > 1.0:
            print(f"[{elapsed:5.1f} s] {msg}", file=sys.stderr, flush=True)

    return say


def _at_labels(text: str | None, n: int) -> list[dict[str, float]] | None:
    if text is None:
        return None
    name, sep, values = text.partition("=")
    if not sep or name.strip() not in ("mass", "z"):
        raise ValueError(f"--at must be mass=V1,V2,... or z=V1,V2,..., got {text!r}")
    try:
        vals = [float(x) for x in values.split(",")]
    except ValueError:
        raise ValueError(f"--at values must be numbers separated by commas, got {values!r}") from None
    if len(vals) != n:
        raise ValueError(f"--at has {len(vals)} values for {n} files; give one per file")
    return [{name.strip(): x} for x in vals]


def _identify_cmd(args: argparse.Namespace) -> int:
    try:
        if args.command == "calibrate":
            return _calibrate_cmd(args)
        nm = _n_modes(args.modes)  # arguments before the file is read
        ds = load_csv(args.file)
        if args.input is not None:
            if args.output is None:
                raise ValueError("--output is required with --input")
            r = identify(ds.t, ds.column(args.input), ds.column(args.output), n_modes=nm,
                         method=args.method or "oe")
        elif ds.kind in ("klipper_raw", "klipper_psd"):
            if args.output is not None or args.method not in (None, "psd"):
                raise ValueError("Klipper files are identified from their spectrum (method psd); "
                                 "--output and other methods do not apply")
            r = identify_resonances(resonance_data(ds, args.axis), nm)
        elif args.output is not None:
            method = args.method or "psd"
            r = identify(ds.t, None, ds.column(args.output), n_modes=nm if method == "psd" else
                         (1 if nm == "auto" else nm), method=method)
        else:
            raise ValueError("--output is required (or --input and --output) for CSV data")
    except NoModeFound as exc:
        print(f"posicast: {exc}", file=sys.stderr)
        return 1
    if args.json:
        print(json.dumps({"method": r.method, "modes": [
            {"omega": m.omega, "freq_hz": m.freq_hz, "zeta": m.zeta, "omega_95": list(iv.omega),
             "zeta_95": list(iv.zeta)} for m, iv in zip(r.modes, r.intervals)],
            "fit_percent": None if math.isnan(r.fit_percent) else r.fit_percent,
            "whiteness_p": None if math.isnan(r.whiteness_p) else r.whiteness_p}, indent=2))
    else:
        print(r.summary())
    return 0


def _calibrate_cmd(args: argparse.Namespace) -> int:
    if args.vtol is not None:
        v.in_open_interval(args.vtol, "--vtol", 0.0, 1.0)
    margin = v.real_in_range(args.margin, "--margin", 0.0, 0.5, hi_open=True)
    if args.max_smoothing is not None:
        v.positive(args.max_smoothing, "--max-smoothing")
    firmware = [f.strip().lower() for f in args.firmware.split(",") if f.strip()]
    labels = _at_labels(args.at, len(args.files))
    cal = calibrate(args.files, firmware=firmware, axis=args.axis, at=labels, vtol=args.vtol, margin=margin,
                    max_smoothing=args.max_smoothing, slack=args.slack, klipper_version=args.klipper_version,
                    input=args.input,
                    output=args.output, n_modes=_n_modes(args.modes), progress=_progress(args.quiet))
    if args.plot:  # everything computed: only now write
        _pyplot()  # the Agg backend before the figure is drawn
        _save_atomic(calibration_plot(cal), args.plot)
    if args.json:
        print(json.dumps(cal.to_dict(), indent=2))
    else:
        print(cal.summary())
        if args.plot:
            print(f"wrote {args.plot}")
    return 0


def _output_path(value: Any, option: str) -> Path:
    """Check an output figure path before any work (see the module docstring); returns a Path."""
    return v.path_for_output(value, option)


# Output-path options checked by _run before any subcommand starts work.
_OUTPUT_OPTIONS = ("out", "plot", "nyquist")


def _save_atomic(fig: Figure, out: str, option: str = "--plot") -> None:
    """Write ``fig`` at exactly ``out``, atomically: a hidden temporary file in the same directory,
    renamed onto ``out`` once complete.  On any failure nothing is left behind and the error
    (a one-line ValueError) names ``option`` and the user's path, never the temporary file."""
    try:
        target = _output_path(out, option)
        fmt = target.suffix.lower()[1:]
        tmp = None
        try:
            fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part", dir=target.parent)
            with os.fdopen(fd, "wb") as fh:
                fig.savefig(fh, format=fmt, dpi=110, bbox_inches="tight")
            mask = os.umask(0)  # mkstemp makes the file private (0600): give it the usual mode
            os.umask(mask)
            os.chmod(tmp, 0o666 & ~mask)
            os.replace(tmp, target)
            tmp = None
        except (OSError, ValueError, RuntimeError) as exc:
            reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc).splitlines()[0]
            raise ValueError(f"{option}: cannot write {str(out)!r}: {reason}") from None
        finally:
            if tmp is not None and os.path.exists(tmp):
                os.unlink(tmp)
    finally:
        _pyplot().close(fig)


def _params(args: argparse.Namespace, kind: str) -> dict[str, Any]:
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


def _mode(args: argparse.Namespace) -> Mode:
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


def _run(argv: Sequence[str] | None) -> int:
    args = _build_parser().parse_args(argv)
    for opt in _OUTPUT_OPTIONS:  # every output path is checked before any work
        val = getattr(args, opt, None)
        if val is not None:
            _output_path(val, f"--{opt}")
    if args.command in ("identify", "calibrate"):
        return _identify_cmd(args)
    if args.command == "tune":
        return _tune_cmd(args)
    if args.command == "sweep":
        return run_sweep(args, lambda fig, out: _save_atomic(fig, out, "--plot"))
    if args.command == "kinds":
        for name, spec in registry.KINDS.items():
            params = ", ".join(f"{k}={v}" for k, v in spec.params.items())
            print(f"{name:8s} {spec.summary}" + (f"  [{params}]" if params else ""))
        return 0
    if args.command == "sensitivity":  # the tolerance before any design work
        v.real_in_range(args.tol, "--tol", 0.0, 1.0, lo_open=True, hi_open=True)
    mode = _mode(args)
    if args.command == "design":
        kind = args.kind.lower()
        S = registry.design(kind, mode, **_params(args, kind))
        if args.json:
            print(json.dumps(S.to_dict(), indent=2))
        else:
            _print_shaper(S)
        return 0
    # sensitivity: design, analyse, draw; write last
    _pyplot()  # the Agg backend before sensitivity_plot draws
    shapers = [registry.design(k.lower(), mode, **_params(args, k.lower())) for k in args.kinds]
    ref = "unshaped" if any(not math.isfinite(S.duration) for S in shapers) else "end"
    lines = []
    for S in shapers:
        ins = insensitivity(S, args.tol, reference=ref)
        lines.append(f"{S.name:8s} duration {S.duration:.6g} s, insensitivity at {args.tol:g}: {ins.width:.4f}")
    fig, ax = sensitivity_plot(shapers, vtol=args.tol, reference=ref)
    ax.set_title(f"omega = {mode.omega:.4g} rad/s, zeta = {mode.zeta:.4g}")
    _save_atomic(fig, args.out, "--out")
    for line in lines:
        print(line)
    print(f"wrote {args.out}")
    return 0


_EX_SOFTWARE = 70  # sysexits.h: an internal software error


def _origin(exc: BaseException) -> str:
    """``file:line`` (inside posicast when possible) where ``exc`` was raised."""
    frames = traceback.extract_tb(exc.__traceback__)
    root = os.path.dirname(os.path.abspath(__file__))
    for fr in reversed(frames):
        path = os.path.abspath(fr.filename)
        if path.startswith(root + os.sep):
            return f"posicast/{os.path.relpath(path, root)}:{fr.lineno}"
    return f"{os.path.basename(frames[-1].filename)}:{frames[-1].lineno}" if frames else "?"


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``posicast`` command.

    Returns the exit status: 0 success, 1 ``tune`` found no controller or
    ``identify``/``calibrate`` no resonance, 2 any error in the arguments or the files
    (one line on stderr), 70 an internal error (a bug; one line on stderr, the
    traceback with ``POSICAST_TRACEBACK=1``).
    """
    try:
        return _run(argv)
    except (_OneLineError, ValueError, TypeError, OSError, RootFindingError) as exc:
        msg = str(exc).splitlines()[0] if str(exc).strip() else type(exc).__name__
        print(f"posicast: error: {msg}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("posicast: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # a bug: still one line (and the traceback on request)
        if os.environ.get("POSICAST_TRACEBACK"):
            raise
        msg = str(exc).splitlines()[0] if str(exc).strip() else ""
        print(f"posicast: internal error: {type(exc).__name__}{': ' + msg if msg else ''} (at {_origin(exc)}; "
              f"please report it, POSICAST_TRACEBACK=1 shows the traceback)", file=sys.stderr)
        return _EX_SOFTWARE


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
