"""``posicast sweep ...``: what the sweep subcommand runs (its options are built by ``posicast.cli``, which
imports nothing heavy; :mod:`posicast.commands.sweep` calls :func:`run_sweep`).

Four sweeps, one set of execution options::

    posicast sweep chart      [--gain 0.05:1.5:30] [--delay-error -0.5:0.5:11]   seed 000 inverse-ZV loop
    posicast sweep montecarlo [--n 200] [--seed 0] [--grid27] [--no-simulate]    seed 003 two-mass loop
    posicast sweep calibrate  FOLDER [--pattern '*.csv'] [--firmware klipper]    one row per log
    posicast sweep function   MODULE:NAME --grid x=0:1:11 --grid y=1,2,4 | --uniform x=0:1 --n N --seed S

    common: --store DIR (Zarr; resumes) --scheduler tcp://host:8786 | --workers N | --serial
            --batch-size N --overwrite --csv TABLE.csv --plot FIG.png --quiet

A value list is ``START:STOP:NUM`` (``numpy.linspace``) or comma-separated numbers.
Exit status 0, or 1 when some points failed (their messages are in the summary and the
table); errors are the command line's one line and status 2, checked before any work
(``--csv`` and ``--plot`` paths, values, an unreachable scheduler: nothing is written).
"""

from __future__ import annotations

import argparse
import importlib
import json
from typing import Any, Callable

import numpy as np
from scipy import stats

from .. import _validate as v
from .charts import StabilityChart, seed000_chart
from .engine import sweep
from .farm import calibration_table
from .montecarlo import two_mass_grid, two_mass_monte_carlo
from .plots import histogram, value_map
from .result import SweepResult

__all__ = ["run_sweep", "values_of"]


def values_of(text: str, option: str) -> list[float]:
    """``START:STOP:NUM`` or ``a,b,c`` as a list of floats.

    >>> values_of("0:1:3", "--gain"), values_of("1,2.5", "--x")
    ([0.0, 0.5, 1.0], [1.0, 2.5])
    """
    try:
        if ":" in text:
            a, b, n = text.split(":")
            return [float(x) for x in np.linspace(float(a), float(b), v.integer_in_range(int(n), option, 1, 10**6))]
        return [float(x) for x in text.split(",")]
    except ValueError as exc:
        if str(exc).startswith(option):
            raise
        raise ValueError(f"{option} must be START:STOP:NUM or comma-separated numbers, got {text!r}") from None


def _named(items: list[str] | None, option: str) -> dict[str, str]:
    out = {}
    for item in items or []:
        name, sep, spec = item.partition("=")
        if not sep or not name.strip():
            raise ValueError(f"{option} must be NAME=VALUES, got {item!r}")
        out[name.strip()] = spec
    return out


def _sweep_options(args: argparse.Namespace) -> dict[str, Any]:
    client: Any = "serial" if args.serial else args.scheduler
    return {"store": args.store, "client": client, "workers": args.workers, "batch_size": args.batch_size,
            "progress": False if args.quiet else None, "overwrite": args.overwrite, "connect_timeout": args.timeout}


def _import(target: str) -> Callable[..., Any]:
    mod, sep, name = target.partition(":")
    if not sep or not mod or not name:
        raise ValueError(f"function must be MODULE:NAME, got {target!r}")
    try:
        obj = getattr(importlib.import_module(mod), name)
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"function {target!r} cannot be imported: {exc}") from None
    if not callable(obj):
        raise ValueError(f"function {target!r} is not callable")
    return obj


def run_sweep(args: argparse.Namespace, save_figure: Callable[[Any, str], None]) -> int:
    """Run ``posicast sweep ...``; ``save_figure(fig, path)`` writes a figure atomically (the CLI's)."""
    if args.csv is not None:
        v.path_for_output(args.csv, "--csv", (".csv",))
    if args.plot is not None and (args.sweep == "calibrate" or getattr(args, "grid27", False)):
        raise ValueError("--plot draws a chart, a Monte Carlo histogram or a 2-D function grid; "
                         "use --csv for this table")
    opts = _sweep_options(args)
    fig = None
    chart: StabilityChart | None = None
    if args.sweep == "chart":
        gains, errors = values_of(args.gain, "--gain"), values_of(args.delay_error, "--delay-error")
        chart = seed000_chart(gains, errors, **opts)
        result = chart.result
    elif args.sweep == "montecarlo":
        if args.grid27:
            result = two_mass_grid(shaper=args.shaper, architecture=args.architecture,
                                   simulate_step=not args.no_simulate, **opts)
        else:
            result = two_mass_monte_carlo(args.n, args.seed, shaper=args.shaper, architecture=args.architecture,
                                          simulate_step=not args.no_simulate, **opts)
    elif args.sweep == "calibrate":
        result = calibration_table(args.folder, args.pattern, firmware=args.firmware, **opts)
    else:
        grid = {k: values_of(s, f"--grid {k}") for k, s in _named(args.grid, "--grid").items()}
        uniform = _named(args.uniform, "--uniform")
        if grid and uniform:
            raise ValueError("give --grid or --uniform, not both")
        if uniform:
            params: dict[str, Any] = {}
            for k, s in uniform.items():
                lo, hi = (values_of(s.replace(":", ","), f"--uniform {k}") + [0.0, 0.0])[:2]
                if not hi > lo:
                    raise ValueError(f"--uniform {k} must be LOW:HIGH with LOW < HIGH, got {s!r}")
                params[k] = stats.uniform(lo, hi - lo)
            result = sweep(_import(args.target), params, n=args.n, seed=args.seed, **opts)
        else:
            result = sweep(_import(args.target), grid, **opts)
    as_json = getattr(args, "json", False)
    if not as_json:
        _print_result(result, chart)
    if args.plot is not None:
        if chart is not None:
            fig, _ = chart.plot()
        elif args.sweep == "montecarlo" and not args.grid27:
            fig, _ = histogram(result, args.value)
        else:
            value = getattr(args, "value", None) or next(iter(result.values), "")
            fig, _ = value_map(result, value)
        save_figure(fig, args.plot)
    if args.csv is not None:
        result.to_csv(args.csv)
    if as_json:
        print(json.dumps(sweep_json(result, chart), indent=2))
    else:
        for out in (args.plot, args.csv):
            if out is not None:
                print(f"wrote {out}")
    return 1 if np.any(result.status == "error") else 0


def _print_result(result: SweepResult, chart: StabilityChart | None) -> None:
    print(result.summary())
    if chart is not None:
        bad = chart.disagreements()
        print(f"D-decomposition check: {'agrees' if not bad else f'{len(bad)} disagreements'} to the grid "
              f"resolution; stability boundary per delay error:")
        for e in chart.result.space.axes[1]:
            print(f"  delay_error {e:+.4g}: gain {', '.join(f'{k:.6g}' for k in chart.stability_edges(e)) or '-'}")


def _plain(x: Any) -> Any:
    """A table cell as JSON: numbers (NaN and infinity as null), booleans, strings."""
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return float(x) if np.isfinite(x) else None
    return str(x)


def sweep_json(result: SweepResult, chart: StabilityChart | None = None) -> dict[str, Any]:
    """``posicast sweep --json``: the sweep's shape and status counts, its table (one list per column, one
    entry per point, as :meth:`SweepResult.table`) and, for a chart, the D-decomposition check."""
    counts = {s: int(np.count_nonzero(result.status == s)) for s in ("ok", "error", "missing")}
    doc: dict[str, Any] = {"function": result.function, "kind": result.space.kind, "shape": list(result.shape),
                           "parameters": list(result.space.names), "values": list(result.values),
                           "counts": counts, "table": {k: [_plain(x) for x in col]
                                                       for k, col in result.table().items()}}
    if chart is not None:
        doc["disagreements"] = [list(map(float, b)) for b in chart.disagreements()]
        doc["stability_edges"] = {repr(float(e)): [float(k) for k in chart.stability_edges(e)]
                                  for e in chart.result.space.axes[1]}
    return doc
