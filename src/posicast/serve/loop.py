"""The loop tab: plant, controller and shaper in, a certified verdict, the spectrum and responses out.

The page's fields become a :class:`~posicast.Loop` of the chosen architecture
(``G = num/den e^{-s delay}``, ``C``, an optional flexible load ``F`` and an optional shaper
designed for a mode); the verdict is :func:`posicast.stability` (certified), the spectrum
:meth:`Loop.poles` in a rectangle drawn by :func:`~posicast.loops.plots.spectrum_plot`, the
responses :func:`posicast.simulate` (reference step and load step at the plant input), and
the tuning :func:`posicast.tune_pd` / :func:`posicast.tune_pi` (seed 001).
"""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from .. import _validate as v
from ..core import TransferFunction, as_transfer, delay
from ..loops import Loop
from ..loops.architectures import ARCHITECTURES
from ..loops.plots import spectrum_plot
from ..modes import Mode
from ..shapers import KINDS, Shaper, design
from ..simulation import simulate
from ..spectra import stability
from ..tune import tune_pd, tune_pi
from . import forms
from .figures import svg_figure

__all__ = ["MAX_POINTS", "LoopForm", "loop_view", "tune_view"]

#: Samples of each simulated response.
MAX_POINTS = 1500
_ROOT_TIMEOUT = 20.0  # s: a rectangle the root finder cannot certify in this time is refused with its message


def _block(form: Mapping[str, Any], key: str, label: str, optional: bool = False) -> tuple[Any, list[float] | None]:
    """``(transfer function or None, denominator coefficients)`` of block ``key`` (num, den, delay)."""
    num_t, den_t = forms.text_field(form, f"{key}_num"), forms.text_field(form, f"{key}_den")
    if optional and not num_t and not den_t:
        return None, None
    num = forms.coefficients(num_t, f"{label} numerator")
    den = forms.coefficients(den_t or "1", f"{label} denominator")
    tf = as_transfer((num, den), f"the {label} (num, den)")
    tau = forms.number(form, f"{key}_delay", f"{label} delay", 0.0)
    if tau != 0.0:
        tf = tf * delay(v.nonnegative(tau, f"{label} delay", " [s]"))
    return tf, den


class LoopForm:
    """The loop tab's fields, read and checked (no computation).

    Attributes
    ----------
    G, C, F : TransferFunction (F may be None)
    S : Shaper or None
    mode : Mode or None
    architecture : str
    scale : float
        A frequency scale of the loop [rad/s] (largest pole of G, C, F, the mode; at least 1).
    """

    def __init__(self, form: Mapping[str, Any], controller: bool = True) -> None:
        self.architecture = v.choice(forms.text_field(form, "architecture", "control_action"), "architecture",
                                     tuple(ARCHITECTURES))
        self.G, g_den = _block(form, "G", "plant")
        self.C, c_den = _block(form, "C", "controller") if controller else (None, None)
        self.F, f_den = _block(form, "F", "load F", optional=True)
        kind = forms.text_field(form, "shaper", "none").lower()
        self.S: Shaper | None = None
        self.mode: Mode | None = None
        if kind not in ("", "none"):
            kind = v.choice(kind, "shaper", tuple(KINDS))
            f = v.positive(forms.number(form, "freq_hz", "shaper freq_hz"), "shaper freq_hz")
            self.mode = Mode.from_hz(f, forms.number(form, "zeta", "shaper zeta"))
            self.S = design(kind, self.mode)
        poles = [abs(r) for d in (g_den, c_den, f_den) if d is not None and len(d) > 1 for r in np.roots(d)]
        self.scale = max([1.0] + [p for p in poles if math.isfinite(p)] + ([self.mode.omega] if self.mode else []))
        self.region_text = forms.text_field(form, "region", "auto")
        self.t_end = forms.optional_number(form, "t_end", "t_end")
        if self.t_end is not None:
            v.real_in_range(self.t_end, "t_end", 1e-6, 1e6)

    def loop(self, C: TransferFunction | None = None) -> Loop:
        return Loop(self.architecture, G=self.G, C=self.C if C is None else C, F=self.F, S=self.S)

    def region(self, unstable: np.ndarray) -> tuple[float, float, float, float]:
        """The rectangle searched for poles: typed, or ``[-2w, 0.3w] x [-3w, 3w]`` with ``w`` the loop's
        frequency scale, widened to hold every root right of the axis."""
        if self.region_text.lower() not in ("", "auto"):
            vals = forms.coefficients(self.region_text, "region")
            if len(vals) != 4 or not (vals[0] < vals[1] and vals[2] < vals[3]):
                raise ValueError(f"region must be 're_min re_max im_min im_max' with min < max, got "
                                 f"{self.region_text!r}")
            return (vals[0], vals[1], vals[2], vals[3])
        w = self.scale
        re_hi, im = 0.3 * w, 3.0 * w
        if unstable.size:
            re_hi = max(re_hi, 1.2 * float(unstable.real.max()) + 0.05 * w)
            im = max(im, 1.2 * float(np.abs(unstable.imag).max()))
        return (-2.0 * w, re_hi, -im, im)


def _fmt_root(z: complex) -> str:
    return f"{z.real:.4g} {'+' if z.imag >= 0 else '-'} {abs(z.imag):.4g}j"


def _fmt_pairs(roots: np.ndarray, n: int) -> list[str]:
    """The first ``n`` roots (by decreasing real part) with a conjugate pair written once, ``a ± bj``."""
    out: list[str] = []
    for z in roots:
        if z.imag < 0 and np.any(np.isclose(roots, np.conj(z), rtol=1e-9, atol=1e-12)):
            continue  # its conjugate is written as a pair
        out.append(f"{z.real:.4g} ± {abs(z.imag):.4g}j" if z.imag > 0 else f"{z.real:.4g}")
        if len(out) == n:
            break
    return out


def loop_view(form: Mapping[str, Any]) -> dict[str, Any]:
    """Fields: ``G_num``, ``G_den``, ``G_delay``, ``C_num``, ``C_den``, ``C_delay``, ``F_num``, ``F_den``
    (optional), ``shaper`` (a kind or ``none``), ``freq_hz``, ``zeta``, ``architecture``, ``region``
    (``auto`` or four numbers), ``t_end`` (``auto`` or seconds)."""
    lf = LoopForm(form)
    loop = lf.loop()
    st = stability(loop)
    region = lf.region(np.asarray(st.unstable_roots))
    poles = np.asarray(loop.poles(region, timeout=_ROOT_TIMEOUT).roots)
    poles = poles[np.argsort(-poles.real)] if poles.size else poles
    plots: dict[str, Any] = {}
    with svg_figure(plots, "spectrum", width=4.4, height=4.4) as (fig, ax):
        spectrum_plot(loop, region, ax=ax)
        if poles.size and lf.region_text.lower() in ("", "auto"):  # zoom on the poles found (the search stays)
            lo = 1.25 * min(float(poles.real.min()), -0.05 * lf.scale)
            ax.set_xlim(lo, min(region[1], max(-0.15 * lo, 1.25 * float(poles.real.max()))))
        ax.set_xlabel("Re s [1/s]")
        ax.set_ylabel("Im s [rad/s]")
        ax.set_title("closed-loop poles and shaper zeros")
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.14), fontsize=8)
    out: dict[str, Any] = {
        "verdict": {"stable": bool(st.stable), "marginal": bool(st.marginal), "kind": st.kind, "reason": st.reason,
                    "unstable_roots": [_fmt_root(z) for z in st.unstable_roots]},
        "loop": loop.label, "region": list(region), "poles": _fmt_pairs(poles, 8),
        "n_poles": int(poles.size), "plots": plots, "responses_error": None, "metrics": {}}
    decay = -float(poles.real.max()) if poles.size else math.nan  # < 0: the loop grows
    t_end = lf.t_end or _auto_t_end(decay, lf)
    try:
        _responses(out, loop, t_end)
    except ValueError as exc:  # e.g. an improper controller: the verdict stands, the responses cannot be run
        msg = str(exc).splitlines()[0]
        if "internal rate" in msg or "internal steps" in msg:  # the page's knob is the time span, not t or substeps
            msg += (f" (the page simulates {MAX_POINTS} points up to 'Simulate until' = {t_end:.4g} s: "
                    "a shorter time gives a finer step and fewer steps)")
        out["responses_error"] = msg
    return out


def _auto_t_end(decay: float, lf: LoopForm) -> float:
    """About seven time constants of the slowest pole found, or ten of the fastest growing one (bounded),
    at least three times the shaper."""
    if not math.isfinite(decay) or decay == 0.0:
        t = 20.0 / lf.scale
    else:
        t = 7.0 / decay if decay > 0 else 10.0 / -decay
    if lf.S is not None and math.isfinite(lf.S.duration):  # an IIR shaper (notch) lasts forever
        t = max(t, 3.0 * lf.S.duration)
    return float(min(max(t, 1e-3), 1e4))


def _responses(out: dict[str, Any], loop: Loop, t_end: float) -> None:
    t = np.linspace(0.0, t_end, MAX_POINTS)
    one = np.ones_like(t)
    step = simulate(loop, t, w=one, outputs=("z", "y", "u"))
    load = simulate(loop, t, di=one, outputs=("z", "y", "u"))
    m: dict[str, Any] = {"t_end": t_end, "mode": step.mode}
    for name, r in (("step", step), ("load", load)):
        if r.diverged is not None:
            m[f"{name}_diverged"] = f"{r.diverged_signal} diverged at t = {r.diverged:.4g} s"
    m["step_peak"] = float(np.max(np.abs(step.y)))
    if step.diverged is None:
        m["overshoot_percent"] = float(step.overshoot("y"))  # already in %
        m["settling_time"] = float(step.settling_time("y"))
    if load.diverged is None:
        m["load_peak"] = float(np.max(np.abs(load.y)))
    out["metrics"] = {k: (None if isinstance(x, float) and not math.isfinite(x) else x) for k, x in m.items()}
    same = np.allclose(step.z, step.y) if step.z.shape == step.y.shape else False
    for key, r, title in (("step", step, "reference step w = 1"), ("load", load, "load step at the plant input")):
        with svg_figure(out["plots"], key, width=4.4, height=3.4) as (fig, ax):
            if key == "step":
                ax.plot(r.time, np.ones_like(r.time), color="0.5", lw=0.8, ls="--", label="w")
            ax.plot(r.time, r.y, lw=1.5, label="y (load)")
            if not same:
                ax.plot(r.time, r.z, lw=1.0, label="z (actuator side)")
            ax.set_xlabel("time [s]")
            ax.set_ylabel("output")
            ax.set_title(title)
            ax.legend(loc="best")


def tune_view(form: Mapping[str, Any]) -> dict[str, Any]:
    """A robust PD or PI for the page's plant and shaper (seed 001): ``controller`` (``pd``/``pi``), ``ms``
    (peak sensitivity bound, default 2), ``derivative_filter`` (PD's ``Tf``, default none)."""
    lf = LoopForm(form, controller=False)
    kind = v.choice(forms.text_field(form, "controller", "pd"), "controller", ("pd", "pi"))
    ms = forms.number(form, "ms", "ms", 2.0)
    tf = forms.optional_number(form, "derivative_filter", "derivative_filter")
    if kind == "pd":
        r = tune_pd(lf.G, lf.S, lf.architecture, ms=ms, F=lf.F, derivative_filter=tf)
    else:
        if tf is not None:
            raise ValueError("derivative_filter applies to a pd controller only")
        r = tune_pi(lf.G, lf.S, lf.architecture, ms=ms, F=lf.F)
    out: dict[str, Any] = {"summary": r.summary(), "reason": r.reason, "gains": None, "C_num": None, "C_den": None,
                           "ms": None if not math.isfinite(r.ms) else float(r.ms), "stable": bool(r.stable),
                           "seconds": float(sum(r.timings.values()))}
    if r.gains is not None:
        g = {k: float(x) for k, x in r.gains.items()}
        out["gains"] = g
        if kind == "pi":  # C = kp + ki / s
            num, den = [g["kp"], g["ki"]], [1.0, 0.0]
        elif tf:  # C = kp + kd s / (tf s + 1)
            num, den = [g["kp"] * tf + g["kd"], g["kp"]], [tf, 1.0]
        else:  # C = kp + kd s
            num, den = [g["kd"], g["kp"]], [1.0]
        out["C_num"] = " ".join(f"{x:.10g}" for x in num)
        out["C_den"] = " ".join(f"{x:.10g}" for x in den)
    return out
