"""``posicast identify`` and ``posicast calibrate``: modes from measured data, firmware settings from resonance tests."""

from __future__ import annotations

import argparse
import json
import math
import sys

from .. import _validate as v
from ..identification import NoModeFound, calibrate, load_csv
from ..identification.calibration import identify_resonances
from ..identification.estimators import identify
from ..identification.plots import calibration_plot
from ..identification.resonance import resonance_data
from ..identification.significance import MAX_MODES
from .figures import pyplot, save_atomic
from .progress import steps, working

__all__ = ["run"]


def run(args: argparse.Namespace) -> int:
    try:
        if args.command == "calibrate":
            return _calibrate_cmd(args)
        nm = _n_modes(args.modes)  # arguments before the file is read
        with working(f"identifying modes in {args.file}", args.quiet):
            ds = load_csv(args.file)
            if args.input is not None:
                if args.output is None:
                    raise ValueError("--output is required with --input")
                method = args.method or "oe"
                r = identify(ds.t, ds.column(args.input), ds.column(args.output), method=method,
                             n_modes=_fixed_unless_auto_fits(nm, method))
            elif ds.kind in ("klipper_raw", "klipper_psd"):
                if args.output is not None or args.method not in (None, "psd"):
                    raise ValueError("Klipper files are identified from their spectrum (method psd); "
                                     "--output and other methods do not apply")
                r = identify_resonances(resonance_data(ds, args.axis), nm)
            elif args.output is not None:
                method = args.method or "psd"
                r = identify(ds.t, None, ds.column(args.output), n_modes=_fixed_unless_auto_fits(nm, method),
                             method=method)
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
    n_modes = _n_modes(args.modes)
    with steps(args.quiet) as say:
        cal = calibrate(args.files, firmware=firmware, axis=args.axis, at=labels, vtol=args.vtol, margin=margin,
                        max_smoothing=args.max_smoothing, slack=args.slack, klipper_version=args.klipper_version,
                        input=args.input, output=args.output, n_modes=n_modes, progress=say,
                        band=None if args.band is None else tuple(args.band))
    if args.plot:  # everything computed: only now write
        pyplot()  # the Agg backend before the figure is drawn
        save_atomic(calibration_plot(cal)[0], args.plot)
    if args.json:
        print(json.dumps(cal.to_dict(), indent=2))
    else:
        print(cal.summary())
        if args.plot:
            print(f"wrote {args.plot}")
    return 0


def _fixed_unless_auto_fits(n_modes: int | str, method: str) -> int | str:
    """``--modes auto`` (the default) picks the order by BIC where the estimator can (oe, psd); the
    others (arx, freq: one mode; decay) fit one mode unless ``--modes`` says how many."""
    return 1 if n_modes == "auto" and method not in ("oe", "psd") else n_modes


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
