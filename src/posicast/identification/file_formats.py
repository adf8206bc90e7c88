"""What a file is, by its name and its columns: Klipper's PSD files, RepRapFirmware's accelerometer files.

* Klipper PSD (``TEST_RESONANCES``: ``resonances_<axis>_*.csv``;
  ``SHAPER_CALIBRATE``: ``calibration_data_<axis>_*.csv``):
  ``freq,psd_x,psd_y,psd_z,psd_xyz`` with or without a leading ``#``, Kalico's
  extra ``accel_per_hz`` column, and one column per shaper (``zv(59.0)``) in
  calibration files, kept apart in :attr:`Dataset.shaper_columns`.
* RepRapFirmware accelerometer file (``M956``, Accelerometers.cpp): ``Sample,X,Y,Z``
  (the axes recorded, in g) closed by ``Rate <Hz>, overflows <n>``; kind
  ``"rrf_accelerometer"``, columns ``accel_x`` ... in mm/s^2, time from the rate.
* The axis and the Klipper output named in the file name (:func:`name_info`).
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .csv_reader import Table, file_error
from .dataset import Dataset

__all__ = ["MIN_SAMPLES", "NameInfo", "name_info", "klipper_psd_dataset", "rrf_dataset"]

#: The fewest samples a time record may have.
MIN_SAMPLES = 16
#: A shaper column of Klipper's calibration_data files: "zv(59.0)".
_SHAPER = re.compile(r"([a-z0-9_]+)\(\s*([0-9]+(?:\.[0-9]*)?)\s*\)")
_G = 9806.65  # mm/s^2
_KLIPPER_PREFIX = re.compile(r"(?:^|[^a-z0-9])(resonances|calibration_data|raw_data)_(.*)", re.IGNORECASE)


class NameInfo(NamedTuple):
    """What a file name says: the axis (``"x"``, ``"y"``, ``"z"`` or None) and Klipper's output prefix (or None)."""

    axis: str | None
    klipper_output: str | None


def name_info(p: str) -> NameInfo:
    """(axis, Klipper output prefix) from the file name."""
    name = os.path.basename(p)
    stem = name[:-4] if name.lower().endswith(".csv") else Path(name).stem
    m = _KLIPPER_PREFIX.search(stem)  # also after a prefix of the user's: "ender3_resonances_x_..."
    if m:
        tok = m.group(2).split("_")[0].lower()
        return NameInfo(tok if tok in ("x", "y", "z") else None, m.group(1).lower())
    tok = re.split(r"[-_]", stem)[-1].lower()
    return NameInfo(tok if tok in ("x", "y", "z") else None, None)


def rrf_dataset(tab: Table, axis: str | None) -> Dataset:
    """RepRapFirmware's M956 recording: sample numbers, accelerations in g, the rate on the last line."""
    p = tab.path
    rate = float(tab.rate or 0.0)
    if not rate > 0:
        raise file_error(p, "the closing 'Rate' line gives no sampling rate")
    if tab.n < MIN_SAMPLES:
        raise file_error(p, f"only {tab.n} data rows; at least {MIN_SAMPLES} samples are needed")
    k = tab.col(0)
    if np.any(np.diff(k) != 1):
        i = int(np.flatnonzero(np.diff(k) != 1)[0]) + 1
        raise file_error(p, f"line {tab.line(i)}: sample {k[i]:.0f} follows {k[i - 1]:.0f}: samples are missing")
    columns = {}
    for j, name in enumerate(tab.header[1:], start=1):
        if name not in ("X", "Y", "Z"):
            raise file_error(p, f"line {tab.header_line}: RepRapFirmware records columns X, Y, Z, got {name!r}")
        columns[f"accel_{name.lower()}"] = tab.col(j) * _G
    notes = list(tab.notes) + [f"RepRapFirmware accelerometer file: {rate:g} Hz (its closing line), accelerations "
                               "converted from g to mm/s^2"]
    return Dataset(p, "rrf_accelerometer", (k - k[0]) / rate, columns, rate, False, notes, axis=axis)


def klipper_psd_dataset(tab: Table, low: list[str], axis: str | None, prefix: str | None) -> Dataset:
    """Klipper's PSD file (``resonances`` or ``calibration_data``): frequencies, PSD columns, shaper columns."""
    p = tab.path
    f = tab.col(0)
    bad = np.flatnonzero(np.diff(f) <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise file_error(p, f"line {tab.line(i)}: frequencies must increase ({f[i]:.9g} after {f[i - 1]:.9g})")
    columns: dict[str, np.ndarray] = {}
    shapers: dict[str, np.ndarray] = {}
    freqs: dict[str, float] = {}
    accel_per_hz = None
    notes = list(tab.notes)
    for j, name in enumerate(low[1:], start=1):
        col = tab.col(j)
        m = _SHAPER.fullmatch(name)
        if name == "accel_per_hz" and np.all(col == col[0]):
            accel_per_hz = float(col[0])
        elif m and not name.startswith("psd"):
            if m.group(1) in shapers:
                raise file_error(p, f"line {tab.header_line}: two columns for shaper {m.group(1)!r}")
            shapers[m.group(1)] = col
            freqs[m.group(1)] = float(m.group(2))
        else:
            columns[name] = col
    if prefix == "calibration_data" or shapers:
        out = "calibration_data"
    else:
        out = "resonances"
    return Dataset(p, "klipper_psd", f, columns, notes=notes, axis=axis, klipper_output=out,
                   shaper_columns=shapers, shaper_freqs=freqs, accel_per_hz=accel_per_hz)
