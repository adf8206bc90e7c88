"""Figures of the command line: matplotlib on the Agg backend, written atomically at exactly the path given.

:func:`pyplot` is the command line's one matplotlib import: only the subcommands
that draw pay for it.
"""

from __future__ import annotations

from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any, BinaryIO, Callable

from .. import _validate as v
from .._files import atomic_write

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["pyplot", "output_path", "save_atomic", "write_atomic"]


def pyplot() -> ModuleType:
    """``matplotlib.pyplot`` on the file-only Agg backend, imported on first use (the CLI's one matplotlib import)."""
    import matplotlib  # lazy: about half a second that only the drawing subcommands need

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def output_path(value: Any, option: str) -> Path:
    """Check an output figure path before any work (see the module docstring); returns a Path."""
    return v.path_for_output(value, option)


def save_atomic(fig: Figure, out: str, option: str = "--plot") -> None:
    """Write ``fig`` at exactly ``out``, atomically: a hidden temporary file in the same directory,
    renamed onto ``out`` once complete.  On any failure nothing is left behind and the error
    (a one-line ValueError) names ``option`` and the user's path, never the temporary file."""
    try:
        target = output_path(out, option)
        fmt = target.suffix.lower()[1:]
        write_atomic(target, out, option, lambda fh: fig.savefig(fh, format=fmt, dpi=110, bbox_inches="tight"))
    finally:
        pyplot().close(fig)


def write_atomic(target: Path, out: str, option: str, write: Callable[[BinaryIO], Any]) -> None:
    """Call ``write(fh)`` on a temporary file beside ``target`` and rename it onto ``target``
    (:func:`posicast._files.atomic_write`; ``out`` is the user's spelling of the path, for the message)."""
    atomic_write(target, write, name=option, shown=out)
