"""The result of :func:`posicast.simulate`: signals, metrics and a plot."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from .. import _validate as v

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

    def _sig(self, signal: str, name: str = "signal") -> np.ndarray:
        v.choice(signal, name, tuple(self.signals))
        if self.time.size == 0:
            raise ValueError(f"the response is empty (the loop diverged at t = {self.diverged}): no {name} to measure")
        return self.signals[signal]

    def _time(self, value: Any, name: str) -> float:
        t = v.finite_real(value, name)
        if t > self.time[-1]:
            raise ValueError(f"{name} = {t:g} s is beyond the simulated time {self.time[-1]:.4g} s")
        return t

    def residual_vibration(self, after: float, signal: str = "y") -> float:
        """Largest deviation ``|x(t) - x(t_end)|`` for ``t >= after``."""
        x = self._sig(signal)
        after = self._time(after, "after")
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
        tol = v.positive(tol, "tol")
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
            return self._time(start, "start")
        w = self.signals["w"]
        ch = np.flatnonzero(np.diff(w) != 0)
        return float(self.time[ch[0] + 1]) if ch.size else float(self.time[0])

    def plot(self, signals: Sequence[str] = ("w", "z", "y", "u"), axes: Any = None, label: str | None = None) -> Any:
        """Plot ``signals`` on stacked axes; returns ``(fig, axes)``.

        ``signals`` are names of :attr:`signals` (those absent from this loop are
        skipped, at least one must be present); ``axes`` one Axes per drawn signal.
        ``label`` names this response's curves in a legend on every axes (draw
        several responses on the same ``axes`` to compare them).

        Examples
        --------
        >>> import numpy as np, posicast as pc
        >>> t = np.arange(0, 2, 0.01)
        >>> r = pc.simulate(pc.feedforward(G=([1], [1, 1]), C=2.0), t, w=np.ones_like(t))
        >>> fig, axes = r.plot(["y"], label="P = 2")
        >>> [t.get_text() for t in axes[0].get_legend().get_texts()]
        ['P = 2']
        """
        names_in = [signals] if isinstance(signals, str) else v.sequence(signals, "signals", min_len=1)
        for nm in names_in:
            if not isinstance(nm, str):
                raise TypeError(f"signals must be signal names (str), got {type(nm).__name__}")
        names = [s for s in names_in if s in self.signals]
        if not names:
            raise ValueError(f"signals: none of {names_in} is a signal of this response {tuple(self.signals)}")
        if label is not None and not isinstance(label, str):
            raise TypeError(f"label must be a string or None, got {type(label).__name__}")
        if axes is not None:
            ax_list = [axes] if not isinstance(axes, (list, tuple, np.ndarray)) else list(np.ravel(axes))
            for a in ax_list:
                v.axes(a, "axes")
            if len(ax_list) < len(names):
                raise ValueError(f"axes has {len(ax_list)} Axes for {len(names)} signals")
        import matplotlib.pyplot as plt

        if axes is None:
            fig, axes = plt.subplots(len(names), 1, sharex=True, figsize=(8, 1.8 * len(names) + 0.8), squeeze=False)
            axes = axes[:, 0]
        else:
            axes = np.array(ax_list, dtype=object)
            fig = axes[0].figure
        for ax, nm in zip(axes, names):
            ax.plot(self.time, self.signals[nm], lw=1.0, label=label)
            ax.set_ylabel(_LABELS.get(nm, nm), fontsize=8)
            ax.grid(True, alpha=0.3)
            if self.diverged is not None:
                ax.axvline(self.diverged, color="r", ls=":", lw=1)
            if label is not None:  # every labelled curve drawn on this axes so far
                ax.legend(fontsize=8, loc="best")
        axes[-1].set_xlabel("time [s]")
        if self.diverged is not None:
            axes[0].set_title(f"diverged: |{self.diverged_signal}| at t = {self.diverged:.3g} s", fontsize=9)
        return fig, axes
