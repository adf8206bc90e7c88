"""Lazy public names: the one way posicast defers its imports (issue #15).

``import posicast`` and ``posicast --help`` must be quick, and most of posicast's
cost at import is scipy (``scipy.signal`` pulls in ``scipy.stats``) and
matplotlib, which only some functions need.  A package therefore lists its
public names in a table, ``name -> module``, and resolves each name on first use
(PEP 562: a module-level ``__getattr__`` and ``__dir__``):

>>> from posicast._lazy import lazy_names
>>> __getattr__, __dir__, __all__ = lazy_names("posicast", {"Mode": ".modes", "cases": ".cases"})
>>> __all__
['Mode', 'cases']
>>> __getattr__("Mode").__name__
'Mode'

A table entry ``name: ".module"`` means ``from .module import name``; an entry
whose name is the module's own last component (``"cases": ".cases"``) is the
module itself; any other submodule of the package is imported on first access
too (``posicast.tune`` after ``import posicast``, as with eager imports).  The resolved value is stored in the package's namespace, so
``__getattr__`` runs once per name.  Type checkers and IDEs read the same names
from an ``if TYPE_CHECKING:`` block of real imports next to the table (a test
keeps the two in step).  tests/test_layers.py reads every table of this form
as the imports it stands for.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from typing import Any, Callable, Mapping

__all__ = ["lazy_names"]


def lazy_names(package: str, table: Mapping[str, str],
               fallback: Callable[[str], Any] | None = None
               ) -> tuple[Callable[[str], Any], Callable[[], list[str]], list[str]]:
    """``(__getattr__, __dir__, __all__)`` for ``package`` whose public names are ``table``.

    Parameters
    ----------
    package : str
        The package's ``__name__`` (relative module paths are resolved against it).
    table : mapping of str to str
        Public name -> module (relative, ``".shapers"``, or absolute).
    fallback : callable, optional
        Called with a name that is not in the table (e.g. to name a moved
        attribute); it returns the value or raises AttributeError.  Without it
        an unknown name raises the usual AttributeError.
    """
    names = dict(table)

    def __getattr__(name: str) -> Any:
        target = names.get(name)
        if target is None and not name.startswith("__") and importlib.util.find_spec(f"{package}.{name}"):
            target = f".{name}"  # a subpackage or module not imported yet: ``posicast.tune`` after ``import posicast``
        if target is None:
            if fallback is not None:
                return fallback(name)
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module = importlib.import_module(target, package)
        value = module if target.rpartition(".")[2] == name else getattr(module, name)
        setattr(sys.modules[package], name, value)  # the next access is an ordinary attribute
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(names))

    return __getattr__, __dir__, list(names)
