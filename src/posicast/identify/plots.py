"""Plots: measured spectrum with the fitted model, and the chosen shaper's attenuation."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..analysis import residual_vibration
from .estimators import Identification, _etfe
from .recommend import Calibration

__all__ = ["fit_plot", "calibration_plot"]


def fit_plot(ident: Identification, t: Any = None, y: Any = None, ax: Any = None) -> tuple[Any, Any]:
    """Spectrum (PSD fits) or time series (OE-type fits) with the model; returns ``(fig, ax)``."""
    import matplotlib.pyplot as plt

    if not isinstance(ident, Identification):
        raise TypeError("ident must be an Identification")
    fig, ax = plt.subplots(figsize=(7, 3.5)) if ax is None else (ax.figure, ax)
    if ident.freqs is not None and ident.spectrum is not None:
        ax.semilogy(ident.freqs, ident.spectrum, lw=0.8, label="measured PSD")
        ax.semilogy(ident.freqs, ident.y_fit, lw=1.5, label="fitted modal model")
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel("PSD")
    else:
        if y is None or ident.y_fit is None:
            raise ValueError("y is required to plot a time-domain fit")
        tt = np.arange(len(ident.y_fit)) / ident.fs if t is None else np.asarray(t)
        ax.plot(tt, y, lw=0.6, label="measured")
        ax.plot(tt, ident.y_fit, lw=1.2, label=f"model (fit {ident.fit_percent:.1f} %)")
        ax.set_xlabel("t [s]")
    for m in ident.modes:
        if ident.freqs is not None:
            ax.axvline(m.freq_hz, color="k", lw=0.5, ls=":")
    ax.legend(fontsize=8)
    return fig, ax


def calibration_plot(cal: Calibration) -> Any:
    """Two panels: spectrum with fitted model; residual vibration of the recommended shaper."""
    import matplotlib.pyplot as plt

    if not isinstance(cal, Calibration):
        raise TypeError("cal must be a Calibration")
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4))
    ident = cal.identification
    if ident is not None and ident.freqs is not None:
        fit_plot(ident, ax=a1)
    elif ident is not None and ident.residual is not None and ident.y_fit is not None:
        y = ident.y_fit + ident.residual
        f, H = _etfe(None, y, ident.fs)
        fm, Hm = _etfe(None, ident.y_fit, ident.fs)
        a1.semilogy(f, H, lw=0.7, label="measured output spectrum")
        a1.semilogy(fm, Hm, lw=1.2, label="model output spectrum")
        a1.set_xlim(0, ident.fs / 2)
        a1.set_xlabel("frequency [Hz]")
        a1.legend(fontsize=8)
    a1.set_title("identified modes: " + ", ".join(f"{m.freq_hz:.1f} Hz / {m.zeta:.3f}" for m in cal.modes))
    fmax = 2.0 * max(m.freq_hz for m in cal.modes)
    f = np.linspace(0.2 * min(m.freq_hz for m in cal.modes), fmax, 600)
    for c in cal.candidates[:4]:
        vv = residual_vibration(c.shaper, 2 * math.pi * f, float(np.mean([m.zeta for m in cal.modes])))
        a2.plot(f, 100 * np.asarray(vv), lw=2.0 if c.shaper is cal.recommended else 0.9, label=c.label)
    for m, iv in zip(cal.modes, cal.intervals):
        a2.axvspan(*iv.freq_hz, color="orange", alpha=0.3)
    a2.axhline(5, color="k", lw=0.5, ls="--")
    a2.set_xlabel("frequency [Hz]")
    a2.set_ylabel("residual vibration [%]")
    a2.set_ylim(0, 100)
    a2.legend(fontsize=8)
    a2.set_title(f"recommended: {cal.label}")
    fig.tight_layout()
    return fig
