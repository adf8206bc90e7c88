"""Argument checks shared by the public entry points (one clear message each)."""

from __future__ import annotations

import functools
import math
import warnings
from numbers import Integral, Real
from typing import Any

import numpy as np


def real(value: Any, name: str) -> float:
    """A finite real scalar, or TypeError/ValueError naming ``name``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (Real, np.floating, np.integer)):
        raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {v}")
    return v


def positive(value: Any, name: str) -> float:
    v = real(value, name)
    if v <= 0:
        raise ValueError(f"{name} must be > 0, got {v:g}")
    return v


def in_open_interval(value: Any, name: str, lo: float, hi: float) -> float:
    v = real(value, name)
    if not lo < v < hi:
        raise ValueError(f"{name} must be in ({lo:g}, {hi:g}), got {v:g}")
    return v


def integer(value: Any, name: str, minimum: int) -> int:
    if isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be an integer, got bool")
    if isinstance(value, (float, np.floating)) and float(value).is_integer():
        value = int(value)
    if not isinstance(value, (Integral, np.integer)):
        raise TypeError(f"{name} must be an integer, got {type(value).__name__}")
    v = int(value)
    if v < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {v}")
    return v


def real_array(value: Any, name: str) -> np.ndarray:
    try:
        is_complex = np.iscomplexobj(value)
    except (TypeError, ValueError) as exc:  # ragged nesting
        raise TypeError(f"{name} must be an array of real numbers (rectangular)") from exc
    if is_complex:  # np.asarray(..., float) would drop the imaginary part with only a warning
        raise TypeError(f"{name} must be an array of real numbers, got complex numbers")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be an array of real numbers") from exc
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (no NaN or inf)")
    return arr


# --- appended: strict scalar/array checks (huge integers, complex, strings, empty arrays) ---


def finite_real(value: Any, name: str) -> float:
    """:func:`real`, and an integer too large for a float is a ValueError naming ``name``."""
    if isinstance(value, (Integral, np.integer)) and not isinstance(value, (bool, np.bool_)):
        try:
            float(value)
        except OverflowError:
            raise ValueError(f"{name} must be finite, got an integer of {len(str(abs(int(value))))} digits") from None
    return real(value, name)


def real_in_range(value: Any, name: str, lo: float, hi: float, *, lo_open: bool = False,
                  hi_open: bool = False, hint: str = "") -> float:
    """A finite real in ``[lo, hi]`` (ends open on request); the message shows the interval."""
    x = finite_real(value, name)
    if not ((x > lo if lo_open else x >= lo) and (x < hi if hi_open else x <= hi)):
        span = f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
        raise ValueError(f"{name} must be in {span}, got {x:g}{hint}")
    return x


def integer_in_range(value: Any, name: str, minimum: int, maximum: int, hint: str = "") -> int:
    """:func:`integer` with an upper bound; ``hint`` is appended to the message (e.g. why)."""
    k = integer(value, name, minimum)
    if k > maximum:
        shown = f"{k}" if k < 10**15 else f"{float(k):.3g}"
        raise ValueError(f"{name} must be an integer in [{minimum}, {maximum}], got {shown}{hint}")
    return k


def strict_real_array(value: Any, name: str, *, allow_empty: bool = False) -> np.ndarray:
    """Real numbers as a float array: strings, bools, complex and other objects are a TypeError,
    NaN/inf, integers too large for a float and (unless ``allow_empty``) empty input a ValueError."""
    if isinstance(value, (str, bytes)):
        raise TypeError(f"{name} must be a real number or an array of real numbers, got {type(value).__name__}")
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError) as exc:  # ragged nesting
        raise TypeError(f"{name} must be a real number or a rectangular array of real numbers") from exc
    kind = arr.dtype.kind
    if kind == "O":
        arr = np.array([finite_real(x, name) for x in arr.ravel()], dtype=float).reshape(arr.shape)
    elif kind in "iuf":
        arr = arr.astype(float)
    else:
        what = {"b": "booleans", "c": "complex numbers", "U": "strings", "S": "bytes"}.get(kind, str(arr.dtype))
        raise TypeError(f"{name} must be real numbers, got {what}")
    if arr.size == 0 and not allow_empty:
        raise ValueError(f"{name} must not be empty")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (no NaN or inf)")
    return arr


# --- appended (issue #13, structural rules): choices, systems, output paths, up-front work estimates ---

#: Image formats a figure may be written in (the extension chooses the format; matplotlib writes each
#: without extra software).  A path without one of these is refused, never guessed.
IMAGE_EXTENSIONS = (".png", ".pdf", ".svg", ".eps", ".ps", ".jpg", ".jpeg", ".tif", ".tiff")


def choice(value: Any, name: str, options: Any) -> str:
    """``value`` is one of the strings ``options``; TypeError for a non-string, ValueError otherwise.

    >>> choice("pd", "controller", ("pd", "pi"))
    'pd'
    """
    opts = tuple(options)
    if not isinstance(value, str):
        raise TypeError(f"{name} must be one of {opts}, got {type(value).__name__} {value!r}")
    if value not in opts:
        raise ValueError(f"{name} must be one of {opts}, got {value!r}")
    return value


def optional_real(value: Any, name: str) -> float | None:
    """None, or a finite real scalar (:func:`finite_real`)."""
    return None if value is None else finite_real(value, name)


def sequence(value: Any, name: str, *, min_len: int = 0) -> list[Any]:
    """A list/tuple (any non-string iterable but a mapping) as a list; TypeError naming ``name``."""
    if isinstance(value, (str, bytes, dict)) or not hasattr(value, "__iter__"):
        raise TypeError(f"{name} must be a sequence, got {type(value).__name__}")
    try:
        out = list(value)
    except TypeError as exc:
        raise TypeError(f"{name} must be a sequence, got {type(value).__name__}") from exc
    if len(out) < min_len:
        raise ValueError(f"{name} must have at least {min_len} entr{'y' if min_len == 1 else 'ies'}, got {len(out)}")
    return out


def labels(value: Any, name: str, count: int) -> list[str] | None:
    """None, or ``count`` strings (one per drawn item)."""
    if value is None:
        return None
    items = sequence(value, name)
    if len(items) != count:
        raise ValueError(f"{name} has {len(items)} entries for {count} item{'s' if count != 1 else ''}")
    for x in items:
        if not isinstance(x, str):
            raise TypeError(f"{name} must be strings, got {type(x).__name__}")
    return items


def axes(value: Any, name: str = "ax") -> Any:
    """None or a matplotlib Axes (TypeError naming ``name`` otherwise)."""
    if value is None:
        return None
    from matplotlib.axes import Axes

    if not isinstance(value, Axes):
        raise TypeError(f"{name} must be a matplotlib Axes (or None for a new figure), got {type(value).__name__}")
    return value


def complex_array(value: Any, name: str) -> np.ndarray:
    """Finite complex numbers as an array (strings, objects, NaN and inf refused, naming ``name``)."""
    if isinstance(value, (str, bytes)) or value is None:
        raise TypeError(f"{name} must be a complex number or an array of them, got {type(value).__name__}")
    try:
        arr = np.asarray(value)
        if arr.dtype.kind not in "iufc":
            arr = np.asarray(arr, dtype=complex) if arr.dtype.kind == "O" else None
        if arr is None:
            raise TypeError
        arr = arr.astype(complex)
    except (TypeError, ValueError, OverflowError):
        raise TypeError(f"{name} must be a complex number or an array of them") from None
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (no NaN or inf)")
    return arr


def path_for_output(value: Any, name: str, extensions: Any = IMAGE_EXTENSIONS) -> Any:
    """Check, before any work, that a file can be written at exactly the path ``value``.

    The path must be a non-empty string or ``os.PathLike``, end in one of ``extensions``
    (case-insensitive; the extension chooses the format, a missing one is refused rather
    than guessed), not name a directory, and sit in an existing, writable directory.
    Returns the ``pathlib.Path``.  Every error is a ValueError/TypeError naming ``name``
    and the user's path.

    >>> path_for_output("fig.svg", "--plot").name
    'fig.svg'
    >>> path_for_output("fig", "--plot")
    Traceback (most recent call last):
    ...
    ValueError: --plot 'fig' has no image extension: use one of .png, .pdf, .svg, .eps, .ps, .jpg, .jpeg, .tif, .tiff
    """
    import os
    from pathlib import Path

    text = path_text(value, name)
    exts = tuple(e.lower() for e in extensions)
    if text.endswith(("/", os.sep)):
        raise ValueError(f"{name} {text!r} is a directory path, not a file")
    path = Path(text)
    if path.suffix.lower() not in exts or path.name.lower() in exts:
        raise ValueError(f"{name} {text!r} has no {'image ' if exts == IMAGE_EXTENSIONS else ''}extension: "
                         f"use one of {', '.join(exts)}")
    if path.is_dir():
        raise ValueError(f"{name} {text!r} is a directory, not a file")
    parent = path.parent
    if not parent.is_dir():
        raise ValueError(f"{name} {text!r}: the directory {str(parent)!r} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ValueError(f"{name} {text!r}: the directory {str(parent)!r} is not writable")
    if path.exists() and not os.access(path, os.W_OK):
        raise ValueError(f"{name} {text!r} exists and is not writable")
    return path


def refuse_large(estimate: float, limit: float, what: str, change: str, unit: str = "") -> None:
    """Refuse work whose up-front ``estimate`` exceeds ``limit``, saying how much and what to change.

    ``what`` names the work ("the simulation's signals"), ``change`` the parameter(s) that
    reduce it; ``unit`` is ``"bytes"`` (shown in GB/MB) or any label.

    >>> refuse_large(3e9, 1e9, "the simulation's signals", "use fewer samples in t", "bytes")
    Traceback (most recent call last):
    ...
    ValueError: the simulation's signals would need about 3 GB (limit 1 GB): use fewer samples in t
    """
    if estimate <= limit:
        return

    def show(x: float) -> str:
        if unit == "bytes":
            for size, u in ((1e9, "GB"), (1e6, "MB"), (1e3, "kB")):
                if x >= size:
                    return f"{x / size:.3g} {u}"
            return f"{x:.3g} bytes"
        return f"{x:.3g}{' ' + unit if unit else ''}"

    raise ValueError(f"{what} would need about {show(estimate)} (limit {show(limit)}): {change}")


# --- lead (issue #14): instances


def instance_of(value: Any, cls: type | tuple[type, ...], name: str, what: str) -> Any:
    """``value`` is an instance of ``cls``, or a TypeError "``name`` must be ``what``, got <type>".

    >>> instance_of(2.0, float, "x", "a float")
    2.0
    """
    if not isinstance(value, cls):
        raise TypeError(f"{name} must be {what}, got {type(value).__name__}")
    return value


# --- layers


def nonnegative(value: Any, name: str, unit: str = "") -> float:
    """A finite real ``>= 0``; ``unit`` (e.g. ``' [s]'``) follows the bound in the message.

    >>> nonnegative(0.0, "delay")
    0.0
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (Real, np.floating, np.integer)):
        raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
    try:
        x = float(value)
    except OverflowError:  # an integer beyond the float range
        x = math.inf
    if not (math.isfinite(x) and x >= 0):
        raise ValueError(f"{name} must be a finite number >= 0{unit}, got {x:g}")
    return x


# --- tune
def pair(value: Any, name: str, what: str = "a (low, high) pair of numbers") -> tuple[Any, Any]:
    """The two items of a length-2 sequence (not a string); TypeError otherwise, saying ``what`` was expected.

    >>> pair((1.0, 2.0), "kp_range")
    (1.0, 2.0)
    """
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__") or len(value) != 2:
        raise TypeError(f"{name} must be {what}, got {type(value).__name__}")
    return value[0], value[1]


def index(value: Any, name: str, size: int, what: str = "an index") -> int:
    """An integer index into ``size`` items (bools refused): TypeError for a non-integer, ValueError
    outside ``[0, size - 1]``; ``what`` names the kind of index in the message.

    >>> index(2, "i", 5, "a line index")
    2
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (Integral, np.integer)):
        raise TypeError(f"{name} must be {what} (int), got {type(value).__name__}")
    if not 0 <= value < size:
        raise ValueError(f"{name} must be {what} in [0, {size - 1}], got {value}")
    return int(value)


# --- lead (issue #14): renamed keywords


def renamed_keywords(**old_to_new: str) -> Any:
    """Decorator: a keyword's old name still works, with a FutureWarning (one word per concept).

    >>> @renamed_keywords(fs="sample_rate")
    ... def f(sample_rate): return sample_rate
    >>> import warnings
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     f(fs=2.0), caught[0].category.__name__
    (2.0, 'FutureWarning')
    """

    def wrap(func: Any) -> Any:
        @functools.wraps(func)
        def inner(*args: Any, **kwargs: Any) -> Any:
            for old, new in old_to_new.items():
                if old in kwargs:
                    if new in kwargs:
                        raise TypeError(f"give {new} only ({old} is its old name)")
                    warnings.warn(f"{func.__name__}: the keyword {old}= is now {new}=", FutureWarning, stacklevel=2)
                    kwargs[new] = kwargs.pop(old)
            return func(*args, **kwargs)

        return inner

    return wrap


# --- issue #17
def ordered_pair(value: Any, name: str, lo: float, hi: float, *, lo_open: bool = False,
                 hi_open: bool = False) -> tuple[float, float]:
    """A ``(low, high)`` pair of reals with ``low <= high``, both in the range ``[lo, hi]`` (ends open as asked).

    >>> ordered_pair((0.9, 1.1), "band", 0.0, 1e3, lo_open=True)
    (0.9, 1.1)
    """
    a, b = pair(value, name)
    a = real_in_range(a, f"{name}[0]", lo, hi, lo_open=lo_open, hi_open=hi_open)
    b = real_in_range(b, f"{name}[1]", lo, hi, lo_open=lo_open, hi_open=hi_open)
    if a > b:
        raise ValueError(f"{name} must be a (low, high) pair with low <= high, got ({a:g}, {b:g})")
    return a, b


# --- review of wave 3: one check of a path argument's text (files and the sweep store's directory)
def path_text(value: Any, name: str, what: str = "file path") -> str:
    """The text of a path argument: a non-empty ``str`` or ``os.PathLike`` (not bytes) without NUL.

    >>> path_text("out.csv", "--csv")
    'out.csv'
    >>> path_text(b"x", "store", "directory path")
    Traceback (most recent call last):
    ...
    TypeError: store must be a directory path (str or os.PathLike), got bytes
    """
    import os

    if isinstance(value, bytes) or not isinstance(value, (str, os.PathLike)):
        raise TypeError(f"{name} must be a {what} (str or os.PathLike), got {type(value).__name__}")
    text = os.fspath(value)
    if not isinstance(text, str) or not text.strip():
        raise ValueError(f"{name} must be a {what}, got {text!r}")
    if "\x00" in text:
        raise ValueError(f"{name} must not contain a NUL character, got {text!r}")
    return text
