"""The repository's own text: no merge-conflict markers left in any file a user or the suite reads."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
_MARKER = re.compile(r"^(<{7} |={7}$|>{7} )", re.MULTILINE)
_TEXT = {".py", ".md", ".toml", ".cfg", ".ini", ".txt", ".json", ".yml", ".yaml", ".html", ".css", ".js"}


def _text_files() -> list[Path]:
    files = [ROOT / "Makefile", ROOT / "README.md", ROOT / "pyproject.toml"]
    for folder in ("src", "tests", "benchmarks", "docs", ".ci"):
        base = ROOT / folder
        if base.is_dir():
            files += [p for p in base.rglob("*") if p.is_file() and p.suffix in _TEXT and ".venv" not in p.parts
                      and "data" not in p.relative_to(ROOT).parts[:2]]
    return [p for p in files if p.exists()]


def test_no_merge_conflict_markers():
    bad = []
    for path in _text_files():
        text = path.read_text(encoding="utf-8", errors="replace")
        for m in _MARKER.finditer(text):
            bad.append(f"{path.relative_to(ROOT)}:{text.count(chr(10), 0, m.start()) + 1}")
    assert not bad, "merge-conflict markers left in: " + ", ".join(bad)


def test_the_check_sees_a_marker():
    """The pattern catches a real conflict block (so the test above can fail)."""
    sample = "a\n<<<<<<< HEAD\nx\n=======\ny\n>>>>>>> branch\n"
    assert len(_MARKER.findall(sample)) == 3
