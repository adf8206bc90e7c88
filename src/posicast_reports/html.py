"""A small self-contained HTML report writer (tables, figures, notes).

Figures are written as PNG files next to ``index.html``; the page has no
external dependencies and opens offline.
"""

from __future__ import annotations

import html
import math
import os
import re
import tempfile
from pathlib import Path
from typing import Any, Sequence

import matplotlib.pyplot as plt

from posicast import _validate as v

__all__ = ["Report"]

_CSS = """
body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
h1{border-bottom:2px solid #345}h2{margin-top:2em;border-bottom:1px solid #ccc}
table{border-collapse:collapse;margin:1em 0;font-size:0.9em}
td,th{border:1px solid #bbb;padding:3px 8px;text-align:right}th{background:#eef}
td:first-child,th:first-child{text-align:left}
figure{margin:1em 0}figcaption{font-size:0.85em;color:#555}
.note{background:#fff8e0;border-left:4px solid #e0a000;padding:0.5em 1em;margin:1em 0}
code{background:#f3f3f3;padding:0 3px}
"""


def _fmt(value: Any, digits: int = 4) -> str:
    if isinstance(value, float):
        if math.isinf(value):
            return "∞"
        if math.isnan(value):
            return "–"
        if value != 0 and (abs(value) < 1e-3 or abs(value) >= 1e5):
            return f"{value:.{digits - 1}e}"
        return f"{value:.{digits}f}"
    return html.escape(str(value))


class Report:
    """Collects sections and writes ``<out>/index.html``.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> r = Report("demo", d)
    >>> r.section("Numbers")
    >>> r.table(["x", "y"], [["a", 1.0]])
    >>> (d / "index.html").exists() is False and r.write().name
    'index.html'
    """

    def __init__(self, title: str, out_dir: str | Path) -> None:
        self.title = _text(title, "title")
        if isinstance(out_dir, bytes) or not isinstance(out_dir, (str, os.PathLike)):
            raise TypeError(f"out_dir must be a directory path (str or os.PathLike), got {type(out_dir).__name__}")
        text = os.fspath(out_dir)
        if not isinstance(text, str) or not text.strip() or "\x00" in text:
            raise ValueError(f"out_dir must be a directory path, got {text!r}")
        self.out = Path(text)
        if self.out.exists() and not self.out.is_dir():
            raise ValueError(f"out_dir {text!r} exists and is not a directory")
        try:
            self.out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ValueError(f"out_dir {text!r} cannot be created: {exc.strerror or exc}") from None
        self._parts: list[str] = []
        self._n_fig = 0

    def section(self, title: str, text: str | None = None) -> None:
        self._parts.append(f"<h2>{html.escape(_text(title, 'title'))}</h2>")
        if text is not None and _text(text, "text"):
            self.paragraph(text)

    def paragraph(self, text: str) -> None:
        """A paragraph; ``text`` is trusted HTML (written by posicast itself)."""
        self._parts.append(f"<p>{_text(text, 'text')}</p>")

    def note(self, text: str) -> None:
        self._parts.append(f'<div class="note">{_text(text, "text")}</div>')

    def table(self, headers: Sequence[str], rows: Sequence[Sequence[Any]], digits: int = 4) -> None:
        heads = [_text(h, "headers") for h in v.sequence(headers, "headers")]
        digits = v.integer_in_range(digits, "digits", 0, 17)
        body_rows = []
        for i, row in enumerate(v.sequence(rows, "rows")):
            cells = v.sequence(row, f"rows[{i}]")
            body_rows.append("<tr>" + "".join(f"<td>{_fmt(c, digits)}</td>" for c in cells) + "</tr>")
        head = "".join(f"<th>{html.escape(h)}</th>" for h in heads)
        self._parts.append(f"<table><tr>{head}</tr>{''.join(body_rows)}</table>")

    def figure(self, fig: Any, name: str, caption: str = "") -> None:
        """Write ``fig`` as ``NN_name.png`` next to the page (atomically) and show it with ``caption``."""
        if not callable(getattr(fig, "savefig", None)):
            raise TypeError(f"fig must be a matplotlib Figure, got {type(fig).__name__}")
        if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z0-9_.-]{1,80}", name):
            raise ValueError(f"name must be 1 to 80 letters, digits, '_', '-' or '.', got {name!r}")
        caption = _text(caption, "caption")
        self._n_fig += 1
        fname = f"{self._n_fig:02d}_{name}.png"
        _atomic(self.out / fname, lambda fh: fig.savefig(fh, format="png", dpi=100, bbox_inches="tight"))
        plt.close(fig)
        cap = f"<figcaption>{caption}</figcaption>" if caption else ""
        self._parts.append(f'<figure><img src="{fname}" alt="{html.escape(name)}" style="max-width:100%">{cap}</figure>')

    def write(self) -> Path:
        page = (
            f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(self.title)}</title>"
            f"<style>{_CSS}</style></head><body><h1>{html.escape(self.title)}</h1>"
            + "\n".join(self._parts)
            + "</body></html>"
        )
        path = self.out / "index.html"
        _atomic(path, lambda fh: fh.write(page.encode("utf-8")))
        return path


def _text(value: Any, name: str) -> str:
    if not isinstance(value, str):
        raise TypeError(f"{name} must be a string, got {type(value).__name__}")
    return value


def _atomic(path: Path, write: Any) -> None:
    """Write through ``write(binary file)`` to a temporary file next to ``path``, then rename it onto ``path``;
    nothing is left behind on error (a ValueError naming ``path``)."""
    tmp = None
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
        with os.fdopen(fd, "wb") as fh:
            write(fh)
        mask = os.umask(0)  # mkstemp makes the file private (0600): give it the usual mode
        os.umask(mask)
        os.chmod(tmp, 0o666 & ~mask)
        os.replace(tmp, path)
        tmp = None
    except OSError as exc:
        raise ValueError(f"cannot write {str(path)!r}: {exc.strerror or exc}") from None
    finally:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)
