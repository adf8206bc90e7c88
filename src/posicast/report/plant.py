""""Your plant → your loop": a plant, a shaper and a controller in; certified verdicts, tuned gains, responses out.

:func:`analyse_plant` computes everything first (:class:`PlantAnalysis`); :func:`plant_part`
adds it to a page, each result with the command and the Python code that gives it.
"""

from __future__ import annotations

import html
import json
import math
from dataclasses import dataclass
from typing import Any

import matplotlib.pyplot as plt
import numpy as np

from .. import _validate as v
from ..loops import Loop
from ..shapers import Shaper, design
from ..simulation import SimulationResponse, simulate
from ..spectra import Stability
from ..tune import TuningResult, tune_pd, tune_pi
from .page import Page
from .plantfile import PlantSpec

__all__ = ["PlantAnalysis", "LoopCase", "analyse_plant", "plant_part", "TITLE"]

TITLE = "Your plant → your loop"
#: Derivative filter of a tuned PD, in units of 1/omega of the mode (a proper controller to simulate).
PD_FILTER = 0.05
#: Time steps per period of the mode in the simulations.
STEPS_PER_PERIOD = 50


@dataclass(frozen=True)
class LoopCase:
    """One loop of the analysis: its controller, shaper (or none), certified verdict and step response."""

    label: str
    loop: Loop
    stability: Stability
    abscissa: float
    response: SimulationResponse | None
    shaped: bool
    note: str = ""


@dataclass(frozen=True)
class PlantAnalysis:
    """Everything the part shows, computed before anything is written.

    Attributes
    ----------
    spec : PlantSpec
    S : Shaper
    tuned : TuningResult
        The controller tuned with the shaper in its architecture.
    cases : tuple of LoopCase
        Your controller without and with the shaper (when the file gives one), the tuned controller
        without the shaper (same gains) and with it.
    t : ndarray
        Simulation time; the set-point step is at ``step_at``.
    """

    spec: PlantSpec
    S: Shaper
    tuned: TuningResult
    cases: tuple[LoopCase, ...]
    t: np.ndarray
    step_at: float

    @property
    def stable(self) -> bool:
        """Every loop with the shaper certified stable."""
        return all(c.stability.stable for c in self.cases if c.shaped)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready summary."""
        def gains(r: TuningResult) -> dict[str, Any]:
            return {"gains": None if r.gains is None else {k: float(x) for k, x in r.gains.items()},
                    "ms": _num(r.ms), "stable": bool(r.stable), "reason": r.reason}

        return {"name": self.spec.name, "mode": {"omega": self.spec.mode.omega, "freq_hz": self.spec.mode.freq_hz,
                                                 "zeta": self.spec.mode.zeta},
                "shaper": {"kind": self.spec.shaper, "duration": _num(self.S.duration)},
                "architecture": self.spec.architecture,
                "tuned": gains(self.tuned),
                "loops": [{"label": c.label, "stable": bool(c.stability.stable), "reason": c.stability.reason,
                           "spectral_abscissa": _num(c.abscissa)} for c in self.cases]}


def _num(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def _tune(spec: PlantSpec, S: Shaper | None) -> TuningResult:
    kw: dict[str, Any] = {"F": spec.F} if spec.has_load else {}
    if spec.controller == "pi":
        return tune_pi(spec.G, S, spec.architecture, ms=spec.ms, **kw)
    return tune_pd(spec.G, S, spec.architecture, ms=spec.ms, derivative_filter=PD_FILTER / spec.mode.omega, **kw)


def _case(label: str, loop: Loop, shaped: bool, t: np.ndarray, w: np.ndarray) -> LoopCase:
    st = loop.stability()
    try:
        absc = float(loop.spectral_abscissa())
    except ValueError:
        absc = math.nan
    if not st.stable:
        return LoopCase(label, loop, st, absc, None, shaped, "not simulated: not stable")
    try:
        resp = simulate(loop, t, w=w)
    except ValueError as exc:  # a loop the simulator cannot run (e.g. a rational block with a delay)
        return LoopCase(label, loop, st, absc, None, shaped, f"not simulated: {exc}")
    return LoopCase(label, loop, st, absc, resp, shaped)


def analyse_plant(spec: PlantSpec) -> PlantAnalysis:
    """Design the shaper, tune the controller with it, certify the loops with and without it, simulate steps.

    ``spec`` comes from :func:`~posicast.report.plantfile.load_plant` or :func:`~posicast.report.plantfile.plant_spec`.
    """
    v.instance_of(spec, PlantSpec, "spec", "a PlantSpec (from load_plant or plant_spec)")
    S = design(spec.shaper, spec.mode, **dict(spec.shaper_params))
    period = 2.0 * math.pi / spec.mode.omega
    dt = period / STEPS_PER_PERIOD
    t = np.arange(0.0, spec.horizon, dt)
    step_at = min(period, 0.05 * spec.horizon)
    w = (t >= step_at).astype(float)
    F = spec.F if spec.has_load else None
    tuned = _tune(spec, S)
    cases = []
    if spec.C is not None:
        cases.append(_case("your controller, no shaper", Loop(spec.architecture, G=spec.G, C=spec.C, F=F), False, t, w))
        cases.append(_case(f"your controller + {spec.shaper}", Loop(spec.architecture, G=spec.G, C=spec.C, F=F, S=S),
                           True, t, w))
    name = spec.controller.upper()
    if tuned.loop is not None and tuned.controller is not None:
        cases.append(_case(f"tuned {name}, shaper removed", Loop(spec.architecture, G=spec.G, C=tuned.controller, F=F),
                           False, t, w))
        cases.append(_case(f"tuned {name} + {spec.shaper}", tuned.loop, True, t, w))
    return PlantAnalysis(spec, S, tuned, tuple(cases), t, step_at)


def plant_file_text(spec: PlantSpec) -> str:
    """The plant file as JSON text (what the page shows): one line per key."""
    return "{\n" + ",\n".join(f"  {json.dumps(k)}: {json.dumps(val, ensure_ascii=False)}"
                              for k, val in spec.source.items()) + "\n}"


def plant_part(page: Page, a: PlantAnalysis, path: str, about: str = "") -> None:
    """Add the part "Your plant → your loop" for the analysis ``a`` of the plant file ``path`` to ``page``."""
    spec = a.spec
    page.part(TITLE, (about + " " if about else "") +
              f"<b>{html.escape(spec.name)}</b>: the shaper {html.escape(spec.shaper)} for the mode "
              f"ω = {spec.mode.omega:.4g} rad/s ({spec.mode.freq_hz:.4g} Hz), ζ = {spec.mode.zeta:.4g} (from "
              f"{html.escape(spec.mode_source)}), {1e3 * a.S.duration:.4g} ms long, in the "
              f"{spec.architecture.replace('_', ' ')} architecture.")
    page.code(plant_file_text(spec), f"The plant file <code>{html.escape(path)}</code> (format: README, "
              "\"A report for your own data\"):", language="json")
    page.code(f"posicast report {path} --out report", "The command that writes this part for your file:",
              command="report")
    _verdicts(page, a)
    _tuning(page, a, path)
    _responses(page, a)


def _verdicts(page: Page, a: PlantAnalysis) -> None:
    page.section("Certified stability")
    rows = [[c.label, "stable" if c.stability.stable else ("marginal" if c.stability.marginal else "UNSTABLE"),
             c.abscissa, c.stability.reason] for c in a.cases]
    page.paragraph("Each verdict counts every closed-loop root with Re s ≥ 0 by the argument principle on a "
                   "certified contour (delays exact, no Padé); the spectral abscissa is the decay rate of the "
                   "slowest closed-loop mode (negative: stable).")
    page.table(["loop", "verdict", "spectral abscissa [1/s]", "reason"], rows)
    spec = a.spec
    args = _loop_args(spec)
    page.code("import posicast as pc\n"
              f"S = pc.design({spec.shaper!r}, pc.Mode({spec.mode.omega:.6g}, {spec.mode.zeta:.6g})"
              + "".join(f", {k}={val!r}" for k, val in spec.shaper_params.items()) + ")\n"
              f"loop = pc.Loop({spec.architecture!r}, {args}, S=S)\n"
              "st = loop.stability()\n"
              "print(st.stable, st.reason, loop.spectral_abscissa())", "Python:", language="python")


def _poly(spec: PlantSpec, key: str) -> str:
    """Python for the block ``key`` of the plant file."""
    b = spec.source.get(key, {})
    if b.get("delay"):
        return f"pc.TransferFunction.from_poly({b.get('num')!r}, {b.get('den')!r}, {b['delay']!r})"
    return f"pc.as_transfer(({b.get('num')!r}, {b.get('den')!r}))"


def _loop_args(spec: PlantSpec) -> str:
    out = f"G={_poly(spec, 'plant')}, C={_poly(spec, 'controller') if spec.C is not None else 'C'}"
    return out + (f", F={_poly(spec, 'load')}" if spec.has_load else "")


def _tuning(page: Page, a: PlantAnalysis, path: str) -> None:
    spec = a.spec
    name = spec.controller.upper()
    page.section(f"Tuned {name}")
    page.paragraph(f"The robust {name} of seed 001's method: the H∞ regions |S| < {spec.ms:g} in the gain plane, "
                   "intersected with the certified stability region, then the largest "
                   + ("integral gain" if spec.controller == "pi" else "proportional gain")
                   + (f" (derivative filter {PD_FILTER:g}/ω)" if spec.controller == "pd" else "")
                   + f", with the shaper {spec.shaper} in the loop. The stability and step response of the same "
                   "gains with the shaper removed are in the tables around this one.")
    r = a.tuned
    g = r.gains or {}
    page.table(["shaper", "Kp", "Ki" if spec.controller == "pi" else "Kd", "achieved Ms", "certified stable",
                "why this point"],
               [[spec.shaper, g.get("kp", math.nan), g.get("ki" if spec.controller == "pi" else "kd", math.nan),
                 r.ms, "yes" if r.stable else "no", r.reason]])
    fn = "tune_pi" if spec.controller == "pi" else "tune_pd"
    extra = "" if spec.controller == "pi" else f", derivative_filter={PD_FILTER / spec.mode.omega:.4g}"
    load = ", F=F" if spec.has_load else ""
    page.code(f"G = {_poly(spec, 'plant')}\n" + (f"F = {_poly(spec, 'load')}\n" if spec.has_load else "")
              + f"r = pc.{fn}(G, S, {spec.architecture!r}, ms={spec.ms:g}{extra}{load})\n"
              "print(r.summary())\nr.plot(); r.nyquist_plot()",
              "Python (<code>posicast tune --num ... --den ... --controller "
              f"{spec.controller} --shaper {html.escape(spec.shaper)} --ms {spec.ms:g}</code> on the command line):",
              language="python")


def _responses(page: Page, a: PlantAnalysis) -> None:
    spec = a.spec
    page.section("Step response with and without the shaper")
    shown = [c for c in a.cases if c.response is not None]
    if shown:
        _response_figure(page, a, shown)
    else:
        page.note("No loop simulated (the table says why).")
    rows = []
    after = a.step_at + 0.5 * (a.t[-1] - a.step_at)
    for c in a.cases:
        r = c.response
        if r is None:
            rows.append([c.label, math.nan, math.nan, math.nan, math.nan, c.note])
            continue
        rows.append([c.label, r.overshoot("y", start=a.step_at), r.settling_time("y", start=a.step_at),
                     r.residual_vibration(after=after), r.peak("u"), c.note])
    page.table(["loop", "overshoot of y [%]", "2 % settling time [s]", f"|y − y(end)| after {after:.3g} s",
                "peak |u|", "note"], rows)
    page.code(f"import numpy as np\nt = np.arange(0.0, {spec.horizon:.4g}, {a.t[1] - a.t[0]:.4g})\n"
              f"resp = pc.simulate(loop, t, w=(t >= {a.step_at:.4g}).astype(float))\n"
              "print(resp.overshoot(\"y\"), resp.settling_time(\"y\"))\nresp.plot()", "Python:", language="python")


def _response_figure(page: Page, a: PlantAnalysis, shown: list[LoopCase]) -> None:
    spec = a.spec
    fig, axes = plt.subplots(2, 1, sharex=True, figsize=(9, 5.2))
    for c in shown:
        r = c.response
        assert r is not None
        ls = "-" if c.shaped else "--"
        axes[0].plot(r.time, r.signals["y"], ls, lw=1.2, label=c.label)
        axes[1].plot(r.time, r.signals["u"], ls, lw=1.0, label=c.label)
    axes[0].plot(a.t, (a.t >= a.step_at).astype(float), color="0.6", lw=0.8, label="set-point")
    axes[0].set_ylabel("y (load)" if spec.has_load else "y")
    axes[1].set_ylabel("u (control)")
    axes[1].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    page.figure(fig, "step_response", f"Set-point step at t = {a.step_at:.3g} s: the output (top) and the control "
                "signal (bottom); solid with the shaper, dashed without. Unstable loops are not simulated (see the "
                "table's notes).")
