"""``calibrate``: resonance-test files in, firmware lines out.

One or several files (Klipper raw logs, Klipper PSD files, or input/output CSV):

1. each file is read (:func:`~posicast.identification.load_csv`), its axis taken from its
   name (``--axis`` when the name does not say), its spectra built
   (:mod:`.resonance`) and its modes identified with 95 % intervals
   (:func:`~posicast.identification.spectral.fit_spectrum`); a file without a resonance is
   reported as such;
2. the files of one axis together (several probe points or print masses) give a
   worst-case recommendation per firmware (:mod:`.recommend`); RepRapFirmware, which
   runs one shaper for all axes, gets one over every axis;
3. files labelled with a mass or a Z height (``at=[{"mass": 0}, ...]``) also give the
   frequency schedule of the dominant mode, ``f = c / sqrt(m0 + m)`` (a mass on a
   spring) with its residual, and its straight-line form for the firmwares that
   schedule linearly (Prusa's weight adjustment, Marlin's dynamic frequency);
4. posicast's own optimum (exact designs, convolved over the modes) for JSON or C export.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, NamedTuple, Sequence

import numpy as np
import numpy.typing as npt
from scipy import optimize

from .. import _validate as v
from ..firmware import FIRMWARES, Firmware, Klipper, MarlinFT, Prusa, RepRapFirmware
from ..modes import Mode
from ..shapers import Shaper
from .data import Dataset, load_csv
from .estimators import METHODS, identify
from .results import Identification, Interval
from .recommend import Candidate, ModeBox, Recommendation, mode_boxes, optimum, recommend_setting
from .resonance import ResonanceData, resonance_data
from .significance import NoModeFound
from .spectral import fit_spectrum

__all__ = ["calibrate", "Calibration", "FileResult", "Schedule", "identify_resonances"]

Progress = Callable[[str], None]
#: Filament mass per mm of 1.75 mm PLA (1.24 g/cm^3): Marlin's mass-based frequency follows the extruder position.
PLA_G_PER_MM = 1.24e-3 * math.pi * 0.875 ** 2


@dataclass
class FileResult:
    """One file: its data, its identification, or why it has none."""

    path: str
    axis: str | None
    kind: str
    identification: Identification | None = None
    resonance: ResonanceData | None = None
    label: dict[str, float] = field(default_factory=dict)
    no_mode: str | None = None


@dataclass
class Schedule:
    """A mode frequency against a label (mass in g, or Z height in mm).

    Attributes
    ----------
    variable : str
    values, freqs : ndarray
        Label values and the dominant mode's frequency (Hz) in each file.
    c, m0 : float
        ``f = c / sqrt(m0 + value)`` (a mass on a spring); NaN with fewer than 3 files.
    residual : float
        RMS relative residual of that fit.
    f0, slope : float
        The straight line ``f = f0 + slope value`` through the same points.
    linear_residual : float
        Its RMS relative residual.
    lines : list of str
        Firmware schedule lines (Prusa's weight adjustment, Marlin's dynamic frequency).
    """

    variable: str
    values: np.ndarray
    freqs: np.ndarray
    c: float
    m0: float
    residual: float
    f0: float
    slope: float
    linear_residual: float
    lines: list[str] = field(default_factory=list)

    def frequency(self, value: npt.ArrayLike) -> np.ndarray:
        """The fitted frequency at ``value``."""
        return self.c / np.sqrt(self.m0 + np.asarray(value, dtype=float))


@dataclass
class Calibration:
    """Result of :func:`calibrate`.

    Attributes
    ----------
    files : list of FileResult
    recommendations : list of Recommendation
        One per firmware and axis.
    shaper : Shaper
        posicast's optimum over every identified mode (no firmware limits).
    shaper_vibration : float
        Its worst case over the modes' boxes.
    shaper_label : str
    schedule : Schedule or None
    notes : list of str
    """

    files: list[FileResult]
    recommendations: list[Recommendation]
    shaper: Shaper
    shaper_vibration: float
    shaper_label: str
    schedule: Schedule | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def modes(self) -> list[Mode]:
        return [m for fr in self.files if fr.identification for m in fr.identification.modes]

    @property
    def intervals(self) -> list[Interval]:
        return [iv for fr in self.files if fr.identification for iv in fr.identification.intervals]

    @property
    def identification(self) -> Identification | None:
        """The first file's identification (single-file use)."""
        return next((fr.identification for fr in self.files if fr.identification), None)

    @property
    def config(self) -> list[str]:
        """Every firmware's lines (and the schedule's); a firmware's header comment once, not once per axis."""
        out: list[str] = []
        for rec in self.recommendations:
            # a repeated header comment is dropped; a warning (it names its axis) never is
            out += [ln for ln in rec.config if not (ln[:1] in ("#", ";") and "warning:" not in ln and ln in out)]
        if self.schedule is not None:
            out += self.schedule.lines
        return out

    def recommendation(self, firmware: str, axis: str | None = None) -> Recommendation:
        for rec in self.recommendations:
            if rec.firmware.name == firmware and (axis is None or rec.axis in (axis, None)):
                return rec
        raise KeyError(f"no recommendation for {firmware} axis {axis}")

    def summary(self) -> str:
        out: list[str] = []
        for fr in self.files:
            head = f"{Path(fr.path).name} (axis {fr.axis or '?'}, {fr.kind})"
            if fr.no_mode:
                out.append(f"{head}: {fr.no_mode}")
                continue
            assert fr.identification is not None
            out.append(head)
            ident = fr.identification
            shares = ident.shares if len(ident.shares) == len(ident.modes) else [None] * len(ident.modes)
            for m, iv, sh, edge in zip(ident.modes, ident.intervals, shares,
                                       ident.at_edge or [False] * len(ident.modes)):
                out.append(f"  mode {m.freq_hz:7.2f} Hz [{iv.freq_hz[0]:.2f}, {iv.freq_hz[1]:.2f}]  zeta {m.zeta:.3f} "
                           f"[{iv.zeta[0]:.3f}, {iv.zeta[1]:.3f}]" + ("" if sh is None else f"  share {sh:.2f}")
                           + ("  (band edge)" if edge else ""))
        for rec in self.recommendations:
            out.append("")
            out.append(f"{rec.firmware.name}" + (f", axis {rec.axis}" if rec.axis else ", all axes"))
            out.append(rec.table())
            out += ["  " + r for r in rec.reasoning]
        if self.schedule is not None:
            s = self.schedule
            out.append("")
            out.append(f"schedule: f = {s.c:.2f} / sqrt({s.m0:.1f} + {s.variable}) Hz, rms residual "
                       f"{100 * s.residual:.2f} %; linear f = {s.f0:.2f} {s.slope:+.4f} {s.variable} "
                       f"(rms {100 * s.linear_residual:.2f} %)")
        out.append("")
        out.append(f"posicast optimum (no firmware limits): {self.shaper_label}, {1000 * self.shaper.duration:.2f} ms, "
                   f"worst case {100 * self.shaper_vibration:.1f} %")
        out += ["note: " + n for n in self.notes]
        out.append("")
        out += self.config
        return "\n".join(out)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready description (NaN as None)."""
        def num(x: float) -> float | None:
            return None if x is None or not math.isfinite(x) else float(x)

        def cand(c: Candidate) -> dict[str, Any]:
            return {"type": c.setting.shaper_type.written, "freq_hz": num(c.setting.freq),
                    "damping": num(c.setting.damping), "worst_vibration": num(c.vibration),
                    "firmware_vibration": num(c.firmware_vibration), "smoothing_mm": num(c.smoothing),
                    "max_accel": num(c.max_accel)}

        files = []
        for fr in self.files:
            d: dict[str, Any] = {"path": fr.path, "axis": fr.axis, "kind": fr.kind, "label": fr.label,
                                 "no_mode": fr.no_mode, "modes": []}
            if fr.identification is not None:
                for m, iv in zip(fr.identification.modes, fr.identification.intervals):
                    d["modes"].append({"freq_hz": num(m.freq_hz), "zeta": num(m.zeta),
                                       "freq_hz_95": [num(x) for x in iv.freq_hz], "zeta_95": [num(x) for x in iv.zeta]})
            files.append(d)
        recs = [{"firmware": r.firmware.name, "axis": r.axis, "recommended": cand(r.best),
                 "per_type": [cand(c) for c in r.per_type.values()],
                 "firmware_own_pick": cand(r.reference) if r.reference else None,
                 "config": r.config} for r in self.recommendations]
        T, A = self.shaper.impulses
        out: dict[str, Any] = {"files": files, "recommendations": recs,
                               "shaper": {"label": self.shaper_label, "times": [float(t) for t in T],
                                          "amplitudes": [float(a) for a in A],
                                          "worst_vibration": num(self.shaper_vibration)},
                               "notes": self.notes}
        if self.schedule is not None:
            s = self.schedule
            out["schedule"] = {"variable": s.variable, "values": s.values.tolist(), "freqs_hz": s.freqs.tolist(),
                               "c": num(s.c), "m0": num(s.m0), "residual": num(s.residual), "f0": num(s.f0),
                               "slope": num(s.slope), "lines": s.lines}
        return out


def identify_resonances(rd: ResonanceData, n_modes: int | str = "auto", progress: Progress | None = None
                        ) -> Identification:
    """Identify the modes of one resonance test (its fit spectrum), as an :class:`Identification`."""
    r = fit_spectrum(rd.spectrum, n_modes, progress=progress)
    ident = Identification(r.modes, [Interval(*iv) for iv in r.intervals], "psd", covariance="whittle",
                           y_fit=r.fit.model, freqs=r.fit.freqs, spectrum=r.fit.psd, shares=r.shares,
                           tests=r.tests, at_edge=r.at_edge,
                           notes=[f"{rd.spectrum.source}: fitted on {rd.spectrum.band[0]:.1f}-"
                                  f"{rd.spectrum.band[1]:.1f} Hz, excitation ~ f^2 (Klipper's sweep)"] + r.notes)
    ident.sample_rate = float("nan")
    return ident


def _firmwares(firmware: str | Sequence[str], klipper_version: str) -> list[Firmware]:
    names = [firmware] if isinstance(firmware, str) else v.sequence(firmware, "firmware")
    if names == ["all"]:
        names = list(FIRMWARES)
    klipper_version = v.choice(klipper_version, "klipper_version", ("v0.13", "master", "kalico"))
    out: list[Firmware] = []
    for n in names:
        n = v.choice(n, "firmware", tuple(FIRMWARES) + ("all",))
        if n == "all":
            raise ValueError("firmware 'all' cannot be combined with other names")
        out.append(Klipper(klipper_version) if n == "klipper" else FIRMWARES[n]())
    if not out:
        raise ValueError("at least one firmware is needed")
    return out


def _labels(at: Sequence[dict[str, float]] | None, n: int) -> list[dict[str, float]]:
    if at is None:
        return [{} for _ in range(n)]
    at = list(at)
    if len(at) != n:
        raise ValueError(f"at has {len(at)} labels for {n} files; give one per file")
    out = []
    for d in at:
        if not isinstance(d, dict) or len(d) != 1:
            raise ValueError(f"each label must be one name=value pair (mass=200, z=50), got {d!r}")
        (k, val), = d.items()
        if k not in ("mass", "z"):
            raise ValueError(f"label name must be 'mass' (g) or 'z' (mm), got {k!r}")
        out.append({k: v.real(val, f"{k} label")})
    names = {next(iter(d)) for d in out}
    if len(names) > 1:
        raise ValueError(f"all files must carry the same label, got {', '.join(sorted(names))}")
    return out


def calibrate(paths: str | Path | Sequence[str | Path], *, firmware: str | Sequence[str] = "klipper",
              axis: str | None = None, at: Sequence[dict[str, float]] | None = None, vtol: float | None = None,
              margin: float = 0.05, max_smoothing: float | None = None, slack: float = 0.01,
              klipper_version: str = "v0.13",
              input: str | None = None, output: str | None = None, method: str | None = None,
              n_modes: int | str = "auto", progress: Progress | None = None,
              band: tuple[float, float] | None = None) -> Calibration:
    """Identify the modes in resonance-test files and recommend what each firmware should run.

    Parameters
    ----------
    paths : path, Dataset or a list of them
        Klipper raw accelerometer logs (``#time,accel_x,accel_y,accel_z``), Klipper PSD
        files (``resonances_*.csv``, ``calibration_data_*.csv``), or CSV with ``input``
        and ``output`` columns.
    firmware : str or list of str
        ``"klipper"``, ``"reprapfirmware"``, ``"marlin"``, ``"prusa"`` or ``"all"``.
    axis : {"x", "y", "z"}, optional
        The tested axis when the file names do not say it.
    at : list of dict, optional
        One label per file: ``{"mass": grams}`` or ``{"z": mm}``, for a frequency schedule.
    vtol : float, optional
        Worst-case residual vibration target, in (0, 1); None (default): the best trade-off
        of vibration and smoothing (see :mod:`.recommend`).
    margin : float
        Relative frequency drift added to every mode's interval, in [0, 0.5).
    max_smoothing : float, optional
        Upper bound on Klipper's smoothing (mm).
    slack : float
        Remaining vibration (the firmware tool's own measure, 0..0.2) posicast may add to
        the tool's own pick in exchange for less smoothing (see :mod:`.recommend`).
    klipper_version : {"v0.13", "master", "kalico"}
    input, output, method, n_modes :
        For input/output CSV data (output-error identification).
    progress : callable, optional
        Called with a line of text as the work proceeds.
    band : (float, float), optional
        Search for modes only between these frequencies [Hz] (resonance-test files): the
        fitted band is the test's excited band intersected with it.  The firmware settings
        are still scored on the whole measured spectrum.

    Raises
    ------
    NoModeFound
        When no file shows a resonance.
    """
    paths = _path_list(paths)
    axis, method, n_modes, margin, slack = _check_options(axis, input, output, method, n_modes, margin, slack,
                                                          progress)
    fws = _firmwares(firmware, klipper_version)
    labels = _labels(at, len(paths))
    if vtol is not None:
        vtol = v.in_open_interval(vtol, "vtol", 0.0, 1.0)
    if max_smoothing is not None:
        max_smoothing = v.positive(max_smoothing, "max_smoothing")
    say = progress or (lambda s: None)
    band = None if band is None else _check_band(band)
    files = [_identify_file(item, lab, axis, input, output, method, n_modes, say, band)
             for item, lab in zip(paths, labels)]
    good = [fr for fr in files if fr.identification is not None]
    if not good:
        msgs = "; ".join(f"{Path(fr.path).name}: {fr.no_mode}" for fr in files)
        raise NoModeFound(f"no resonance found: {msgs}" if len(files) > 1 else str(files[0].no_mode))
    notes = _default_axis(good)
    boxes_of = {id(fr): mode_boxes(fr.identification.modes, fr.identification.intervals,  # type: ignore[union-attr]
                                   fr.identification.shares, margin) for fr in good}  # type: ignore[union-attr]
    recs = _recommendations(fws, good, boxes_of, vtol=vtol, max_smoothing=max_smoothing, margin=margin,
                            slack=slack, say=say)
    all_boxes = [b for fr in good for b in boxes_of[id(fr)]]
    S, worst, label = optimum(all_boxes, vtol=0.05 if vtol is None else vtol)
    schedule = _schedule(good, fws) if any(fr.label for fr in good) else None
    for fr in files:
        if fr.no_mode:
            notes.append(f"{Path(fr.path).name}: {fr.no_mode}")
    return Calibration(files, recs, S, worst, label, schedule, notes)


def _default_axis(files: list[FileResult]) -> list[str]:
    """Files whose name gives no axis are taken as x: set it, and say so."""
    unknown = [fr for fr in files if fr.axis is None]
    if not unknown:
        return []
    for fr in unknown:
        fr.axis = "x"
    return ["the axis of " + ", ".join(Path(fr.path).name for fr in unknown) +
            " is not in the file name: taken as x (use --axis)"]


class _Options(NamedTuple):
    """The checked options of :func:`calibrate` that concern every file."""

    axis: str | None
    method: str | None
    n_modes: int | str
    margin: float
    slack: float


def _check_options(axis: object, input: object, output: object, method: object, n_modes: object, margin: object,
                   slack: object, progress: object) -> _Options:
    if axis is not None:
        axis = v.choice(axis, "axis", ("x", "y", "z"))
    for name, col in (("input", input), ("output", output)):
        if col is not None and not isinstance(col, str):
            raise TypeError(f"{name} must be a column name (str), got {type(col).__name__}")
    if method is not None:
        method = v.choice(method, "method", METHODS)
    if n_modes != "auto":
        n_modes = v.integer(n_modes, "n_modes", 1)
    margin = v.real_in_range(margin, "margin", 0.0, 0.5, hi_open=True)
    slack = v.real_in_range(slack, "slack", 0.0, 0.2)
    if progress is not None and not callable(progress):
        raise TypeError("progress must be a callable taking a str, or None")
    return _Options(axis, method, n_modes, margin, slack)  # type: ignore[arg-type]


def _recommendations(fws: list[Firmware], good: list[FileResult], boxes_of: dict[int, list[ModeBox]], *,
                     vtol: float | None, max_smoothing: float | None, margin: float, slack: float,
                     say: Progress) -> list[Recommendation]:
    """One recommendation per firmware and axis (RepRapFirmware: one over every axis), over the files' mode boxes."""
    recs: list[Recommendation] = []
    axes = sorted({fr.axis for fr in good})  # type: ignore[type-var]
    for fw in fws:
        groups = [None] if isinstance(fw, RepRapFirmware) else axes
        for ax in groups:
            members = [fr for fr in good if ax is None or fr.axis == ax]
            boxes: list[ModeBox] = [b for fr in members for b in boxes_of[id(fr)]]
            spectra = [(fr.resonance.firmware_freqs, fr.resonance.firmware_psd) for fr in members
                       if fr.resonance is not None]
            say(f"searching {fw.name} settings" + (f" for axis {ax}" if ax else ""))
            recs.append(recommend_setting(fw, boxes, spectra, vtol=vtol, max_smoothing=max_smoothing, axis=ax,
                                          margin=margin, slack=slack))
    return recs


def _path_list(paths: object) -> list[str | Path | Dataset]:
    """``paths`` as a non-empty list of file paths or loaded Datasets."""
    if isinstance(paths, (str, Path, Dataset)):
        paths = [paths]
    if not isinstance(paths, (list, tuple)):
        raise TypeError(f"paths must be a file path or a list of them, got {type(paths).__name__}")
    out = list(paths)
    if not out:
        raise ValueError("no files given")
    for p in out:
        if not isinstance(p, (str, Path, Dataset)):
            raise TypeError(f"paths must be file paths (or loaded Datasets), got {type(p).__name__}")
    return out


def _check_band(band: object) -> tuple[float, float]:
    """``band`` as two frequencies ``0 <= low < high`` [Hz] (a named error otherwise)."""
    vals = v.sequence(band, "band", min_len=2)
    if len(vals) != 2:
        raise ValueError(f"band must be two frequencies (low, high) in Hz, got {len(vals)} values")
    lo, hi = (v.real(x, "band") for x in vals)
    if not 0.0 <= lo < hi:
        raise ValueError(f"band must satisfy 0 <= low < high [Hz], got ({lo:g}, {hi:g})")
    return lo, hi


def _restrict(rd: ResonanceData, band: tuple[float, float]) -> ResonanceData:
    """``rd`` with its fitted band narrowed to ``band``; a band outside the excited one is refused."""
    lo, hi = rd.spectrum.band
    new = (max(lo, band[0]), min(hi, band[1]))
    if not new[1] - new[0] >= 4.0 * rd.spectrum.resolution:
        raise ValueError(f"band ({band[0]:g}, {band[1]:g}) Hz leaves less than 4 bins of the band "
                         f"{lo:.1f}-{hi:.1f} Hz that {Path(rd.path).name} excited")
    return dataclasses.replace(rd, spectrum=dataclasses.replace(rd.spectrum, band=new),
                               notes=rd.notes + (f"modes searched in {new[0]:.1f}-{new[1]:.1f} Hz (band)",))


def _identify_file(item: str | Path | Dataset, label: dict[str, float], axis: str | None, input: str | None,
                   output: str | None, method: str | None, n_modes: int | str, say: Progress,
                   band: tuple[float, float] | None = None) -> FileResult:
    """Read one file and identify its modes: a resonance test's spectrum, or input/output columns by
    :func:`~posicast.identification.identify`; a file without a mode keeps the reason in ``no_mode``."""
    path = item.path if isinstance(item, Dataset) else str(item)
    say(f"reading {Path(path).name}")
    ds = item if isinstance(item, Dataset) else load_csv(item)
    if ds.kind in ("klipper_raw", "klipper_psd", "rrf_accelerometer"):  # the last one is refused, with a way
        rd = resonance_data(ds, axis)
        if band is not None:
            rd = _restrict(rd, band)
        fr = FileResult(str(path), rd.axis, rd.kind, resonance=rd, label=label)
        say(f"identifying modes in {Path(path).name} ({rd.spectrum.band[0]:.0f}-{rd.spectrum.band[1]:.0f} Hz)")
        try:
            fr.identification = identify_resonances(rd, n_modes, progress=say)
        except NoModeFound as exc:
            fr.no_mode = str(exc)
        return fr
    if band is not None:
        raise ValueError(f"{path}: band applies to resonance-test files (Klipper logs and PSD files), not to "
                         "input/output CSV")
    if input is None or output is None:
        raise ValueError(f"{path}: not a Klipper file; give the input and output columns (--input, --output)")
    fr = FileResult(str(path), axis, "csv", label=label)
    try:
        fr.identification = identify(ds.t, ds.column(input), ds.column(output), n_modes=n_modes,
                                     method=method or "oe")
    except NoModeFound as exc:
        fr.no_mode = str(exc)
    return fr


def _schedule(files: list[FileResult], fws: list[Firmware]) -> Schedule | None:
    var = next(iter(files[0].label))
    pts = []
    for fr in files:
        if not fr.label or fr.identification is None:
            continue
        ident = fr.identification
        w = ident.shares or [1.0] * len(ident.modes)
        dom = ident.modes[int(np.argmax(w))]
        pts.append((fr.label[var], dom.freq_hz, fr.axis))
    if len(pts) < 2:
        return None
    x = np.array([p[0] for p in pts])
    f = np.array([p[1] for p in pts])
    A = np.column_stack([np.ones_like(x), x])
    (f0, slope), *_ = np.linalg.lstsq(A, f, rcond=None)
    lin_res = float(np.sqrt(np.mean(((f0 + slope * x) / f - 1.0) ** 2)))
    c, m0, res = math.nan, math.nan, math.nan
    if len(pts) >= 3:
        # f = c / sqrt(m0 + x): 1/f^2 = (m0 + x)/c^2 is linear in x; start there, refine on relative error
        k, b = np.polyfit(x, 1.0 / f ** 2, 1)
        if k > 0:
            c0, m00 = 1.0 / math.sqrt(k), b / k
            sol = optimize.least_squares(lambda p: p[0] / np.sqrt(np.maximum(p[1] + x, 1e-12)) / f - 1.0,
                                         [c0, m00], x_scale="jac")
            c, m0 = float(sol.x[0]), float(sol.x[1])
            res = float(np.sqrt(np.mean(sol.fun ** 2)))
    lines: list[str] = []
    axis = pts[0][2] or "y"
    for fw in fws:
        if isinstance(fw, Prusa) and var == "mass" and slope < 0:
            span = float(x.max())
            lines += ["; Prusa weight adjustment (Y): f = f0 + A min(m / M, 1), set the mass with M74 W<grams>"]
            lines += [f"M593 Y F{f0:.1f}"] + fw.weight_adjustment(slope * span, span)
        if isinstance(fw, MarlinFT):
            if var == "z":
                lines += ["; Marlin FT_MOTION dynamic frequency by Z: f = A + F z",
                          f"M493 {axis.upper()} D1 A{f0:.1f} F{slope:.4f}"]
            elif var == "mass":
                per_mm = slope * PLA_G_PER_MM
                lines += [f"; Marlin FT_MOTION dynamic frequency by extruded filament (1.75 mm PLA, "
                          f"{PLA_G_PER_MM * 1000:.2f} mg/mm): f = A + F e",
                          f"M493 {axis.upper()} D2 A{f0:.1f} F{per_mm:.6f}"]
    return Schedule(var, x, f, c, m0, res, float(f0), float(slope), lin_res, lines)
