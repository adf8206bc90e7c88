"""docs/ARCHITECTURE.md stays a true map: every module of the package is named there, and the line counts it
prints are near the files' (they drifted to half the real size of cli.py before issue #20's README walk)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "posicast"
DOC = ROOT / "docs" / "ARCHITECTURE.md"
_COUNTED = re.compile(r"`([\w/]+\.py)`\s+\((\d+)")


def _lines(path: Path) -> int:
    with open(path, encoding="utf-8") as fh:
        return sum(1 for _ in fh)


def _modules() -> list[str]:
    return sorted(str(p.relative_to(PACKAGE)) for p in PACKAGE.rglob("*.py")
                  if p.name != "__init__.py" and "static" not in p.parts)


def test_every_module_is_named() -> None:
    text = DOC.read_text(encoding="utf-8")
    missing = [m for m in _modules()
               if f"`{m}`" not in text and not (f"`{Path(m).name}`" in text and f"`{Path(m).parent}/`" in text)]
    assert not missing, "modules not named in docs/ARCHITECTURE.md: " + ", ".join(missing)


def test_printed_line_counts_are_near_the_files() -> None:
    """A count may lag a small edit (other branches change the files), not a rewrite: within 35 % or 60 lines."""
    text = DOC.read_text(encoding="utf-8")
    counted = [(m.group(1), int(m.group(2))) for m in _COUNTED.finditer(text)]
    assert len(counted) > 80  # the per-module list is there and the pattern reads it
    stale = []
    for rel, printed in counted:
        path = PACKAGE / rel
        if not path.exists():
            stale.append(f"{rel}: no such module")
            continue
        real = _lines(path)
        if abs(real - printed) > max(60, 0.35 * printed):
            stale.append(f"{rel}: printed {printed}, has {real}")
    assert not stale, "stale entries in docs/ARCHITECTURE.md: " + "; ".join(stale)


def test_the_count_check_sees_a_stale_count(tmp_path) -> None:
    """The pattern reads both list styles of the document (so the check above can fail)."""
    sample = "- `cli.py` (240): Command line\n  `commands/shaping.py` (104: `design`)"
    assert [(m.group(1), int(m.group(2))) for m in _COUNTED.finditer(sample)] == [("cli.py", 240), ("commands/shaping.py", 104)]
