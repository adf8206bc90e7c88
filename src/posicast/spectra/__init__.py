"""Spectra of quasi-polynomials and of loops with shapers: certified roots, stability.

The verbs (each also a method of every object, see :mod:`posicast.spectra.systems`):

=======================  ==================================================================
``roots(h, region)``     every root of a quasi-polynomial in a rectangle, certified count
``poles(sys, region)``   poles of a transfer function, shaper or loop
``zeros(sys, region)``   zeros (a loop: of one channel)
``stability(h)``         exponential stability, with the reason (marginal on the axis)
``spectral_abscissa(h)`` the largest real part, with a certified error
``rightmost(h, n)``      the ``n`` rightmost roots
``unstable_count(h)``    the number of roots with ``Re s >= 0`` (argument principle only)
=======================  ==================================================================

Tools: :func:`difference_spectrum` (a neutral quasi-polynomial's difference operator),
:func:`root_bound`; results :class:`Roots`, :class:`Stability`, :class:`SpectralAbscissa`,
:class:`DifferenceSpectrum`; errors :class:`RootFindingError`, :class:`BudgetExceeded`.
"""

from .rootfinder import BudgetExceeded, RootFindingError, Roots
from .verdict import (
    DifferenceSpectrum,
    SpectralAbscissa,
    Stability,
    difference_spectrum,
    root_bound,
)
from .systems import Characteristic, characteristic_of, poles, rightmost, roots, spectral_abscissa, stability, \
    unstable_count, zeros

__all__ = [
    "roots",
    "poles",
    "zeros",
    "Roots",
    "RootFindingError",
    "BudgetExceeded",
    "root_bound",
    "difference_spectrum",
    "DifferenceSpectrum",
    "spectral_abscissa",
    "SpectralAbscissa",
    "rightmost",
    "stability",
    "Stability",
    "unstable_count",
    "characteristic_of",
    "Characteristic",
]
