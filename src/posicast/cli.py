"""Command line: ``posicast design``, ``sensitivity``, ``kinds``, ``export``, ``identify``, ``calibrate``, ``tune``,
``qft``, ``sweep`` (issue #19: :mod:`posicast.sweeps.command` runs it), ``stability`` and ``simulate`` (issue #20);
``posicast --version``.

Every subcommand takes ``--json``: its result as one JSON document on stdout (no NaN or
infinity: null), and nothing else there.  Long work shows its progress on stderr (a tqdm
bar or a line per step, after the first second), so stdout stays parseable; ``--quiet``
silences it.

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

The command line is posicast's top layer.  It builds the parser without importing any
computation: each subcommand lives in a module of :mod:`posicast.commands` (``run(args)``),
imported by :func:`_run` through the table ``_COMMANDS`` when that subcommand runs, so
``posicast --help`` answers in a fraction of a second (issue #15).  To add a subcommand:
its parser lines in :func:`_build_parser`, its module in :mod:`posicast.commands`, one
line in ``_COMMANDS``.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import traceback
import warnings
from typing import Any, Sequence

__all__ = ["main"]


class _OneLineError(Exception):
    pass


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> Any:  # argparse prints usage + message; we want one line
        raise _OneLineError(message)


class _Version(argparse.Action):
    """``--version``: the installed package's version, looked up only when asked (no import of posicast's code)."""

    def __init__(self, option_strings: Sequence[str], dest: str = argparse.SUPPRESS, **kw: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS,
                         help="print posicast's version and exit")

    def __call__(self, parser: argparse.ArgumentParser, namespace: Any, values: Any, option: Any = None) -> None:
        from importlib.metadata import PackageNotFoundError, version

        try:
            text = version("posicast")
        except PackageNotFoundError:  # running from a source tree that was not installed
            text = "unknown (not installed)"
        print(f"posicast {text}")
        parser.exit(0)


def _add_output_args(p: argparse.ArgumentParser, progress: bool = False) -> None:
    """``--json`` (and ``--quiet`` for subcommands whose work can take long) on subcommand ``p``."""
    p.add_argument("--json", action="store_true", help="print the result as one JSON document on stdout")
    if progress:
        p.add_argument("--quiet", action="store_true", help="no progress on stderr")


def _add_mode_args(p: argparse.ArgumentParser) -> None:
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--omega", type=float, help="the mode's natural frequency [rad/s]")
    g.add_argument("--freq-hz", type=float, help="the mode's natural frequency [Hz]")
    p.add_argument("--zeta", type=float, required=True, help="the mode's damping ratio, in [0, 1)")


def _add_param_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--vtol", type=float,
                   help="tolerable residual vibration for ei/ei2/ei3/si/um_si, in (0, 1) (default 0.05)")
    p.add_argument("--k", type=int, help="derivative order for zvdk, >= 0 (default 1)")
    p.add_argument("--n", type=int, help="impulses of mis_zv (default 3) / of mis_zvd's first factor (default 2), >= 2")
    p.add_argument("--m", type=int, help="impulses of mis_zvd's second factor, >= 2 (default 3)")
    p.add_argument("--T", type=float, help="kernel length for dezv/dtzv/dczv/dtazv [s] (default pi/omega)")
    p.add_argument("--method", choices=("exact", "singhose", "fit"),
                   help="ei: exact (default), singhose (t3 = T_d) or Singhose's fit")


def _build_parser() -> _Parser:
    parser = _Parser(
        prog="posicast", description="Time-delay signal shapers for flexible machines.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="start here:\n"
               "  posicast report resonances_x_*.csv   your resonance test -> modes, shaper, firmware lines (HTML)\n"
               "  posicast report plant.json           your plant -> certified stability, tuned loop (HTML)\n"
               "  posicast serve                       the designer in the browser (machine, design, loop)\n"
               "every subcommand: posicast SUBCOMMAND --help; --json prints one JSON document")
    parser.add_argument("--version", action=_Version)
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    d = sub.add_parser("design", help="design a shaper and print it")
    d.add_argument("kind", help="shaper kind (see 'posicast kinds')")
    _add_mode_args(d)
    _add_param_args(d)
    _add_output_args(d)

    s = sub.add_parser("sensitivity", help="plot residual vibration against omega/omega_model")
    s.add_argument("kinds", nargs="+", help="one or more shaper kinds (see 'posicast kinds')")
    _add_mode_args(s)
    _add_param_args(s)
    s.add_argument("--out", help="output image (png, pdf, svg); needed unless --json")
    s.add_argument("--tol", type=float, default=0.05,
                   help="residual vibration level of the tolerance line and of the insensitivity width, in (0, 1) "
                        "(default 0.05)")
    _add_output_args(s)

    k = sub.add_parser("kinds", help="list the shaper kinds")
    _add_output_args(k)

    x = sub.add_parser("export", help="export a shaper (or its inverse) for a controller as C or JSON")
    x.add_argument("kind", help="shaper kind (see 'posicast kinds')")
    _add_mode_args(x)
    _add_param_args(x)
    x.add_argument("--sample-rate", type=float, required=True, help="controller sample rate [Hz]")
    x.add_argument("--zplane", action="store_true",
                   help="design in the z plane at 1/sample-rate (zv/zvd/zvdd/zvddd/zvdk, seed 002 eq. 8)")
    x.add_argument("--stride", default=None,
                   help="with --zplane: samples between taps, or 'positive' (default: the smallest stride with nonnegative "
                        "taps)")
    # the choices are posicast.io.export's EXPORT_FORMATS/FORMS/PRECISIONS, spelled out so that building the
    # parser imports nothing (tests/test_cli.py checks they agree)
    x.add_argument("--format", choices=("json", "c"), default="c", help="c (default) or json")
    x.add_argument("--form", choices=("sparse", "dense"), default="sparse", help="sparse taps (default) or dense")
    x.add_argument("--precision", choices=("double", "float"), default="double", help="C type (default double)")
    x.add_argument("--inverse", action="store_true", help="export 1/S (seed 000 eq. 19-20)")
    x.add_argument("--name", default="shaper", help="C identifier for the arrays and functions (default shaper)")
    x.add_argument("--output", help="write to this file (.h, .c, .json, .txt) instead of standard output")
    _add_output_args(x)

    i = sub.add_parser("identify", help="identify lightly damped modes in a CSV or Klipper file")
    i.add_argument("file", help="CSV with a time column, Klipper accelerometer log or PSD file")
    i.add_argument("--input", help="input column (omit for output-only data)")
    i.add_argument("--output", help="output column (not for Klipper files)")
    i.add_argument("--axis", choices=("x", "y", "z"), help="tested axis of a Klipper file whose name does not say")
    i.add_argument("--modes", default="auto",
                   help="number of modes, 1 to 6, or 'auto' (default: by BIC for oe and psd, 1 for the others)")
    i.add_argument("--method", choices=("oe", "arx", "freq", "decay", "psd"),
                   help="estimator (default: oe with --input, psd without)")
    _add_output_args(i, progress=True)

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
    c.add_argument("--margin", type=float, default=0.05,
                   help="relative frequency drift of the modes, in [0, 0.5) (default 0.05: +-5 %%)")
    c.add_argument("--max-smoothing", type=float, help="upper bound on Klipper's smoothing [mm] (default: none)")
    c.add_argument("--slack", type=float, default=0.01,
                   help="remaining vibration (the firmware tool's measure) that may be traded for less smoothing "
                        "against the tool's own pick, in [0, 0.2] (default 0.01)")
    c.add_argument("--input", help="input column (input/output CSV)")
    c.add_argument("--output", help="output column (input/output CSV)")
    c.add_argument("--modes", default="auto",
                   help="number of modes, 1 to 6, or 'auto' (default: every significant mode)")
    c.add_argument("--band", type=float, nargs=2, metavar=("FMIN", "FMAX"),
                   help="search for modes only in this band [Hz], inside the band the test excited (default: that "
                        "band)")
    c.add_argument("--plot", help="write the calibration figure (png, pdf, svg)")
    _add_output_args(c, progress=True)

    t = sub.add_parser("tune", help="robust PD/PI for a loop with a shaper (H-infinity regions, seed 001)")
    src = t.add_mutually_exclusive_group(required=True)
    src.add_argument("--case", help="a seed plant from posicast.cases (e.g. gantry_crane)")
    src.add_argument("--num", help="plant numerator, descending powers, e.g. '1'")
    t.add_argument("--den", help="plant denominator, descending powers, e.g. '1 1 0' (with --num)")
    t.add_argument("--delay", type=float, default=0.0, help="plant dead time [s] (default 0)")
    t.add_argument("--shaper", help="shaper kind (see 'posicast kinds') (default: none)")
    t.add_argument("--omega", type=float,
                   help="natural frequency of the shaper's mode [rad/s] (default: the case's mode)")
    t.add_argument("--zeta", type=float, help="damping ratio of the shaper's mode (default: the case's mode)")
    t.add_argument("--architecture", default=None,
                   choices=("control_action", "inverse_shaper", "feedforward"),
                   help="where the shaper sits (default control_action)")
    t.add_argument("--structure", default=None, choices=("control_action", "inverse_shaper", "feedforward"),
                   help=argparse.SUPPRESS)  # the 0.1 spelling: still read, with a warning on stderr
    t.add_argument("--controller", default="pd", choices=("pd", "pi"), help="controller structure (default pd)")
    t.add_argument("--ms", type=float, default=2.0, help="bound on the peak sensitivity Ms = ||S||inf (default 2)")
    t.add_argument("--derivative-filter", type=float,
                   help="time constant Tf [s] of Kd s / (Tf s + 1), pd only (default: none, Kd s)")
    for g in ("kp", "ki", "kd"):
        t.add_argument(f"--{g}-range", type=float, nargs=2, metavar=("LOW", "HIGH"),
                       help=f"search range of {g} (default: +-10^4 times its natural scale)")
    t.add_argument("--plot", help="write the region in the gain plane (png, pdf, svg)")
    t.add_argument("--nyquist", help="write the Nyquist plot, zoomed on -1 with the Ms circle (png, pdf, svg)")
    _add_output_args(t, progress=True)

    q = sub.add_parser("qft", help="QFT inner-loop model matching over seed 003's uncertain two-mass plants")
    q.add_argument("--uncertainty", type=float, default=50.0, help="c1, c2, k2 uncertainty [%%] (default 50)")
    q.add_argument("--stability", type=float, default=1.413, help="bound on |PG/(1+PG)| (default 1.413, eq. 2)")
    q.add_argument("--matching", type=float, default=0.1, help="bound on |PGF/(1+PG) - F_m| (default 0.1, eq. 3)")
    q.add_argument("--structure", default="lead,lead,lead",
                   help="controller sections, comma-separated: lead, real_zero, real_pole, complex_zero, "
                        "complex_pole, second_order, notch, integrator (default lead,lead,lead)")
    q.add_argument("--plot", help="write the Nichols chart with the bounds (png, pdf, svg)")
    _add_output_args(q, progress=True)

    _add_sweep_parser(sub)
    _add_stability_parser(sub)
    _add_simulate_parser(sub)

    r = sub.add_parser("report", help="an HTML report for your resonance test(s) or plant file")
    r.add_argument("data", nargs="+", metavar="DATA",
                   help="Klipper raw logs or PSD files (what 'calibrate' reads), or one plant file (.json, see README)")
    r.add_argument("--out", dest="out_dir", metavar="DIR", default="report", help="output folder (default: report)")
    r.add_argument("--firmware", default="klipper", help="for logs: as for 'calibrate' (default klipper)")
    r.add_argument("--axis", choices=("x", "y", "z"), help="for logs: the tested axis when the file names do not say")
    _add_output_args(r, progress=True)

    w = sub.add_parser("serve", help="the interactive designer in the browser (local; needs posicast[serve])")
    w.add_argument("--port", type=int, default=8765, help="TCP port (default 8765; 0: any free port)")
    w.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1: this machine only)")
    w.add_argument("--no-browser", action="store_true", help="do not open the page in a browser")
    w.add_argument("--json", action="store_true", help="print the address as JSON once listening (for scripts)")
    return parser


_SYSTEM_SYNTAX = ("descending powers, e.g. '1 0.2 4'; a term with a delay after @ and terms joined by ';': "
                  "'1 0.2 4; 2 @0.5' is s^2 + 0.2 s + 4 + 2 e^(-0.5 s)")


def _add_system_args(p: argparse.ArgumentParser) -> None:
    """A plant (``--case`` or ``--num/--den`` with ``--delay``), optionally a controller, a shaper and an
    architecture: ``stability`` and ``simulate`` (the parsing is :mod:`posicast.commands.systems`)."""
    g = p.add_argument_group("system (the plant G)")
    src = g.add_mutually_exclusive_group(required=True)
    src.add_argument("--case", help="a seed plant from posicast.cases (e.g. gantry_crane); its load F comes along")
    src.add_argument("--num", help="numerator: " + _SYSTEM_SYNTAX)
    g.add_argument("--den", help="denominator (with --num), same syntax")
    g.add_argument("--delay", type=float, default=0.0, help="dead time of the plant [s] (default 0)")
    c = p.add_argument_group("loop (with a controller: gains not given are 0; without one the plant alone is "
                                "analysed)")
    c.add_argument("--kp", type=float, help="proportional gain")
    c.add_argument("--ki", type=float, help="integral gain")
    c.add_argument("--kd", type=float, help="derivative gain")
    c.add_argument("--derivative-filter", type=float,
                   help="time constant Tf [s] of Kd s / (Tf s + 1) (default: none, Kd s)")
    c.add_argument("--controller-num", help="controller numerator (instead of --kp/--ki/--kd), same syntax")
    c.add_argument("--controller-den", help="controller denominator (default 1)")
    c.add_argument("--architecture", default=None,
                   choices=("feedforward", "control_action", "inverse_shaper"),
                   help="where the shaper sits (default control_action)")
    h = p.add_argument_group("shaper")
    h.add_argument("--shaper", help="shaper kind (see 'posicast kinds') (default: none)")
    h.add_argument("--omega", type=float,
                   help="natural frequency of the shaper's mode [rad/s] (default: the case's mode)")
    h.add_argument("--zeta", type=float, help="damping ratio of the shaper's mode (default: the case's mode)")


def _add_stability_parser(sub: Any) -> None:
    """``posicast stability``: certified verdict, spectral abscissa and rightmost roots of a system or loop."""
    p = sub.add_parser("stability", help="certified stability, spectral abscissa and rightmost roots of a "
                                         "system or loop")
    _add_system_args(p)
    p.add_argument("--roots", type=int, default=6, help="how many rightmost roots to print (default 6)")
    p.add_argument("--plot", help="write the spectrum (poles in the complex plane; png, pdf, svg)")
    _add_output_args(p, progress=True)


def _add_simulate_parser(sub: Any) -> None:
    """``posicast simulate``: a loop's response to a step or a given reference, as CSV and/or a figure."""
    p = sub.add_parser("simulate", help="step (or given input) response of a loop: CSV and/or figure")
    _add_system_args(p)
    p.add_argument("--t-end", type=float, default=10.0, help="end of the run [s] (default 10)")
    p.add_argument("--dt", type=float, help="time step [s] (default: 1/sample-rate, or t-end/5000)")
    p.add_argument("--sample-rate", type=float,
                   help="controller and shaper sampled at this rate [Hz] (default: continuous)")
    p.add_argument("--step-time", type=float, default=0.0, help="time of the reference step [s] (default 0)")
    p.add_argument("--step", type=float, default=1.0, help="height of the reference step (default 1)")
    p.add_argument("--input", metavar="FILE",
                   help="reference w from a CSV file with columns t [s], w, held from each row to the next "
                        "(instead of a step)")
    p.add_argument("--disturbance", type=float, nargs=2, metavar=("TIME", "SIZE"),
                   help="an output disturbance step d of SIZE at TIME [s]")
    p.add_argument("--input-disturbance", type=float, nargs=2, metavar=("TIME", "SIZE"),
                   help="an input disturbance step di of SIZE at TIME [s]")
    p.add_argument("--signals", default="w,u,z,y", help="signals to keep, comma-separated (default w,u,z,y)")
    p.add_argument("--out", help="write the response as CSV (.csv)")
    p.add_argument("--plot", help="write the response figure (png, pdf, svg)")
    _add_output_args(p, progress=True)


def _add_sweep_parser(sub: Any) -> None:
    """The ``sweep`` subcommand and its four sweeps on the CLI's subparsers ``sub``."""
    s = sub.add_parser("sweep", help="sweeps on Dask: stability charts, Monte Carlo, calibration farms")
    kinds = s.add_subparsers(dest="sweep", required=True, parser_class=type(s))
    c = kinds.add_parser("chart", help="certified stability of seed 000's inverse-ZV loop over gain x delay error")
    c.add_argument("--gain", default="0.05:1.5:30", help="controller gain values, START:STOP:NUM or comma-separated (default 0.05:1.5:30)")
    c.add_argument("--delay-error", default="-0.5:0.5:11", help="relative shaper delay errors, START:STOP:NUM or comma-separated; a negative "
                        "start needs '=' (default -0.5:0.5:11)")
    m = kinds.add_parser("montecarlo", help="seed 003's two-mass loop over c1, c2, k2 (uniform draws)")
    m.add_argument("--n", type=int, default=100, help="draws (default 100)")
    m.add_argument("--seed", type=int, default=0, help="seed of the draws (default 0)")
    m.add_argument("--grid27", action="store_true", help="the seed's 27 plants instead of draws")
    m.add_argument("--shaper", default="zvdk",
                   help="shaper kind (see 'posicast kinds') for the nominal mode (default zvdk: ZVD^2)")
    m.add_argument("--architecture", default="control_action", choices=("control_action", "feedforward"),
                   help="the shaper inside the loop (seed 003, default) or in front of it")
    m.add_argument("--no-simulate", action="store_true", help="skip the step response (overshoot, settling)")
    m.add_argument("--value", default="ms", help="value to histogram with --plot (default ms)")
    k = kinds.add_parser("calibrate", help="a folder of resonance-test logs to one table")
    k.add_argument("folder", help="directory of Klipper logs / PSD files")
    k.add_argument("--pattern", default="*.csv", help="file glob (default *.csv)")
    k.add_argument("--firmware", default="klipper", help="klipper, reprapfirmware, marlin or prusa (default klipper)")
    f = kinds.add_parser("function", help="any importable function over a grid or seeded draws")
    f.add_argument("target", help="MODULE:NAME of a function taking the parameters as keywords")
    f.add_argument("--grid", action="append", metavar="NAME=VALUES",
                   help="a grid axis, VALUES as START:STOP:NUM or comma-separated (repeat)")
    f.add_argument("--uniform", action="append", metavar="NAME=LOW:HIGH", help="uniform draws (repeat)")
    f.add_argument("--n", type=int, help="draws (with --uniform)")
    f.add_argument("--seed", type=int, help="seed of the draws (with --uniform)")
    f.add_argument("--value", help="value to draw with --plot (a 2-D grid)")
    for p in (c, m, k, f):
        g = p.add_argument_group("execution")
        where = g.add_mutually_exclusive_group()
        where.add_argument("--scheduler", help="Dask scheduler address, e.g. tcp://10.0.0.5:8786")
        where.add_argument("--workers", type=int, help="local worker processes (default: the CPU count)")
        where.add_argument("--serial", action="store_true", help="in this process, without Dask")
        g.add_argument("--store", help="Zarr directory: results persist as they arrive; rerun to resume")
        g.add_argument("--overwrite", action="store_true", help="discard what --store holds")
        g.add_argument("--batch-size", type=int, help="points per task (default: about 16 tasks per worker)")
        g.add_argument("--timeout", type=float, default=10.0, help="seconds to reach --scheduler (default 10)")
        g.add_argument("--csv", help="write the table (one row per point) to this .csv file")
        g.add_argument("--plot", help="write a figure (png, pdf, svg)")
        g.add_argument("--quiet", action="store_true", help="no progress bar")
        g.add_argument("--json", action="store_true", help="print the result as one JSON document on stdout")


# Subcommand -> module of posicast.commands whose run(args) it calls (imported when it runs).
_COMMANDS = {
    "design": "shaping", "kinds": "shaping", "sensitivity": "shaping", "export": "export",
    "identify": "identification", "calibrate": "identification",
    "tune": "tuning",
    "qft": "qft", "sweep": "sweep",
    "stability": "stability",
    "simulate": "simulate",
    "report": "report",
    "serve": "serve",
}

# Output-path options checked by _run before any subcommand starts work.
_OUTPUT_OPTIONS = ("out", "plot", "nyquist")


def _run(argv: Sequence[str] | None) -> int:
    args = _build_parser().parse_args(argv)
    figures = importlib.import_module("posicast.commands.figures")
    for opt in _OUTPUT_OPTIONS:  # every output path is checked before any work
        val = getattr(args, opt, None)
        if opt == "out" and args.command == "simulate":  # a CSV table there: checked by its module first
            continue
        if val is not None:
            figures.output_path(val, f"--{opt}")
    return importlib.import_module(f"posicast.commands.{_COMMANDS[args.command]}").run(args)


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


def _user_errors() -> tuple[type[BaseException], ...]:
    """The exceptions reported as one-line errors (status 2).  A root-finding failure can only have
    been raised if its module was imported, so it is looked up without importing the spectra."""
    rootfinder = sys.modules.get("posicast.spectra.rootfinder")
    return (_OneLineError, ValueError, TypeError, OSError) + ((rootfinder.RootFindingError,) if rootfinder else ())


def _one_line_warning(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                      file: Any = None, line: str | None = None) -> None:
    """A warning raised while a subcommand runs, as one line on stderr (no source line)."""
    text = str(message).strip().splitlines()
    print(f"posicast: warning: {text[0] if text else category.__name__}", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``posicast`` command.

    Returns the exit status: 0 success, 1 ``tune`` found no controller or
    ``identify``/``calibrate`` no resonance, 2 any error in the arguments or the files
    (one line on stderr), 70 an internal error (a bug; one line on stderr, the
    traceback with ``POSICAST_TRACEBACK=1``).
    """
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _one_line_warning  # restored when the block ends
            return _run(argv)
    except KeyboardInterrupt:
        print("posicast: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:
        if isinstance(exc, _user_errors()):
            msg = str(exc).splitlines()[0] if str(exc).strip() else type(exc).__name__
            print(f"posicast: error: {msg}", file=sys.stderr)
            return 2
        # a bug: still one line (and the traceback on request)
        if os.environ.get("POSICAST_TRACEBACK"):
            raise
        msg = str(exc).splitlines()[0] if str(exc).strip() else ""
        print(f"posicast: internal error: {type(exc).__name__}{': ' + msg if msg else ''} (at {_origin(exc)}; "
              f"please report it, POSICAST_TRACEBACK=1 shows the traceback)", file=sys.stderr)
        return _EX_SOFTWARE


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
