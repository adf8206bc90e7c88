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
* Klipper PSD (``TEST_RESONANCES``: ``resonances_<axis>_*.csv``;
  ``SHAPER_CALIBRATE``: ``calibration_data_<axis>_*.csv``):
  ``freq,psd_x,psd_y,psd_z,psd_xyz`` with or without a leading ``#``, Kalico's
  extra ``accel_per_hz`` column, and one column per shaper (``zv(59.0)``) in
  calibration files, kept apart in :attr:`Dataset.shaper_columns`.
* RepRapFirmware accelerometer file (``M956``, Accelerometers.cpp): ``Sample,X,Y,Z``
  (the axes recorded, in g) closed by ``Rate <Hz>, overflows <n>``; kind
  ``"rrf_accelerometer"``, columns ``accel_x`` ... in mm/s^2, time from the rate.

Uneven sampling: steps within 1 % of the median are taken as they are (the
rate from the mean step).  Time stamps that all lie within half a step of the
least-squares uniform grid (Klipper's jitter, e.g. +-0.3 of a step, which makes
single steps anywhere from 0.4 to 1.6 steps long) are resampled by linear
interpolation onto a uniform grid from the first to the last stamp; anything
farther off is refused: a gap of missing samples (a missing sample puts two
neighbours at least half a step off any uniform grid) or a change of rate.

Speed and memory: the file is read in 1 MiB blocks of whole lines; each block
is parsed in bulk -- numbers written with a fixed number of decimals, as Klipper
writes them ("%.6f"), as integers then divided by the power of ten (the same
correctly rounded doubles ``float()`` and ``np.loadtxt`` give), 2-4x faster than
``np.loadtxt``; other number formats with ``np.fromstring``, at about
``np.loadtxt``'s speed.  Only a block that fails (comments, blank lines, a bad
cell) goes line by line, which names the exact line.  The numbers go into one
array sized from the file size: the peak memory of :func:`load_csv` on a Klipper
log is about 1.6x the file size (the numbers plus a resampled copy).  A file
whose estimated memory exceeds ``max_bytes`` is refused before it is read.
"""

from __future__ import annotations

import bisect
import math
import os
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import _validate as v

__all__ = ["Dataset", "load_csv", "read_table", "MAX_BYTES"]

MAX_BYTES = 2**31
"""Default ``max_bytes`` of :func:`load_csv`: 2 GiB of estimated memory (about
33 million rows of a four-column Klipper log, a 1.6 GB file: 2.9 hours at 3200 Hz)."""

MIN_SAMPLES = 16

_CHUNK = 1 << 20  # bytes read at a time (whole lines are parsed together)
_MAX_LINE = 1 << 20  # a longer "line" is not CSV
_MAX_HEAD = 1 << 26  # look this far for the first data row
_BOM = b"\xef\xbb\xbf"
_NL_TO_COMMA = bytes.maketrans(b"\n", b",")
_NUM = re.compile(r"[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|nan|inf|infinity)", re.IGNORECASE | re.ASCII)
_FIXED = re.compile(rb"\s*[+-]?\d*\.(\d{1,15})\s*")
_SHAPER = re.compile(r"([a-z0-9_]+)\(\s*([0-9]+(?:\.[0-9]*)?)\s*\)")
KLIPPER_RAW = ("time", "accel_x", "accel_y", "accel_z")
#: RepRapFirmware's M956 accelerometer files: "Sample,X,Y,Z" (axes as recorded, in g), then "Rate <Hz>, overflows <n>".
_RRF_RATE = re.compile(rb"Rate (\d+(?:\.\d+)?), overflows (\d+)")
_G = 9806.65  # mm/s^2
KLIPPER_PSD = ("freq", "psd_x", "psd_y", "psd_z", "psd_xyz")
_KLIPPER_PREFIX = re.compile(r"(?:^|[^a-z0-9])(resonances|calibration_data|raw_data)_(.*)", re.IGNORECASE)

# time-column units: name -> (multiply, divide) to get seconds (division keeps exact decimals exact)
_UNITS: dict[str, tuple[float, float]] = {}
for _names, _conv in (
    (("s", "sec", "secs", "second", "seconds"), (1.0, 1.0)),
    (("ms", "msec", "msecs", "millisecond", "milliseconds"), (1.0, 1e3)),
    (("us", "\u00b5s", "\u03bcs", "usec", "usecs", "microsecond", "microseconds"), (1.0, 1e6)),
    (("ns", "nsec", "nsecs", "nanosecond", "nanoseconds"), (1.0, 1e9)),
    (("min", "mins", "minute", "minutes"), (60.0, 1.0)),
):
    for _n in _names:
        _UNITS[_n] = _conv
_TIME_WORDS = ("time", "t", "timestamp")
_TIME_UNIT = re.compile(
    r"(time|t|timestamp)\s*(?:[_\s]\s*([^\s\[\]()/]+)|\[\s*([^\]]*?)\s*\]|\(\s*([^)]*?)\s*\)|/\s*(\S+))")


@dataclass
class Dataset:
    """A parsed file: uniform time base and named signals.

    Attributes
    ----------
    path : str
        The file.
    kind : {"csv", "klipper_raw", "klipper_psd", "rrf_accelerometer"}
        ``"klipper_psd"``: ``t`` holds the frequencies (Hz) and ``columns`` the PSDs
        (lower-case names ``psd_x`` ... ``psd_xyz``).  ``"rrf_accelerometer"``:
        RepRapFirmware's M956 recording, ``columns`` ``accel_x`` ... in mm/s^2.
    t : ndarray
        Time (s) from the first sample, uniform (resampled if needed); frequencies for PSD files.
    columns : dict of str to ndarray
        The signals (every column but time; for PSD files the PSD columns only).
    fs : float
        Sampling rate (Hz); NaN for PSD files.
    resampled : bool
        The time stamps were resampled onto a uniform grid.
    notes : list of str
        What was done to the data (resampling, time unit conversion, skipped lines).
    axis : {"x", "y", "z"} or None
        The axis named in the file name: Klipper's ``resonances_<axis>_...``,
        ``calibration_data_<axis>_...``, ``raw_data_<axis>_...`` (also after a
        prefix: ``ender3_resonances_x_...``) or a last ``-<axis>``/``_<axis>``
        before ``.csv`` (``adxl345-bed-x.csv``); None for other names and for
        Klipper's diagonal ``axis=1.000,1.000,...`` tests.
    klipper_output : {"resonances", "calibration_data", "raw_data"} or None
        Which Klipper output the file is, by Klipper's file-name prefix:
        ``"resonances"`` (``TEST_RESONANCES`` PSD), ``"calibration_data"``
        (``SHAPER_CALIBRATE`` PSD, also recognised by its shaper columns),
        ``"raw_data"`` (accelerometer log written with ``OUTPUT=raw_data``); a PSD
        file without such a name is ``"resonances"``; None otherwise.
    shaper_columns : dict of str to ndarray
        ``calibration_data`` files: each shaper's response column (header
        ``zv(59.0)`` becomes key ``"zv"``); empty otherwise.
    shaper_freqs : dict of str to float
        The frequency (Hz) written in each shaper column's header.
    accel_per_hz : float or None
        Kalico's ``accel_per_hz`` column (one value for the whole test).
    t0 : float
        The first time stamp of the file in seconds (``t`` starts at 0); NaN for PSD files.
    """

    path: str
    kind: str
    t: np.ndarray
    columns: dict[str, np.ndarray]
    fs: float = float("nan")
    resampled: bool = False
    notes: list[str] = field(default_factory=list)
    axis: str | None = None
    klipper_output: str | None = None
    shaper_columns: dict[str, np.ndarray] = field(default_factory=dict)
    shaper_freqs: dict[str, float] = field(default_factory=dict)
    accel_per_hz: float | None = None
    t0: float = float("nan")

    def column(self, name: str) -> np.ndarray:
        """The signal ``name`` (a key of ``columns``)."""
        if not isinstance(name, str):
            raise TypeError(f"name must be a str (a column name), got {type(name).__name__}")
        if name not in self.columns:
            raise ValueError(f"{self.path}: column {name!r} not found; columns are {', '.join(self.columns)}")
        return self.columns[name]

    def projection(self, axis: str = "auto") -> np.ndarray:
        """Klipper acceleration along ``axis`` ("x", "y", "z") or, for ``"auto"``/``"all"``,
        the projection of the three axes on their principal direction (mean removed)."""
        if axis in ("x", "y", "z"):
            return self.column(f"accel_{axis}")
        if axis not in ("auto", "all"):
            raise ValueError(f"axis must be 'x', 'y', 'z' or 'all', got {axis!r}")
        A = np.column_stack([self.column(f"accel_{a}") for a in "xyz"])
        A = A - A.mean(axis=0)
        _, _, Vt = np.linalg.svd(A[:: max(1, A.shape[0] // 20000)], full_matrices=False)
        return A @ Vt[0]


def _err(path: str, msg: str) -> ValueError:
    return ValueError(f"{path}: {msg}")


def _plural(k: int, word: str) -> str:
    return f"{k} {word}" + ("" if k == 1 else "s")


def _mib(nbytes: float) -> str:
    return f"{nbytes / 2**20:.3g} MiB" if nbytes >= 2**20 else f"{nbytes / 1024:.3g} KiB"


def _isnum(s: str) -> bool:
    return _NUM.fullmatch(s.strip()) is not None


# ----------------------------------------------------------------------------- the table


class _Table:
    """Header, numbers (one contiguous array per column) and the file line of every row."""

    def __init__(self, path: str, header: list[str], header_line: int, ncol: int, cap: int) -> None:
        self.path = path
        self.header = header
        self.header_line = header_line
        self.block = np.empty((ncol, max(cap, 16)))
        self.n = 0
        self._rows: list[int] = []  # row index where a run of consecutive file lines starts
        self._lines: list[int] = []  # its line number
        self.notes: list[str] = []
        self.rate: float | None = None  # RepRapFirmware's closing "Rate <Hz>, overflows <n>" line

    def col(self, j: int) -> np.ndarray:
        return self.block[j, : self.n]

    def line(self, row: int) -> int:
        k = bisect.bisect_right(self._rows, row) - 1
        return self._lines[k] + row - self._rows[k]

    def lines(self) -> np.ndarray:
        out = np.empty(self.n, dtype=np.int64)
        ends = self._rows[1:] + [self.n]
        for r0, r1, ln in zip(self._rows, ends, self._lines):
            out[r0:r1] = ln + np.arange(r1 - r0)
        return out

    def append(self, X: np.ndarray, line0: int, kept: np.ndarray | None, remaining: int) -> None:
        """Rows ``X`` (rows x columns) read from file lines ``line0 + kept`` (consecutive if None);
        ``remaining``: estimated rows still to come."""
        m = X.shape[0]
        if self.n + m > self.block.shape[1]:  # the size estimate was short: grow by what is left
            new = np.empty((self.block.shape[0], int((self.n + m + remaining) * 1.05) + 64))
            new[:, : self.n] = self.block[:, : self.n]
            self.block = new
        self.block[:, self.n : self.n + m] = X.T
        if kept is None:
            starts, lines = [0], [line0]
        else:
            brk = np.flatnonzero(np.diff(kept) != 1) + 1
            starts = [0, *brk.tolist()]
            lines = (line0 + kept[starts]).tolist()
        for s, ln in zip(starts, lines):
            if self._rows and self._lines[-1] + (self.n + s - self._rows[-1]) == ln:
                continue  # continues the previous run
            self._rows.append(self.n + s)
            self._lines.append(int(ln))
        self.n += m


# ----------------------------------------------------------------------------- bulk parsers


def _fromstring(b: bytes, dtype: type) -> np.ndarray | None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "could not be read to its end": the count check catches it
        try:
            return np.fromstring(b, dtype=dtype, sep=",")
        except ValueError:
            return None


def _separators(a: np.ndarray, nlines: int, ncol: int) -> np.ndarray | None:
    """Positions of the field ends if every line has exactly ``ncol`` comma-separated fields."""
    sep = np.flatnonzero((a == 44) | (a == 10))
    if sep.size != nlines * ncol:
        return None
    kinds = a[sep].reshape(nlines, ncol)
    if not (np.all(kinds[:, -1] == 10) and np.all(kinds[:, :-1] == 44)):
        return None
    return sep


def _parse_fixed(c: bytes, nlines: int, ncol: int, decimals: np.ndarray) -> np.ndarray | None:
    """Lines of numbers written with ``decimals[j]`` digits after the point in column j ("%.6f").

    Each number is read as the integer of its digits and divided by 10**decimals:
    an integer below 2**53 and a power of ten up to 1e22 are exact doubles and IEEE
    division rounds correctly, so the result is the correctly rounded value of the
    decimal -- what ``float()``, ``strtod`` and ``np.loadtxt`` return.
    """
    a = np.frombuffer(c, dtype=np.uint8)
    sep = _separators(a, nlines, ncol)
    if sep is None:
        return None
    dots = np.flatnonzero(a == 46)
    if dots.size != sep.size or not (np.all(dots < sep) and np.all(dots[1:] > sep[:-1])):
        return None  # not exactly one point per field
    if not np.array_equal((sep - dots - 1).reshape(nlines, ncol), np.broadcast_to(decimals, (nlines, ncol))):
        return None
    M = _fromstring(c.translate(_NL_TO_COMMA, b"."), np.int64)
    if M is None or M.size != sep.size or np.any((M >= 2**53) | (M <= -(2**53))):
        return None
    X = M.reshape(nlines, ncol) / 10.0 ** decimals
    zero = np.flatnonzero(M == 0)
    if zero.size:  # "-0.000" is -0.0 for strtod
        start = np.where(zero > 0, sep[zero - 1] + 1, 0)
        for _ in range(8):  # skip leading blanks
            ch = a[start]
            sp = (ch == 32) | (ch == 9)
            if not sp.any():
                break
            start = start + sp
        neg = zero[a[start] == 45]
        X.reshape(-1)[neg] = -0.0
    return X


def _parse_float(c: bytes, nlines: int, ncol: int) -> np.ndarray | None:
    a = np.frombuffer(c, dtype=np.uint8)
    if _separators(a, nlines, ncol) is None:
        return None
    x = _fromstring(c.translate(_NL_TO_COMMA), np.float64)
    if x is None or x.size != nlines * ncol:
        return None
    return x.reshape(nlines, ncol)


def _parse_lines(p: str, lines: list[bytes], numbers: list[int], header: list[str]) -> np.ndarray:
    """Line by line: the first bad line raises its precise error; else the numbers."""
    ncol = len(header)
    out = np.empty((len(lines), ncol))
    for r, (s, ln) in enumerate(zip(lines, numbers)):
        try:
            text = s.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise _err(p, f"line {ln}: not UTF-8 text (byte 0x{s[exc.start]:02x}); "
                          "save the file as UTF-8") from None
        cells = text.split(",")
        if len(cells) != ncol:
            raise _err(p, f"line {ln}: {_plural(len(cells), 'value')}, header has {_plural(ncol, 'column')}")
        for j, (cell, name) in enumerate(zip(cells, header)):
            cell = cell.strip()
            if not cell:
                raise _err(p, f"line {ln}, column {name!r}: empty cell")
            if not _NUM.fullmatch(cell):
                raise _err(p, f"line {ln}, column {name!r}: {cell!r} is not a number")
            x = float(cell)
            if not math.isfinite(x):
                raise _err(p, f"line {ln}, column {name!r}: value is {x} (NaN or inf)")
            out[r, j] = x
    return out


def _check_finite(p: str, X: np.ndarray, header: list[str], line_of) -> None:
    if not np.isfinite(X).all():
        r, c = np.argwhere(~np.isfinite(X))[0]
        raise _err(p, f"line {line_of(int(r))}, column {header[c]!r}: value is {X[r, c]} (NaN or inf)")


# ----------------------------------------------------------------------------- reading


def _blocks(f, pending: list[bytes], cr_only: bool, lineno: int, p: str):
    """Blocks of whole lines (each ending with a newline, CRLF turned into LF) and their line counts.

    ``pending`` holds the bytes the caller already read (popped: no reference outlives its use).
    """
    data = pending.pop() if pending else b""
    eof = False
    while True:
        if not data or data.rfind(b"\n") < 0:  # need more bytes
            more = f.read(_CHUNK)
            eof = not more
            if cr_only:
                more = more.replace(b"\r", b"\n")
            data = data + more if data else more
            del more
        if eof:
            if data:
                data = data.replace(b"\r\n", b"\n") + (b"" if data.endswith(b"\n") else b"\n")
                yield data, data.count(b"\n")
            return
        cut = data.rfind(b"\n") + 1
        if cut == 0:
            if len(data) > _MAX_LINE:
                raise _err(p, f"line {lineno}: longer than {_MAX_LINE // 2**20} MiB without a line break "
                              "(not a CSV text file?)")
            continue
        block, data = data[:cut], data[cut:]
        if b"\r" in block:
            block = block.replace(b"\r\n", b"\n")
        k = block.count(b"\n")
        lineno += k
        yield block, k
        del block


def _fields(text: str) -> list[str]:
    cells = [c.strip() for c in text.split(",")]
    if len(cells) > 1 and not cells[-1]:
        cells.pop()  # a trailing comma
    return cells


def _names(text: str) -> list[str]:
    return [c[1:-1].strip() if len(c) >= 2 and c[0] == c[-1] == '"' else c for c in _fields(text.lstrip("#"))]


def _open_path(path) -> str:
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"path must be a str or os.PathLike, got {type(path).__name__}")
    p = os.fspath(path)
    if isinstance(p, bytes):
        raise TypeError("path must be a str or os.PathLike of str, got bytes")
    if os.path.isdir(p):
        raise ValueError(f"path {p!r} is a directory, not a file")
    if not os.path.isfile(p):
        raise ValueError(f"path {p!r}: no such file")
    return p


def _max_bytes(max_bytes) -> int | None:
    return None if max_bytes is None else v.integer(max_bytes, "max_bytes", 1)


def _is_header(text: str) -> bool:
    names = _names(text)
    return any(names) and not any(_isnum(n) for n in names if n)


def _klipper_header(text: str) -> bool:
    low = tuple(n.lower() for n in _names(text))
    return low == KLIPPER_RAW or low[: len(KLIPPER_PSD)] == KLIPPER_PSD


def _choose_header(p: str, seen: list, data_line: int | None) -> int:
    """Index in ``seen`` of the header line (see the module docstring)."""
    if not seen:
        raise _err(p, "file is empty")
    end = len(seen) if data_line is None else data_line
    cands = [i for i in range(end) if _is_header(seen[i][1])]
    klipper = [i for i in cands if _klipper_header(seen[i][1])]
    if data_line is None:
        if all(s[2] for s in seen):
            raise _err(p, "file has no data (only comment lines)")
        plain = [i for i in cands if not seen[i][2]]
        h = klipper[-1] if klipper else (plain[0] if plain else (cands[-1] if cands else None))
        if h is None:
            ln, text = next((s[0], s[1]) for s in seen if not s[2])
            raise _err(p, f"line {ln}: expected a header line of column names, got {text!r}")
        if all(s[2] for s in seen[h + 1:]):
            raise _err(p, f"no data rows after the header (line {seen[h][0]})")
        return h  # the rows after it are not all numbers: reading them names the line
    if klipper:
        return klipper[-1]
    nd = len(_fields(seen[data_line][1]))
    match = [i for i in cands if len(_names(seen[i][1])) == nd]
    plain = [i for i in match if not seen[i][2]]
    if plain:
        return plain[0]
    if match:
        return match[-1]
    ln = seen[data_line][0]
    if cands:
        h = next((i for i in cands if not seen[i][2]), cands[-1])
        raise _err(p, f"line {ln}: {_plural(nd, 'value')}, but the header (line {seen[h][0]}) has "
                      f"{_plural(len(_names(seen[h][1])), 'column')}")
    raise _err(p, f"line {ln}: a data row with no header line of column names before it")


def _check_header(p: str, hl: int, text: str, header: list[str]) -> None:
    for j, name in enumerate(header):
        if not name:
            raise _err(p, f"line {hl}: empty column name (column {j + 1}) in header {text!r}")
    seen: dict[str, int] = {}
    for j, name in enumerate(header):
        k = name.lower()
        if k in seen:
            raise _err(p, f"line {hl}: duplicate column name {name!r} (columns {seen[k] + 1} and {j + 1}); "
                          "names must be unique (case-insensitive)")
        seen[k] = j


def _decimals(seen: list, data_line: int | None, ncol: int) -> np.ndarray | None:
    """Digits after the point in each column of the first data row, if all are fixed-point."""
    if data_line is None:
        return None
    cells = _fields(seen[data_line][1])
    if len(cells) != ncol:
        return None
    ms = [_FIXED.fullmatch(c.encode()) for c in cells]
    if not all(ms):
        return None
    return np.array([len(m.group(1)) for m in ms], dtype=np.int64)


class _State:
    def __init__(self, decimals: np.ndarray | None) -> None:
        self.decimals = decimals


def _parse_block(tab: _Table, c: bytes, nl: int, line0: int, st: _State, remaining: int) -> None:
    p, header, ncol = tab.path, tab.header, len(tab.header)
    if b"#" not in c:
        X = _parse_fixed(c, nl, ncol, st.decimals) if st.decimals is not None else None
        if X is None:
            X = _parse_float(c, nl, ncol)
            if X is not None:
                st.decimals = None  # not fixed-point throughout: do not try again
                _check_finite(p, X, header, lambda r: line0 + r)
        if X is not None:
            tab.append(X, line0, None, remaining)
            return
    # comments, blank lines, trailing commas or a bad line: line by line
    parts = c.split(b"\n")
    parts.pop()
    keep: list[int] = []
    lines: list[bytes] = []
    for i, s in enumerate(parts):
        s = s.strip()
        if not s or s[:1] == b"#":
            continue
        m = _RRF_RATE.fullmatch(s) if header[:1] == ["Sample"] else None
        if m:  # RepRapFirmware's M956 ends its file with the sample rate (Accelerometers.cpp)
            tab.rate = float(m.group(1))
            if int(m.group(2)):
                tab.notes.append(f"the accelerometer reported {int(m.group(2))} overflow(s): samples were lost")
            continue
        if s[-1:] == b"," and s.count(b",") == ncol:  # a trailing comma, not an empty last cell
            s = s[:-1].rstrip()
        keep.append(i)
        lines.append(s)
    if not lines:
        return
    kept = np.asarray(keep, dtype=np.int64)
    joined = b"\n".join(lines) + b"\n"
    X = _parse_fixed(joined, len(lines), ncol, st.decimals) if st.decimals is not None else None
    if X is None:
        X = _parse_float(joined, len(lines), ncol)
        if X is not None:
            st.decimals = None
    if X is None:
        X = _parse_lines(p, lines, (line0 + kept).tolist(), header)
    else:
        _check_finite(p, X, header, lambda r: line0 + int(kept[r]))
    tab.append(X, line0, kept, remaining)


def _read(p: str, max_bytes: int | None) -> _Table:
    size = os.path.getsize(p)
    with open(p, "rb") as f:
        first = f.read(_CHUNK)
        if first.startswith(_BOM):
            first = first[len(_BOM):]
        elif first[:2] in (b"\xff\xfe", b"\xfe\xff"):
            raise _err(p, "line 1: not UTF-8 text (UTF-16 byte-order mark); save the file as UTF-8")
        cr_only = b"\n" not in first and b"\r" in first
        if cr_only:
            first = first.replace(b"\r", b"\n")
        pending = [first]
        del first
        blocks = _blocks(f, pending, cr_only, 1, p)
        # ---- header: scan lines up to the first row of numbers
        head = b""
        pos = 0
        lineno = 0
        seen: list[tuple[int, str, bool, int]] = []  # non-blank lines: (line, text, is comment, end offset)
        data_line = None
        while data_line is None:
            e = head.find(b"\n", pos)
            if e < 0:
                if len(head) > _MAX_HEAD:
                    raise _err(p, f"no row of numbers in the first {_MAX_HEAD >> 20} MiB")
                nxt = next(blocks, None)
                if nxt is None:
                    break
                head = head + nxt[0]
                del nxt
                continue
            raw = head[pos:e]
            lineno += 1
            pos = e + 1
            if b"\x00" in raw:
                raise _err(p, f"line {lineno}: NUL bytes: not a text file")
            try:
                text = raw.decode("utf-8").strip()
            except UnicodeDecodeError as exc:
                raise _err(p, f"line {lineno}: not UTF-8 text (byte 0x{raw[exc.start]:02x}); "
                              "save the file as UTF-8") from None
            if not text:
                continue
            comment = text.startswith("#")
            seen.append((lineno, text, comment, pos))
            if not comment and all(_isnum(c) for c in _fields(text)):
                data_line = len(seen) - 1
        ih = _choose_header(p, seen, data_line)
        hl, htext, _, hend = seen[ih]
        header = _names(htext)
        _check_header(p, hl, htext, header)
        ncol = len(header)
        rest = head[hend:]
        del head
        # ---- memory: estimate the rows from the bytes per line seen so far, refuse before reading on
        sample = rest[: 1 << 16]
        k = sample.count(b"\n")
        per_line = (sample.rfind(b"\n") + 1) / k if k else max(2.0 * ncol, len(htext) / 2)
        rows_est = rest.count(b"\n") + max(0, size - f.tell()) / per_line
        need = rows_est * ncol * 8 * 2
        if max_bytes is not None and need > max_bytes:
            raise _err(p, f"about {rows_est:.3g} rows x {ncol} columns would need about {_mib(need)} "
                          f"(the numbers and a resampled copy), more than max_bytes={max_bytes} "
                          f"({_mib(max_bytes)}); pass a larger max_bytes (None: no limit) if the "
                          "memory is there, or split the file (e.g. `split -l`, repeating the header)")
        tab = _Table(p, header, hl, ncol, int(rows_est * 1.02) + 64)
        skipped = [s[0] for s in seen[:ih] if not s[2]]
        if skipped:
            tab.notes.append(f"line(s) {', '.join(map(str, skipped))} before the header (line {hl}) skipped")
        st = _State(_decimals(seen, data_line, ncol))
        line0 = hl + 1
        pieces = [rest] if rest else []
        del rest
        for c, nl in _chain(pieces, blocks):
            _parse_block(tab, c, nl, line0, st, int(max(0, size - f.tell()) / per_line))
            line0 += nl
            del c
    if tab.n == 0:
        raise _err(p, f"no data rows after the header (line {hl})")
    return tab


def _chain(first: list[bytes], rest):
    while first:
        c = first.pop()
        yield c, c.count(b"\n")
        del c
    yield from rest


def read_table(path: str | os.PathLike[str], *, max_bytes: int | None = MAX_BYTES,
               ) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Header names, float data (rows x columns) and the file line number of each row.

    The parsing of :func:`load_csv` without its interpretation (time column, Klipper
    kinds, resampling).  ``data`` is a column-major view: ``data[:, j]`` is contiguous.

    Examples
    --------
    >>> import tempfile, os
    >>> fn = os.path.join(tempfile.mkdtemp(), "d.csv")
    >>> _ = open(fn, "w").write("# exported\\ntime,y\\n0.00,1.5\\n\\n0.01,-2.25\\n")
    >>> header, data, lines = read_table(fn)
    >>> header, data.tolist(), lines.tolist()
    (['time', 'y'], [[0.0, 1.5], [0.01, -2.25]], [3, 5])
    """
    p = _open_path(path)
    tab = _read(p, _max_bytes(max_bytes))
    return tab.header, tab.block[:, : tab.n].T, tab.lines()


# ----------------------------------------------------------------------------- interpretation


def _name_info(p: str) -> tuple[str | None, str | None]:
    """(axis, Klipper output prefix) from the file name."""
    name = os.path.basename(p)
    stem = name[:-4] if name.lower().endswith(".csv") else Path(name).stem
    m = _KLIPPER_PREFIX.search(stem)  # also after a prefix of the user's: "ender3_resonances_x_..."
    if m:
        tok = m.group(2).split("_")[0].lower()
        return (tok if tok in ("x", "y", "z") else None), m.group(1).lower()
    tok = re.split(r"[-_]", stem)[-1].lower()
    return (tok if tok in ("x", "y", "z") else None), None


def _time_column(p: str, header: list[str], hl: int) -> tuple[int, float, float, str | None]:
    """Index of the time column, (multiply, divide) to seconds, and a note."""
    low = [h.strip().lower() for h in header]
    for j, name in enumerate(low):
        if name in _TIME_WORDS:
            return j, 1.0, 1.0, None
    for j, name in enumerate(low):
        m = _TIME_UNIT.fullmatch(name)
        if m:
            unit = next(g for g in m.groups()[1:] if g is not None).strip()
            if unit not in _UNITS:
                raise _err(p, f"line {hl}: time column {header[j]!r} has an unknown unit {unit!r}; known units: "
                              "s, ms, us, ns, min (e.g. 'time_ms', 't[us]'); name it 'time' for seconds")
            mul, div = _UNITS[unit]
            note = None if mul == div == 1.0 else f"time column {header[j]!r} is in {unit}: converted to seconds"
            return j, mul, div, note
    return 0, 1.0, 1.0, None


def _uniform(p: str, t: np.ndarray, line_of, resample: str) -> tuple[np.ndarray | None, float, str | None]:
    """(uniform grid or None if ``t`` already is one, sampling rate, note)."""
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        if dt[i - 1] == 0:
            raise _err(p, f"line {line_of(i)}: duplicated time {t[i]:.9g}")
        raise _err(p, f"line {line_of(i)}: time {t[i]:.9g} goes back (previous {t[i - 1]:.9g}); times must increase")
    h = float(np.median(dt))
    dev = np.abs(dt - h)
    i = int(np.argmax(dev))
    if dev[i] <= 0.01 * h:  # uniform enough as it is; the mean step is the better rate (rounded stamps)
        return None, (t.size - 1) / float(t[-1] - t[0]), None
    if resample == "never":
        raise _err(p, f"line {line_of(i + 1)}: uneven sampling (step {dt[i]:.3g} s against a median step of "
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
            missing = _plural(max(1, round(dt[g] / h) - 1), "missing sample")
            raise _err(p, f"line {line_of(g + 1)}: gap of {dt[g]:.3g} s in the time column (median step {h:.3g} s: "
                          f"about {missing}); time stamps may be at most half a step off a uniform grid: "
                          "refusing to interpolate over missing samples")
        raise _err(p, f"line {line_of(worst)}: time {t[worst]:.9g} is {off:.2f} steps off the best uniform grid "
                      f"(step {hfit:.3g} s); time stamps may be at most half a step off a uniform grid "
                      "(did the sampling rate change?)")
    hu = float((t[-1] - t[0]) / (n - 1))  # mean step
    tu = t[0] + hu * np.arange(n)
    return tu, 1.0 / hu, (f"uneven time stamps (up to {off:.2f} of a step off a uniform grid) resampled to "
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
    >>> d.kind, round(d.fs), list(d.columns)
    ('csv', 100, ['u', 'y'])
    >>> _ = open(fn, "w").write("time_ms,y\\n" + "".join(f"{10 * k},{k}\\n" for k in range(20)))
    >>> round(load_csv(fn).fs)  # milliseconds: 100 Hz, not 0.1 Hz
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
    p = _open_path(path)
    tab = _read(p, _max_bytes(max_bytes))
    header = tab.header
    low = [h.lower() for h in header]
    axis, prefix = _name_info(p)
    if low[0] == "freq" and any(h.startswith("psd") for h in low[1:]):
        return _psd(tab, low, axis, prefix)
    if header[0] == "Sample" and tab.rate is not None:
        return _rrf(tab, axis)
    kind = "klipper_raw" if tuple(low) == KLIPPER_RAW else "csv"
    tcol, mul, div, tnote = _time_column(p, header, tab.header_line)
    names = [h for j, h in enumerate(header) if j != tcol]
    if not names:
        raise _err(p, "no signal columns besides time")
    n = tab.n
    if n < MIN_SAMPLES:
        if n == 1:
            raise _err(p, f"line {tab.line(0)}: a single data row; at least {MIN_SAMPLES} samples are needed")
        raise _err(p, f"only {n} data rows; at least {MIN_SAMPLES} samples are needed")
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


def _rrf(tab: _Table, axis: str | None) -> Dataset:
    """RepRapFirmware's M956 recording: sample numbers, accelerations in g, the rate on the last line."""
    p = tab.path
    rate = float(tab.rate or 0.0)
    if not rate > 0:
        raise _err(p, "the closing 'Rate' line gives no sampling rate")
    if tab.n < MIN_SAMPLES:
        raise _err(p, f"only {tab.n} data rows; at least {MIN_SAMPLES} samples are needed")
    k = tab.col(0)
    if np.any(np.diff(k) != 1):
        i = int(np.flatnonzero(np.diff(k) != 1)[0]) + 1
        raise _err(p, f"line {tab.line(i)}: sample {k[i]:.0f} follows {k[i - 1]:.0f}: samples are missing")
    columns = {}
    for j, name in enumerate(tab.header[1:], start=1):
        if name not in ("X", "Y", "Z"):
            raise _err(p, f"line {tab.header_line}: RepRapFirmware records columns X, Y, Z, got {name!r}")
        columns[f"accel_{name.lower()}"] = tab.col(j) * _G
    notes = list(tab.notes) + [f"RepRapFirmware accelerometer file: {rate:g} Hz (its closing line), accelerations "
                               "converted from g to mm/s^2"]
    return Dataset(p, "rrf_accelerometer", (k - k[0]) / rate, columns, rate, False, notes, axis=axis)


def _psd(tab: _Table, low: list[str], axis: str | None, prefix: str | None) -> Dataset:
    p = tab.path
    f = tab.col(0)
    bad = np.flatnonzero(np.diff(f) <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise _err(p, f"line {tab.line(i)}: frequencies must increase ({f[i]:.9g} after {f[i - 1]:.9g})")
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
                raise _err(p, f"line {tab.header_line}: two columns for shaper {m.group(1)!r}")
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
