"""posicast's layers point one way (issue #14, acceptance 3).

Every module of ``src/posicast`` is parsed (not imported); each ``import`` of a
posicast module, at module level or inside a function, is checked against the
layer table below: a module may import its own layer or a lower one, never a
higher one.  The reports package ``posicast_reports`` sits above everything and no
posicast module may import it.

Layers (low to high):

0. ``_validate`` (argument checks), ``_lazy`` (lazy public names) and ``_files`` (atomic writes): import nothing of posicast.
1. ``core`` (exact delay transfer functions) and ``modes`` (the Mode value type).
2. ``shapers`` and ``spectra``.
3. ``loops`` and ``cases``: the seeds' plants are loop data (transfer functions and
   modes); they sit with the loops so that the layers above (tune, the CLI's
   ``--case``) may use them and nothing below needs them.
4. ``analysis``, ``simulation``, ``tune``, ``qft``, ``identification`` and ``firmware``: the
   applications.  ``firmware`` (what each printer firmware runs) is imported by
   ``identification`` (the calibration's recommendations) and imports only shapers;
   it shares the layer, and a sideways import within a layer is allowed.
4.5. ``sweeps``: runs the applications over grids and draws (on Dask); above them, below io and cli.
5. ``io`` (export) and ``testing`` (synthetic data, brute-force region check).
6. ``cli``, ``commands``, ``report`` (the user-first HTML report), ``__main__`` and the package's ``__init__`` (the façade that re-exports
   the public names: nothing inside posicast may import ``posicast`` itself).

The test fails on any upward import, naming file and line.  A lazy name table
(``__getattr__, __dir__, __all__ = lazy_names(__name__, TABLE)``, :mod:`posicast._lazy`) is read as
the imports it stands for: each ``"name": ".module"`` entry imports that module.  Imports under
``if TYPE_CHECKING:`` are annotations, never executed, and are not dependencies.
Two explicit lists soften the rule, each entry with its reason: deprecated aliases
(a module ``__getattr__`` that returns a moved name behind a FutureWarning) and the
method twins (``core/verbs.py``: ``G.poles(region)`` *is* ``posicast.poles(G, region)``,
and ``spectra`` builds on ``core``, so the method imports its function when called).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"
PKG = SRC / "posicast"

LAYERS: dict[str, float] = {
    "_validate": 0, "_lazy": 0, "_files": 0,
    "core": 1, "modes": 1,
    "shapers": 2, "spectra": 2,
    "loops": 3, "cases": 3,
    "analysis": 4, "simulation": 4, "tune": 4, "identification": 4, "firmware": 4, "qft": 4,
    "sweeps": 4.5,  # issue #19: maps the applications over parameter spaces; io and cli may use it
    "io": 5, "testing": 5,
    "cli": 6, "commands": 6, "__main__": 6, "": 6,  # "": posicast/__init__.py, the façade
    "report": 6,  # issue #20: the user-first report (posicast report DATA) uses every application, like the CLI
    "serve": 6,  # issue #20: the designer in the browser (posicast serve), beside the command line
}

# Deprecated aliases: (file, imported module) allowed upward inside the module-level __getattr__ only.
DEPRECATED_ALIASES = {
    ("tune/__init__.py", "posicast.testing"),  # posicast.tune.sample_check, RegionCheck
    ("identification/__init__.py", "posicast.testing"),  # posicast.identification.synthetic, simulate, INPUTS, ...
}

# Method twins: (file, imported module) allowed upward at call time only (inside a method, never at module level).
METHOD_TWINS = {
    ("core/verbs.py", "posicast.spectra.systems"),  # QuasiPolynomial/TransferFunction/Shaper/Loop .roots/.poles/...
}

# Known violations (file, line, imported module): none.  An entry must say why, and the list only shrinks.
KNOWN_VIOLATIONS: set[tuple[str, int, str]] = set()


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _layer_of(module: str) -> float:
    """The layer of a posicast module name (``posicast.tune.design`` -> layer of ``tune``)."""
    parts = module.split(".")
    key = parts[1] if len(parts) > 1 else ""
    if key not in LAYERS:
        raise AssertionError(f"{module}: not in the layer table of tests/test_layers.py (add it)")
    return LAYERS[key]


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _dynamic_target(call: ast.Call) -> str | None:
    """The module named by ``importlib.import_module("posicast....")`` or ``__import__("posicast....")``."""
    f = call.func
    name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else ""
    if name not in ("import_module", "__import__") or not call.args:
        return None
    arg = call.args[0]
    if isinstance(arg, ast.Constant) and isinstance(arg.value, str) and arg.value.split(".")[0] in (
            "posicast", "posicast_reports"):
        return arg.value
    return None


def _string_tables(tree: ast.Module) -> dict[str, ast.Dict]:
    """Module-level ``NAME = {...}`` / ``NAME: T = {...}`` dictionaries whose values are all strings."""
    out = {}
    for node in tree.body:
        target = node.targets[0] if isinstance(node, ast.Assign) and len(node.targets) == 1 else \
            node.target if isinstance(node, ast.AnnAssign) else None
        value = node.value if isinstance(node, (ast.Assign, ast.AnnAssign)) else None
        if isinstance(target, ast.Name) and isinstance(value, ast.Dict) and all(
                isinstance(v, ast.Constant) and isinstance(v.value, str) for v in value.values):
            out[target.id] = value
    return out


def _lazy_table(call: ast.Call, tables: dict[str, ast.Dict]) -> ast.Dict | None:
    """The name table of a ``lazy_names(package, TABLE)`` call (a dict literal or a module-level dict)."""
    f = call.func
    name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else ""
    if name != "lazy_names" or len(call.args) < 2:
        return None
    arg = call.args[1]
    return arg if isinstance(arg, ast.Dict) else tables.get(arg.id) if isinstance(arg, ast.Name) else None


def imports_of(path: Path) -> list[tuple[int, str, str | None]]:
    """``(line, absolute module, outermost enclosing function or method, or None)`` for every import in ``path``."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    name = _module_name(path)
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    out: list[tuple[int, str, str | None]] = []
    tables = _string_tables(tree)

    def absolute(module: str) -> str:
        level = len(module) - len(module.lstrip("."))
        if not level:
            return module
        return ".".join(package[: len(package) - level + 1] + ([module[level:]] if module[level:] else []))

    def visit(node: ast.AST, func: str | None) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _is_type_checking(child.test):
                visit(ast.Module(body=child.orelse, type_ignores=[]), func)  # the body: annotations only
                continue
            inner = func
            if func is None and isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                inner = child.name
            if isinstance(child, ast.Call) and _dynamic_target(child):  # importlib.import_module("posicast.x")
                out.append((child.lineno, _dynamic_target(child), func))
            if isinstance(child, ast.Call) and _lazy_table(child, tables) is not None:  # lazy_names(pkg, TABLE)
                out.extend((child.lineno, absolute(v.value), func) for v in _lazy_table(child, tables).values)
            if isinstance(child, ast.Import):
                out.extend((child.lineno, a.name, func) for a in child.names)
            elif isinstance(child, ast.ImportFrom):
                if child.level:
                    base = package[: len(package) - child.level + 1]
                    target = ".".join(base + ([child.module] if child.module else []))
                else:
                    target = child.module or ""
                if child.module is None or target in ("posicast",):  # from . import x: x may be a module
                    out.extend((child.lineno, f"{target}.{a.name}", func) for a in child.names)
                else:
                    out.append((child.lineno, target, func))
            visit(child, inner)

    visit(tree, None)
    return out


def violations(root: Path = PKG) -> list[str]:
    """Every upward import below ``root`` as ``'file:line: module (layer a) imports target (layer b)'``."""
    found = []
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(PKG).as_posix()
        here = _layer_of(_module_name(path))
        for line, target, func in imports_of(path):
            if target.split(".")[0] == "posicast_reports":
                found.append(f"{rel}:{line}: imports {target}: posicast never imports the reports package")
                continue
            if target.split(".")[0] != "posicast":
                continue
            there = _layer_of(target)
            if there <= here:
                continue
            if func == "__getattr__" and (rel, ".".join(target.split(".")[:2])) in DEPRECATED_ALIASES:
                continue
            if func is not None and (rel, target) in METHOD_TWINS:
                continue
            if (rel, line, target) in KNOWN_VIOLATIONS:
                continue
            found.append(f"{rel}:{line}: {_module_name(path)} (layer {here}) imports {target} (layer {there})")
    return found


def test_layers_point_one_way():
    bad = violations()
    assert not bad, "upward imports (see the layer table in tests/test_layers.py):\n" + "\n".join(bad)


def test_known_violations_are_still_there():
    """An entry of KNOWN_VIOLATIONS that no longer occurs must be removed (the list only shrinks)."""
    present = set()
    for path in sorted(PKG.rglob("*.py")):
        rel = path.relative_to(PKG).as_posix()
        present |= {(rel, line, target) for line, target, _ in imports_of(path)}
    stale = sorted(KNOWN_VIOLATIONS - present)
    assert not stale, f"fixed: remove from KNOWN_VIOLATIONS: {stale}"


def test_every_module_has_a_layer():
    for path in PKG.rglob("*.py"):
        _layer_of(_module_name(path))  # raises naming the module


def test_reports_package_is_outside_posicast():
    assert (SRC / "posicast_reports" / "__init__.py").exists()
    assert not (PKG / "demo.py").exists()


@pytest.mark.parametrize("snippet, expected", [
    ("from ..tune import tune_pd\n", "imports posicast.tune (layer 4)"),  # module level, upward
    ("def f():\n    from ..cli import main\n", "imports posicast.cli (layer 6)"),  # function level, upward
    ("import posicast_reports.demo\n", "posicast never imports the reports package"),
    ("from .. import testing\n", "imports posicast.testing (layer 5)"),
    ("import importlib\ndef f():\n    return importlib.import_module('posicast.tune')\n",
     "imports posicast.tune (layer 4)"),  # a dynamic import is an import too
    ("from .._lazy import lazy_names\n_T = {'tune_pd': '..tune', 'Shaper': '.base'}\n"
     "__getattr__, __dir__, __all__ = lazy_names(__name__, _T)\n",
     "imports posicast.tune (layer 4)"),  # a lazy name table is read as its imports
])
def test_a_planted_violation_is_found(tmp_path, monkeypatch, snippet, expected):
    """The check sees upward imports at module and function level (planted in a copy of a layer-2 module)."""
    fake = tmp_path / "src" / "posicast"
    (fake / "shapers").mkdir(parents=True)
    (fake / "shapers" / "planted.py").write_text(snippet)
    monkeypatch.setitem(globals(), "SRC", tmp_path / "src")
    monkeypatch.setitem(globals(), "PKG", fake)
    bad = violations(fake)
    assert len(bad) == 1 and bad[0].startswith("shapers/planted.py:") and expected in bad[0], bad


def test_method_twins_are_allowed_only_at_call_time(tmp_path, monkeypatch):
    fake = tmp_path / "src" / "posicast"
    (fake / "core").mkdir(parents=True)
    (fake / "core" / "verbs.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from ..spectra.rootfinder import Roots\n"
        "class V:\n    def poles(self):\n        from ..spectra.systems import poles\n")
    monkeypatch.setitem(globals(), "SRC", tmp_path / "src")
    monkeypatch.setitem(globals(), "PKG", fake)
    assert violations(fake) == []
    (fake / "core" / "verbs.py").write_text("from ..spectra.systems import poles\n")  # module level: upward
    assert len(violations(fake)) == 1


def test_lower_and_sideways_imports_pass(tmp_path, monkeypatch):
    fake = tmp_path / "src" / "posicast"
    (fake / "tune").mkdir(parents=True)
    (fake / "tune" / "ok.py").write_text("from ..spectra import roots\nfrom ..simulation import simulate\n"
                                         "def g():\n    from .. import _validate as v\n")
    monkeypatch.setitem(globals(), "SRC", tmp_path / "src")
    monkeypatch.setitem(globals(), "PKG", fake)
    assert violations(fake) == []
