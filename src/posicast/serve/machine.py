"""The machine tab: a resonance test (or modes typed by hand) in, a firmware's shaper settings out.

A Klipper log (raw accelerometer CSV ``#time,accel_x,...``, or a PSD file ``resonances_*``,
``calibration_data_*``), or a CSV with input and output columns, goes through
:func:`posicast.calibrate` exactly as ``posicast calibrate FILE`` does: the page shows the
spectrum with the fitted model, the modes with their 95 % intervals, every shaper type the
firmware offers (worst-case vibration, smoothing, max_accel), their vibration curves and the
configuration lines.  Modes typed by hand are scored by
:func:`~posicast.identification.recommend.recommend_setting` over the same boxes
(:func:`~posicast.identification.recommend.mode_boxes`) without a spectrum.
"""

from __future__ import annotations

import math
import os
import re
import tempfile
from typing import Any, Mapping

import numpy as np

from .. import _validate as v
from ..firmware import FIRMWARES, Firmware, Klipper
from ..firmware.base import vibration_grid
from ..firmware.klipper import KLIPPER_TEST_DAMPING
from ..identification import Calibration, Interval, calibrate
from ..identification.recommend import Candidate, Recommendation, mode_boxes, recommend_setting
from ..modes import Mode
from . import forms
from .figures import COLOURS, svg_figure

__all__ = ["FIRMWARE_CHOICES", "MAX_FILES", "MAX_UPLOAD", "machine_view"]

#: The page's firmware menu: its value -> (posicast firmware name, Klipper version).
FIRMWARE_CHOICES: dict[str, tuple[str, str]] = {
    "klipper": ("klipper", "v0.13"), "klipper-master": ("klipper", "master"), "kalico": ("klipper", "kalico"),
    "reprapfirmware": ("reprapfirmware", "v0.13"), "marlin": ("marlin", "v0.13"), "prusa": ("prusa", "v0.13"),
}
#: Most characters the page may send (all files together): an hour-long raw log at 3.2 kHz is about 100 MB.
MAX_UPLOAD = 200_000_000
#: Most files at once (probe points, print masses, axes).
MAX_FILES = 16
#: Highest mode typed by hand [Hz] (the firmware scoring grid ends at 1 MHz; printer modes are below 1 kHz).
MAX_TYPED_HZ = 1e5
#: The command line's options named in the library's messages, as the page's fields.
_FIELDS = (("(--input, --output)", "(the Input column and Output column fields)"),
           ("(use --axis)", "(choose the Axis)"))


def machine_view(form: Mapping[str, Any]) -> dict[str, Any]:
    """Calibrate the uploaded files (``form["files"] = [{"name", "text"}, ...]``, or one ``form["file"]``)
    together, as ``posicast calibrate FILE...`` does, or score the typed ``form["modes"]``.

    Other fields: ``firmware`` (a key of :data:`FIRMWARE_CHOICES`), ``axis`` (``x``, ``y``, ``z`` or
    empty), ``margin`` (frequency drift, default 0.05), ``vtol`` (optional worst-case target),
    ``input`` and ``output`` (columns of an input/output CSV).
    """
    choice = v.choice(forms.text_field(form, "firmware", "klipper"), "firmware", FIRMWARE_CHOICES)
    fw_name, version = FIRMWARE_CHOICES[choice]
    axis = forms.text_field(form, "axis") or None
    if axis is not None:
        axis = v.choice(axis, "axis", ("x", "y", "z"))
    margin = v.real_in_range(forms.number(form, "margin", "margin", 0.05), "margin", 0.0, 0.5, hi_open=True)
    vtol = forms.optional_number(form, "vtol")
    if vtol is not None:
        vtol = v.in_open_interval(vtol, "vtol", 0.0, 1.0)
    if form.get("files") is not None or form.get("file"):
        cal = _calibrate_upload(_uploads(form), fw_name, version, axis, margin, vtol,
                                forms.text_field(form, "input") or None, forms.text_field(form, "output") or None)
        return _calibration_view(cal)
    modes = forms.mode_lines(forms.text_field(form, "modes"))
    for k, m in enumerate(modes, 1):  # the firmware's scoring grid ends at 1 MHz, with the drift on top
        if m.freq_hz > MAX_TYPED_HZ:
            raise ValueError(f"modes line {k}: frequency must be <= {MAX_TYPED_HZ:g} Hz for a firmware's shaper, "
                             f"got {m.freq_hz:g}")
    fw: Firmware = Klipper(version) if fw_name == "klipper" else FIRMWARES[fw_name]()
    zero = [Interval((m.omega, m.omega), (m.zeta, m.zeta)) for m in modes]  # the margin widens them
    rec = recommend_setting(fw, mode_boxes(modes, zero, None, margin), None, vtol=vtol, axis=axis or "x",
                            margin=margin)
    out = {"source": "modes typed by hand", "files": [{"name": "typed", "axis": axis or "x", "kind": "modes",
                                                       "modes": [_mode_row(m, None, None) for m in modes],
                                                       "no_mode": None}],
           "recommendations": [_recommendation_row(rec)], "config": "\n".join(rec.config), "notes": [],
           "plots": {}}
    _candidate_plot(out["plots"], [rec], modes, [])
    return out


def _safe_name(name: str) -> str:
    """The upload's base name, reduced to safe characters (the axis is read from the name: keep it)."""
    base = os.path.basename(name.replace("\\", "/")) or "upload.csv"
    base = re.sub(r"[^A-Za-z0-9._-]", "_", base)[:120]
    return base if base.lower().endswith(".csv") else base + ".csv"


def _uploads(form: Mapping[str, Any]) -> list[tuple[str, str]]:
    """``(name, text)`` of each uploaded file: ``form["files"]`` (a list) or ``form["file"]``."""
    items = form.get("files")
    if items is None:
        items = [form["file"]]
    items = v.sequence(items, "files", min_len=1)
    if len(items) > MAX_FILES:
        raise ValueError(f"files: at most {MAX_FILES} files at once, got {len(items)}")
    out, total = [], 0
    for upload in items:
        if not isinstance(upload, Mapping):
            raise TypeError("file must be an object with 'name' and 'text'")
        name = forms.text_field(upload, "name", "upload.csv")
        text = upload.get("text")
        if not isinstance(text, str):
            raise TypeError(f"file text must be a string, got {type(text).__name__}")
        if not text.strip():
            raise ValueError(f"{name}: the file is empty")
        total += len(text)
        if total > MAX_UPLOAD:
            raise ValueError(f"{name}: the files have more than {MAX_UPLOAD} characters, the most the designer reads")
        out.append((name, text))
    return out


def _calibrate_upload(uploads: list[tuple[str, str]], fw_name: str, version: str, axis: str | None, margin: float,
                      vtol: float | None, input_col: str | None, output_col: str | None) -> Calibration:
    """:func:`posicast.calibrate` of the uploaded files (copied to a temporary directory under their own
    names: the axis is read from the name)."""
    with tempfile.TemporaryDirectory(prefix="posicast-serve-") as tmp:
        paths: dict[str, str] = {}
        for k, (name, text) in enumerate(uploads):
            safe = _safe_name(name)
            path = os.path.join(tmp, safe if not os.path.exists(os.path.join(tmp, safe)) else f"{k}_{safe}")
            with open(path, "w", encoding="utf-8") as fh:
                fh.write(text)
            paths[path] = name
        try:
            cal = calibrate(list(paths), firmware=[fw_name], klipper_version=version, axis=axis, margin=margin,
                            vtol=vtol, input=input_col, output=output_col)
        except (ValueError, TypeError) as exc:  # the library's message, about the user's files, not the copies
            exc.args = tuple(_user_names(a, paths) if isinstance(a, str) else a for a in exc.args)
            if len(uploads) == 1 and exc.args and isinstance(exc.args[0], str) and uploads[0][0] not in exc.args[0]:
                exc.args = (f"{uploads[0][0]}: {exc.args[0]}",) + exc.args[1:]  # which file (the page may hold several)
            raise
    for fr in cal.files:
        fr.path = paths.get(fr.path, fr.path)
    cal.notes = [_user_names(n, paths) for n in cal.notes]
    return cal


def _user_names(text: str, paths: Mapping[str, str]) -> str:
    """``text`` with the temporary copies' paths as the user's file names, command-line options as fields."""
    for path, name in paths.items():
        text = text.replace(path, name).replace(os.path.basename(path), name)
    for option, field in _FIELDS:
        text = text.replace(option, field)
    return text


def _num(x: Any) -> float | None:
    return None if x is None or not math.isfinite(float(x)) else float(x)


def _mode_row(m: Mode, iv: Interval | None, share: float | None) -> dict[str, Any]:
    return {"freq_hz": m.freq_hz, "zeta": m.zeta,
            "freq_hz_95": None if iv is None else [_num(x) for x in iv.freq_hz],
            "zeta_95": None if iv is None else [_num(x) for x in iv.zeta], "share": _num(share)}


def _candidate_row(c: Candidate, best: Candidate, reference: Candidate | None) -> dict[str, Any]:
    s = c.setting
    return {"type": s.shaper_type.written, "freq_hz": s.freq, "damping": s.damping,
            "vibration": _num(c.vibration), "firmware_vibration": _num(c.firmware_vibration),
            "smoothing_mm": _num(c.smoothing), "max_accel": _num(c.max_accel),
            "recommended": s == best.setting, "own_tool": reference is not None and s == reference.setting}


def _recommendation_row(rec: Recommendation) -> dict[str, Any]:
    rows = [_candidate_row(c, rec.best, rec.reference) for c in rec.per_type.values()]
    if rec.reference is not None and not any(r["own_tool"] for r in rows):
        rows.append(_candidate_row(rec.reference, rec.best, rec.reference))
    return {"firmware": rec.firmware.name, "axis": rec.axis, "best": rec.best.label, "candidates": rows,
            "reasoning": list(rec.reasoning), "config": list(rec.config)}


def _calibration_view(cal: Calibration) -> dict[str, Any]:
    files = []
    for fr in cal.files:
        ident = fr.identification
        modes = []
        if ident is not None:
            shares = ident.shares if len(ident.shares) == len(ident.modes) else [None] * len(ident.modes)
            modes = [_mode_row(m, iv, sh) for m, iv, sh in zip(ident.modes, ident.intervals, shares)]
        files.append({"name": fr.path, "axis": fr.axis, "kind": fr.kind, "modes": modes, "no_mode": fr.no_mode})
    out: dict[str, Any] = {"source": ", ".join(fr.path for fr in cal.files), "files": files,
                           "recommendations": [_recommendation_row(r) for r in cal.recommendations],
                           "config": "\n".join(cal.config), "notes": list(cal.notes), "plots": {}}
    _spectrum_plot(out["plots"], cal)
    spectra = [(fr.resonance.firmware_freqs, fr.resonance.firmware_psd) for fr in cal.files if fr.resonance]
    _candidate_plot(out["plots"], cal.recommendations, cal.modes, spectra)
    return out


def _spectrum_plot(plots: dict[str, Any], cal: Calibration) -> None:
    """Measured PSD, the fitted model and each mode's 95 % frequency interval (no plot when no file has a
    spectrum: an input/output record is fitted in time)."""
    if not any(fr.resonance is not None or (fr.identification is not None and fr.identification.freqs is not None)
               for fr in cal.files):
        return
    with svg_figure(plots, "psd", height=4.2) as (fig, ax):
        for k, fr in enumerate(cal.files):
            c = COLOURS[k % len(COLOURS)]
            tag = f"{fr.axis or '?'}: " if len(cal.files) > 1 else ""
            ident = fr.identification
            if ident is None or ident.freqs is None:
                if fr.resonance is not None:
                    sp = fr.resonance.spectrum
                    ax.semilogy(sp.freqs, np.maximum(sp.psd, 1e-300), ".", ms=2, color=c, label=tag + "measured (no mode)")
                continue
            ax.semilogy(ident.freqs, ident.spectrum, ".", ms=3, color=c, label=tag + "measured PSD")
            ax.semilogy(ident.freqs, ident.y_fit, "-", lw=1.3, color=c, alpha=0.8, label=tag + "fitted model")
            for j, (m, iv) in enumerate(zip(ident.modes, ident.intervals)):
                ax.axvspan(*iv.freq_hz, color=c, alpha=0.18, label=tag + "95 % interval" if j == 0 else None)
                ax.axvline(m.freq_hz, color=c, lw=0.7, ls=":")
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel("PSD [(mm/s²)²/Hz]")
        ax.set_title(f"measured spectrum, fitted model, {len(cal.modes)} identified mode"
                     + ("s" if len(cal.modes) != 1 else ""))
        ax.legend(loc="best")


def _candidate_plot(plots: dict[str, Any], recs: list[Recommendation], modes: list[Mode],
                    spectra: list[tuple[np.ndarray, np.ndarray]]) -> None:
    """Remaining vibration of each candidate against frequency (worst over damping 0.075-0.15)."""
    fmax = max(2.5 * max(m.freq_hz for m in modes), 50.0)
    f = np.linspace(1.0, fmax, 600)
    with svg_figure(plots, "candidates", height=4.2) as (fig, ax):
        if spectra:
            ax2 = ax.twinx()
            for b, p in spectra:
                keep = b <= fmax
                ax2.fill_between(b[keep], p[keep], color="0.88", lw=0)
            ax2.set_yticks([])
            ax2.grid(False)
            ax.set_zorder(3)
            ax.patch.set_visible(False)
        k = 0
        for rec in recs:
            tag = f"{rec.axis}: " if len(recs) > 1 and rec.axis else ""
            for c in rec.per_type.values():
                A, T = c.setting.impulses
                V = vibration_grid(A, T[None, :], f, np.asarray(KLIPPER_TEST_DAMPING))[0].max(axis=1)
                best = c.setting == rec.best.setting
                ax.plot(f, 100 * V, "-", color=COLOURS[k % len(COLOURS)], lw=2.2 if best else 1.0,
                        label=tag + c.setting.describe() + ("  (recommended)" if best else ""))
                k += 1
        for m in modes:
            ax.axvline(m.freq_hz, color="k", lw=0.7, ls=":")
        ax.set_xlim(0, fmax)
        ax.set_ylim(0, 100)
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel("remaining vibration [%]")
        ax.set_title("candidate shapers, worst over damping 0.075–0.15" + (" (measured spectrum in grey)"
                                                                           if spectra else ""))
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.16), ncols=2)
