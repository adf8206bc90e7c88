"""``posicast simulate``: a loop's response to a reference step (or a reference read from a file), with
optional disturbance steps, written as CSV (``--out``) and/or a figure (``--plot``).

The loop is described by the options of :mod:`.systems` and needs a controller
(:func:`posicast.simulate` runs loops).  Continuous mode by default; ``--sample-rate``
runs the controller and the shaper sampled (seed 000 section VI).  The CSV has a
header ``t,<signals>`` and one row per time step.
"""

from __future__ import annotations

import argparse
import io
import json
import math
from typing import Any

import numpy as np

from .. import _validate as v
from ..identification.data import read_table
from ..simulation import simulate
from ..simulation.response import SimulationResponse
from .figures import pyplot, save_atomic, write_atomic
from .progress import working
from .systems import system_of

__all__ = ["run"]

_SIGNALS = ("w", "d", "di", "n", "e", "v", "u", "z", "y", "r", "m")
_INPUTS = _SIGNALS[:4]
#: At most this many time steps (a CSV row each).
MAX_STEPS = 20_000_000


def run(args: argparse.Namespace) -> int:
    """Simulate, then write the CSV and the figure (only once everything succeeded) and print a summary."""
    csv_path = None if args.out is None else v.path_for_output(args.out, "--out", (".csv",))
    signals = _signals(args.signals)
    t = _time(args)
    system = system_of(args)
    if system.loop is None:
        raise ValueError("simulate runs a loop: give a controller (--kp/--ki/--kd or --controller-num)")
    w = _reference(args, t)
    d = _step(args.disturbance, t, "--disturbance")
    di = _step(args.input_disturbance, t, "--input-disturbance")
    with working(f"simulating {t.size} steps", args.quiet):
        resp = simulate(system.loop, t, w=w, d=d, di=di, sample_rate=args.sample_rate,
                        outputs=tuple(s for s in signals if s not in _INPUTS))
    kept = [s for s in signals if s in resp.signals]
    fig = None
    if args.plot:
        pyplot()  # the Agg backend before the response draws
        fig, axes = resp.plot(kept)
        axes[0].set_title(f"{system.description} ({resp.mode})", fontsize=9)
    if csv_path is not None:  # everything computed: only now write
        write_atomic(csv_path, args.out, "--out", lambda fh: fh.write(_csv(resp, kept)))
    if fig is not None:
        save_atomic(fig, args.plot, "--plot")
    summary = _summary(resp, kept, None if args.input else args.step_time, args.step,
                       {sig: _dc_gain(system.loop, sig) for sig in ("z", "y") if sig in resp.signals})
    if args.json:
        print(json.dumps({"system": system.description, "architecture": system.loop.architecture,
                          "mode": resp.mode, "sample_rate": resp.sample_rate, "steps": int(resp.time.size),
                          "dt": float(t[1] - t[0]), "t_end": float(t[-1]), "accuracy": _number(resp.accuracy),
                          "diverged": resp.diverged, "diverged_signal": resp.diverged_signal,
                          "signals": kept, "out": args.out, "plot": args.plot, **summary}, indent=2))
        return 0
    print(f"{system.description}: {resp.mode} simulation, {resp.time.size} steps of {t[1] - t[0]:.4g} s")
    if resp.diverged is not None:
        print(f"DIVERGED: |{resp.diverged_signal}| exceeded the limit at t = {resp.diverged:.4g} s")
    for name, val in summary["final"].items():
        print(f"  {name}: final {val:.6g}, peak |{name}| {summary['peak'][name]:.6g}")
    for name, m in summary["step_response"].items():
        settle = "not within the run" if m["settling_time"] is None else f"{m['settling_time']:.4g} s"
        print(f"  {name} after the step: overshoot {m['overshoot_percent']:.4g} %, settling (2 %) {settle}")
    for out in (args.out, args.plot):
        if out:
            print(f"wrote {out}")
    return 0


def _number(x: Any) -> float | None:
    return float(x) if x is not None and math.isfinite(float(x)) else None


def _signals(text: str) -> list[str]:
    names = [s.strip() for s in text.split(",") if s.strip()]
    if not names:
        raise ValueError("--signals must name at least one signal")
    for s in names:
        v.choice(s, "--signals", _SIGNALS)
    if all(s in _INPUTS for s in names):
        raise ValueError(f"--signals must name at least one loop output ({', '.join(_SIGNALS[4:])}) besides the "
                         f"inputs, got {text!r}")
    return list(dict.fromkeys(names))


def _time(args: argparse.Namespace) -> np.ndarray:
    t_end = v.positive(args.t_end, "--t-end")
    if args.sample_rate is not None:
        v.positive(args.sample_rate, "--sample-rate")
    dt = args.dt if args.dt is not None else (1.0 / args.sample_rate if args.sample_rate else t_end / 5000.0)
    dt = v.positive(dt, "--dt")
    n = math.floor(t_end / dt + 1e-9) + 1
    if n < 2:
        raise ValueError(f"--dt must be shorter than --t-end, got dt = {dt:g} s, t-end = {t_end:g} s")
    if n > MAX_STEPS:
        raise ValueError(f"--t-end / --dt gives {n} steps, more than {MAX_STEPS}: use a larger --dt")
    return np.arange(n) * dt


def _reference(args: argparse.Namespace, t: np.ndarray) -> np.ndarray:
    if args.input is None:
        v.finite_real(args.step_time, "--step-time")
        return v.finite_real(args.step, "--step") * (t >= args.step_time).astype(float)
    header, data, lines = read_table(args.input)
    low = [h.strip().lower() for h in header]
    tcol = next((j for j, h in enumerate(low) if h in ("t", "time")), 0)
    rest = [j for j in range(len(header)) if j != tcol]
    col = next((j for j in rest if low[j] == "w"), rest[0] if len(rest) == 1 else None)
    if col is None:
        raise ValueError(f"--input: {args.input} must have a time column and a column 'w' (or one signal), "
                         f"got columns {', '.join(header)}")
    tf, wf = data[:, tcol], data[:, col]
    bad = np.flatnonzero(np.diff(tf) <= 0)
    if bad.size:
        raise ValueError(f"--input: {args.input}: line {lines[bad[0] + 1]}: time {tf[bad[0] + 1]:g} s does not "
                         f"increase (previous {tf[bad[0]]:g} s)")
    # the reference is held from each row's time to the next (zero-order hold, any spacing, in the file's
    # own time: 0 before its first row), its last value after its end
    idx = np.clip(np.searchsorted(tf, t, side="right") - 1, 0, tf.size - 1)
    return np.where(t >= tf[0], wf[idx], 0.0)


def _step(spec: list[float] | None, t: np.ndarray, name: str) -> np.ndarray | None:
    if spec is None:
        return None
    at, size = v.finite_real(spec[0], name), v.finite_real(spec[1], name)
    return size * (t >= at).astype(float)


def _csv(resp: SimulationResponse, kept: list[str]) -> bytes:
    cols = [resp.time] + [resp.signals[s] for s in kept]
    buf = io.StringIO()
    buf.write(",".join(["t"] + kept) + "\n")
    np.savetxt(buf, np.column_stack(cols), delimiter=",", fmt="%.17g")
    return buf.getvalue().encode()


def _dc_gain(loop: Any, signal: str) -> float:
    """The loop's steady-state gain from w to ``signal`` (nan when it cannot be evaluated)."""
    try:
        return float(loop.transfer("w", signal).dc_gain)
    except (ValueError, ArithmeticError):
        return math.nan


def _summary(resp: SimulationResponse, kept: list[str], step_time: float | None,
             step: float = 1.0, dc_gains: dict[str, float] | None = None) -> dict[str, Any]:
    """Final and peak values; for a step reference, the overshoot [%] and 2 % settling time [s] after it of
    each of z and y whose steady-state move is at least 1 % of the step: by the loop's DC gain from w when
    it is finite (a load's swing, F(0) = 0, has none even when the run ends mid-swing), else by the run's
    last sample."""
    final = {s: float(resp.signals[s][-1]) for s in kept} if resp.time.size else {}
    peak = {s: float(np.max(np.abs(resp.signals[s]))) for s in kept} if resp.time.size else {}
    metrics: dict[str, Any] = {}
    if resp.diverged is None and step_time is not None and resp.time.size and step_time < resp.time[-1]:
        start = max(step_time, float(resp.time[0]))
        for sig in ("z", "y"):
            if sig not in resp.signals:
                continue
            x = resp.signals[sig][resp.time >= start]
            gain = (dc_gains or {}).get(sig, math.nan)
            moves = abs(gain) >= 0.01 if math.isfinite(gain) else abs(x[-1] - x[0]) >= 0.01 * abs(step)
            if moves:
                metrics[sig] = {"overshoot_percent": resp.overshoot(sig, start=start),
                                "settling_time": _number(resp.settling_time(sig, start=start))}
    return {"final": final, "peak": peak, "step_response": metrics}
