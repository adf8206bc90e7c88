"""Reading a CSV file into a table of numbers: header, rows, the file line of each row.

The parsing behind :func:`~posicast.identification.load_csv` (which interprets the
table: :mod:`.data`), with every problem reported as one ``ValueError`` line naming
the file line or column; nothing is returned half-parsed.

A header line of column names, then comma-separated numbers.  ``#`` comment lines
and blank lines are skipped anywhere; a UTF-8 byte-order mark, Windows (CRLF) or
old-Mac (CR) line ends, spaces around values and a trailing comma on a line are
accepted.  The header is the line of names just before the first data row with as
many fields as that row (a leading ``#`` is allowed, so Klipper's
``#time,accel_x,...`` is a header while a ``#`` comment line before it is not);
duplicate names are refused.  RepRapFirmware's closing ``Rate <Hz>, overflows <n>``
line is read into :attr:`Table.rate`.

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
from typing import BinaryIO, Callable, Iterator, NamedTuple

import numpy as np

from .. import _validate as v

__all__ = ["read_table", "MAX_BYTES", "Table", "KLIPPER_RAW", "KLIPPER_PSD"]

MAX_BYTES = 2**31
"""Default ``max_bytes`` of :func:`load_csv`: 2 GiB of estimated memory (about
33 million rows of a four-column Klipper log, a 1.6 GB file: 2.9 hours at 3200 Hz)."""

_CHUNK = 1 << 20  # bytes read at a time (whole lines are parsed together)
_MAX_LINE = 1 << 20  # a longer "line" is not CSV
_MAX_HEAD = 1 << 26  # look this far for the first data row
_BOM = b"\xef\xbb\xbf"
_NL_TO_COMMA = bytes.maketrans(b"\n", b",")
_NUM = re.compile(r"[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|nan|inf|infinity)", re.IGNORECASE | re.ASCII)
_FIXED = re.compile(rb"\s*[+-]?\d*\.(\d{1,15})\s*")
KLIPPER_RAW = ("time", "accel_x", "accel_y", "accel_z")
#: RepRapFirmware's M956 accelerometer files: "Sample,X,Y,Z" (axes as recorded, in g), then "Rate <Hz>, overflows <n>".
RRF_RATE = re.compile(rb"Rate (\d+(?:\.\d+)?), overflows (\d+)")
KLIPPER_PSD = ("freq", "psd_x", "psd_y", "psd_z", "psd_xyz")


def file_error(path: str, msg: str) -> ValueError:
    """The one error of a file: ``"<path>: <msg>"``."""
    return ValueError(f"{path}: {msg}")


def plural(k: int, word: str) -> str:
    """``"1 value"``, ``"2 values"``."""
    return f"{k} {word}" + ("" if k == 1 else "s")


def _mib(nbytes: float) -> str:
    return f"{nbytes / 2**20:.3g} MiB" if nbytes >= 2**20 else f"{nbytes / 1024:.3g} KiB"


def _isnum(s: str) -> bool:
    return _NUM.fullmatch(s.strip()) is not None


# ----------------------------------------------------------------------------- the table


class Table:
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
            raise file_error(p, f"line {ln}: not UTF-8 text (byte 0x{s[exc.start]:02x}); "
                          "save the file as UTF-8") from None
        cells = text.split(",")
        if len(cells) != ncol:
            raise file_error(p, f"line {ln}: {plural(len(cells), 'value')}, header has {plural(ncol, 'column')}")
        for j, (cell, name) in enumerate(zip(cells, header)):
            cell = cell.strip()
            if not cell:
                raise file_error(p, f"line {ln}, column {name!r}: empty cell")
            if not _NUM.fullmatch(cell):
                raise file_error(p, f"line {ln}, column {name!r}: {cell!r} is not a number")
            x = float(cell)
            if not math.isfinite(x):
                raise file_error(p, f"line {ln}, column {name!r}: value is {x} (NaN or inf)")
            out[r, j] = x
    return out


def _check_finite(p: str, X: np.ndarray, header: list[str], line_of: Callable[[int], int]) -> None:
    if not np.isfinite(X).all():
        r, c = np.argwhere(~np.isfinite(X))[0]
        raise file_error(p, f"line {line_of(int(r))}, column {header[c]!r}: value is {X[r, c]} (NaN or inf)")


# ----------------------------------------------------------------------------- reading


def _blocks(f: BinaryIO, pending: list[bytes], cr_only: bool, lineno: int, p: str) -> Iterator[tuple[bytes, int]]:
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
                raise file_error(p, f"line {lineno}: longer than {_MAX_LINE // 2**20} MiB without a line break "
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


def open_path(path: object) -> str:
    """``path`` as a str naming an existing file (TypeError / ValueError otherwise)."""
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


def max_bytes_arg(max_bytes: object) -> int | None:
    """The ``max_bytes`` argument: None (no limit) or an integer >= 1."""
    return None if max_bytes is None else v.integer(max_bytes, "max_bytes", 1)


def _is_header(text: str) -> bool:
    names = _names(text)
    return any(names) and not any(_isnum(n) for n in names if n)


def _klipper_header(text: str) -> bool:
    low = tuple(n.lower() for n in _names(text))
    return low == KLIPPER_RAW or low[: len(KLIPPER_PSD)] == KLIPPER_PSD


class HeadLine(NamedTuple):
    """A non-blank line before the data: its line number, text, whether it is a ``#`` comment, its end offset."""

    line: int
    text: str
    comment: bool
    end: int


def _choose_header(p: str, seen: list[HeadLine], data_line: int | None) -> int:
    """Index in ``seen`` of the header line (see the module docstring)."""
    if not seen:
        raise file_error(p, "file is empty")
    end = len(seen) if data_line is None else data_line
    cands = [i for i in range(end) if _is_header(seen[i].text)]
    klipper = [i for i in cands if _klipper_header(seen[i].text)]
    if data_line is None:
        return _header_without_data(p, seen, cands, klipper)
    if klipper:
        return klipper[-1]
    nd = len(_fields(seen[data_line].text))
    match = [i for i in cands if len(_names(seen[i].text)) == nd]
    plain = [i for i in match if not seen[i].comment]
    if plain:
        return plain[0]
    if match:
        return match[-1]
    ln = seen[data_line].line
    if cands:
        h = next((i for i in cands if not seen[i].comment), cands[-1])
        raise file_error(p, f"line {ln}: {plural(nd, 'value')}, but the header (line {seen[h].line}) has "
                            f"{plural(len(_names(seen[h].text)), 'column')}")
    raise file_error(p, f"line {ln}: a data row with no header line of column names before it")


def _header_without_data(p: str, seen: list[HeadLine], cands: list[int], klipper: list[int]) -> int:
    """The header when no line of the head is all numbers: the rows after it are not all numbers, and
    reading them names the bad line."""
    if all(s.comment for s in seen):
        raise file_error(p, "file has no data (only comment lines)")
    plain = [i for i in cands if not seen[i].comment]
    h = klipper[-1] if klipper else (plain[0] if plain else (cands[-1] if cands else None))
    if h is None:
        ln, text = next((s.line, s.text) for s in seen if not s.comment)
        raise file_error(p, f"line {ln}: expected a header line of column names, got {text!r}")
    if all(s.comment for s in seen[h + 1:]):
        raise file_error(p, f"no data rows after the header (line {seen[h].line})")
    return h


def _check_header(p: str, hl: int, text: str, header: list[str]) -> None:
    for j, name in enumerate(header):
        if not name:
            raise file_error(p, f"line {hl}: empty column name (column {j + 1}) in header {text!r}")
    seen: dict[str, int] = {}
    for j, name in enumerate(header):
        k = name.lower()
        if k in seen:
            raise file_error(p, f"line {hl}: duplicate column name {name!r} (columns {seen[k] + 1} and {j + 1}); "
                          "names must be unique (case-insensitive)")
        seen[k] = j


def _decimals(seen: list[HeadLine], data_line: int | None, ncol: int) -> np.ndarray | None:
    """Digits after the point in each column of the first data row, if all are fixed-point."""
    if data_line is None:
        return None
    cells = _fields(seen[data_line].text)
    if len(cells) != ncol:
        return None
    ms = [_FIXED.fullmatch(c.encode()) for c in cells]
    if not all(ms):
        return None
    return np.array([len(m.group(1)) for m in ms], dtype=np.int64)


class _State:
    def __init__(self, decimals: np.ndarray | None) -> None:
        self.decimals = decimals


def _parse_block(tab: Table, c: bytes, nl: int, line0: int, st: _State, remaining: int) -> None:
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
        m = RRF_RATE.fullmatch(s) if header[:1] == ["Sample"] else None
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


class _Head(NamedTuple):
    """The bytes read up to the first row of numbers, its non-blank lines, and that row's index in them."""

    data: bytes
    seen: list[HeadLine]
    data_line: int | None


def _scan_head(p: str, blocks: Iterator[tuple[bytes, int]]) -> _Head:
    """Read lines up to the first row of numbers (at most ``_MAX_HEAD`` bytes)."""
    head = b""
    pos = 0
    lineno = 0
    seen: list[HeadLine] = []
    data_line = None
    while data_line is None:
        e = head.find(b"\n", pos)
        if e < 0:
            if len(head) > _MAX_HEAD:
                raise file_error(p, f"no row of numbers in the first {_MAX_HEAD >> 20} MiB")
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
            raise file_error(p, f"line {lineno}: NUL bytes: not a text file")
        try:
            text = raw.decode("utf-8").strip()
        except UnicodeDecodeError as exc:
            raise file_error(p, f"line {lineno}: not UTF-8 text (byte 0x{raw[exc.start]:02x}); "
                                "save the file as UTF-8") from None
        if not text:
            continue
        comment = text.startswith("#")
        seen.append(HeadLine(lineno, text, comment, pos))
        if not comment and all(_isnum(c) for c in _fields(text)):
            data_line = len(seen) - 1
    return _Head(head, seen, data_line)


def _bytes_per_line(p: str, rest: bytes, htext: str, ncol: int, unread: int, max_bytes: int | None) -> tuple[float, float]:
    """Estimated rows of the file and bytes per line, from the lines seen so far; refuses before reading on
    when the numbers (and a resampled copy) would need more than ``max_bytes``."""
    sample = rest[: 1 << 16]
    k = sample.count(b"\n")
    per_line = (sample.rfind(b"\n") + 1) / k if k else max(2.0 * ncol, len(htext) / 2)
    rows_est = rest.count(b"\n") + unread / per_line
    need = rows_est * ncol * 8 * 2
    if max_bytes is not None and need > max_bytes:
        raise file_error(p, f"about {rows_est:.3g} rows x {ncol} columns would need about {_mib(need)} "
                            f"(the numbers and a resampled copy), more than max_bytes={max_bytes} "
                            f"({_mib(max_bytes)}); pass a larger max_bytes (None: no limit) if the "
                            "memory is there, or split the file (e.g. `split -l`, repeating the header)")
    return rows_est, per_line


def _open_blocks(p: str, f: BinaryIO) -> Iterator[tuple[bytes, int]]:
    """The file's blocks of whole lines, after a UTF-8 byte-order mark; old-Mac (CR) line ends made LF."""
    first = f.read(_CHUNK)
    if first.startswith(_BOM):
        first = first[len(_BOM):]
    elif first[:2] in (b"\xff\xfe", b"\xfe\xff"):
        raise file_error(p, "line 1: not UTF-8 text (UTF-16 byte-order mark); save the file as UTF-8")
    cr_only = b"\n" not in first and b"\r" in first
    if cr_only:
        first = first.replace(b"\r", b"\n")
    pending = [first]
    del first
    return _blocks(f, pending, cr_only, 1, p)


def read_csv_table(p: str, max_bytes: int | None) -> Table:
    """The :class:`Table` of the file ``p`` (an existing path; see the module docstring)."""
    size = os.path.getsize(p)
    with open(p, "rb") as f:
        blocks = _open_blocks(p, f)
        scan = _scan_head(p, blocks)
        seen, data_line = scan.seen, scan.data_line
        ih = _choose_header(p, seen, data_line)
        hl, htext, _, hend = seen[ih]
        header = _names(htext)
        _check_header(p, hl, htext, header)
        ncol = len(header)
        rest = scan.data[hend:]
        del scan
        rows_est, per_line = _bytes_per_line(p, rest, htext, ncol, max(0, size - f.tell()), max_bytes)
        tab = Table(p, header, hl, ncol, int(rows_est * 1.02) + 64)
        skipped = [s.line for s in seen[:ih] if not s.comment]
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
        raise file_error(p, f"no data rows after the header (line {hl})")
    return tab


def _chain(first: list[bytes], rest: Iterator[tuple[bytes, int]]) -> Iterator[tuple[bytes, int]]:
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
    p = open_path(path)
    tab = read_csv_table(p, max_bytes_arg(max_bytes))
    return tab.header, tab.block[:, : tab.n].T, tab.lines()
