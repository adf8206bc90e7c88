"""The spectral verbs as methods: every object answers what :mod:`posicast.spectra` computes.

python-control's rule: ``posicast.poles(G, region)`` and ``G.poles(region)`` are one
computation.  The free functions live in :mod:`posicast.spectra.systems`, which
builds on this package (``core``); the methods here import them on call.  That
call-time import is the one place ``core`` reaches up a layer, and it is the
cycle that requires it (``spectra`` imports ``core`` at module level).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Sequence

if TYPE_CHECKING:  # annotations only
    import numpy as np

    from ..spectra.rootfinder import Roots
    from ..spectra.verdict import SpectralAbscissa, Stability

__all__ = ["SystemVerbs", "QuasiPolynomialVerbs"]


class _SpectrumVerbs:
    """The verbs a quasi-polynomial and a system share (a system answers them for its poles); each method
    takes the same arguments as its free function after the object."""

    __slots__ = ()

    def stability(self, *, ignore: Any = None, max_evaluations: float = 5e7, timeout: float = 120.0) -> Stability:
        """Exponential stability (:func:`posicast.spectra.stability`)."""
        from ..spectra.systems import stability  # cycle: spectra builds on core

        return stability(self, ignore=ignore, max_evaluations=max_evaluations, timeout=timeout)

    def spectral_abscissa(self, *, ignore: Any = None, max_radius: float = 2e4) -> SpectralAbscissa:
        """Largest real part of the roots or poles (:func:`posicast.spectra.spectral_abscissa`)."""
        from ..spectra.systems import spectral_abscissa  # cycle: spectra builds on core

        return spectral_abscissa(self, ignore=ignore, max_radius=max_radius)

    def rightmost(self, n: int = 1, *, ignore: Any = None, max_alpha_steps: int = 12,
                  max_radius: float = 2e4) -> np.ndarray:
        """The ``n`` rightmost roots or poles (:func:`posicast.spectra.rightmost`)."""
        from ..spectra.systems import rightmost  # cycle: spectra builds on core

        return rightmost(self, n, ignore=ignore, max_alpha_steps=max_alpha_steps, max_radius=max_radius)

    def roots(self, region: Sequence[float], *, ignore: Any = None, max_evaluations: float = 5e7,
              timeout: float = 120.0) -> Roots:
        """Every root in ``region`` with a certified count (a system: its poles; :func:`posicast.spectra.roots`)."""
        from ..spectra.systems import roots  # cycle: spectra builds on core

        return roots(self, region, ignore=ignore, max_evaluations=max_evaluations, timeout=timeout)


class SystemVerbs(_SpectrumVerbs):
    """``poles``, ``zeros``, ``roots`` (the poles), ``stability``, ``spectral_abscissa``, ``rightmost`` of a system.

    Mixed into :class:`~posicast.core.transfer.TransferFunction`,
    :class:`~posicast.shapers.base.Shaper` and :class:`~posicast.loops.loop.Loop`;
    each method is its free function's twin (same arguments after the object).
    """

    __slots__ = ()

    def poles(self, region: Sequence[float], *, max_evaluations: float = 5e7, timeout: float = 120.0) -> Roots:
        """Poles in ``region`` (:func:`posicast.spectra.poles`)."""
        from ..spectra.systems import poles  # cycle: spectra builds on core

        return poles(self, region, max_evaluations=max_evaluations, timeout=timeout)

    def zeros(self, region: Sequence[float], *, channel: Sequence[str] | None = None, max_evaluations: float = 5e7,
              timeout: float = 120.0) -> Roots:
        """Zeros in ``region`` (:func:`posicast.spectra.zeros`; a loop takes ``channel=(src, dst)``)."""
        from ..spectra.systems import zeros  # cycle: spectra builds on core

        return zeros(self, region, channel=channel, max_evaluations=max_evaluations, timeout=timeout)


class QuasiPolynomialVerbs(_SpectrumVerbs):
    """``roots``, ``zeros`` (the same), ``stability``, ``spectral_abscissa``, ``rightmost`` of a quasi-polynomial."""

    __slots__ = ()

    def zeros(self, region: Sequence[float], *, max_evaluations: float = 5e7, timeout: float = 120.0) -> Roots:
        """The zeros of ``h``, its roots (:func:`posicast.spectra.zeros`)."""
        from ..spectra.systems import zeros  # cycle: spectra builds on core

        return zeros(self, region, max_evaluations=max_evaluations, timeout=timeout)
