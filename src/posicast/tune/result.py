"""The result of a tuning: the chosen controller with its independent checks (seed 001 Algorithm 1, step 6)."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any, Mapping

import numpy as np

from ..core.transfer import TransferFunction
from ..loops import Loop
from ..spectra.rootfinder import RootFindingError
from .constraints import Constraint
from .family import ControllerFamily
from .regions import Region

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from ..spectra import Stability

__all__ = ["TuningResult"]


@dataclass(frozen=True)
class TuningResult:
    """A fixed-structure controller chosen from its admissible region, with its checks.

    Attributes
    ----------
    family : ControllerFamily
        The controller structure (``family.describe()``).
    architecture : str
        ``'feedforward'``, ``'control_action'`` or ``'inverse_shaper'`` (where the
        shaper sits, as :class:`~posicast.loops.Loop` names it; formerly ``structure``).
    gains : Mapping[str, float] or None
        ``{'kp', 'ki', 'kd'}`` of the chosen controller (None if the region is empty).
    controller : TransferFunction or None
    loop : Loop or None
        The closed loop with the chosen controller (and ``F``, if given).
    ms : float
        Achieved peak sensitivity ``||1 / (1 + L)||_inf`` (from the loop's own
        sensitivity, refined in frequency); ``nan`` when empty.
    omega_ms : float
        Where it peaks [rad/s] (``inf``: the high-frequency limit).
    sm : float
        Stability margin ``1 / ms``: the least distance of the Nyquist curve to -1.
    stable : bool
        Certified spectrum check of the chosen loop (issue #3).
    stability : Stability or None
    abscissa : float
        Spectral abscissa of the chosen loop (its exponential decay rate is
        ``-abscissa``); computed on first access.
    norms : tuple of float
        Achieved ``||W X||_inf`` for each constraint, in order.
    active : tuple of bool
        Which constraints hold with equality (to 1e-6 relative) at the chosen point.
    constraints : tuple of Constraint
    region : Region
        The admissible region, exact on every scan line over ``region.y_range``.
        For a loop whose frequency grid is large (a lumped shaper or a delay in
        the loop: ``|L|`` does not decay) the final scan refines only a window of
        the maximised gain around the optimum's component (``+/- R``, ``R`` twice
        its largest ``|ky|`` on the sweep lines rounded up to 1, 2 or 5 times a
        power of ten, widened tenfold while the admissible set reaches the
        window's top or the component its bottom): then ``region.windowed`` is
        True, ``region.y_range`` is that window, ``region.search_range`` the whole
        search range, and ``region.sweep`` the first pass (the whole search range
        on the logarithmic sweep lines, coarser in the scanned gain).
        :meth:`summary` states the window.
    empty, unbounded : bool
        No admissible controller; or the maximised gain is not bounded by the
        constraints within the ranges (the point returned is then the best one
        inside them, on a range edge).
    reason : str
        One sentence: why this point, or why nothing.
    timings : Mapping[str, float]
        Seconds spent per stage.
    """

    family: ControllerFamily
    architecture: str
    gains: Mapping[str, float] | None
    controller: TransferFunction | None
    loop: Loop | None
    ms: float
    omega_ms: float
    sm: float
    stable: bool
    stability: Stability | None
    norms: tuple[float, ...]
    active: tuple[bool, ...]
    constraints: tuple[Constraint, ...]
    region: Region
    empty: bool
    unbounded: bool
    reason: str
    timings: Mapping[str, float] = field(default_factory=dict)

    @property
    def structure(self) -> str:
        """Former name of :attr:`architecture` (FutureWarning)."""
        warnings.warn("TuningResult.structure is now TuningResult.architecture (the word posicast.Loop uses)",
                      FutureWarning, stacklevel=2)
        return self.architecture

    @cached_property
    def abscissa(self) -> float:
        """Spectral abscissa of the chosen loop (certified search; ``nan`` if empty or not resolved)."""
        if self.loop is None:
            return math.nan
        try:
            return float(self.loop.spectral_abscissa())
        except (RootFindingError, ValueError):
            return math.nan

    def _gain(self, name: str) -> float | None:
        if self.gains is None:
            return None
        present = name in (self.family.x, self.family.y) or name in self.family.fixed
        return float(self.gains[name]) if present else None

    @property
    def kp(self) -> float | None:
        """Proportional gain (None if the family has none or the region is empty)."""
        return self._gain("kp")

    @property
    def ki(self) -> float | None:
        """Integral gain (None if the family has none or the region is empty)."""
        return self._gain("ki")

    @property
    def kd(self) -> float | None:
        """Derivative gain (None if the family has none or the region is empty)."""
        return self._gain("kd")

    @property
    def point(self) -> tuple[float, float] | None:
        """The chosen ``(kx, ky)`` in the region's plane."""
        if self.gains is None:
            return None
        return float(self.gains[self.family.x]), float(self.gains[self.family.y])

    def plot(self, ax: Axes | None = None, **kwargs: Any) -> tuple[Figure, Axes]:
        """Regions in the gain plane with the chosen point (seed 001 Fig. 5-6); returns ``(fig, ax)``."""
        from .plots import region_plot  # plots imports this module

        return region_plot(self, ax=ax, **kwargs)

    def nyquist_plot(self, ax: Axes | None = None, **kwargs: Any) -> tuple[Figure, Axes]:
        """Nyquist curve of the chosen loop with the Ms circle (seed 001 Fig. 7); returns ``(fig, ax)``."""
        from .plots import tuning_nyquist_plot  # plots imports this module

        return tuning_nyquist_plot(self, ax=ax, **kwargs)

    def summary(self) -> str:
        """A few lines: controller, achieved norms, stability, region."""
        if self.gains is None:
            what = "unbounded, no design returned" if self.unbounded else "no admissible controller"
            return f"{self.family.describe()} in {self.architecture}: {what}. {self.reason}"
        g = ", ".join(f"{k} = {self.gains[k]:.6g}" for k in ("kp", "ki", "kd") if self._gain(k) is not None)
        cons = "; ".join(f"{c.label}: {n:.6g}{' (active)' if a else ''}"
                         for c, n, a in zip(self.constraints, self.norms, self.active))
        out = (f"{self.family.describe()} in {self.architecture}: {g}\n"
               f"  Ms = {self.ms:.6g} at {self.omega_ms:.4g} rad/s (stability margin {self.sm:.4g}); {cons}\n"
               f"  {'stable' if self.stable else 'UNSTABLE'} (spectral abscissa {self.abscissa:.4g}); {self.reason}")
        reg = self.region
        if reg.windowed and reg.search_range is not None:
            y, (lo, hi), (slo, shi) = reg.y_name, reg.y_range, reg.search_range
            out += (f"\n  region: {reg.x.size} lines exact for {y} in [{lo:.4g}, {hi:.4g}] (the window around the "
                    f"optimum's component); {y} in [{slo:.4g}, {shi:.4g}] on the {reg.sweep_lines} "
                    f"sweep lines only (region.sweep)")
        if reg.skipped is not None:
            sk = reg.skipped
            of = "of them" if reg.windowed else f"of the {sk.n_sweep} sweep lines in its first pass"
            y, n = reg.y_name, sk.x.size
            out += (f"\n  the design scanned {sk.n_sweep - n} {of}: on the {n} with |{reg.x_name}| >= "
                    f"{float(np.min(np.abs(sk.x))):.4g} no ")
            if not sk.scanned:
                out += f"{y} >= {sk.floor:.4g} meets the constraints (shown exactly on {sk.probe} frequency columns)"
            else:
                found = (f"their admissible {y} there in {sk.unstable} cell{'s' if sk.unstable > 1 else ''} shown "
                         "unstable by a spectrum check") if sk.unstable else f"no admissible {y} there"
                out += (f"stable {y} >= {sk.floor:.4g} meets the constraints ({n - sk.scanned} shown to have no "
                        f"admissible {y} there on {sk.probe} exact frequency columns; {sk.scanned} scanned exactly "
                        f"on an extended grid: {found})")
        return out

    def __repr__(self) -> str:
        if self.gains is None:
            return f"TuningResult({self.architecture}, {self.family.name}: empty)"
        g = ", ".join(f"{k}={self.gains[k]:.5g}" for k in ("kp", "ki", "kd") if self._gain(k) is not None)
        return f"TuningResult({self.architecture}, {self.family.name}: {g}, ms={self.ms:.5g}, stable={self.stable})"
