"""Writing a file atomically: the one way posicast writes what a user asked for.

A hidden temporary file beside the target is written, given the usual permissions (``mkstemp``
makes it private, 0600) and renamed onto the target once complete, so a failure never leaves a
half-written file or a stray temporary behind.  Used by the command line's figures and exports,
the HTML report and the sweep tables.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Any, BinaryIO, Callable

__all__ = ["atomic_write"]


def atomic_write(path: str | os.PathLike[str], write: Callable[[BinaryIO], Any], *, name: str | None = None,
                 shown: str | None = None) -> None:
    """Call ``write(binary file)`` on a temporary file beside ``path``, then rename it onto ``path``.

    Raises
    ------
    ValueError
        ``"[name: ]cannot write 'shown': reason"`` (``shown`` defaults to ``path``; ``name`` is the
        option or argument that gave it) when the directory, the writing or the rename fails.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> atomic_write(d / "a.txt", lambda fh: fh.write(b"hello"))
    >>> (d / "a.txt").read_text(), sorted(p.name for p in d.iterdir())
    ('hello', ['a.txt'])
    """
    target = Path(path)
    tmp = None
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part", dir=target.parent)
        with os.fdopen(fd, "wb") as fh:
            write(fh)
        mask = os.umask(0)  # mkstemp makes the file private (0600): give it the usual mode
        os.umask(mask)
        os.chmod(tmp, 0o666 & ~mask)
        os.replace(tmp, target)
        tmp = None
    except (OSError, ValueError, RuntimeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc).splitlines()[0]
        prefix = f"{name}: " if name else ""
        raise ValueError(f"{prefix}cannot write {str(shown if shown is not None else target)!r}: {reason}") from None
    finally:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)
