"""The design tab: mode(s) and a shaper family in, impulses, sensitivity, sampled taps and exports out.

One mode is ``design(kind, mode, **params)``; several modes are one design over all of them
for the kinds that take several (``si``, and the z-plane designs), otherwise the convolution
of the per-mode designs (``S1 * S2``), the usual multi-mode shaper.  With a sample rate the
taps are the z-plane design ``design(kind, modes, sample_period=1/fs)`` (seed 002 eq. 8) for
the kinds that have one (zv, zvd, zvdd, zvddd, zvdk) and the continuous design discretised
(:func:`~posicast.simulation.streaming.discretize`) for the others; the export is
:func:`posicast.export_shaper` of those taps.
"""

from __future__ import annotations

import json
import math
import re
from typing import Any, Mapping

import numpy as np

from .. import _validate as v
from ..analysis import impulse_plot, insensitivity, residual_vibration
from ..io import export_shaper
from ..modes import Mode
from ..shapers import KINDS, Shaper, design
from ..shapers.sampled import SAMPLED_KINDS
from ..simulation.streaming import discretize
from . import forms
from .figures import COLOURS, svg_figure

__all__ = ["MAX_IMPULSES", "MAX_ROWS", "MAX_SPAN", "kinds_view", "design_view", "export_view"]

#: Most impulses a design typed into the page may have (``k``, ``n``, ``n m``); the library allows 1e5.
MAX_IMPULSES = 2000
#: Most samples a discretised shaper may span (duration x sample rate).
MAX_SPAN = 1e6
#: Rows of a table sent to the page (the export holds every tap).
MAX_ROWS = 400
_INTEGER_PARAMS = ("k", "n", "m", "max_impulses")
_PAIR_PARAMS = ("band", "damping")


def kinds_view() -> dict[str, Any]:
    """Every shaper kind with its parameters and their defaults (for the page's menus)."""
    return {"kinds": [{"kind": k, "summary": s.summary, "params": {p: (list(d) if isinstance(d, tuple) else d)
                                                                   for p, d in s.params.items()},
                       "multi_mode": s.multi_mode, "sampled": k in SAMPLED_KINDS} for k, s in KINDS.items()]}


def _modes(form: Mapping[str, Any]) -> list[Mode]:
    items = v.sequence(form.get("modes"), "modes", min_len=1)
    if len(items) > forms.MAX_MODES:
        raise ValueError(f"modes: at most {forms.MAX_MODES} modes, got {len(items)}")
    out = []
    for k, it in enumerate(items, 1):
        if not isinstance(it, Mapping):
            raise TypeError(f"modes[{k}] must be an object with freq_hz and zeta")
        tag = "" if len(items) == 1 else f" (mode {k})"
        out.append(Mode.from_hz(v.positive(forms.number(it, "freq_hz", "freq_hz" + tag), "freq_hz" + tag),
                                forms.number(it, "zeta", "zeta" + tag)))
    return out


def _params(kind: str, form: Mapping[str, Any]) -> dict[str, Any]:
    """The kind's parameters typed into the page (empty fields keep the library's defaults)."""
    given = form.get("params") or {}
    if not isinstance(given, Mapping):
        raise TypeError("params must be an object")
    out: dict[str, Any] = {}
    for name in KINDS[kind].params:
        text = forms.text_field(given, name)
        if text == "" or text.lower() in ("auto", "default"):
            continue
        if name == "method":
            out[name] = text
        elif name in _PAIR_PARAMS:
            out[name] = tuple(forms.coefficients(text, name))
        elif name in _INTEGER_PARAMS:
            x = forms.number(given, name)
            if x != int(x):
                raise ValueError(f"{name} must be an integer, got {text}")
            out[name] = int(x)
        else:
            out[name] = forms.number(given, name)
    size = (out.get("k", 1) + 2) if kind == "zvdk" else out.get("n", 3) * (out.get("m", 1) if kind == "mis_zvd" else 1)
    if size > MAX_IMPULSES or out.get("max_impulses", 0) > MAX_IMPULSES:
        raise ValueError(f"{kind}: the designer builds shapers of at most {MAX_IMPULSES} impulses; "
                         "use the Python API for more")
    return out


def _design(kind: str, modes: list[Mode], params: dict[str, Any], **extra: Any) -> Shaper:
    if len(modes) == 1:
        return design(kind, modes[0], **params, **extra)
    if KINDS[kind].multi_mode or extra:
        return design(kind, modes, **params, **extra)
    S = design(kind, modes[0], **params)
    for m in modes[1:]:
        S = S * design(kind, m, **params)
    return S


class _Designed:
    """The page's design: the continuous shaper and, with a sample rate, its taps."""

    def __init__(self, form: Mapping[str, Any]) -> None:
        kind = forms.text_field(form, "kind", "zvd").lower()
        self.kind, self.modes = kind, _modes(form)
        if kind not in KINDS:
            design(kind, self.modes[0])  # raises the library's message (the kinds it knows)
        self.params = _params(kind, form)
        self.S = _design(kind, self.modes, self.params)
        # an IIR part never ends: its vibration is measured against the unshaped response (analysis.vibration)
        self.reference = "unshaped" if self.S.continuous is not None else "end"
        fs = forms.optional_number(form, "sample_rate", "sample_rate")
        self.sample_rate = None if fs is None else v.positive(fs, "sample_rate")
        self.sampled: Shaper | None = None
        self.method = ""
        if self.sample_rate is not None:
            if kind in SAMPLED_KINDS:
                k = {"k": self.params["k"]} if "k" in self.params else {}
                self.sampled = _design(kind, self.modes, k, sample_period=1.0 / self.sample_rate)
                self.method = "z-plane design at the sample period (seed 002 eq. 8)"
            else:
                self.method = "continuous design discretised (fractional delays split linearly)"


def _taps(d: _Designed) -> dict[str, Any]:
    """The taps at the sample rate: index, time, weight (first :data:`MAX_ROWS`)."""
    fs = d.sample_rate
    assert fs is not None
    if d.sampled is not None:
        T, A = d.sampled.impulses
        idx = np.rint(T * fs).astype(int)
        w = A
        iir = False
    else:
        T = d.S.impulses[0]  # an IIR part (notch) lasts forever: its taps are the lumped part, the rest is (b, a)
        span = (d.S.duration if math.isfinite(d.S.duration) else float(T.max(initial=0.0))) * fs
        if span > MAX_SPAN:
            raise ValueError(f"sample_rate {fs:g} Hz spreads the {d.S.name} shaper over {span:.3g} samples; "
                             f"the designer handles at most {MAX_SPAN:g} (lower the sample rate)")
        D = discretize(d.S, fs)
        idx = np.flatnonzero(D.taps)
        w = D.taps[idx]
        iir = D.b is not None
    rows = [[int(i), float(i) / fs, float(x)] for i, x in zip(idx[:MAX_ROWS], w[:MAX_ROWS])]
    vib: list[float] = []
    if not iir and idx.size <= MAX_IMPULSES:  # a dense kernel's thousands of taps: the table says enough
        taps = d.sampled if d.sampled is not None else _discrete_shaper(idx, w, fs, d)
        vib = [float(residual_vibration(taps, m.omega, m.zeta)) for m in d.modes]
    return {"sample_rate": fs, "method": d.method, "rows": rows, "n_taps": int(idx.size),
            "more": max(0, int(idx.size) - MAX_ROWS), "sum": float(np.sum(w)), "iir": iir,
            "residual_vibration": vib}


def _discrete_shaper(idx: np.ndarray, w: np.ndarray, fs: float, d: _Designed) -> Shaper:
    """The discretised taps as a lumped shaper (to evaluate what the controller really runs)."""
    return Shaper(idx / fs, w, name=f"{d.kind} @ {fs:g} Hz", modes=tuple(d.modes))


def design_view(form: Mapping[str, Any]) -> dict[str, Any]:
    """Fields: ``kind``, ``modes`` (``[{"freq_hz", "zeta"}, ...]``), ``params`` (the kind's), ``vtol``
    (insensitivity level, default 0.05), ``sample_rate`` (optional, Hz)."""
    d = _Designed(form)
    vtol = v.in_open_interval(forms.number(form, "vtol", "vtol", 0.05), "vtol", 0.0, 1.0)
    T, A = d.S.impulses
    out: dict[str, Any] = {
        "name": d.S.name, "kind": d.kind, "duration": d.S.duration, "n_impulses": int(T.size),
        "impulses": [[float(t), float(a)] for t, a in zip(T[:MAX_ROWS], A[:MAX_ROWS])],
        "more": max(0, int(T.size) - MAX_ROWS),
        "distributed": bool(d.S.distributed), "iir": d.S.continuous is not None,
        "insensitivity": [], "taps": None, "plots": {}}
    if d.S.distributed or d.S.continuous is not None:
        out["note"] = ("this shaper also has a distributed (kernel) part" if d.S.distributed else
                       "this shaper also has an IIR part") + ": see the impulse plot"
    for m in d.modes:
        ins = insensitivity(d.S, vtol, mode=m, reference=d.reference)
        out["insensitivity"].append({"freq_hz": m.freq_hz, "zeta": m.zeta, "width": ins.width, "low": ins.low,
                                     "high": ins.high, "vtol": vtol, "at_limit": bool(ins.at_limit),
                                     "residual": float(residual_vibration(d.S, m.omega, m.zeta, d.reference))})
    if d.sample_rate is not None:
        out["taps"] = _taps(d)
    _plots(out["plots"], d, vtol, out["insensitivity"])
    return out


def _plots(plots: dict[str, Any], d: _Designed, vtol: float, bands: list[dict[str, Any]]) -> None:
    fmax = 2.0 * max(m.freq_hz for m in d.modes)
    f = np.linspace(fmax / 800, fmax, 800)
    with svg_figure(plots, "sensitivity") as (fig, ax):
        for k, (m, b) in enumerate(zip(d.modes, bands)):
            c = COLOURS[k % len(COLOURS)]
            V = residual_vibration(d.S, 2 * math.pi * f, m.zeta, d.reference)
            ax.plot(f, 100 * np.asarray(V), color=c, lw=1.6, label=f"{d.S.name}, ζ = {m.zeta:.3g}")
            if d.sampled is not None:
                Vs = residual_vibration(d.sampled, 2 * math.pi * f, m.zeta)
                ax.plot(f, 100 * np.asarray(Vs), color=c, lw=1.0, ls="--",
                        label=f"taps at {d.sample_rate:g} Hz")
            if b["width"] > 0:
                ax.axvspan(b["low"] * m.freq_hz, b["high"] * m.freq_hz, color=c, alpha=0.12,
                           label=f"V ≤ {100 * vtol:g} %: {b['low'] * m.freq_hz:.1f}–{b['high'] * m.freq_hz:.1f} Hz "
                                 f"(I = {b['width']:.3f})")
            ax.axvline(m.freq_hz, color=c, lw=0.7, ls=":")
        ax.axhline(100 * vtol, color="0.3", lw=0.8, ls="--")
        ax.set_xlim(0, fmax)
        ax.set_ylim(0, 105)
        ax.set_xlabel("mode frequency [Hz]")
        ax.set_ylabel("residual vibration [%]")
        ax.set_title("sensitivity and insensitivity band")
        ax.legend(loc="upper right")
    with svg_figure(plots, "impulses", height=2.8) as (fig, ax):
        impulse_plot(d.S, ax=ax)
        ax.set_xlabel("time [s]")
        ax.set_ylabel("amplitude")
        ax.set_title(f"{d.S.name}: {d.S.n_impulses} impulses over {1000 * d.S.duration:.2f} ms")


_C_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def export_view(form: Mapping[str, Any]) -> tuple[str, str, str]:
    """The export of the page's design at its sample rate: ``(file name, text, media type)``.

    Extra fields: ``format`` (``c`` or ``json``), ``form`` (``sparse`` or ``dense``), ``name``
    (C identifier), ``inverse`` (bool).
    """
    d = _Designed(form)
    if d.sample_rate is None:
        raise ValueError("sample_rate is required for an export (the controller's rate, Hz)")
    fmt = v.choice(forms.text_field(form, "format", "c"), "format", ("c", "json"))
    layout = v.choice(forms.text_field(form, "form", "sparse"), "form", ("sparse", "dense"))
    name = forms.text_field(form, "name", "shaper") or "shaper"
    inverse = form.get("inverse", False)
    v.instance_of(inverse, bool, "inverse", "true or false")
    S = d.sampled if d.sampled is not None else d.S
    text = export_shaper(S, d.sample_rate, fmt, name=name, form=layout, inverse=inverse)
    # the file is named by the C name the user chose; left at "shaper", it says what it holds (kind, rate), and
    # an inverse never takes the forward shaper's name
    stem = name if _C_NAME.match(name) and name != "shaper" else f"shaper_{d.kind}_{d.sample_rate:g}Hz"
    stem = re.sub(r"[^A-Za-z0-9_-]", "_", stem) + ("_inverse" if inverse else "")
    if fmt == "json":
        json.loads(text)  # the export is JSON: a broken one is a bug, not a download
        return f"{stem}.json", text, "application/json"
    return f"{stem}.h", text, "text/x-c"
