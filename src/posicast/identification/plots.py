"""Plots: measured spectrum with the fitted model, and the chosen shaper's attenuation.

Imported only when plotting (the CLI's ``--plot`` and the reports import it where they
draw), so matplotlib is imported here at module level.
"""

from __future__ import annotations

from typing import Any

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from .. import _validate as v
from ..firmware import vibration_grid
from ..firmware.klipper import KLIPPER_TEST_DAMPING
from .calibration import Calibration
from .results import Identification

__all__ = ["fit_plot", "calibration_plot"]


def fit_plot(ident: Identification, t: Any = None, y: Any = None, ax: Axes | None = None) -> tuple[Figure, Axes]:
    """Spectrum (PSD fits) or time series (OE-type fits) with the model; returns ``(fig, ax)``."""
    v.instance_of(ident, Identification, "ident", "an Identification")
    fig, ax = plt.subplots(figsize=(7, 3.5)) if ax is None else (ax.figure, ax)
    if ident.freqs is not None and ident.spectrum is not None:
        ax.semilogy(ident.freqs, ident.spectrum, lw=0.8, label="measured PSD")
        ax.semilogy(ident.freqs, ident.y_fit, lw=1.5, label="fitted modal model")
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel("PSD")
    else:
        if y is None or ident.y_fit is None:
            raise ValueError("y is required to plot a time-domain fit")
        tt = np.arange(len(ident.y_fit)) / ident.sample_rate if t is None else np.asarray(t)
        ax.plot(tt, y, lw=0.6, label="measured")
        ax.plot(tt, ident.y_fit, lw=1.2, label=f"model (fit {ident.fit_percent:.1f} %)")
        ax.set_xlabel("t [s]")
    for m in ident.modes:
        if ident.freqs is not None:
            ax.axvline(m.freq_hz, color="k", lw=0.5, ls=":")
    ax.legend(fontsize=8)
    return fig, ax


def calibration_plot(cal: Calibration) -> tuple[Figure, tuple[Axes, Axes]]:
    """The calibration figure; returns ``(fig, (ax_spectra, ax_vibration))`` as the other plots do.

    Left, per file: the measured PSD, the fitted model and its background (excitation
    through a flat path, sweep lines, sensor floor), the excitation shape, each mode's
    95 % frequency interval and the fitted band.  Right: the spectrum the firmware
    scores on (grey) and the vibration left by each recommended setting (solid) and by
    the firmware tool's own pick (dashed), worst over damping 0.075-0.15.
    """
    v.instance_of(cal, Calibration, "cal", "a Calibration")
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(13, 4.5))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    _spectra_panel(a1, cal, colours)
    _vibration_panel(a2, cal, colours)
    fig.tight_layout()
    return fig, (a1, a2)


def _spectra_panel(a1: Axes, cal: Calibration, colours: list[str]) -> None:
    """Per file: measured PSD, fitted model, excitation shape, fitted band and the modes' intervals."""
    for k, fr in enumerate(cal.files):
        c = colours[k % len(colours)]
        name = fr.path.rsplit("/", 1)[-1]
        ident = fr.identification
        if ident is None or ident.freqs is None:
            if fr.resonance is not None:
                sp = fr.resonance.spectrum
                a1.semilogy(sp.freqs, np.maximum(sp.psd, 1e-300), ".", ms=2, color=c, label=f"{name}: no resonance")
            continue
        a1.semilogy(ident.freqs, ident.spectrum, ".", ms=2.5, color=c, label=f"{name} (measured)")
        a1.semilogy(ident.freqs, ident.y_fit, "-", lw=1.3, color=c, label="fitted model")
        if fr.resonance is not None:
            sp = fr.resonance.spectrum
            sel = (sp.freqs >= sp.band[0]) & (sp.freqs <= sp.band[1])
            E = sp.excitation[sel] * (1.0 if sp.normalisation is None else sp.normalisation[sel])
            if np.any(E > 0):
                scale = float(np.median(ident.spectrum)) / float(np.median(E[E > 0]))
                a1.semilogy(sp.freqs[sel], E * scale, ":", lw=1, color=c, label="excitation (shape)")
            for edge in sp.band:
                a1.axvline(edge, color=c, lw=0.6, ls="--")
        for m, iv in zip(ident.modes, ident.intervals):
            a1.axvspan(*iv.freq_hz, color=c, alpha=0.15)
    a1.set_xlabel("frequency [Hz]")
    a1.set_ylabel("PSD")
    a1.set_title("identified modes: " + ", ".join(f"{m.freq_hz:.1f} Hz / {m.zeta:.3f}" for m in cal.modes),
                 fontsize=9)
    if a1.get_legend_handles_labels()[0]:
        a1.legend(fontsize=7)


def _vibration_panel(a2: Axes, cal: Calibration, colours: list[str]) -> None:
    """The firmware's spectrum (grey) and the vibration each recommended setting and each tool's pick leave."""
    spectra = [(fr.resonance.firmware_freqs, fr.resonance.firmware_psd) for fr in cal.files if fr.resonance]
    fmax = 2.5 * max(m.freq_hz for m in cal.modes)
    f = np.linspace(1.0, max(fmax, 50.0), 800)
    if spectra:
        a2b = a2.twinx()
        for b, p in spectra:
            keep = b <= f[-1]
            a2b.fill_between(b[keep], p[keep], color="0.85", lw=0)
        a2b.set_yticks([])
    for k, rec in enumerate(cal.recommendations):
        c = colours[k % len(colours)]
        for cand, ls, tag in ((rec.best, "-", "posicast"), (rec.reference, "--", "own tool")):
            if cand is None:
                continue
            A, T = cand.setting.impulses
            V = vibration_grid(A, T[None, :], f, np.asarray(KLIPPER_TEST_DAMPING))[0].max(axis=1)
            lab = f"{rec.firmware.name}{' ' + rec.axis if rec.axis else ''} {tag}: {cand.setting.describe()}"
            a2.plot(f, 100 * V, ls, color=c, lw=1.6 if tag == "posicast" else 1.0, label=lab)
    a2.set_zorder(3)
    a2.patch.set_visible(False)
    a2.set_xlabel("frequency [Hz]")
    a2.set_ylabel("remaining vibration [%]")
    a2.set_ylim(0, 100)
    if a2.get_legend_handles_labels()[0]:
        a2.legend(fontsize=7)
    a2.set_title("shaper response over the measured spectrum (grey)", fontsize=9)
