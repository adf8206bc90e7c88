"""A print farm's calibration: a folder of resonance-test logs in, one table out.

Each file is one point of a sweep over its path: :func:`posicast.calibrate` identifies
its modes and picks the firmware's shaper; a row of the table holds the axis, the
dominant mode (the largest share of the measured response) and the recommended
setting with its worst-case vibration, smoothing and acceleration limit, beside the
firmware tool's own pick.  A file without a resonance (or unreadable) is a failed
row with its message; the other files go on.  On a cluster the files must be
readable by the workers at the same paths (a shared file system).
"""

from __future__ import annotations

import functools
import os
from pathlib import Path
from typing import Any

from .. import _validate as v
from ..identification import calibrate
from .engine import sweep
from .result import SweepResult

__all__ = ["calibration_point", "calibration_table"]


def calibration_point(path: str, firmware: str = "klipper", axis: str | None = None) -> dict[str, Any]:
    """One file's calibration as a row (see the module docstring); ``firmware`` as in :func:`posicast.calibrate`."""
    c = calibrate(path, firmware=firmware, axis=axis)
    fr = c.files[0]
    ident = fr.identification
    assert ident is not None  # calibrate raised NoModeFound otherwise
    k = max(range(len(ident.modes)), key=lambda i: ident.shares[i] if ident.shares else 0.0)
    rec = c.recommendations[0]
    best = rec.best
    row: dict[str, Any] = {
        "axis": fr.axis or "", "kind": fr.kind, "modes": len(ident.modes),
        "freq_hz": ident.modes[k].freq_hz, "zeta": ident.modes[k].zeta,
        "shaper_type": best.setting.shaper_type.name, "shaper_freq": best.setting.freq,
        "damping": best.setting.damping, "vibration_pct": 100.0 * best.vibration,
        "smoothing": best.smoothing, "max_accel": best.max_accel,
    }
    ref = rec.reference
    row["tool_type"] = ref.setting.shaper_type.name if ref is not None else ""
    row["tool_freq"] = ref.setting.freq if ref is not None else float("nan")
    return row


def calibration_table(folder: str | os.PathLike[str], pattern: str = "*.csv", *, firmware: str = "klipper",
                      **sweep_kwargs: Any) -> SweepResult:
    """Calibrate every file of ``folder`` matching ``pattern`` (sorted by name): one row per file.

    ``sweep_kwargs`` are :func:`posicast.sweep`'s options (``store``, ``client``, ...); the
    table: :meth:`~posicast.sweeps.SweepResult.table` or ``.to_csv(path)``.

    Raises
    ------
    ValueError
        No such folder, or no file matches.
    """
    v.instance_of(folder, (str, os.PathLike), "folder", "a directory path")
    v.instance_of(pattern, str, "pattern", "a glob pattern (str)")
    root = Path(folder)
    if not root.is_dir():
        raise ValueError(f"folder {str(folder)!r} is not a directory")
    files = sorted(str(p) for p in root.glob(pattern) if p.is_file())
    if not files:
        raise ValueError(f"folder {str(folder)!r} has no file matching {pattern!r}")
    return sweep(functools.partial(calibration_point, firmware=firmware), {"path": files}, **sweep_kwargs)
