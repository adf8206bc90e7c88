"""Issues #12 and #13 (reader part): posicast.identification.data -- speed path, memory, edge cases,
Klipper file variants, time units, size limit.

Reference values come from np.loadtxt / float() (an independent parser), from
analytic time bases, and from the formats Klipper's own writers use:
adxl345.py ``write_to_file`` ("%.6f,%.6f,%.6f,%.6f", header ``#time,accel_x,accel_y,accel_z``,
preceded by a ``##drops=...`` statistics line in early versions) and
shaper_calibrate.py ``save_calibration_data`` ("%.1f,%.3e,%.3e,%.3e,%.3e", plus ",%.3f"
per shaper under headers ``name(%.1f)``; Kalico adds ``accel_per_hz`` as "%.1f").
"""

from __future__ import annotations

import math
import os
import re
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from posicast.identification import csv_reader as D  # the reader (its block size, its parsers)
from posicast.identification.data import load_csv, read_table

RAW_HEADER = "#time,accel_x,accel_y,accel_z\n"
STATS_LINE = "##drops=0,overflows=0,time_per_sample=0.000312500,start_range=0.000120,end_range=0.000118\n"


def _raw_rows(n: int, seed: int = 0, jitter: float = 0.2, fs: float = 3200.0) -> tuple[np.ndarray, str]:
    """Klipper-like raw log rows: jittered time stamps, signed accelerations, gravity on z."""
    rng = np.random.default_rng(seed)
    t = 1000.0 + (np.arange(n) + jitter * rng.uniform(-1, 1, n)) / fs
    a = rng.normal(0.0, 400.0, (n, 3))
    a[:, 2] += 9806.65
    a[rng.integers(0, n, max(1, n // 50)), 0] = -0.0000001  # prints as -0.000000 (strtod: -0.0)
    A = np.column_stack([t, a])
    return A, "".join("%.6f,%.6f,%.6f,%.6f\n" % tuple(r) for r in A)


def _write(tmp_path, name: str, content: str | bytes):
    f = tmp_path / name
    f.write_bytes(content if isinstance(content, bytes) else content.encode("utf-8"))
    return f


def _loadtxt(f) -> np.ndarray:
    """np.loadtxt as Klipper's scripts call it; a header without '#' skipped."""
    with open(f, encoding="utf-8") as fh:
        skip = 0 if fh.readline().startswith("#") else 1
    return np.loadtxt(f, comments="#", delimiter=",", ndmin=2, skiprows=skip)


@pytest.fixture
def small_blocks(monkeypatch):
    """4 KiB blocks, so that small files go through many blocks and their seams."""
    monkeypatch.setattr(D, "_CHUNK", 4096)


# ----------------------------------------------------------------------------- values


def test_klipper_raw_values_equal_loadtxt_bit_for_bit(tmp_path, small_blocks) -> None:
    _, rows = _raw_rows(3000)
    f = _write(tmp_path, "adxl345-x.csv", RAW_HEADER + rows)
    ref = _loadtxt(f)
    header, data, lines = read_table(f)
    assert header == ["time", "accel_x", "accel_y", "accel_z"]
    assert np.array_equal(data, ref) and np.array_equal(np.signbit(data), np.signbit(ref))
    assert np.signbit(ref).any()  # the "-0.000000" cells are there
    assert lines[0] == 2 and lines[-1] == 3001


def test_clean_files_are_parsed_in_bulk(tmp_path, monkeypatch) -> None:
    def never(*args):
        raise AssertionError("went line by line")

    monkeypatch.setattr(D, "_parse_lines", never)
    monkeypatch.setattr(D, "_CHUNK", 8192)
    _, rows = _raw_rows(2000)
    f = _write(tmp_path, "raw.csv", RAW_HEADER + rows)
    assert np.array_equal(read_table(f)[1], _loadtxt(f))
    g = _write(tmp_path, "sci.csv", "time,y\n" + "".join(f"{k / 1000!r},{math.sin(k):.9e}\n" for k in range(2000)))
    assert np.array_equal(read_table(g)[1], _loadtxt(g))


@pytest.mark.parametrize("fmt", ["%.1f,%.3f,%.6e", "%g,%d,%.17g", "%.3f,%.3f,%.3f"])
def test_other_number_formats_equal_loadtxt(tmp_path, small_blocks, fmt: str) -> None:
    rng = np.random.default_rng(3)
    X = np.column_stack([np.arange(1500) * 0.01, rng.integers(-50, 50, 1500), rng.normal(0, 1e3, 1500)])
    text = "".join((fmt + "\n") % tuple(r) for r in X)
    f = _write(tmp_path, "f.csv", "time,u,y\n" + text)
    assert np.array_equal(read_table(f)[1], _loadtxt(f))


def test_format_changes_mid_file_and_huge_mantissa(tmp_path, small_blocks) -> None:
    _, rows = _raw_rows(1500)
    lines = rows.splitlines(keepends=True)
    lines[900] = "1000.281250,1.5e+02,-2.000000,123456789012345678901.25\n"  # exponent; > 2**53 digits
    f = _write(tmp_path, "r.csv", RAW_HEADER + "".join(lines))
    data = read_table(f)[1]
    assert np.array_equal(data, _loadtxt(f))
    assert data[900, 3] == float("123456789012345678901.25")


# ----------------------------------------------------------------------------- precise errors


def test_error_line_is_exact_far_into_the_file(tmp_path, small_blocks) -> None:
    _, rows = _raw_rows(5000)
    lines = rows.splitlines(keepends=True)
    lines[3210] = lines[3210].split(",")[0] + ",1.000000,x,2.000000\n"
    body = "".join(lines[:1000]) + "# a comment\n\n" + "".join(lines[1000:])  # two extra lines before it
    f = _write(tmp_path, "r.csv", STATS_LINE + RAW_HEADER + body)
    # row 3210 is file line 3210 + 1 (1-based) + 2 (stats, header) + 2 (comment, blank)
    with pytest.raises(ValueError, match=r"r\.csv: line 3215, column 'accel_y': 'x' is not a number$"):
        load_csv(f)


@pytest.mark.parametrize("cell, expect", [
    ("nan", "column 'y': value is nan (NaN or inf)"),
    ("-inf", "column 'y': value is -inf (NaN or inf)"),
    ("", "column 'y': empty cell"),
    ("1.5.2", "column 'y': '1.5.2' is not a number"),
    ("1,2", ": 4 values, header has 3 columns"),
    ("\u0661", "column 'y': '\u0661' is not a number"),  # an Arabic-Indic digit: float() takes it, CSV does not
])
def test_bad_cell_named_with_line_and_column(tmp_path, small_blocks, cell: str, expect: str) -> None:
    rows = [f"{k / 100:.2f},{k % 2},{k / 7:.6f}" for k in range(800)]
    rows[600] = f"{600 / 100:.2f},0,{cell}"
    f = _write(tmp_path, "bad.csv", "time,u,y\n" + "\n".join(rows) + "\n")
    with pytest.raises(ValueError, match=re.escape(f"line 602{expect if expect[0] == ':' else ', ' + expect}")):
        load_csv(f)


@pytest.mark.parametrize("row, expect", [
    ("0.06,1", "line 8: 2 values, header has 3 columns"),
    ("0.06,1,2,3", "line 8: 4 values, header has 3 columns"),
    ("0.06", "line 8: 1 value, header has 3 columns"),
])
def test_ragged_rows(tmp_path, row: str, expect: str) -> None:
    rows = [f"{k / 100},{k % 2},{k}" for k in range(20)]
    rows[6] = row
    f = _write(tmp_path, "ragged.csv", "time,u,y\n" + "\n".join(rows) + "\n")
    with pytest.raises(ValueError, match=expect):
        load_csv(f)


def test_non_utf8_bytes(tmp_path) -> None:
    rows = "".join(f"{k / 100},{k}\n" for k in range(20)).encode()
    f = _write(tmp_path, "a.csv", b"time,y\n" + rows.replace(b"0.05,5", b"0.05,\xb5"))
    with pytest.raises(ValueError, match=r"line 7: not UTF-8 text \(byte 0xb5\)"):
        load_csv(f)
    g = _write(tmp_path, "b.csv", b"time,\xe9t\xe9\n" + rows)  # Latin-1 header
    with pytest.raises(ValueError, match=r"line 1: not UTF-8 text \(byte 0xe9\)"):
        load_csv(g)
    h = _write(tmp_path, "c.csv", ("time,y\n" + rows.decode()).encode("utf-16"))
    with pytest.raises(ValueError, match="UTF-16"):
        load_csv(h)
    k = _write(tmp_path, "d.csv", b"\x00" * 100 + b"\n")
    with pytest.raises(ValueError, match="not a text file"):
        load_csv(k)


def test_binary_without_line_breaks_is_refused_not_buffered(tmp_path) -> None:
    f = _write(tmp_path, "blob.csv", b"time,y\n" + bytes(range(1, 256)).replace(b"\n", b"") * 9000)
    with pytest.raises(ValueError, match="line 2: longer than 1 MiB without a line break"):
        load_csv(f)


# ----------------------------------------------------------------------------- header, comments, encodings


def test_bom_before_klipper_header(tmp_path) -> None:
    _, rows = _raw_rows(100)
    f = _write(tmp_path, "raw.csv", b"\xef\xbb\xbf" + (RAW_HEADER + rows).encode())
    ds = load_csv(f)
    assert ds.kind == "klipper_raw" and list(ds.columns) == ["accel_x", "accel_y", "accel_z"]


def test_comment_line_before_header_is_not_the_header(tmp_path) -> None:
    rows = "".join(f"{k / 100},{k % 2},{k}\n" for k in range(20))
    f = _write(tmp_path, "c.csv", "# exported by scope, channel 1, channel 2\ntime,u,y\n" + rows)
    ds = load_csv(f)
    assert list(ds.columns) == ["u", "y"] and ds.sample_rate == pytest.approx(100.0)
    # early Klipper: a "##drops=..." statistics line (5 fields) before the "#time,..." header (4 fields)
    _, raw = _raw_rows(100)
    g = _write(tmp_path, "adxl345-y.csv", STATS_LINE + RAW_HEADER + raw)
    ds = load_csv(g)
    assert ds.kind == "klipper_raw" and ds.axis == "y"
    assert np.array_equal(read_table(g)[1], _loadtxt(g))
    # a '#'-prefixed header (not Klipper's) after a '#' comment of another width
    h = _write(tmp_path, "h.csv", "# recorded 2024-01-01\n#time,u,y\n" + rows)
    assert list(load_csv(h).columns) == ["u", "y"]


def test_long_comment_block_between_header_and_data(tmp_path, small_blocks) -> None:
    comments = "".join(f"# setting {k}: {'x' * 40}\n" for k in range(300))  # ~15 kB: several 4 KiB blocks
    _, rows = _raw_rows(1000)
    f = _write(tmp_path, "raw.csv", RAW_HEADER + comments + rows)
    header, data, lines = read_table(f)
    assert header[0] == "time" and np.array_equal(data, _loadtxt(f))
    assert lines[0] == 302 and lines[-1] == 1301
    bad = rows.splitlines(keepends=True)
    bad[0] = "1000.0,oops,1,2\n"
    with pytest.raises(ValueError, match="line 302, column 'accel_x': 'oops' is not a number"):
        load_csv(_write(tmp_path, "bad.csv", RAW_HEADER + comments + "".join(bad)))


def test_text_before_the_header_is_skipped_with_a_note(tmp_path) -> None:
    rows = "".join(f"{k / 100},{k % 2},{k}\n" for k in range(20))
    ds = load_csv(_write(tmp_path, "c.csv", "Scope export v2\ntime,u,y\n" + rows))
    assert list(ds.columns) == ["u", "y"] and any("line(s) 1 before the header (line 2)" in n for n in ds.notes)


def test_duplicate_column_names_refused(tmp_path) -> None:
    rows = "".join(f"{k / 100},{k % 2},{k}\n" for k in range(20))
    with pytest.raises(ValueError, match=r"line 1: duplicate column name 'y' \(columns 2 and 3\)"):
        load_csv(_write(tmp_path, "d.csv", "time,y,y\n" + rows))
    with pytest.raises(ValueError, match="duplicate column name 'Y'"):
        load_csv(_write(tmp_path, "e.csv", "time,y,Y\n" + rows))
    with pytest.raises(ValueError, match=r"line 1: empty column name \(column 2\)"):
        load_csv(_write(tmp_path, "f.csv", "time,,y\n" + rows))


def test_data_without_header_refused(tmp_path) -> None:
    rows = "".join(f"{k / 100},{k % 2},{k}\n" for k in range(20))
    with pytest.raises(ValueError, match="line 1: a data row with no header line"):
        load_csv(_write(tmp_path, "n.csv", rows))
    with pytest.raises(ValueError, match=r"line 2: 3 values, but the header \(line 1\) has 2 columns"):
        load_csv(_write(tmp_path, "m.csv", "time,y\n" + rows))


def test_line_endings_and_trailing_commas_and_spaces(tmp_path, small_blocks) -> None:
    rows = [f"{k / 100:.2f},{k % 2},{math.sin(k):.6f}" for k in range(700)]
    clean = _write(tmp_path, "clean.csv", "time,u,y\n" + "\n".join(rows) + "\n")
    ref = read_table(clean)[1]
    assert np.array_equal(ref, _loadtxt(clean))
    variants = {
        "crlf": "time,u,y\r\n" + "\r\n".join(rows) + "\r\n",
        "cr": "time,u,y\r" + "\r".join(rows) + "\r",
        "no final newline": "time,u,y\n" + "\n".join(rows),
        "trailing comma": "time,u,y,\n" + ",\n".join(rows) + ",\n",
        "trailing comma and spaces": "time,u,y, \n" + ", \n".join(rows) + ",  \n",
        "spaces": "time , u , y\n" + "\n".join(" " + r.replace(",", " , ") + "   " for r in rows) + "\n",
        "blank lines and comments": "time,u,y\n\n" + "\n".join(rows[:300]) + "\n# pause\n\n"
                                    + "\n".join(rows[300:]) + "\n\n\n",
    }
    for name, text in variants.items():
        header, data, _ = read_table(_write(tmp_path, "v.csv", text))
        assert header == ["time", "u", "y"], name
        assert np.array_equal(data, ref), name
    ds = load_csv(_write(tmp_path, "v.csv", variants["crlf"]))
    assert ds.sample_rate == pytest.approx(100.0) and list(ds.columns) == ["u", "y"]


# ----------------------------------------------------------------------------- small and empty files, paths


@pytest.mark.parametrize("text, expect", [
    ("", "file is empty"),
    ("\n  \n\n", "file is empty"),
    ("# only\n# comments\n", r"no data \(only comment lines\)"),
    ("time,u,y\n", r"no data rows after the header \(line 1\)"),
    ("time,u,y\n# nothing yet\n\n", r"no data rows after the header \(line 1\)"),
    ("time,u,y\n0,1,2\n", "line 2: a single data row; at least 16 samples"),
    ("time,u,y\n" + "".join(f"{k},1,2\n" for k in range(5)), "only 5 data rows; at least 16 samples"),
    ("time\n" + "".join(f"{k}\n" for k in range(20)), "no signal columns besides time"),
])
def test_empty_and_short_files(tmp_path, text: str, expect: str) -> None:
    with pytest.raises(ValueError, match=expect):
        load_csv(_write(tmp_path, "s.csv", text))


def test_paths(tmp_path) -> None:
    with pytest.raises(TypeError, match="path must be a str or os.PathLike, got NoneType"):
        load_csv(None)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="got int"):
        load_csv(3)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="path .* is a directory, not a file"):
        load_csv(tmp_path)
    with pytest.raises(ValueError, match="path .*missing.csv.: no such file"):
        load_csv(tmp_path / "missing.csv")
    with pytest.raises(ValueError, match="resample must be 'auto' or 'never'"):
        load_csv(tmp_path / "missing.csv", resample="sometimes")


# ----------------------------------------------------------------------------- time stamps


def _jittered(tmp_path, offsets: np.ndarray, h: float = 1e-3):
    """y = 3 + 2 t on time stamps k h + offsets[k] h: linear interpolation reproduces y exactly."""
    t = 5.0 + (np.arange(offsets.size) + offsets) * h
    text = "time,y\n" + "".join(f"{a!r},{3.0 + 2.0 * a!r}\n" for a in t.tolist())
    return _write(tmp_path, "j.csv", text), t


def test_jitter_within_half_step_is_resampled(tmp_path) -> None:
    # +-0.3 step alternating: steps of 0.4 and 1.6 steps (refused before as a "gap" of the smallest step)
    off = 0.3 * (-1.0) ** np.arange(401)
    f, t = _jittered(tmp_path, off)
    ds = load_csv(f)
    assert ds.resampled and ds.sample_rate == pytest.approx(1000.0, rel=1e-12)  # (t[-1] - t[0]) / 400 = 1 ms exactly
    assert ds.t0 == t[0]
    np.testing.assert_allclose(ds.column("y"), 3.0 + 2.0 * (ds.t0 + ds.t), rtol=0, atol=1e-12)
    assert any("0.30 of a step" in n and "resampled to 1000 Hz" in n for n in ds.notes)
    rng = np.random.default_rng(5)
    f, _ = _jittered(tmp_path, rng.uniform(-0.3, 0.3, 5000))
    assert load_csv(f).resampled
    with pytest.raises(ValueError, match=r"line \d+: uneven sampling .* resampling is off"):
        load_csv(f, resample="never")


def test_missing_sample_is_a_gap_at_its_line(tmp_path) -> None:
    rng = np.random.default_rng(6)
    off = rng.uniform(-0.3, 0.3, 2000)
    off[1200:] += 1.0  # sample 1200 missing: row 1200 (line 1202) comes two steps after row 1199
    f, t = _jittered(tmp_path, off)
    dt = t[1200] - t[1199]
    with pytest.raises(ValueError, match=f"line 1202: gap of {dt:.3g} s .*about 1 missing sample\\)"):
        load_csv(f)


def test_rate_change_is_refused_without_a_gap(tmp_path) -> None:
    off = np.concatenate([np.zeros(500), 0.05 * np.arange(1, 501)])  # the step grows by 5 % half-way
    f, _ = _jittered(tmp_path, off)
    with pytest.raises(ValueError, match="steps off the best uniform grid .*did the sampling rate change"):
        load_csv(f)


@pytest.mark.parametrize("name, scale", [
    ("time_ms", 1e3), ("t[ms]", 1e3), ("time (us)", 1e6), ("Time [µs]", 1e6), ("time_s", 1.0),
    ("t/ns", 1e9), ("timestamp_ms", 1e3), ("time_min", 1 / 60),
])
def test_time_units_converted_to_seconds(tmp_path, name: str, scale: float) -> None:
    h = 0.002  # s
    f = _write(tmp_path, "u.csv", f"{name},y\n" + "".join(f"{k * h * scale!r},{k % 3}\n" for k in range(50)))
    ds = load_csv(f)
    assert ds.sample_rate == pytest.approx(1 / h, rel=1e-9)
    assert (scale == 1.0) or any(name in n and "converted to seconds" in n for n in ds.notes)


def test_unknown_time_unit_refused(tmp_path) -> None:
    f = _write(tmp_path, "u.csv", "time_fortnights,y\n" + "".join(f"{k},{k}\n" for k in range(20)))
    with pytest.raises(ValueError, match="line 1: time column 'time_fortnights' has an unknown unit 'fortnights'"):
        load_csv(f)


def test_exact_time_column_wins_and_first_column_is_the_fallback(tmp_path) -> None:
    rows = "".join(f"{k},{k / 100},{k % 2}\n" for k in range(20))
    assert list(load_csv(_write(tmp_path, "a.csv", "n,time,y\n" + rows)).columns) == ["n", "y"]
    assert list(load_csv(_write(tmp_path, "b.csv", "n,x,y\n" + rows)).columns) == ["x", "y"]


# ----------------------------------------------------------------------------- Klipper variants


def _psd_text(shapers: dict[str, float] | None = None, accel_per_hz: float | None = None, hash_: bool = False) -> str:
    """As shaper_calibrate.py save_calibration_data writes it (Kalico: accel_per_hz after psd_xyz)."""
    f = np.arange(0, 200, 3200 / 4096)
    px, py, pz = 1e3 / (1 + ((f - 42) / 3) ** 2), 1e2 + f, 5.0 + 0 * f
    head = "#" * hash_ + "freq,psd_x,psd_y,psd_z,psd_xyz" + (",accel_per_hz" if accel_per_hz is not None else "")
    head += "".join(",%s(%.1f)" % (n, fr) for n, fr in (shapers or {}).items())
    lines = [head]
    for i in range(f.size):
        s = "%.1f,%.3e,%.3e,%.3e,%.3e" % (f[i], px[i], py[i], pz[i], px[i] + py[i] + pz[i])
        if accel_per_hz is not None:
            s += ",%.1f" % accel_per_hz
        s += "".join(",%.3f" % (0.01 * k * (i % 7)) for k, _ in enumerate(shapers or {}, 1))
        lines.append(s)
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("hash_", [False, True])
def test_resonances_psd(tmp_path, hash_: bool) -> None:
    f = _write(tmp_path, "resonances_x_20240501_101010.csv", _psd_text(hash_=hash_))
    ds = load_csv(f)
    ref = _loadtxt(f)
    assert ds.kind == "klipper_psd" and ds.klipper_output == "resonances" and ds.axis == "x"
    assert list(ds.columns) == ["psd_x", "psd_y", "psd_z", "psd_xyz"] and not ds.shaper_columns
    assert np.array_equal(ds.t, ref[:, 0]) and np.array_equal(ds.columns["psd_xyz"], ref[:, 4])
    assert ds.accel_per_hz is None and math.isnan(ds.sample_rate)


def test_calibration_data_keeps_shaper_columns_apart(tmp_path) -> None:
    shapers = {"zv": 59.0, "mzv": 53.8, "ei": 67.2, "2hump_ei": 80.6, "3hump_ei": 95.4}
    f = _write(tmp_path, "calibration_data_y_20240501_101010.csv", _psd_text(shapers))
    ds = load_csv(f)
    ref = _loadtxt(f)
    assert ds.klipper_output == "calibration_data" and ds.axis == "y"
    assert list(ds.columns) == ["psd_x", "psd_y", "psd_z", "psd_xyz"]
    assert list(ds.shaper_columns) == list(shapers) and ds.shaper_freqs == shapers
    assert np.array_equal(ds.shaper_columns["2hump_ei"], ref[:, 8])


def test_kalico_accel_per_hz(tmp_path) -> None:
    f = _write(tmp_path, "calibration_data_x_1.csv", _psd_text({"zv": 61.2}, accel_per_hz=75.0))
    ds = load_csv(f)
    assert ds.accel_per_hz == 75.0 and "accel_per_hz" not in ds.columns
    assert ds.shaper_freqs == {"zv": 61.2} and list(ds.columns) == ["psd_x", "psd_y", "psd_z", "psd_xyz"]


def test_psd_frequencies_must_increase(tmp_path) -> None:
    lines = _psd_text().splitlines()
    lines[10] = lines[9]
    with pytest.raises(ValueError, match="line 11: frequencies must increase"):
        load_csv(_write(tmp_path, "resonances_x_1.csv", "\n".join(lines) + "\n"))


REAL = Path(__file__).parent / "data" / "real"


@pytest.mark.skipif(not REAL.is_dir(), reason="no real Klipper files in tests/data/real")
def test_real_klipper_psd_files(monkeypatch) -> None:
    """Unmodified Klipper outputs from public repositories (tests/data/real/MANIFEST.md)."""
    files = sorted(REAL.glob("*.csv"))
    assert files
    monkeypatch.setattr(D, "_CHUNK", 2048)  # several blocks even for these small files
    for f in files:
        ds = load_csv(f)
        ref = _loadtxt(f)
        calib = "calibration_data" in f.name
        assert ds.kind == "klipper_psd", f.name
        assert ds.klipper_output == ("calibration_data" if calib else "resonances"), f.name
        assert ds.axis == f.name.split("_resonances_" if not calib else "_calibration_data_")[1][0], f.name
        assert np.array_equal(ds.t, ref[:, 0]) and np.array_equal(ds.columns["psd_xyz"], ref[:, 4]), f.name
        assert len(ds.shaper_columns) == (5 if calib else 0), f.name
        if calib:
            assert np.array_equal(np.column_stack(list(ds.shaper_columns.values())), ref[:, 5:]), f.name
            with open(f, encoding="utf-8") as fh:
                labels = fh.readline().strip().split(",")[5:]
            assert [f"{k}({v:.1f})" for k, v in ds.shaper_freqs.items()] == labels, f.name


@pytest.mark.parametrize("name, axis, output", [
    ("raw_data_x_20240501_101010.csv", "x", "raw_data"),
    ("ender3_raw_data_y_20240501_101010.csv", "y", "raw_data"),
    ("raw_data_z_adxl345_bed_20240501.csv", "z", "raw_data"),
    ("raw_data_axis=1.000,-1.000_belt.csv", None, "raw_data"),
    ("adxl345-y.csv", "y", None),
    ("adxl345-toolhead-X.csv", "x", None),
    ("adxl345-20240501_101010.csv", None, None),
])
def test_raw_log_names(tmp_path, name: str, axis, output) -> None:
    _, rows = _raw_rows(200)
    ds = load_csv(_write(tmp_path, name, RAW_HEADER + rows))
    assert ds.kind == "klipper_raw" and ds.axis == axis and ds.klipper_output == output
    assert ds.sample_rate == pytest.approx(3200.0, rel=1e-3) and ds.t0 == pytest.approx(1000.0, abs=1e-3)


# ----------------------------------------------------------------------------- size and memory


def test_max_bytes_refuses_before_reading(tmp_path, monkeypatch) -> None:
    _, rows = _raw_rows(3000)
    f = _write(tmp_path, "raw.csv", RAW_HEADER + rows)

    def never(*args):
        raise AssertionError("parsed although refused")

    monkeypatch.setattr(D, "_parse_block", never)
    # 3000 rows x 4 columns x 8 bytes x 2 (numbers and a resampled copy) = 192000 bytes
    with pytest.raises(ValueError, match=r"about 3e\+03 rows x 4 columns would need about 18\d KiB .*"
                                         r"max_bytes=100000 .*pass a larger max_bytes"):
        load_csv(f, max_bytes=100_000)
    with pytest.raises(TypeError, match="max_bytes must be an integer"):
        load_csv(f, max_bytes="1GB")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="max_bytes must be an integer >= 1"):
        load_csv(f, max_bytes=0)
    monkeypatch.undo()
    assert load_csv(f, max_bytes=None).kind == "klipper_raw"


def test_peak_memory_below_three_times_the_file(tmp_path) -> None:
    _, rows = _raw_rows(150_000, jitter=0.05)
    f = _write(tmp_path, "raw_data_x_1.csv", RAW_HEADER + rows)
    del rows
    size = os.path.getsize(f)
    tracemalloc.start()
    try:
        ds = load_csv(f)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert ds.resampled and ds.t.size == 150_000
    assert peak < 3 * size, f"peak {peak / size:.2f} x the file size"
