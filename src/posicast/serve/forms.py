"""Reading the designer's forms: the text a person types, as the numbers posicast's functions take.

Every field arrives as text (or a JSON number) and is turned into a number, a list of
coefficients or a :class:`~posicast.Mode` here; the range checks stay with the library
(``Mode.from_hz`` names ``freq_hz``, ``design`` names ``vtol``, ...), so the page shows the
library's own message.  What only the designer limits (the size of the work one click may
start: polynomial degrees, impulse counts, simulation points) is checked here, by name.

>>> coefficients("1, 2 0.5", "plant numerator")
[1.0, 2.0, 0.5]
>>> [(round(m.freq_hz, 6), m.zeta) for m in mode_lines("40 0.05\\n95.5 0.02")]
[(40.0, 0.05), (95.5, 0.02)]
"""

from __future__ import annotations

import math
from typing import Any, Mapping

from .. import _validate as v
from ..modes import Mode

__all__ = ["MAX_DEGREE", "MAX_MODES", "number", "optional_number", "coefficients", "mode_lines", "text_field"]

#: Largest polynomial degree of a plant or controller typed into the page (the root finder's work
#: grows with it; the seeds' plants are of degree <= 6).
MAX_DEGREE = 40
#: Largest number of modes typed by hand.
MAX_MODES = 6


def text_field(form: Mapping[str, Any], key: str, default: str = "") -> str:
    """The text of field ``key`` (``default`` when absent); TypeError for anything but text or a number."""
    value = form.get(key, default)
    if value is None:
        return default
    if isinstance(value, bool) or not isinstance(value, (str, int, float)):
        raise TypeError(f"{key} must be text or a number, got {type(value).__name__}")
    return str(value).strip()


def _finite(text: str, name: str, kind: str, finite: str) -> float:
    """``text`` as a finite float: ValueError "``name`` must be ``kind`` / ``finite``, got ..." otherwise."""
    try:
        x = float(text)
    except ValueError:
        raise ValueError(f"{name} must be {kind}, got {text!r}") from None
    if not math.isfinite(x):
        raise ValueError(f"{name} must be {finite}, got {text}")
    return x


def number(form: Mapping[str, Any], key: str, name: str | None = None, default: float | None = None) -> float:
    """Field ``key`` as a finite float; ValueError naming ``name`` (default ``key``) otherwise.

    >>> number({"fs": "1000"}, "fs", "sample_rate")
    1000.0
    >>> number({"fs": "fast"}, "fs", "sample_rate")
    Traceback (most recent call last):
    ...
    ValueError: sample_rate must be a number, got 'fast'
    """
    name = name or key
    text = text_field(form, key)
    if text == "":
        if default is None:
            raise ValueError(f"{name} is required")
        return default
    return _finite(text, name, "a number", "finite")


def optional_number(form: Mapping[str, Any], key: str, name: str | None = None) -> float | None:
    """Field ``key`` as a float, or None when empty or ``auto``."""
    text = text_field(form, key)
    if text == "" or text.lower() == "auto":
        return None
    return number(form, key, name)


def coefficients(text: str, name: str) -> list[float]:
    """Polynomial coefficients typed as ``"1 2 0.5"`` or ``"1, 2, 0.5"`` (descending powers)."""
    if not isinstance(text, str):
        raise TypeError(f"{name} must be text, got {type(text).__name__}")
    parts = text.replace(",", " ").replace(";", " ").split()
    if not parts:
        raise ValueError(f"{name} must not be empty")
    out = [_finite(p, name, "numbers separated by spaces", "finite numbers") for p in parts]
    while len(out) > 1 and out[0] == 0.0:  # leading zeros do not raise the degree
        out.pop(0)
    if len(out) - 1 > MAX_DEGREE:
        raise ValueError(f"{name} has degree {len(out) - 1}; the designer accepts degree <= {MAX_DEGREE}")
    return out


def mode_lines(text: str) -> list[Mode]:
    """Modes typed one per line as ``frequency_Hz damping``."""
    if not isinstance(text, str):
        raise TypeError(f"modes must be text, got {type(text).__name__}")
    rows = [ln.replace(",", " ").split() for ln in text.splitlines() if ln.strip() and not ln.strip().startswith("#")]
    if not rows:
        raise ValueError("modes must be one 'frequency_Hz damping' pair per line, got nothing")
    if len(rows) > MAX_MODES:
        raise ValueError(f"modes: at most {MAX_MODES} modes, got {len(rows)}")
    out = []
    for k, row in enumerate(rows, 1):
        if len(row) != 2:
            raise ValueError(f"modes line {k} must be 'frequency_Hz damping', got {' '.join(row)!r}")
        f = number({"f": row[0]}, "f", f"modes line {k}: frequency")
        z = number({"z": row[1]}, "z", f"modes line {k}: damping")
        z = v.real_in_range(z, f"modes line {k}: damping", 0.0, 1.0, hi_open=True, hint=" (an underdamped mode)")
        out.append(Mode.from_hz(v.positive(f, f"modes line {k}: frequency"), z))
    return out
