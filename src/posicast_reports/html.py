"""The reports' page: :class:`posicast.report.page.Page` written into a fixed folder.

The HTML helpers (parts and sections with a table of contents, one number format per table
column, tables that scroll instead of widening the page, code blocks) live in the library,
:mod:`posicast.report.page`, because ``posicast report`` writes the same page for a user's own
data; this module keeps the reports' ``Report(title, out_dir)`` spelling (``make demo``,
``make reproduce``).
"""

from __future__ import annotations

import os
from pathlib import Path

from posicast.report.page import Page, format_column, format_number, output_dir

__all__ = ["Report", "NUMBER_FORMATS", "format_column", "format_number"]

#: The reports' note on number formats (under each report's introduction).
NUMBER_FORMATS = (
    "<p><small>Number formats: one per table column; <code>&lt; 1e-12</code> is a value at rounding level (a "
    "residual that is zero in exact arithmetic), <code>–</code> none. Residual vibration uses the Singer-Seering "
    "normalisation V = e<sup>-ζω t<sub>end</sub></sup>|S(p)| (seeds 003, 004) unless stated.</small></p>")


class Report(Page):
    """A :class:`~posicast.report.page.Page` that knows its folder: ``write()`` writes ``<out>/index.html``.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp()) / "r"
    >>> r = Report("demo", d)
    >>> r.section("Numbers")
    'numbers'
    >>> r.table(["x", "y"], [["a", 1.0]])
    >>> d.exists() is False and r.write().name
    'index.html'
    """

    def __init__(self, title: str, out_dir: str | os.PathLike[str]) -> None:
        super().__init__(title)
        self.out: Path = output_dir(out_dir)
        self.intro = ""

    def write(self, out_dir: str | os.PathLike[str] | None = None, intro: str | None = None) -> Path:  # type: ignore[override]
        """Write the page into its folder (or ``out_dir``)."""
        return super().write(self.out if out_dir is None else out_dir, self.intro if intro is None else intro)
