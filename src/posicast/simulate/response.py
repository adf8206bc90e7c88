"""The result of :func:`posicast.simulate`: signals, metrics and a plot."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

__all__ = ["SimulationResponse"]

_LABELS = {
    "w": "reference w", "r": "shaped reference r", "e": "error e", "v": "controller output v",
    "u": "actuator command u", "up": "plant input", "z": "actuator side z", "y": "load y",
    "m": "feedback signal m", "d": "output disturbance d", "di": "input disturbance di",
    "n": "measurement noise n",
}


@dataclass(frozen=True)
class SimulationResponse:
    """Time response of a loop (python-control style data object).

    Attributes
    ----------
    time : ndarray
        Times [s]; shorter than the requested grid when the loop diverged.
    signals : dict of ndarray
        ``w, d, di, n`` (inputs), ``e, v, u, z, y`` and ``r`` (feedforward) or
        ``m`` (inverse shaper).
    mode : str
        ``'sampled'``, ``'continuous'`` or ``'continuous (exact)'``.
    sample_rate : float or None
    accuracy : float
        Continuous mode with the shaper in the loop: max |y| difference to a run
        at twice the internal step when ``substeps`` is even (an estimate of that
        run's error, about three times this one's), at half the step when it is
        odd (then about this run's own error); 0 for the exact and sampled modes,
        whose sampled values are exact for the discretised controller.
    diverged : float or None
        Time at which a signal exceeded the divergence limit.
    diverged_signal : str or None
    architecture : str
    """

    time: np.ndarray
    signals: dict[str, np.ndarray]
    mode: str
    sample_rate: float | None
    accuracy: float
    diverged: float | None
    diverged_signal: str | None
    architecture: str

    def __getattr__(self, name: str) -> np.ndarray:
        sig = object.__getattribute__(self, "signals")
        if name in sig:
            return sig[name]
        raise AttributeError(name)

    @property
    def outputs(self) -> dict[str, np.ndarray]:
        return {k: v for k, v in self.signals.items() if k not in ("w", "d", "di", "n")}

    def _sig(self, signal: str) -> np.ndarray:
        if signal not in self.signals:
            raise ValueError(f"signal must be one of {tuple(self.signals)}, got {signal!r}")
        return self.signals[signal]

    def residual_vibration(self, after: float, signal: str = "y") -> float:
        """Largest deviation ``|x(t) - x(t_end)|`` for ``t >= after``."""
        x = self._sig(signal)
        sel = self.time >= after
        if not np.any(sel):
            raise ValueError(f"after = {after:g} s is beyond the simulated time {self.time[-1]:.4g} s")
        seg = x[sel]
        return float(np.max(np.abs(seg - seg[-1])))

    def settling_time(self, signal: str = "z", tol: float = 0.02, start: float | None = None) -> float:
        """Time after ``start`` (default: first change of ``w``) until ``signal`` stays within ``tol`` of its end value.

        ``tol`` is relative to the size of the change.
        """
        x = self._sig(signal)
        t0 = self._start(start)
        sel = self.time >= t0
        seg, ts = x[sel], self.time[sel]
        final, initial = seg[-1], seg[0]
        band = tol * max(abs(final - initial), 1e-300)
        out = np.flatnonzero(np.abs(seg - final) > band)
        if out.size == 0:
            return 0.0
        if out[-1] + 1 >= ts.size:
            return float("inf")
        return float(ts[out[-1] + 1] - t0)

    def overshoot(self, signal: str = "z", start: float | None = None) -> float:
        """Overshoot in % of the change of ``signal`` after ``start``."""
        x = self._sig(signal)
        seg = x[self.time >= self._start(start)]
        change = seg[-1] - seg[0]
        if change == 0:
            return 0.0
        peak = np.max((seg - seg[0]) / change)
        return float(max(0.0, peak - 1.0) * 100.0)

    def peak(self, signal: str = "u") -> float:
        """Largest magnitude of ``signal`` (e.g. peak actuator command)."""
        return float(np.max(np.abs(self._sig(signal))))

    def _start(self, start: float | None) -> float:
        if start is not None:
            return float(start)
        w = self.signals["w"]
        ch = np.flatnonzero(np.diff(w) != 0)
        return float(self.time[ch[0] + 1]) if ch.size else float(self.time[0])

    def plot(self, signals: Sequence[str] = ("w", "z", "y", "u"), axes: Any = None, label: str | None = None) -> Any:
        """Plot ``signals`` on stacked axes; returns the figure and the axes."""
        import matplotlib.pyplot as plt

        names = [s for s in signals if s in self.signals]
        if axes is None:
            fig, axes = plt.subplots(len(names), 1, sharex=True, figsize=(8, 1.8 * len(names) + 0.8), squeeze=False)
            axes = axes[:, 0]
        else:
            axes = np.atleast_1d(axes)
            fig = axes[0].figure
        for ax, nm in zip(axes, names):
            ax.plot(self.time, self.signals[nm], lw=1.0, label=label)
            ax.set_ylabel(_LABELS.get(nm, nm), fontsize=8)
            ax.grid(True, alpha=0.3)
            if self.diverged is not None:
                ax.axvline(self.diverged, color="r", ls=":", lw=1)
        axes[-1].set_xlabel("time [s]")
        if self.diverged is not None:
            axes[0].set_title(f"diverged: |{self.diverged_signal}| at t = {self.diverged:.3g} s", fontsize=9)
        return fig, axes
