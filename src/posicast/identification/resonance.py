"""From a resonance-test file to the spectra posicast fits and firmware tools score.

Two spectra come out of every file:

* the **fit spectrum** (:class:`~posicast.identification.spectral.Spectrum`): the
  measured PSD with its excitation model and the band the test excited, for
  identification;
* the **firmware spectrum**: the PSD exactly as Klipper's calibration scores
  shapers on it (x + y + z, divided by ``f + 0.1`` and tapered below 10 Hz; for a
  raw log, Klipper's own Welch estimate), so posicast's recommendation and
  Klipper's own can be compared on Klipper's terms.

Raw logs: the sweep is read from the data (spectrogram ridge,
:func:`~posicast.identification.excitation.estimate_sweep`), so the band and the test
method need no configuration; the fit spectrum uses 1 Hz resolution (a choice, not
a fraction of the record: the cost is flat in the log's length).  PSD files: the
excited band ends at the test's ``max_freq``, which Klipper does not write; it is
found where the spectrum falls by the square wave's harmonic ratio (at least 5x)
and otherwise taken as 135 Hz (Klipper's default) when the file extends to its
1.5x (202.5 Hz).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import _validate as v
from .dataset import Dataset
from .excitation import SweepEstimate, estimate_sweep, klipper_normalisation
from .significance import NoModeFound
from .spectral_model import Spectrum
from .welch import KAISER6_CORRELATION, block_kernel, smoothed_periodogram, welch_kernel, welch_psd

__all__ = ["ResonanceData", "resonance_data", "FIT_RESOLUTION"]

#: Frequency resolution of the fit spectrum of a raw log, Hz.
FIT_RESOLUTION = 1.0
#: Klipper's Welch segment, s (shaper_calibrate.py: WINDOW_T_SEC).
KLIPPER_WINDOW = 0.5
_LOWEST = 5.0  # Klipper's MIN_FREQ: below it the sweep's own lines dominate


@dataclass(frozen=True)
class ResonanceData:
    """One resonance test: what was measured and on which axis.

    Attributes
    ----------
    path : str
    axis : str or None
        "x", "y" or "z" from the file name, or as given.
    kind : str
        "raw_data", "resonances" or "calibration_data" (Klipper's names).
    spectrum : Spectrum
        For identification.
    firmware_freqs, firmware_psd : ndarray
        Klipper-normalised x + y + z PSD (what Klipper scores shapers on).
    sweep : SweepEstimate or None
        Raw logs: the sweep read from the data.
    notes : list of str
    """

    path: str
    axis: str | None
    kind: str
    spectrum: Spectrum
    firmware_freqs: np.ndarray
    firmware_psd: np.ndarray
    sweep: SweepEstimate | None
    notes: tuple[str, ...] = ()


def _psd_sum(ds: Dataset) -> np.ndarray:
    if "psd_xyz" in ds.columns:
        return ds.columns["psd_xyz"]
    parts = [ds.columns[c] for c in ("psd_x", "psd_y", "psd_z") if c in ds.columns]
    if parts:
        return np.sum(parts, axis=0)
    return np.sum(list(ds.columns.values()), axis=0)


def _excited_end(f: np.ndarray, P: np.ndarray) -> tuple[float, str]:
    """Upper end of the excited band of a PSD file: the steepest lasting drop, or 135 Hz."""
    hi = float(f[-1])
    logp = np.log(np.maximum(P, 1e-300))
    step = float(np.median(np.diff(f)))
    w = max(2, int(round(6.0 / step)))  # 6 Hz on either side
    best, where = 0.0, math.nan
    # the median of every w-bin window at once (issue #15: was one np.median per bin); the drop at bin i is
    # the window before it against the window from it, and the first largest drop from 60 Hz on is kept
    if f.size > 2 * w:
        med = np.median(np.lib.stride_tricks.sliding_window_view(logp, w), axis=1)
        i = np.arange(w, f.size - w)
        drop = med[i - w] - med[i]
        drop = np.where((f[i] >= 60.0) & ~np.isnan(drop), drop, -np.inf)  # a NaN drop never wins, as in a loop
        k = int(np.argmax(drop))
        if drop[k] > best:
            best, where = float(drop[k]), float(f[i[k]])
    if best > math.log(5.0):
        end = where - 2.0 * step  # the falling edge itself is not excited spectrum
        return end, f"the excitation ends near {where:.0f} Hz (the spectrum falls {math.exp(best):.0f}x there)"
    if hi > 190.0:
        return 135.0, "no end of the excitation is visible; Klipper's default max_freq 135 Hz is assumed"
    return hi, f"the file ends at {hi:.0f} Hz; the whole range is taken as excited"


def resonance_data(ds: Dataset, axis: str | None = None) -> ResonanceData:
    """The spectra of one loaded file (:func:`~posicast.identification.load_csv`).

    Parameters
    ----------
    ds : Dataset
        A Klipper raw accelerometer log or PSD file.
    axis : {"x", "y", "z"}, optional
        The tested axis when the file name does not say it.
    """
    v.instance_of(ds, Dataset, "ds", "a posicast.identification.Dataset (from load_csv)")
    if axis is not None:
        v.choice(axis, "axis", ("x", "y", "z"))
    name_axis = getattr(ds, "axis", None)
    notes: list[str] = list(ds.notes)
    if axis is not None and name_axis is not None and axis != name_axis:
        notes.append(f"the file name says axis {name_axis}, but axis {axis} was asked for: using {axis}")
    ax = axis or name_axis
    if ds.kind == "klipper_psd":
        return _from_psd(ds, ax, notes)
    if ds.kind == "rrf_accelerometer":
        raise ValueError(f"{ds.path}: a RepRapFirmware recording of your own moves has no known excitation (no "
                         "sweep to model), so its spectrum cannot be read as resonances; fit its ring-down instead "
                         "(a recording that ends in the free decay after a move): posicast identify FILE --output "
                         "accel_x --method decay")
    if ds.kind != "klipper_raw":
        raise ValueError(f"{ds.path}: not a Klipper accelerometer log or PSD file, nor a RepRapFirmware "
                         "accelerometer file (expected columns #time,accel_x,accel_y,accel_z, freq,psd_x,... or "
                         "Sample,X,Y,Z)")
    return _from_raw(ds, ax, notes)


def _from_psd(ds: Dataset, ax: str | None, notes: list[str]) -> ResonanceData:
    f = np.asarray(ds.t, dtype=float)
    P = np.asarray(_psd_sum(ds), dtype=float)
    stage = getattr(ds, "klipper_output", None) or "resonances"
    normalised = stage == "calibration_data"
    knorm = klipper_normalisation(f)
    fw_psd = P if normalised else P * knorm
    raw = np.divide(P, knorm, out=np.zeros_like(P), where=knorm > 1e-300) if normalised else P
    end, why = _excited_end(f, raw)
    notes.append(why)
    lo = max(_LOWEST, float(f[f > 0][0]) if np.any(f > 0) else _LOWEST)
    E = np.where((f >= lo) & (f <= end), np.maximum(f, 1e-9) ** 2, 0.0)
    spec = Spectrum(f, P, E, (lo, end), True, knorm if normalised else None,
                    float(np.median(np.diff(f))), f"Klipper {stage} file", correlation=KAISER6_CORRELATION,
                    kernel=welch_kernel())
    keep = f <= 200.0
    return ResonanceData(ds.path, ax, stage, spec, f[keep], fw_psd[keep], None, tuple(notes))


def _from_raw(ds: Dataset, ax: str | None, notes: list[str]) -> ResonanceData:
    fs = float(ds.sample_rate)
    A = np.column_stack([ds.column(f"accel_{a}") for a in "xyz"])  # each estimator removes its own mean
    # the sweep is tracked on the axis that moves most
    lead = int(np.argmax(np.var(A[:: max(1, A.shape[0] // 50000)], axis=0)))
    sweep = estimate_sweep(A[:, lead] - A[:, lead].mean(), fs)
    if sweep is None:
        # noise, or motion whose frequency does not follow a sweep?  Compare the test band with the band
        # above it, where a resonance test puts (almost) nothing
        fk, Pk, _ = welch_psd(A, fs, 1.0 / KLIPPER_WINDOW)
        test_band = float(np.median(Pk[(fk >= 5.0) & (fk <= 135.0)]))
        above = (fk > 300.0) & (fk < 0.45 * fs)
        quiet = float(np.median(Pk[above])) if np.any(above) else 0.0
        if quiet > 0 and test_band < 10.0 * quiet:
            raise NoModeFound(f"no resonance found in {ds.path}: the log holds no frequency sweep, only noise "
                              "(was TEST_RESONANCES or SHAPER_CALIBRATE running while it was recorded?)")
        raise ValueError(f"{ds.path}: the log holds motion, but no frequency sweep could be tracked in it (a "
                         "resonance test's frequency rises steadily); a strong mode below 15 Hz or a test "
                         "interrupted part-way can hide it")
    notes.append(f"sweep {sweep.start:.1f} -> {sweep.end:.1f} Hz at {sweep.rate:.3g} Hz/s read from the data")
    seg = slice(max(0, int((sweep.t_start - 0.5) * fs)), min(A.shape[0], int((sweep.t_end + 0.5) * fs)))
    f, P, k = smoothed_periodogram(A[seg], fs, FIT_RESOLUTION)
    lo = max(_LOWEST, sweep.start)
    hi = min(sweep.end, 0.45 * fs)
    E = np.where((f >= lo) & (f <= hi), np.maximum(f, 1e-9) ** 2, 0.0)
    margin = 2.0 * FIT_RESOLUTION
    # averages of k raw bins of a tapered record: nearly independent blocks, each 1/k in variance for noise
    spec = Spectrum(f, P, E, (lo + margin, hi - margin), True, None, float(f[1] - f[0]), "Klipper raw log",
                    correlation=1.0, dispersion_floor=1.0 / k, kernel=block_kernel())
    # what Klipper would score on: its own Welch estimate (0.5 s) of the whole log, normalised
    fk, Pk, _ = welch_psd(A, fs, 1.0 / KLIPPER_WINDOW)
    keep = fk <= 200.0
    return ResonanceData(ds.path, ax, "raw_data", spec, fk[keep], (Pk * klipper_normalisation(fk))[keep], sweep,
                         tuple(notes))
