"""Reading measured data: CSV with a time column, Klipper accelerometer logs and PSD files.

Every problem is reported as one ``ValueError`` line naming the file line or
column; nothing is returned half-parsed.

* Generic CSV: a header line of column names (a leading ``#`` is allowed),
  comma-separated numbers, ``#`` comment lines skipped; a time column
  (``time``, ``t`` or the first column).
* Klipper raw accelerometer log (``ACCELEROMETER_MEASURE``):
  ``#time,accel_x,accel_y,accel_z`` in s and mm/s^2.
* Klipper resonance PSD (``TEST_RESONANCES`` output):
  ``freq,psd_x,psd_y,psd_z,psd_xyz``.

Uneven sampling: steps within 1 % of the median are accepted as they are;
jitter up to half a median step (Klipper's time stamps) is resampled onto a
uniform grid by linear interpolation; larger gaps are refused.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["Dataset", "load_csv", "read_table"]


@dataclass
class Dataset:
    """A parsed file: uniform time base and named signals.

    ``kind`` is ``"csv"``, ``"klipper_raw"`` or ``"klipper_psd"`` (then ``t`` holds frequencies).
    """

    path: str
    kind: str
    t: np.ndarray
    columns: dict[str, np.ndarray]
    fs: float = float("nan")
    resampled: bool = False
    notes: list[str] = field(default_factory=list)

    def column(self, name: str) -> np.ndarray:
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


def read_table(path: str | Path) -> tuple[list[str], np.ndarray, list[int]]:
    """Header names, float data (rows x columns) and the file line number of each row."""
    p = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8", errors="strict")
    except UnicodeDecodeError as exc:
        raise _err(p, f"not a text file ({exc.reason})") from None
    lines = text.splitlines()
    header = None
    rows: list[str] = []
    numbers: list[int] = []
    for i, line in enumerate(lines, start=1):
        s = line.strip()
        if not s:
            continue
        if header is None:
            header = [h.strip() for h in s.lstrip("#").split(",")]
            if any(not h for h in header):
                raise _err(p, f"line {i}: empty column name in header {s!r}")
            if all(_isnum(h) for h in header):
                raise _err(p, f"line {i}: first line must be a header of column names, got numbers")
            continue
        if s.startswith("#"):
            continue
        rows.append(s)
        numbers.append(i)
    if header is None:
        raise _err(p, "file is empty")
    if not rows:
        raise _err(p, "no data rows after the header")
    ncol = len(header)
    try:
        data = np.array([r.split(",") for r in rows], dtype=float)
        if data.ndim != 2 or data.shape[1] != ncol:
            raise ValueError
    except ValueError:
        for r, ln in zip(rows, numbers):
            cells = r.split(",")
            if len(cells) != ncol:
                raise _err(p, f"line {ln}: {len(cells)} values, header has {ncol} columns") from None
            for c, name in zip(cells, header):
                if not _isnum(c):
                    raise _err(p, f"line {ln}, column {name!r}: {c.strip()!r} is not a number") from None
        raise _err(p, "could not parse the numbers") from None
    bad = ~np.isfinite(data)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise _err(p, f"line {numbers[r]}, column {header[c]!r}: value is {data[r, c]} (NaN or inf)")
    return header, data, numbers


def _isnum(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


def _uniform(p: str, t: np.ndarray, X: np.ndarray, numbers: list[int], resample: str) -> tuple[np.ndarray, np.ndarray, bool, float]:
    if t.size < 2:
        raise _err(p, f"line {numbers[0]}: a single data row; at least 16 samples are needed")
    dt = np.diff(t)
    if np.any(dt == 0):
        i = int(np.nonzero(dt == 0)[0][0]) + 1
        raise _err(p, f"line {numbers[i]}: duplicated time {t[i]:.9g}")
    if np.any(dt < 0):
        i = int(np.nonzero(dt < 0)[0][0]) + 1
        raise _err(p, f"line {numbers[i]}: time {t[i]:.9g} goes back (previous {t[i - 1]:.9g}); times must increase")
    h = float(np.median(dt))
    dev = np.abs(dt - h)
    if np.max(dev) <= 0.01 * h:
        return t, X, False, 1.0 / h
    i = int(np.argmax(dev)) + 1
    if resample == "never":
        raise _err(p, f"line {numbers[i]}: uneven sampling (step {dt[i - 1]:.3g} s, median {h:.3g} s); "
                      "resampling is off")
    if np.max(dt) > 1.5 * h:
        raise _err(p, f"line {numbers[i]}: gap of {dt[i - 1]:.3g} s in the time column (median step {h:.3g} s); "
                      "refusing to interpolate over missing samples")
    h = float((t[-1] - t[0]) / (t.size - 1))  # mean step: immune to rounded time stamps
    tu = t[0] + h * np.arange(int(math.floor((t[-1] - t[0]) / h + 1e-9)) + 1)
    Xu = np.column_stack([np.interp(tu, t, X[:, j]) for j in range(X.shape[1])])
    return tu, Xu, True, 1.0 / h


def load_csv(path: str | Path, *, resample: str = "auto") -> Dataset:
    """Read a CSV / Klipper file into a :class:`Dataset` (see the module docstring).

    Parameters
    ----------
    path : str or Path
        The file.
    resample : {"auto", "never"}
        Resample jittered time stamps (``"auto"``) or refuse them.

    Examples
    --------
    >>> import tempfile, os
    >>> fn = os.path.join(tempfile.mkdtemp(), "d.csv")
    >>> _ = open(fn, "w").write("time,u,y\\n" + "".join(f"{k/100},{k > 3:d},{k/7}\\n" for k in range(20)))
    >>> d = load_csv(fn)
    >>> d.kind, round(d.fs), list(d.columns)
    ('csv', 100, ['u', 'y'])
    >>> _ = open(fn, "w").write("time,u,y\\n0,1,2\\n0.01,1,x\\n")
    >>> load_csv(fn)
    Traceback (most recent call last):
    ...
    ValueError: ...d.csv: line 3, column 'y': 'x' is not a number
    """
    if resample not in ("auto", "never"):
        raise ValueError(f"resample must be 'auto' or 'never', got {resample!r}")
    p = str(path)
    if not Path(path).is_file():
        raise _err(p, "no such file")
    header, data, numbers = read_table(path)
    low = [h.lower() for h in header]
    if low[:1] == ["freq"] and any(h.startswith("psd") for h in low):
        f = data[:, 0]
        if np.any(np.diff(f) <= 0):
            i = int(np.nonzero(np.diff(f) <= 0)[0][0]) + 1
            raise _err(p, f"line {numbers[i]}: frequencies must increase")
        cols = {h: data[:, j] for j, h in enumerate(low) if j > 0}
        return Dataset(p, "klipper_psd", f, cols)
    kind = "klipper_raw" if low[:4] == ["time", "accel_x", "accel_y", "accel_z"] else "csv"
    tcol = low.index("time") if "time" in low else (low.index("t") if "t" in low else 0)
    t = data[:, tcol]
    X = np.delete(data, tcol, axis=1)
    names = [h for j, h in enumerate(header) if j != tcol]
    if X.shape[1] == 0:
        raise _err(p, "no signal columns besides time")
    if t.size < 16:
        if t.size == 1:
            raise _err(p, f"line {numbers[0]}: a single data row; at least 16 samples are needed")
        raise _err(p, f"only {t.size} data rows; at least 16 samples are needed")
    tu, Xu, res, fs = _uniform(p, t, X, numbers, resample)
    ds = Dataset(p, kind, tu - tu[0], {n: Xu[:, j] for j, n in enumerate(names)}, fs, res)
    if res:
        ds.notes.append(f"uneven time stamps resampled to {fs:.6g} Hz by linear interpolation")
    return ds
