"""The measured data :func:`~posicast.identification.load_csv` returns: a uniform time base and named signals."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from .. import _validate as v

__all__ = ["Dataset"]


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
    sample_rate : float
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
    sample_rate: float = float("nan")
    resampled: bool = False
    notes: list[str] = field(default_factory=list)
    axis: str | None = None
    klipper_output: str | None = None
    shaper_columns: dict[str, np.ndarray] = field(default_factory=dict)
    shaper_freqs: dict[str, float] = field(default_factory=dict)
    accel_per_hz: float | None = None
    t0: float = float("nan")

    @property
    def fs(self) -> float:
        """The 0.1 name of :attr:`sample_rate` (with a FutureWarning)."""
        warnings.warn("Dataset.fs is now Dataset.sample_rate", FutureWarning, stacklevel=2)
        return self.sample_rate

    def column(self, name: str) -> np.ndarray:
        """The signal ``name`` (a key of ``columns``)."""
        v.instance_of(name, str, "name", "a str (a column name)")
        if name not in self.columns:
            raise ValueError(f"{self.path}: column {name!r} not found; columns are {', '.join(self.columns)}")
        return self.columns[name]

    def projection(self, axis: str = "auto") -> np.ndarray:
        """Klipper acceleration along ``axis`` ("x", "y", "z") or, for ``"auto"``/``"all"``,
        the projection of the three axes on their principal direction (mean removed)."""
        if axis in ("x", "y", "z"):
            return self.column(f"accel_{axis}")
        v.choice(axis, "axis", ("x", "y", "z", "auto", "all"))
        A = np.column_stack([self.column(f"accel_{a}") for a in "xyz"])
        A = A - A.mean(axis=0)
        _, _, Vt = np.linalg.svd(A[:: max(1, A.shape[0] // 20000)], full_matrices=False)
        return A @ Vt[0]
