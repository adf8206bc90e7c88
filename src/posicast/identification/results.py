"""What :func:`~posicast.identification.identify` returns (the modes, their 95 % intervals and the fit), and the
starting guess the fits share."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from ..modes import Mode
from .significance import ModeTest

__all__ = ["Interval", "Identification", "PeakGuess"]


class Interval(NamedTuple):
    """95 % confidence intervals of one mode: ``omega`` (rad/s) and ``zeta``, each ``(low, high)``.

    Indexable by position (``iv[0]``), attribute (``iv.omega``) or name (``iv["zeta"]``).
    """

    omega: tuple[float, float]
    zeta: tuple[float, float]

    def __getitem__(self, key: Any) -> Any:  # type: ignore[override]
        if isinstance(key, str):
            return getattr(self, key)
        return tuple.__getitem__(self, key)

    @property
    def freq_hz(self) -> tuple[float, float]:
        return (self.omega[0] / (2 * math.pi), self.omega[1] / (2 * math.pi))

    def contains(self, mode: Mode) -> bool:
        """True when ``mode`` lies inside both intervals."""
        return self.omega[0] <= mode.omega <= self.omega[1] and self.zeta[0] <= mode.zeta <= self.zeta[1]


@dataclass
class Identification:
    """Result of :func:`identify`.

    Attributes
    ----------
    modes : list of Mode
        Identified modes, sorted by frequency.
    intervals : list of Interval
        95 % confidence intervals, one per mode.
    method : str
    fit_percent : float
        ``100 (1 - ||y - y_hat|| / ||y - mean y||)`` (NRMSE fit), NaN for ``psd``.
    whiteness_p : float
        Ljung-Box p-value of the residual (20 lags); small = coloured residual.
    covariance : str
        ``"gauss-newton"``, ``"hac"`` (Newey-West) or ``"delta"`` (ARX).
    y_fit : ndarray or None
        Model output (``psd``: model PSD on ``freqs``).
    order_scores : dict
        BIC per number of modes when the order was chosen automatically.
    shares : list of float
        ``psd``: each mode's share of the fitted spectrum's power (empty for the other methods).
    notes : list of str
    """

    modes: list[Mode]
    intervals: list[Interval]
    method: str
    fit_percent: float = float("nan")
    whiteness_p: float = float("nan")
    covariance: str = "gauss-newton"
    y_fit: np.ndarray | None = None
    residual: np.ndarray | None = None
    sample_rate: float = float("nan")
    order_scores: dict[int, float] = field(default_factory=dict)
    freqs: np.ndarray | None = None
    spectrum: np.ndarray | None = None
    shares: list[float] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    tests: list[ModeTest] = field(default_factory=list)
    at_edge: list[bool] = field(default_factory=list)

    @property
    def amplitudes(self) -> list[float]:
        """Deprecated name of :attr:`shares` ("amplitudes" are a shaper's impulse amplitudes)."""
        warnings.warn("Identification.amplitudes is now Identification.shares", FutureWarning, stacklevel=2)
        return self.shares

    @property
    def fs(self) -> float:
        """The 0.1 name of :attr:`sample_rate` (with a FutureWarning)."""
        warnings.warn("Identification.fs is now Identification.sample_rate", FutureWarning, stacklevel=2)
        return self.sample_rate

    def summary(self) -> str:
        lines = [f"method {self.method}: {len(self.modes)} mode(s)"]
        for m, iv in zip(self.modes, self.intervals):
            f0, f1 = iv.freq_hz
            lines.append(f"  f = {m.freq_hz:.4f} Hz [{f0:.4f}, {f1:.4f}], zeta = {m.zeta:.4f} "
                         f"[{iv.zeta[0]:.4f}, {iv.zeta[1]:.4f}]")
        if math.isfinite(self.fit_percent):
            lines.append(f"  fit {self.fit_percent:.2f} %, residual whiteness p = {self.whiteness_p:.3g} "
                         f"({self.covariance} intervals)")
        lines.extend("  note: " + n for n in self.notes)
        return "\n".join(lines)


class PeakGuess(NamedTuple):
    """A spectral peak as a starting point: its frequency (Hz) and a half-power damping guess."""

    freq_hz: float
    zeta: float
