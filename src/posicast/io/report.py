"""A small self-contained HTML report writer (tables, figures, notes).

Figures are written as PNG files next to ``index.html``; the page has no
external dependencies and opens offline.
"""

from __future__ import annotations

import html
import math
from pathlib import Path
from typing import Any, Sequence

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
        self.title = title
        self.out = Path(out_dir)
        self.out.mkdir(parents=True, exist_ok=True)
        self._parts: list[str] = []
        self._n_fig = 0

    def section(self, title: str, text: str | None = None) -> None:
        self._parts.append(f"<h2>{html.escape(title)}</h2>")
        if text:
            self.paragraph(text)

    def paragraph(self, text: str) -> None:
        """A paragraph; ``text`` is trusted HTML (written by posicast itself)."""
        self._parts.append(f"<p>{text}</p>")

    def note(self, text: str) -> None:
        self._parts.append(f'<div class="note">{text}</div>')

    def table(self, headers: Sequence[str], rows: Sequence[Sequence[Any]], digits: int = 4) -> None:
        head = "".join(f"<th>{html.escape(h)}</th>" for h in headers)
        body = "".join("<tr>" + "".join(f"<td>{_fmt(c, digits)}</td>" for c in row) + "</tr>" for row in rows)
        self._parts.append(f"<table><tr>{head}</tr>{body}</table>")

    def figure(self, fig: Any, name: str, caption: str = "") -> None:
        import matplotlib.pyplot as plt

        self._n_fig += 1
        fname = f"{self._n_fig:02d}_{name}.png"
        fig.savefig(self.out / fname, dpi=100, bbox_inches="tight")
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
        path.write_text(page, encoding="utf-8")
        return path
