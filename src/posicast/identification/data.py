"""Reading measured data: CSV with a time column, Klipper accelerometer logs and PSD files.

Every problem is reported as one ``ValueError`` line naming the file line or
column; nothing is returned half-parsed.

* Generic CSV: a header line of column names, then comma-separated numbers.
  ``#`` comment lines and blank lines are skipped anywhere; a UTF-8 byte-order
  mark, Windows (CRLF) or old-Mac (CR) line ends, spaces around values and a
  trailing comma on a line are accepted.  The header is the line of names just
  before the first data row with as many fields as that row (a leading ``#`` is
  allowed, so Klipper's ``#time,accel_x,...`` is a header while a ``#`` comment
  line before it is not); duplicate names are refused.
* Time column: ``time``, ``t`` or ``timestamp``; else one of those with a unit
  (``time_ms``, ``t[ms]``, ``time (us)``, ``time_s``, ``t/ns``, ``time_min``),
  converted to seconds with a note (an unknown unit is refused); else the first
  column, in seconds.
* Klipper raw accelerometer log (``ACCELEROMETER_MEASURE``, ``TEST_RESONANCES
  OUTPUT=raw_data``): ``#time,accel_x,accel_y,accel_z`` in s and mm/s^2, also
  after Klipper's early ``##drops=...`` statistics line.
* Klipper PSD files (``resonances_*``, ``calibration_data_*``) and RepRapFirmware
  accelerometer files (``M956``): see :mod:`posicast.identification.file_formats`.

Uneven sampling: steps within 1 % of the median are taken as they are (the
rate from the mean step).  Time stamps that all lie within half a step of the
least-squares uniform grid (Klipper's jitter, e.g. +-0.3 of a step, which makes
single steps anywhere from 0.4 to 1.6 steps long) are resampled by linear
interpolation onto a uniform grid from the first to the last stamp; anything
farther off is refused: a gap of missing samples (a missing sample puts two
neighbours at least half a step off any uniform grid) or a change of rate.

Parsing, speed and memory: :mod:`.csv_reader`; Klipper's PSD and RepRapFirmware files:
:mod:`.file_formats`; the result: :class:`~.dataset.Dataset`.
"""

from __future__ import annotations

import os
import re
from typing import Callable, NamedTuple

import numpy as np

from .csv_reader import KLIPPER_RAW, MAX_BYTES, Table, file_error, max_bytes_arg, open_path, plural, read_csv_table
from .csv_reader import read_table  # noqa: F401 (re-exported: posicast.identification.data.read_table)
from .dataset import Dataset
from .file_formats import MIN_SAMPLES, klipper_psd_dataset, name_info, rrf_dataset

__all__ = ["Dataset", "load_csv", "read_table", "MAX_BYTES"]

# time-column units: name -> (multiply, divide) to get seconds (division keeps exact decimals exact)
_UNITS: dict[str, tuple[float, float]] = {
    name: conv
    for names, conv in (
        (("s", "sec", "secs", "second", "seconds"), (1.0, 1.0)),
        (("ms", "msec", "msecs", "millisecond", "milliseconds"), (1.0, 1e3)),
        (("us", "\u00b5s", "\u03bcs", "usec", "usecs", "microsecond", "microseconds"), (1.0, 1e6)),
        (("ns", "nsec", "nsecs", "nanosecond", "nanoseconds"), (1.0, 1e9)),
        (("min", "mins", "minute", "minutes"), (60.0, 1.0)),
    )
    for name in names
}
_TIME_WORDS = ("time", "t", "timestamp")
_TIME_UNIT = re.compile(
    r"(time|t|timestamp)\s*(?:[_\s]\s*([^\s\[\]()/]+)|\[\s*([^\]]*?)\s*\]|\(\s*([^)]*?)\s*\)|/\s*(\S+))")


class TimeColumn(NamedTuple):
    """The time column: its index, ``(multiply, divide)`` to get seconds, and a note (None in seconds)."""

    index: int
    multiply: float
    divide: float
    note: str | None


class UniformGrid(NamedTuple):
    """A uniform time grid (None when the stamps already are one), the sampling rate, and a note."""

    t: np.ndarray | None
    fs: float
    note: str | None


def _time_column(p: str, header: list[str], hl: int) -> TimeColumn:
    """Index of the time column, (multiply, divide) to seconds, and a note."""
    low = [h.strip().lower() for h in header]
    for j, name in enumerate(low):
        if name in _TIME_WORDS:
            return TimeColumn(j, 1.0, 1.0, None)
    for j, name in enumerate(low):
        m = _TIME_UNIT.fullmatch(name)
        if m:
            unit = next(g for g in m.groups()[1:] if g is not None).strip()
            if unit not in _UNITS:
                raise file_error(p, f"line {hl}: time column {header[j]!r} has an unknown unit {unit!r}; known units: "
                              "s, ms, us, ns, min (e.g. 'time_ms', 't[us]'); name it 'time' for seconds")
            mul, div = _UNITS[unit]
            note = None if mul == div == 1.0 else f"time column {header[j]!r} is in {unit}: converted to seconds"
            return TimeColumn(j, mul, div, note)
    return TimeColumn(0, 1.0, 1.0, None)


def _uniform(p: str, t: np.ndarray, line_of: Callable[[int], int], resample: str) -> UniformGrid:
    """(uniform grid or None if ``t`` already is one, sampling rate, note)."""
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        if dt[i - 1] == 0:
            raise file_error(p, f"line {line_of(i)}: duplicated time {t[i]:.9g}")
        raise file_error(p, f"line {line_of(i)}: time {t[i]:.9g} goes back (previous {t[i - 1]:.9g}); times must increase")
    h = float(np.median(dt))
    dev = np.abs(dt - h)
    i = int(np.argmax(dev))
    if dev[i] <= 0.01 * h:  # uniform enough as it is; the mean step is the better rate (rounded stamps)
        return UniformGrid(None, (t.size - 1) / float(t[-1] - t[0]), None)
    if resample == "never":
        raise file_error(p, f"line {line_of(i + 1)}: uneven sampling (step {dt[i]:.3g} s against a median step of "
                      f"{h:.3g} s, more than 1 % off); resampling is off (resample='never')")
    # Least-squares uniform grid through the time stamps: jitter within half a step of it is
    # resampled; a missing sample puts two neighbours at least half a step off any grid.
    n = t.size
    kc = np.arange(n, dtype=float)
    kc -= (n - 1) / 2.0
    tm = float(t.mean())
    r = t - tm
    hfit = float(np.dot(kc, r) / np.dot(kc, kc))
    kc *= hfit
    r -= kc
    np.abs(r, out=r)
    worst = int(np.argmax(r))
    off = float(r[worst]) / hfit
    del kc, r
    if off >= 0.5:
        g = int(np.argmax(dt))
        if dt[g] > 1.5 * h:
            missing = plural(max(1, round(dt[g] / h) - 1), "missing sample")
            raise file_error(p, f"line {line_of(g + 1)}: gap of {dt[g]:.3g} s in the time column (median step {h:.3g} s: "
                          f"about {missing}); time stamps may be at most half a step off a uniform grid: "
                          "refusing to interpolate over missing samples")
        raise file_error(p, f"line {line_of(worst)}: time {t[worst]:.9g} is {off:.2f} steps off the best uniform grid "
                      f"(step {hfit:.3g} s); time stamps may be at most half a step off a uniform grid "
                      "(did the sampling rate change?)")
    hu = float((t[-1] - t[0]) / (n - 1))  # mean step
    tu = t[0] + hu * np.arange(n)
    return UniformGrid(tu, 1.0 / hu, f"uneven time stamps (up to {off:.2f} of a step off a uniform grid) resampled to "
                                   f"{1.0 / hu:.6g} Hz by linear interpolation")


def load_csv(path: str | os.PathLike[str], *, resample: str = "auto", max_bytes: int | None = MAX_BYTES) -> Dataset:
    """Read a CSV / Klipper file into a :class:`Dataset` (see the module docstring).

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    resample : {"auto", "never"}
        Resample jittered time stamps (``"auto"``) or refuse them.
    max_bytes : int or None
        Refuse a file whose numbers (and a resampled copy) would take more memory than
        this, estimated from the file size before reading (default :data:`MAX_BYTES`,
        2 GiB); None: no limit.

    Examples
    --------
    >>> import tempfile, os
    >>> fn = os.path.join(tempfile.mkdtemp(), "d.csv")
    >>> _ = open(fn, "w").write("time,u,y\\n" + "".join(f"{k/100},{k > 3:d},{k/7}\\n" for k in range(20)))
    >>> d = load_csv(fn)
    >>> d.kind, round(d.sample_rate), list(d.columns)
    ('csv', 100, ['u', 'y'])
    >>> _ = open(fn, "w").write("time_ms,y\\n" + "".join(f"{10 * k},{k}\\n" for k in range(20)))
    >>> round(load_csv(fn).sample_rate)  # milliseconds: 100 Hz, not 0.1 Hz
    100
    >>> _ = open(fn, "w").write("time,u,y\\n0,1,2\\n0.01,1,x\\n")
    >>> load_csv(fn)
    Traceback (most recent call last):
    ...
    ValueError: ...d.csv: line 3, column 'y': 'x' is not a number
    >>> fn = os.path.join(tempfile.mkdtemp(), "calibration_data_y_20240101_120000.csv")
    >>> _ = open(fn, "w").write("freq,psd_x,psd_y,psd_z,psd_xyz,zv(59.0)\\n"
    ...                         "5.0,1.0e+02,2.0e+03,3.0e+01,2.1e+03,0.125\\n"
    ...                         "10.0,2.0e+02,4.0e+03,1.0e+01,4.2e+03,0.250\\n")
    >>> d = load_csv(fn)
    >>> d.kind, d.klipper_output, d.axis, list(d.columns), d.shaper_freqs
    ('klipper_psd', 'calibration_data', 'y', ['psd_x', 'psd_y', 'psd_z', 'psd_xyz'], {'zv': 59.0})
    """
    if not isinstance(resample, str):
        raise TypeError(f"resample must be 'auto' or 'never', got {type(resample).__name__}")
    if resample not in ("auto", "never"):
        raise ValueError(f"resample must be 'auto' or 'never', got {resample!r}")
    p = open_path(path)
    tab = read_csv_table(p, max_bytes_arg(max_bytes))
    low = [h.lower() for h in tab.header]
    axis, prefix = name_info(p)
    if low[0] == "freq" and any(h.startswith("psd") for h in low[1:]):
        return klipper_psd_dataset(tab, low, axis, prefix)
    if tab.header[0] == "Sample" and tab.rate is not None:
        return rrf_dataset(tab, axis)
    return _time_record(tab, low, axis, prefix, resample)


def _time_record(tab: Table, low: list[str], axis: str | None, prefix: str | None, resample: str) -> Dataset:
    """A CSV with a time column (or Klipper's raw accelerometer log): seconds, a uniform grid, the signals."""
    p, header = tab.path, tab.header
    kind = "klipper_raw" if tuple(low) == KLIPPER_RAW else "csv"
    tcol, mul, div, tnote = _time_column(p, header, tab.header_line)
    names = [h for j, h in enumerate(header) if j != tcol]
    if not names:
        raise file_error(p, "no signal columns besides time")
    n = tab.n
    if n < MIN_SAMPLES:
        if n == 1:
            raise file_error(p, f"line {tab.line(0)}: a single data row; at least {MIN_SAMPLES} samples are needed")
        raise file_error(p, f"only {n} data rows; at least {MIN_SAMPLES} samples are needed")
    t = tab.col(tcol)
    if mul != 1.0:
        t = t * mul
    if div != 1.0:
        t = t / div
    notes = list(tab.notes)
    if tnote:
        notes.append(tnote)
    tu, fs, rnote = _uniform(p, t, tab.line, resample)
    cols = [j for j in range(len(header)) if j != tcol]
    if tu is None:
        columns = {header[j]: tab.col(j) for j in cols}
        tu = t
    else:
        columns = {header[j]: np.interp(tu, t, tab.col(j)) for j in cols}
        notes.append(rnote)
    t0 = float(tu[0])
    ds = Dataset(p, kind, tu - t0, columns, fs, rnote is not None, notes, axis=axis,
                 klipper_output="raw_data" if kind == "klipper_raw" and prefix == "raw_data" else None, t0=t0)
    return ds
