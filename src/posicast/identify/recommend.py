"""From identified modes to a recommended shaper and firmware configuration lines.

Every lumped shaper family of ``posicast.design`` is designed for the dominant
mode and, when there are several modes, convolved over all of them; each
candidate is scored by its **worst-case residual vibration** over every mode's
95 % box (frequency interval widened by ``margin``, damping interval), weighted
by the mode's share of the response, by its duration, and by Klipper's
smoothing measure (shaper_calibrate.py: positional offset at 5000 mm/s^2,
square corner velocity 5 mm/s).  The shortest (least smoothing) candidate
within ``vtol`` wins; if none is within ``vtol``, the most robust one.

Config lines: Klipper ``[input_shaper]`` (types zv, mzv, zvd, ei, 2hump_ei,
3hump_ei; Klipper designs these itself from ``shaper_freq`` and
``damping_ratio``) and RepRapFirmware ``M593`` (types mzv, zvd, zvdd, zvddd,
ei2, ei3, else ``P"custom"`` with cumulative amplitudes ``H`` and impulse
intervals ``T``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import _validate as v
from ..analysis import residual_vibration
from ..modes import Mode
from ..shapers import Shaper, design
from .data import load_csv
from .estimators import Identification, Interval, identify

__all__ = ["Candidate", "Calibration", "calibrate", "recommend", "klipper_smoothing", "config_lines"]

FAMILIES: list[tuple[str, str, dict[str, Any]]] = [
    ("ZV", "zv", {}), ("MZV", "mzv", {}), ("ZVD", "zvd", {}), ("ZVDD", "zvdd", {}), ("ZVDDD", "zvddd", {}),
    ("EI", "ei", {"vtol": 0.05}), ("2-hump EI", "ei2", {"vtol": 0.05}), ("3-hump EI", "ei3", {"vtol": 0.05}),
]
KLIPPER = {"zv": "zv", "mzv": "mzv", "zvd": "zvd", "ei": "ei", "ei2": "2hump_ei", "ei3": "3hump_ei"}
RRF = {"mzv": "mzv", "zvd": "zvd", "zvdd": "zvdd", "zvddd": "zvddd", "ei2": "ei2", "ei3": "ei3"}


def klipper_smoothing(shaper: Shaper, accel: float = 5000.0, scv: float = 5.0) -> float:
    """Klipper's smoothing of an impulse shaper (mm): max offset of a 90 / 180 degree turn.

    Follows ``_get_shaper_smoothing`` of Klipper's shaper_calibrate.py.

    Examples
    --------
    >>> from posicast import Mode, design
    >>> a = klipper_smoothing(design("zv", Mode.from_hz(50, 0.1)))
    >>> b = klipper_smoothing(design("zvd", Mode.from_hz(50, 0.1)))
    >>> 0 < a < b
    True
    """
    T, A = shaper.impulses
    if shaper.distributed or shaper.continuous is not None:
        return float("nan")
    half = 0.5 * accel
    inv = 1.0 / float(np.sum(A))
    ts = float(np.sum(A * T)) * inv
    d = T - ts
    o90 = float(np.sum(np.where(T >= ts, A * (scv + half * d) * d, 0.0))) * inv * math.sqrt(2.0)
    o180 = float(np.sum(A * half * d * d)) * inv
    return max(o90, o180)


@dataclass
class Candidate:
    """One scored shaper."""

    label: str
    kind: str
    shaper: Shaper
    worst_vibration: float
    duration: float
    smoothing: float
    per_mode: list[float]


@dataclass
class Calibration:
    """Result of :func:`calibrate` / :func:`recommend`.

    Attributes
    ----------
    modes, intervals : identified modes and their 95 % intervals
    recommended : Shaper
    config : list of str
        Klipper and RepRapFirmware lines.
    candidates : list of Candidate, best first
    reasoning : list of str
    identification : Identification
    """

    modes: list[Mode]
    intervals: list[Interval]
    recommended: Shaper
    config: list[str]
    candidates: list[Candidate]
    reasoning: list[str]
    identification: Identification | None = None
    label: str = ""
    notes: list[str] = field(default_factory=list)

    def summary(self) -> str:
        out = []
        if self.identification is not None:
            out.append(self.identification.summary())
        out.append(f"recommended: {self.label}, duration {self.recommended.duration * 1000:.2f} ms")
        out += ["  " + r for r in self.reasoning]
        out += self.config
        return "\n".join(out)


def _box(iv: Interval, margin: float, n_w: int = 21, n_z: int = 5) -> tuple[np.ndarray, np.ndarray]:
    w = np.linspace(iv.omega[0] * (1 - margin), iv.omega[1] * (1 + margin), n_w)
    z = np.linspace(max(iv.zeta[0], 0.0), min(iv.zeta[1], 0.95), n_z)
    return w, z


def _score(S: Shaper, boxes: list[tuple[np.ndarray, np.ndarray]], weights: np.ndarray) -> list[float]:
    out = []
    for (w, zs), wk in zip(boxes, weights):
        vmax = max(float(np.max(residual_vibration(S, w, float(z)))) for z in zs)
        out.append(float(wk * vmax))
    return out


def config_lines(label: str, kind: str, mode: Mode, shaper: Shaper, axis: str = "x") -> list[str]:
    """Klipper and RepRapFirmware lines for ``shaper`` (``kind`` designed at ``mode``)."""
    lines = []
    if kind in KLIPPER:
        lines += ["# Klipper (printer.cfg)", "[input_shaper]", f"shaper_type_{axis}: {KLIPPER[kind]}",
                  f"shaper_freq_{axis}: {mode.freq_hz:.2f}", f"damping_ratio_{axis}: {mode.zeta:.4f}"]
    else:
        lines.append(f"# Klipper: no built-in type for {label}; nearest is mzv or ei")
    T, A = shaper.impulses
    if kind in RRF:
        lines += ["; RepRapFirmware (config.g)", f'M593 P"{RRF[kind]}" F{mode.freq_hz:.2f} S{mode.zeta:.4f}']
    else:
        cum = np.cumsum(A)[:-1]
        dts = np.diff(T)
        lines += ["; RepRapFirmware (config.g), custom shaper: cumulative amplitudes H, impulse intervals T",
                  'M593 P"custom" H' + ":".join(f"{c:.4f}" for c in cum) + " T" + ":".join(f"{d:.5f}" for d in dts)]
    return lines


def recommend(ident: Identification, *, vtol: float = 0.05, margin: float = 0.05, printer: bool = True,
              axis: str = "x") -> Calibration:
    """Score every shaper family over the identified modes' uncertainty and pick one.

    Parameters
    ----------
    ident : Identification
        From :func:`posicast.identify`.
    vtol : float
        Tolerable worst-case residual vibration, in (0, 1).
    margin : float
        Extra relative frequency uncertainty added to each interval (a machine's
        modes move with position and load), in [0, 0.5).
    printer : bool
        Rank feasible shapers by Klipper smoothing (True) or by duration.
    axis : str
        Axis letter in the config lines.
    """
    if not isinstance(ident, Identification):
        raise TypeError("ident must be an Identification (from posicast.identify)")
    vtol = v.in_open_interval(vtol, "vtol", 0.0, 1.0)
    margin = v.real(margin, "margin")
    if not 0.0 <= margin < 0.5:
        raise ValueError(f"margin must be in [0, 0.5), got {margin:g}")
    modes, ivs = ident.modes, ident.intervals
    amps = np.asarray(ident.amplitudes if len(ident.amplitudes) == len(modes) else np.ones(len(modes)), float)
    weights = amps / amps.max()
    dom = int(np.argmax(amps))
    boxes = [_box(iv, margin) for iv in ivs]
    cands = []
    for label, kind, params in FAMILIES:
        S = design(kind, modes[dom], **params)
        options = [(f"{label} @ {modes[dom].freq_hz:.1f} Hz", S, kind)]
        if len(modes) > 1:
            Sc = design(kind, modes[0], **params)
            for m in modes[1:]:
                Sc = Sc * design(kind, m, **params)
            options.append((f"{label} x {len(modes)} modes", Sc, "custom"))
        for lab, Sx, kd in options:
            per = _score(Sx, boxes, weights)
            cands.append(Candidate(lab, kd, Sx, max(per), Sx.duration, klipper_smoothing(Sx), per))
    key = (lambda c: (c.smoothing, c.duration)) if printer else (lambda c: (c.duration, c.smoothing))
    ok = sorted([c for c in cands if c.worst_vibration <= vtol], key=key)
    rest = sorted([c for c in cands if c.worst_vibration > vtol], key=lambda c: c.worst_vibration)
    ranked = ok + rest
    best = ranked[0]
    why = ["modes: " + "; ".join(f"{m.freq_hz:.2f} Hz [{iv.freq_hz[0]:.2f}, {iv.freq_hz[1]:.2f}], "
                                   f"zeta {m.zeta:.3f} [{iv.zeta[0]:.3f}, {iv.zeta[1]:.3f}]" for m, iv in zip(modes, ivs)),
           f"each frequency interval widened by +-{100 * margin:.0f} %; worst-case residual vibration over the boxes, "
           f"weighted by mode share {np.round(weights, 2).tolist()}"]
    if ok:
        why.append(f"{len(ok)} of {len(cands)} candidates keep the worst case <= {100 * vtol:.0f} %; "
                   f"{best.label} has the least {'smoothing' if printer else 'duration'} among them "
                   f"(worst case {100 * best.worst_vibration:.1f} %, {1000 * best.duration:.1f} ms, "
                   f"smoothing {best.smoothing:.3f} mm)")
    else:
        why.append(f"no candidate reaches {100 * vtol:.0f} %; {best.label} is the most robust "
                   f"(worst case {100 * best.worst_vibration:.1f} %)")
    base_kind = best.kind
    cfg = config_lines(best.label, base_kind, modes[dom], best.shaper, axis)
    if base_kind not in KLIPPER:
        kl = next((c for c in ranked if c.kind in KLIPPER), None)
        if kl is not None:
            why.append(f"Klipper has no type for {best.label}; its best built-in option is {kl.label} "
                       f"(worst case {100 * kl.worst_vibration:.1f} %)")
            cfg += [ln for ln in config_lines(kl.label, kl.kind, modes[dom], kl.shaper, axis)
                    if not ln.startswith(("; RepRap", "M593"))]
            cfg = [ln for ln in cfg if not ln.startswith("# Klipper: no built-in")]
    return Calibration(modes, ivs, best.shaper, cfg, ranked, why, ident, best.label)


def calibrate(path: str | Path, *, input: str | None = None, output: str | None = None, axis: str = "auto",
              n_modes: int | str = "auto", method: str | None = None, vtol: float = 0.05, margin: float = 0.05,
              band: tuple[float, float] | None = None, printer: bool = True) -> Calibration:
    """Identify the modes in a data file and recommend a shaper with config lines.

    Parameters
    ----------
    path : str or Path
        CSV (time column plus signals), Klipper raw accelerometer log
        (``#time,accel_x,accel_y,accel_z``) or Klipper resonance PSD file.
    input, output : str, optional
        Column names for input-output CSV data (then the OE estimator runs).
    axis : {"auto", "x", "y", "z", "all"}
        Klipper logs: one axis, or the projection of all three on their principal direction.
    n_modes : int or "auto"
        Modes to fit; ``"auto"`` (default): BIC for OE, up to 2 peaks for PSD data.
    method : str, optional
        Override the estimator (default ``"oe"`` with an input, ``"psd"`` without).
    vtol, margin, printer : see :func:`recommend`.
    band : (float, float), optional
        Frequency band (Hz) for output-only fits (default 5 .. 0.45 fs, Klipper sweeps 5-133 Hz).
    """
    ds = load_csv(path)
    notes = list(ds.notes)
    ax = "x" if axis in ("auto", "all") else axis
    if ds.kind == "klipper_psd":
        col = f"psd_{axis}" if axis in ("x", "y", "z") else ("psd_xyz" if "psd_xyz" in ds.columns else list(ds.columns)[0])
        from .estimators import _psd

        P = ds.column(col)
        nm = 2 if n_modes == "auto" else v.integer(n_modes, "n_modes", 1)
        lo, hi = band if band is not None else (max(float(ds.t[0]), 5.0), float(ds.t[-1]))
        ident = _psd(np.zeros(2), float("nan"), nm, band=(lo, hi), excitation_slope=0.0, freqs=ds.t, psd=P)
        ident.notes.append("Klipper PSD file: the PSD was already divided by nothing; excitation assumed flat")
    elif input is not None or method in ("oe", "arx", "freq"):
        if input is None or output is None:
            raise ValueError("input and output columns are both needed for input-output data (--input, --output)")
        u, y = ds.column(input), ds.column(output)
        ident = identify(ds.t, u, y, n_modes=n_modes, method=method or "oe")
    else:
        if ds.kind == "klipper_raw":
            y = ds.projection(axis)
            slope = 2.0
        else:
            if output is None:
                raise ValueError("output column needed for output-only CSV data (--output)")
            y, slope = ds.column(output), 0.0
        nm = 2 if n_modes == "auto" else v.integer(n_modes, "n_modes", 1)
        b = band if band is not None else (5.0, min(133.0 if ds.kind == "klipper_raw" else 0.45 * ds.fs, 0.45 * ds.fs))
        ident = identify(ds.t, None, y, n_modes=nm, method=method or "psd", band=b, excitation_slope=slope)
    cal = recommend(ident, vtol=vtol, margin=margin, printer=printer, axis=ax)
    cal.notes = notes
    return cal
