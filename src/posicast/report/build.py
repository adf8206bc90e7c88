"""``posicast report DATA``: the user-first report for a user's own resonance test(s) or plant file.

Everything is computed before anything is written: a file that is not a log, a log without a
resonance or a bad plant file raises, and no file is created.
"""

from __future__ import annotations

import html
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

from .. import _validate as v
from ..identification.calibration import calibrate
from .machine import machine_part
from .page import Page, output_dir
from .plant import analyse_plant, plant_part
from .plantfile import load_plant

__all__ = ["write_report", "ReportSummary", "is_plant_file"]


@dataclass(frozen=True)
class ReportSummary:
    """What :func:`write_report` wrote and found.

    Attributes
    ----------
    kind : str
        ``"log"`` (resonance tests) or ``"plant"`` (a plant file).
    index : Path
        The page written.
    figures : tuple of Path
    sections : tuple of str
        The page's headings, in order.
    details : dict
        For logs :meth:`Calibration.to_dict` plus ``"config"`` (every line to paste); for a plant
        :meth:`PlantAnalysis.to_dict`.
    """

    kind: str
    index: Path
    figures: tuple[Path, ...]
    sections: tuple[str, ...]
    details: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "index": str(self.index), "figures": [str(p) for p in self.figures],
                "sections": list(self.sections), **self.details}


def is_plant_file(path: str | os.PathLike[str]) -> bool:
    """A plant file is a ``.json`` file; anything else is read as a resonance test.

    >>> is_plant_file("machine.JSON"), is_plant_file("resonances_x.csv")
    (True, False)
    """
    return v.path_text(path, "path").lower().endswith(".json")


#: calibrate's advice for an input/output CSV, and what the report (which reads resonance tests only) says instead.
_IO_HINT = "give the input and output columns (--input, --output)"
_IO_REPORT = ("the report reads resonance tests; for an input/output record run "
              "'posicast calibrate FILE --input COLUMN --output COLUMN'")

INTRO = ("<p>Made by <code>posicast report</code>. Each result is printed with the command and the Python code that "
         "give it; the numbers in a table column share one format (<code>&lt; 1e-12</code>: a value at rounding "
         "level, <code>–</code>: none).</p>")


def write_report(data: str | os.PathLike[str] | Sequence[str | os.PathLike[str]], out: str | os.PathLike[str] = "report",
                 *, firmware: str | Sequence[str] = "klipper", axis: str | None = None,
                 progress: Callable[[str], None] | None = None) -> ReportSummary:
    """Write the user-first report for ``data`` into ``out`` (``out/index.html`` and its figures).

    Parameters
    ----------
    data : path or list of paths
        One plant file (``.json``, format in :mod:`posicast.report.plantfile`), or resonance tests
        :func:`posicast.calibrate` reads (Klipper raw accelerometer logs, ``resonances_*.csv``,
        ``calibration_data_*.csv``).
    out : path
        Output folder (created; files in it with the same names are replaced).
    firmware, axis :
        As for :func:`posicast.calibrate` (logs only).
    progress : callable, optional
        Called with a line of text as the work proceeds (logs only).

    Raises
    ------
    ValueError
        A file that cannot be read, is not a resonance test, or a bad plant file; nothing is written.
    posicast.identification.NoModeFound
        No resonance in the logs; nothing is written.

    Examples
    --------
    >>> import tempfile, pathlib, json
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (d / "p.json").write_text(json.dumps({"plant": {"num": [1], "den": [1, 0.4, 4, 0]},
    ...                                           "tune": {"controller": "pd", "ms": 2}, "horizon": 30}))
    >>> s = write_report(d / "p.json", d / "out")
    >>> s.kind, s.index.name, s.sections[0]
    ('plant', 'index.html', 'Your plant → your loop')
    """
    paths = [data] if isinstance(data, (str, os.PathLike)) else list(v.sequence(data, "data", min_len=1))
    texts = [v.path_text(p, "data") for p in paths]
    folder = output_dir(out, "out")
    plants = [p for p in texts if is_plant_file(p)]
    if plants and len(texts) > 1:
        raise ValueError("give one plant file (.json), or resonance-test logs, not both or several plant files")
    if plants:
        spec = load_plant(texts[0])
        analysis = analyse_plant(spec)
        page = Page(f"posicast report: {spec.name}")
        plant_part(page, analysis, texts[0])
        kind, details = "plant", analysis.to_dict()
    else:
        names = [firmware] if isinstance(firmware, str) else v.sequence(firmware, "firmware", min_len=1)
        fws = [f.strip().lower() for name in names for f in v.instance_of(name, str, "firmware", "firmware names "
                                                                           "(str)").split(",") if f.strip()]
        try:
            cal = calibrate(texts, firmware=fws, axis=axis, progress=progress)
        except ValueError as exc:  # the report reads resonance tests only: no --input/--output to point at
            if type(exc) is not ValueError or _IO_HINT not in str(exc):
                raise
            raise ValueError(str(exc).replace(_IO_HINT, _IO_REPORT)) from None
        names = ", ".join(Path(p).name for p in texts)
        page = Page(f"posicast report: {names}")
        machine_part(page, cal, texts, firmware=fws, axis=axis,
                     about=f"Resonance test{'s' if len(texts) > 1 else ''}: <code>{html.escape(names)}</code>.")
        kind, details = "log", {**cal.to_dict(), "config": cal.config}
    index = page.write(folder, INTRO)
    figures = tuple(index.parent / name for name in page.figure_names)
    return ReportSummary(kind, index, figures, tuple(h.title for h in page.headings), details)
