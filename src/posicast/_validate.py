"""Argument checks shared by the public entry points (one clear message each)."""

from __future__ import annotations

import math
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
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be an array of real numbers") from exc
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (no NaN or inf)")
    return arr
