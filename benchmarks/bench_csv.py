"""Benchmark: reading Klipper raw accelerometer logs, posicast against np.loadtxt (issue #12/#13).

Files: ``#time,accel_x,accel_y,accel_z`` then "%.6f,%.6f,%.6f,%.6f" rows, as Klipper's
adxl345.py ``write_to_file`` writes them, 3200 Hz with time-stamp jitter (+-0.2 of a step),
signed accelerations and gravity on z:

* 60 s log: 192 000 rows; 600 s log: 1 920 000 rows; 5e6 rows (not with ``--quick``).

Comparator: ``np.loadtxt(path, comments='#', delimiter=',')`` -- the call Klipper's own
calibrate_shaper.py / graph_accelerometer.py make.  Timed (median of up to 5 runs):

* ``read_table``: posicast's parse only (same output as np.loadtxt: numbers and line numbers);
* ``load_csv``: everything (parse, time checks, Klipper detection, resampling of the
  jittered time stamps onto a uniform grid).

The ratio posicast / np.loadtxt should be <= 1.  Peak memory of ``load_csv`` (and of
np.loadtxt) is measured in a fresh subprocess per file, two ways: tracemalloc peak and the
growth of the peak resident set (/proc/self/status VmHWM over VmRSS before the call);
both are given as multiples of the file size (target < 3).  The values read by
``read_table`` are checked bit for bit against np.loadtxt; a difference fails the script.

Usage: python benchmarks/bench_csv.py [--quick]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from _harness import fmt_time, machine_info, md_table, print_machine_info, timed

from posicast.identification.data import load_csv, read_table

FS = 3200.0
HEADER = "#time,accel_x,accel_y,accel_z\n"

MEMORY_PROBE = r"""
import sys, tracemalloc
import numpy as np
from posicast.identification.data import load_csv

def status(key):
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith(key + ":"):
                return int(line.split()[1]) * 1024
    return 0

path, tool, how = sys.argv[1:4]
call = (lambda: load_csv(path)) if tool == "posicast" else (lambda: np.loadtxt(path, comments="#", delimiter=","))
if how == "tracemalloc":
    tracemalloc.start()
    out = call()
    print(tracemalloc.get_traced_memory()[1])
else:
    before = status("VmRSS")
    out = call()
    print(status("VmHWM") - before)
"""


def write_log(path: Path, rows: int, seed: int = 0, block: int = 100_000) -> None:
    rng = np.random.default_rng(seed)
    line = "%.6f,%.6f,%.6f,%.6f\n"
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(HEADER)
        for k0 in range(0, rows, block):
            k = np.arange(k0, min(rows, k0 + block))
            t = 1000.0 + (k + 0.2 * rng.uniform(-1.0, 1.0, k.size)) / FS
            a = rng.normal(0.0, 400.0, (k.size, 3))
            a[:, 2] += 9806.65
            fh.write((line * k.size) % tuple(np.column_stack([t, a]).ravel().tolist()))


def peak_memory(path: Path, tool: str, how: str) -> float:
    out = subprocess.run([sys.executable, "-c", MEMORY_PROBE, str(path), tool, how],
                         capture_output=True, text=True, check=False)
    try:
        return float(out.stdout.strip().splitlines()[-1])
    except (ValueError, IndexError):
        print(f"  memory probe failed ({tool}, {how}): {out.stderr.strip()[-300:]}")
        return float("nan")


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    print_machine_info(machine_info())
    cases = [("60 s log", 192_000)] + ([] if args.quick else [("600 s log", 1_920_000), ("5e6 rows", 5_000_000)])
    repeats = 3 if args.quick else 5
    rows_out, mem_out = [], []
    failed = False
    with tempfile.TemporaryDirectory() as tmp:
        for label, rows in cases:
            path = Path(tmp) / f"raw_data_x_{rows}.csv"
            write_log(path, rows)
            size = os.path.getsize(path)
            budget = 20.0 if rows > 2_000_000 else 10.0
            ref = timed(lambda: np.loadtxt(path, comments="#", delimiter=","), repeats, budget)
            rt = timed(lambda: read_table(path), repeats, budget)
            lc = timed(lambda: load_csv(path), repeats, budget)
            for name, tm in (("np.loadtxt", ref), ("read_table", rt), ("load_csv", lc)):
                if tm.error:
                    print(f"  {label}: {name} failed: {tm.error}")
                    failed = True
            if ref.error or rt.error or lc.error:
                continue
            same = np.array_equal(rt.result[1], ref.result) and np.array_equal(
                np.signbit(rt.result[1]), np.signbit(ref.result))
            failed |= not same
            ds = lc.result
            rows_out.append([label, f"{rows:,}", f"{size / 1e6:.1f} MB", fmt_time(ref.median), fmt_time(rt.median),
                             f"{rt.median / ref.median:.2f}", fmt_time(lc.median), f"{lc.median / ref.median:.2f}",
                             "yes" if same else "NO", f"{ds.sample_rate:.4f}"])
            del ref, rt, lc, ds
            mem = {(tool, how): peak_memory(path, tool, how)
                   for tool in ("posicast", "np.loadtxt") for how in ("tracemalloc", "rss")}
            mem_out.append([label, f"{size / 1e6:.1f} MB",
                            f"{mem['posicast', 'tracemalloc'] / size:.2f}", f"{mem['posicast', 'rss'] / size:.2f}",
                            f"{mem['np.loadtxt', 'tracemalloc'] / size:.2f}", f"{mem['np.loadtxt', 'rss'] / size:.2f}"])
            path.unlink()
    print("\nTime (median; ratio = posicast / np.loadtxt, target <= 1)\n")
    print(md_table(["file", "rows", "size", "np.loadtxt", "read_table", "ratio", "load_csv", "ratio",
                    "same numbers", "load_csv fs [Hz]"], rows_out))
    print("\nPeak memory of one call, in multiples of the file size (target < 3 for load_csv)\n")
    print(md_table(["file", "size", "load_csv tracemalloc", "load_csv RSS growth", "np.loadtxt tracemalloc",
                    "np.loadtxt RSS growth"], mem_out))
    if failed:
        print("\nFAILED: a reader failed or read_table's numbers differ from np.loadtxt")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
