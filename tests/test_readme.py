"""The README's front door (issue #20): its first example runs as printed, and every option a README command
line names is an option of that subcommand (the synopsis cannot drift from ``posicast --help``).

The README's other examples are run by the tests of their features (grep tests/ for README.md).
"""

from __future__ import annotations

import doctest
import re
from pathlib import Path

import pytest

from posicast.cli import _build_parser

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")
_OPTION = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*")


def _subparsers(parser):
    """``{name: parser}`` of the subcommands of ``parser`` (empty when it has none)."""
    for action in parser._actions:
        if action.__class__.__name__ == "_SubParsersAction":
            return dict(action.choices)
    return {}


def _options(parser) -> set[str]:
    return set(parser._option_string_actions)


def _command_lines(text: str) -> list[str]:
    """Every ``posicast ...`` command of the README: logical lines of its sh blocks (a line ending in ``\\``
    or an indented continuation belongs to the one before) and inline code spans, comments removed."""
    lines: list[str] = []
    for block in re.findall(r"```sh\n(.*?)```", text, re.S):
        for raw in block.splitlines():
            code = raw.split(" #", 1)[0].rstrip()
            if lines and (raw.startswith(" ") and lines[-1].startswith("posicast ") or lines[-1].endswith("\\")):
                lines[-1] = lines[-1].rstrip("\\") + " " + code.strip()
            else:
                lines.append(code.strip())
    lines += re.findall(r"`(posicast [^`]+)`", text)
    return [line for line in lines if line.startswith("posicast ")]


def _check(line: str, root) -> list[str]:
    """Options of ``line`` that its (sub)command does not have, as ``'line: --option'``."""
    words = line.split()[1:]
    parser = root
    for w in words:
        subs = _subparsers(parser)
        if not subs or w.startswith("-"):
            break
        if w.upper() == w:  # SUBCOMMAND, a placeholder in the prose
            return []
        if "|" in w:  # alternatives (``sweep chart|montecarlo ...``): the options must hold for each
            return [b for alt in w.split("|") for b in _check(line.replace(w, alt, 1), root)]
        if w not in subs:
            return [f"{line}: no subcommand {w!r}"]
        parser = subs[w]
    return [f"{line}: {opt}" for opt in _OPTION.findall(line) if opt not in _options(parser)]


def test_start_here_example_runs_as_printed(monkeypatch) -> None:
    """The first Python block (a real Klipper file -> config lines; a shaper; a certified loop verdict)."""
    monkeypatch.chdir(ROOT)  # its file path is relative to the repository
    start = README.index("## Start here")
    begin = README.index("```python", start) + len("```python")
    block = README[begin: README.index("```", begin)]
    assert README.index("```python", start) < README.index("## Set-up in detail")
    test = doctest.DocTestParser().get_doctest(block, {}, "README start here", "README.md", 0)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    runner.run(test)
    assert runner.summarize().failed == 0 and runner.summarize().attempted >= 5


def test_every_option_the_readme_names_exists() -> None:
    root = _build_parser()
    lines = _command_lines(README)
    assert len(lines) > 30  # the synopsis, the examples and the prose's spans are all read
    bad = [b for line in lines for b in _check(line, root)]
    assert not bad, "README names options posicast does not have:\n" + "\n".join(bad)


@pytest.mark.parametrize("line, found", [
    ("posicast tune --case gantry_crane --nyquistt n.png", ["posicast tune --case gantry_crane --nyquistt n.png: "
                                                            "--nyquistt"]),
    ("posicast sweep chart --gain 0:1:3 --delay-error=-0.5:0.5:11", []),
    ("posicast sweep charts --gain 0:1:3", ["posicast sweep charts --gain 0:1:3: no subcommand 'charts'"]),
    ("posicast SUBCOMMAND --help", []),
    ("posicast sweep chart|montecarlo --n 3", ["posicast sweep chart --n 3: --n"]),
])
def test_the_option_check_can_fail(line, found) -> None:
    assert _check(line, _build_parser()) == found
