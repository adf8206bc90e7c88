"""A small self-contained HTML page: parts and sections with a table of contents, tables, code, figures.

The page has no external dependencies and opens offline; its figures are PNG files next to
``index.html``.  Nothing is written until :meth:`Page.write`: figures are rendered to memory
when added, so a report that fails half-way leaves no file behind.

Numbers in a table are formatted **per column** (:func:`format_column`): one style for the whole
column (fixed decimals, or significant digits, scientific below 1e-3, when fixed decimals would hide a
value), values below :data:`TINY` in magnitude (rounding-level residuals) as ``< 1e-12``, NaN as
``–``.  So a column never shows ``0.0000`` beside ``1.2e-17``.
"""

from __future__ import annotations

import html
import io
import math
import os
import re
from dataclasses import dataclass
from numbers import Integral, Real
from pathlib import Path
from typing import Any, Sequence

from .. import _validate as v
from .._files import atomic_write

__all__ = ["Page", "Heading", "format_column", "format_number", "TINY", "MISSING"]

#: Magnitudes below this are shown as ``< 1e-12`` (a residual at rounding level, not a number to read).
TINY = 1e-12
#: What a table shows for a missing value (NaN, None).
MISSING = "–"
#: Columns wider than this (in cells) get the smaller font of ``table.wide``.
WIDE_COLUMNS = 7

CSS = """
body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222;line-height:1.4}
h1,h2,h3,p{overflow-wrap:anywhere}h1{border-bottom:2px solid #345}h2{margin-top:2.2em;border-bottom:2px solid #345;color:#234}
h3{margin-top:1.8em;border-bottom:1px solid #ccc}
nav.toc{background:#f5f7fa;border:1px solid #d5dbe3;padding:0.3em 1em;margin:1em 0;font-size:0.9em}
nav.toc>ol{margin:0.2em 0;padding-left:1.4em}nav.toc>ol>li{margin:0.25em 0}nav.toc>ol>li>a{font-weight:600}
nav.toc ol ol{display:block;margin:0;padding:0;font-size:0.92em}nav.toc ol ol li{display:inline}
nav.toc ol ol li+li:before{content:" · ";color:#888}nav.toc a{text-decoration:none}
.tablewrap{max-width:100%;overflow-x:auto;margin:1em 0}
table{border-collapse:collapse;font-size:0.9em}table.wide{font-size:0.78em}
td,th{border:1px solid #bbb;padding:3px 7px;text-align:right;vertical-align:top}th{background:#eef}
td:first-child,th:first-child,td.text,th.text{text-align:left}
figure{margin:1em 0}figure img{max-width:100%;height:auto}figcaption{font-size:0.85em;color:#555}
.note{background:#fff8e0;border-left:4px solid #e0a000;padding:0.5em 1em;margin:1em 0}
pre{background:#f6f8fa;border:1px solid #dde;padding:0.6em 0.8em;overflow-x:auto;max-width:100%;font-size:0.85em}
pre.config{background:#eef8ee;border-color:#9c9}
.label{font-size:0.8em;color:#555;margin:0.8em 0 -0.6em 0}
code{background:#f3f3f3;padding:0 3px}
@media (max-width:900px){body{margin:1em auto}}
"""


def format_number(value: Any, style: str = "fixed", digits: int = 4, zero: str = "0") -> str:
    """One number as a table shows it.

    ``style`` ``"fixed"``: ``digits`` decimals; ``"sig"``: ``digits`` significant digits, positional
    from 1e-3 to 1e5 and scientific outside.  Zero is ``zero``, a magnitude below :data:`TINY`
    ``< 1e-12``, NaN and None ``–``.

    Examples
    --------
    >>> format_number(0.12345), format_number(0.0), format_number(3e-17), format_number(float("nan"))
    ('0.1235', '0', '< 1e-12', '–')
    >>> format_number(2.5e-8, "sig"), format_number(22.5199, "sig"), format_number(float("inf"))
    ('2.500e-08', '22.52', '∞')
    """
    if value is None:
        return MISSING
    if not (_is_float(value) or isinstance(value, Integral)) or isinstance(value, bool):
        raise TypeError(f"value must be a real number or None, got {type(value).__name__}")
    style = v.choice(style, "style", ("fixed", "sig"))
    digits = v.integer_in_range(digits, "digits", 0, 17)
    zero = _text(zero, "zero")
    x = float(value)
    if math.isnan(x):
        return MISSING
    if math.isinf(x):
        return "∞" if x > 0 else "−∞"
    if x == 0.0:
        return zero
    a = abs(x)
    if a < TINY:
        return f"< {TINY:.0e}"
    if style == "fixed":
        return f"{x:.{digits}f}"
    sig = max(digits, 1)
    if 1e-3 <= a < 1e5:
        return f"{x:.{max(sig - 1 - math.floor(math.log10(a)), 0)}f}"
    return f"{x:.{max(sig - 1, 1)}e}"


def _is_float(value: Any) -> bool:
    return isinstance(value, Real) and not isinstance(value, (bool, Integral))


def column_style(values: Sequence[Any], digits: int = 4) -> str:
    """``"sig"`` (significant digits) when ``digits`` decimals would hide a value of the column (one that
    rounds to zero, or 1e5 and above), else ``"fixed"``.  Zeros, tiny values and non-numbers do not count.

    Examples
    --------
    >>> column_style([0.5, 1.25]), column_style([0.5, 2e-8]), column_style([0.5, 0.0, 1e-17])
    ('fixed', 'sig', 'fixed')
    >>> column_style([0.174, 0.0015, 1.23], digits=3), column_style([60116.0, 123456.0], digits=0)
    ('fixed', 'fixed')
    """
    big = 1e5 if digits else 1e12  # whole numbers (max_accel [mm/s²]) stay whole: 123456 beside 60116, not 1.2e+05
    for x in values:
        if _is_float(x) and math.isfinite(float(x)):
            a = abs(float(x))
            if a >= TINY and (a < 0.5 * 10.0 ** -digits or a >= big):
                return "sig"
    return "fixed"


def format_column(values: Sequence[Any], digits: int = 4) -> list[str]:
    """The cells of one table column as text: every float in one style (:func:`column_style`).

    Integers print as integers, strings as given (escaped), floats by :func:`format_number`; a zero
    is written with the column's decimals, or ``0`` in a column of significant digits or one that
    also holds values below :data:`TINY` (never ``0.0000`` beside ``< 1e-12`` or ``1.2e-17``).

    Examples
    --------
    >>> format_column([0.0, 1.7e-17, 0.0553])
    ['0', '< 1e-12', '0.0553']
    >>> format_column([0.0, 0.25, 1.5])
    ['0.0000', '0.2500', '1.5000']
    >>> format_column([0.0, 2.4e-08, 22.52, "n/a", 3])
    ['0', '2.400e-08', '22.52', 'n/a', '3']

    A column of one decimal that must show 0.0227 keeps two significant digits (not 1.56 -> ``2``):

    >>> format_column([1.5567, 0.0, 0.127, 0.0227], digits=1)
    ['1.6', '0', '0.13', '0.023']
    """
    values = v.sequence(values, "values")
    digits = v.integer_in_range(digits, "digits", 0, 17)
    style = column_style(values, digits)
    floats = [float(x) for x in values if _is_float(x) and math.isfinite(float(x))]
    plain_zero = style == "sig" or any(0.0 < abs(x) < TINY for x in floats)
    zero = "0" if plain_zero else f"{0.0:.{digits}f}"
    out = []
    sig = max(digits, 2)  # significant digits when the column's decimals would hide a value
    for x in values:
        if x is None or _is_float(x):
            out.append(format_number(x, style, sig if style == "sig" else digits, zero))
        else:
            out.append(html.escape(str(x)))
    return out


@dataclass(frozen=True)
class Heading:
    """A part (``level`` 2) or section (``level`` 3) of the page and its anchor ``id``."""

    level: int
    title: str
    id: str


def _bbox(fig: Any) -> str | None:
    """``savefig``'s ``bbox_inches`` for ``fig``: None when a layout engine already placed everything.

    ``bbox_inches="tight"`` lays the figure out once more without drawing (a third pass over every
    artist after ``tight_layout``), about 40 % of a figure's cost (issue #15).  A figure laid out by a
    layout engine keeps its axes, titles and legends inside the canvas, so it is saved as it is,
    unless it carries figure-level legends or texts (placed by hand, possibly outside the canvas).
    """
    engine = fig.get_layout_engine()
    if engine is not None and not fig.legends and not fig.texts:
        return None
    return "tight"


class Page:
    """An HTML page built in memory: parts, sections, paragraphs, tables, code, figures.

    Examples
    --------
    >>> p = Page("demo")
    >>> p.part("Results")
    'results'
    >>> p.section("Numbers")
    'numbers'
    >>> p.table(["x", "y"], [["a", 1.0], ["b", 1e-17]])
    >>> 'href="#numbers"' in p.html() and "< 1e-12" in p.html()
    True
    """

    def __init__(self, title: str) -> None:
        self.title = _text(title, "title")
        self.headings: list[Heading] = []
        self._parts: list[str] = []
        self._figures: list[tuple[str, bytes]] = []
        self._ids: set[str] = set()

    # -- structure -------------------------------------------------------------------------------
    def _anchor(self, title: str) -> str:
        base = re.sub(r"[^a-z0-9]+", "-", title.lower()).strip("-")[:60] or "section"
        anchor, n = base, 2
        while anchor in self._ids:
            anchor, n = f"{base}-{n}", n + 1
        self._ids.add(anchor)
        return anchor

    def _heading(self, level: int, title: str, text: str | None) -> str:
        title = _text(title, "title")
        anchor = self._anchor(title)
        self.headings.append(Heading(level, title, anchor))
        self._parts.append(f'<h{level} id="{anchor}">{html.escape(title)}</h{level}>')
        if text is not None and _text(text, "text"):
            self.paragraph(text)
        return anchor

    def part(self, title: str, text: str | None = None) -> str:
        """A top-level part of the page (listed in bold in the contents); returns its anchor."""
        return self._heading(2, title, text)

    def section(self, title: str, text: str | None = None) -> str:
        """A section (within the current part); returns its anchor."""
        return self._heading(3, title, text)

    # -- content ---------------------------------------------------------------------------------
    def paragraph(self, text: str) -> None:
        """A paragraph; ``text`` is trusted HTML (written by posicast itself)."""
        self._parts.append(f"<p>{_text(text, 'text')}</p>")

    def note(self, text: str) -> None:
        """A highlighted note (trusted HTML)."""
        self._parts.append(f'<div class="note">{_text(text, "text")}</div>')

    def code(self, text: str, label: str | None = None, css: str = "code", **data: str) -> None:
        """Preformatted text (escaped), e.g. a command or Python code, after an optional ``label`` (HTML).

        ``data`` become ``data-*`` attributes of the ``<pre>`` (tests and scripts read them).
        """
        if label:
            self._parts.append(f'<p class="label">{_text(label, "label")}</p>')
        attrs = "".join(f' data-{k.replace("_", "-")}="{html.escape(str(val))}"' for k, val in data.items())
        self._parts.append(f'<pre class="{html.escape(css)}"{attrs}>{html.escape(_text(text, "text"))}</pre>')

    def table(self, headers: Sequence[str], rows: Sequence[Sequence[Any]], digits: int | Sequence[int] = 4,
              css: str | None = None) -> None:
        """A table; numbers formatted per column (:func:`format_column`) with ``digits`` decimals (or
        significant digits in scientific columns), one value for every column or one per column.
        Wide tables scroll within the page."""
        heads = [_text(h, "headers") for h in v.sequence(headers, "headers")]
        body = [v.sequence(row, f"rows[{i}]") for i, row in enumerate(v.sequence(rows, "rows"))]
        ncol = max([len(heads)] + [len(r) for r in body])
        if isinstance(digits, Sequence):
            per = [v.integer_in_range(d, "digits", 0, 17) for d in digits]
            if len(per) != ncol:
                raise ValueError(f"digits must have one entry per column ({ncol}), got {len(per)}")
        else:
            per = [v.integer_in_range(digits, "digits", 0, 17)] * ncol
        columns = [format_column([r[j] if j < len(r) else "" for r in body], per[j]) for j in range(ncol)]
        text = [j > 0 and not all(_is_float(r[j]) or isinstance(r[j], Integral) or r[j] is None
                                  for r in body if j < len(r)) for j in range(ncol)]
        body_rows = []
        for i in range(len(body)):
            cells = "".join(f"<td{' class=text' if text[j] else ''}>{columns[j][i]}</td>" for j in range(len(body[i])))
            body_rows.append(f"<tr>{cells}</tr>")
        head = "".join(f"<th{' class=text' if j < ncol and text[j] else ''}>{html.escape(h)}</th>"
                       for j, h in enumerate(heads))
        klass = " ".join(c for c in (css, "wide" if ncol > WIDE_COLUMNS else None) if c)
        cls = f' class="{klass}"' if klass else ""
        self._parts.append(f'<div class="tablewrap"><table{cls}><tr>{head}</tr>{"".join(body_rows)}</table></div>')

    def figure(self, fig: Any, name: str, caption: str = "") -> None:
        """Render ``fig`` (a matplotlib figure; closed afterwards) as ``NN_name.png`` and show it with ``caption``."""
        if not callable(getattr(fig, "savefig", None)):
            raise TypeError(f"fig must be a matplotlib Figure, got {type(fig).__name__}")
        if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z0-9_.-]{1,80}", name):
            raise ValueError(f"name must be 1 to 80 letters, digits, '_', '-' or '.', got {name!r}")
        caption = _text(caption, "caption")
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=100, bbox_inches=_bbox(fig))
        _close(fig)
        fname = f"{len(self._figures) + 1:02d}_{name}.png"
        self._figures.append((fname, buf.getvalue()))
        cap = f"<figcaption>{caption}</figcaption>" if caption else ""
        self._parts.append(f'<figure><img src="{fname}" alt="{html.escape(name)}">{cap}</figure>')

    # -- output ----------------------------------------------------------------------------------
    @property
    def figure_names(self) -> list[str]:
        """The file names of the figures, in order (written next to ``index.html``)."""
        return [name for name, _ in self._figures]

    def toc(self) -> str:
        """The table of contents: parts, each with its sections."""
        items: list[str] = []
        open_sub = False
        for h in self.headings:
            link = f'<a href="#{h.id}">{html.escape(h.title)}</a>'
            if h.level == 2:
                if open_sub:
                    items.append("</ol></li>")
                    open_sub = False
                elif items:
                    items.append("</li>")
                items.append(f"<li>{link}")
            else:
                if not open_sub:
                    items.append("<ol>" if items else "<li><ol>")
                    open_sub = True
                items.append(f"<li>{link}</li>")
        if items:
            items.append("</ol></li>" if open_sub else "</li>")
        return f'<nav class="toc" id="contents"><b>Contents</b><ol>{"".join(items)}</ol></nav>'

    def html(self, intro: str = "") -> str:
        """The whole page as text: title, ``intro`` (trusted HTML), contents, body."""
        return (f"<!doctype html><html lang='en'><head><meta charset='utf-8'>"
                f"<meta name='viewport' content='width=device-width, initial-scale=1'>"
                f"<title>{html.escape(self.title)}</title><style>{CSS}</style></head><body>"
                f"<h1>{html.escape(self.title)}</h1>{intro}{self.toc()}\n" + "\n".join(self._parts)
                + "</body></html>")

    def write(self, out_dir: str | os.PathLike[str], intro: str = "") -> Path:
        """Write the figures and ``index.html`` into ``out_dir`` (created if needed; each file atomically)."""
        out = output_dir(out_dir)
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ValueError(f"out_dir {str(out)!r} cannot be created: {exc.strerror or exc}") from None
        for fname, data in self._figures:
            atomic_write(out / fname, lambda fh, d=data: fh.write(d))
        page = self.html(intro)
        path = out / "index.html"
        atomic_write(path, lambda fh: fh.write(page.encode("utf-8")))
        return path


def output_dir(value: Any, name: str = "out_dir") -> Path:
    """A directory path to write into: checked (not an existing file), not created."""
    if isinstance(value, bytes) or not isinstance(value, (str, os.PathLike)):
        raise TypeError(f"{name} must be a directory path (str or os.PathLike), got {type(value).__name__}")
    text = os.fspath(value)
    if not isinstance(text, str) or not text.strip() or "\x00" in text:
        raise ValueError(f"{name} must be a directory path, got {text!r}")
    out = Path(text)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{name} {text!r} exists and is not a directory")
    return out


def _close(fig: Any) -> None:
    import matplotlib.pyplot as plt  # noqa: PLC0415 - a third-party import: only when a figure is drawn

    plt.close(fig)


def _text(value: Any, name: str) -> str:
    if not isinstance(value, str):
        raise TypeError(f"{name} must be a string, got {type(value).__name__}")
    return value
