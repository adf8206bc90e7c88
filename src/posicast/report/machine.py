""""Your data → your shaper": a resonance test in, the firmware lines to paste out, with how each was made.

From a :class:`~posicast.identification.calibration.Calibration` (one or several Klipper logs):
the measured spectrum with the fitted model and the modes' 95 % intervals, the candidate
settings of each firmware beside the firmware tool's own pick, the configuration lines, and the
vibration each setting leaves over frequency; each with the command and the Python code that
gives it.
"""

from __future__ import annotations

import html
import math
from pathlib import Path
from typing import Sequence

from ..identification.calibration import Calibration
from ..identification.plots import calibration_plot
from ..identification.recommend import Candidate, Recommendation
from .page import Page

__all__ = ["machine_part", "calibrate_command", "calibrate_code", "TITLE"]

TITLE = "Your data → your shaper"


def calibrate_command(paths: Sequence[str], firmware: Sequence[str], axis: str | None = None) -> str:
    """The ``posicast calibrate`` command line that computes what the part shows."""
    fw = "" if list(firmware) == ["klipper"] else f" --firmware {','.join(firmware)}"
    ax = "" if axis is None else f" --axis {axis}"
    return f"posicast calibrate {' '.join(_quote(p) for p in paths)}{fw}{ax} --plot calibration.png"


def calibrate_code(paths: Sequence[str], firmware: Sequence[str], axis: str | None = None) -> str:
    """The Python code that computes what the part shows."""
    files = repr(paths[0]) if len(paths) == 1 else repr(list(paths))
    fw = "" if list(firmware) == ["klipper"] else f", firmware={list(firmware)!r}"
    ax = "" if axis is None else f", axis={axis!r}"
    return (f"import posicast as pc\n"
            f"cal = pc.calibrate({files}{fw}{ax})\n"
            f"print(cal.summary())              # modes with 95 % intervals, per firmware a table\n"
            f"rec = cal.recommendation({firmware[0]!r})\n"
            f"print(\"\\n\".join(rec.config))      # the lines to paste\n")


def machine_part(page: Page, cal: Calibration, paths: Sequence[str], *, firmware: Sequence[str] = ("klipper",),
                 axis: str | None = None, about: str = "") -> None:
    """Add the part "Your data → your shaper" for ``cal`` (computed from ``paths``) to ``page``.

    ``about`` (trusted HTML) says where the data come from.
    """
    command = calibrate_command(paths, firmware, axis)
    page.part(TITLE, (about + " " if about else "") +
              "posicast reads the resonance test, fits the spectrum with a modal model over the test's own "
              "excitation, keeps each mode only when a likelihood-ratio test demands it, and scores every setting "
              "the firmware can run on the identified modes and on the measured spectrum.")
    page.code(command, "The command (prints the same tables and lines; <code>--json</code> for a program):",
              command="calibrate")
    page.code(calibrate_code(paths, firmware, axis), "The same in Python:", language="python")
    _modes_section(page, cal)
    _lines_section(page, cal)
    _sensitivity_section(page, cal)


def _modes_section(page: Page, cal: Calibration) -> None:
    page.section("Spectrum and modes")
    rows = []
    for fr in cal.files:
        name = Path(fr.path).name
        if fr.identification is None:
            rows.append([name, fr.axis or "?", "none: " + (fr.no_mode or ""), "", "", "", "", ""])
            continue
        ident = fr.identification
        shares = ident.shares if len(ident.shares) == len(ident.modes) else [math.nan] * len(ident.modes)
        edges = ident.at_edge or [False] * len(ident.modes)
        for m, iv, sh, edge in zip(ident.modes, ident.intervals, shares, edges):
            rows.append([name, fr.axis or "?", m.freq_hz, f"{iv.freq_hz[0]:.2f} – {iv.freq_hz[1]:.2f}", m.zeta,
                         f"{iv.zeta[0]:.3f} – {iv.zeta[1]:.3f}", float(sh), "at the band edge" if edge else ""])
    n = sum(1 for r in rows if not isinstance(r[2], str))
    page.paragraph(f"{n} mode{'s' if n != 1 else ''} found, with 95 % intervals (the share is the mode's part of "
                   "the measured power). Left of the figure below: the measured spectrum, the fitted model, the "
                   "excitation's shape and each mode's frequency interval (shaded).")
    page.table(["file", "axis", "f [Hz]", "95 % f [Hz]", "ζ", "95 % ζ", "share", "note"], rows,
               digits=[3, 3, 2, 3, 3, 3, 2, 3])
    page.code("for m, iv in zip(cal.modes, cal.intervals):\n"
              "    print(m.freq_hz, iv.freq_hz, m.zeta, iv.zeta)", "Python:", language="python")
    for note in cal.notes:
        page.note(html.escape(note))


def _role(c: Candidate, rec: Recommendation) -> str:
    roles = []
    if c.setting == rec.best.setting:
        roles.append("recommended")
    if rec.reference is not None and c.setting == rec.reference.setting:
        roles.append(f"{rec.firmware.name}'s own tool")
    return ", ".join(roles)


def _row(c: Candidate, rec: Recommendation) -> list[object]:
    fv = math.nan if c.firmware_vibration is None else 100 * c.firmware_vibration
    return [c.setting.shaper_type.written, c.setting.freq, c.setting.damping, 100 * c.vibration, fv, c.smoothing,
            c.max_accel, _role(c, rec)]


def _lines_section(page: Page, cal: Calibration) -> None:
    page.section("The lines to paste")
    page.paragraph("Per firmware (and axis): the best setting of each shaper type the firmware runs, scored by "
                   "posicast's worst case (the vibration left over the measured spectrum, worst over the modes' "
                   "damping intervals and a ±5 % frequency drift) and by the firmware tool's own measure, with "
                   "Klipper's smoothing and the acceleration at which it reaches 0.12 mm.")
    for rec in cal.recommendations:
        where = f"{rec.firmware.name}" + (f", axis {rec.axis}" if rec.axis else ", all axes")
        rows = [_row(c, rec) for c in rec.per_type.values()]
        ref = rec.reference
        if ref is not None and all(ref.setting != c.setting for c in rec.per_type.values()):
            rows.append(_row(ref, rec))
        page.paragraph(f"<b>{html.escape(where)}</b>: {len(rows)} settings, one per shaper type"
                       + (" and the firmware tool's own pick" if len(rows) > len(rec.per_type) else "") + ".")
        page.table(["type", "freq [Hz]", "design ζ", "worst case [%]", "tool's measure [%]", "smoothing [mm]",
                    "max_accel [mm/s²]", "role"], rows, digits=[3, 1, 3, 1, 1, 3, 0, 3])
        best = rec.best
        text = (f"Recommended: <b>{html.escape(best.label)}</b>, worst case {100 * best.vibration:.1f} %, "
                f"smoothing {best.smoothing:.3f} mm")
        if ref is not None:
            fv = "" if ref.firmware_vibration is None else f", its measure {100 * ref.firmware_vibration:.1f} %"
            same = ref.setting == best.setting
            text += (f". {html.escape(rec.firmware.name)}'s own tool picks "
                     f"{'the same setting' if same else html.escape(ref.label)} (worst case "
                     f"{100 * ref.vibration:.1f} %{fv}, smoothing {ref.smoothing:.3f} mm).")
        page.paragraph(text)
        if rec.reasoning:
            page.paragraph("<small>" + "<br>".join(html.escape(r) for r in rec.reasoning) + "</small>")
        page.code("\n".join(rec.config), f"Configuration lines for {html.escape(where)}:", css="config",
                  firmware=rec.firmware.name, axis=rec.axis or "all")
    if cal.schedule is not None:
        page.code("\n".join(cal.schedule.lines), "Frequency schedule lines:", css="config", firmware="schedule")
    page.code(f"rec = cal.recommendation({cal.recommendations[0].firmware.name!r})\n"
              "print(rec.table())                 # the table above\n"
              "print(rec.best.label, rec.reference.label if rec.reference else None)\n"
              "print(\"\\n\".join(cal.config))      # every firmware's lines", "Python:", language="python")


def _sensitivity_section(page: Page, cal: Calibration) -> None:
    page.section("Spectrum, fit and sensitivity")
    page.figure(calibration_plot(cal)[0], "calibration",
                "Left: the measured spectrum (dots), the fitted model, the excitation's shape (dotted), the fitted "
                "band (dashed) and each mode's 95 % frequency interval (shaded). Right: the vibration left by the "
                "recommended setting (solid) and by the firmware tool's own pick (dashed) against frequency, over "
                "the spectrum the firmware scores on (grey); worst over damping 0.075–0.15.")
    page.code("from posicast.identification.plots import calibration_plot\n"
              "calibration_plot(cal)[0].savefig(\"calibration.png\")", "Python (the command's --plot writes it):",
              language="python")


def _quote(text: str) -> str:
    return text if all(ch.isalnum() or ch in "._/-+=:,@" for ch in text) else "'" + text.replace("'", "'\\''") + "'"
