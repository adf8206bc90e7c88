"""Spectra of quasi-polynomials and of loops with shapers: certified roots, stability."""

from .rootfinder import BudgetExceeded, RootFindingError, Roots, roots
from .stability import (
    DifferenceSpectrum,
    SpectralAbscissa,
    Stability,
    difference_spectrum,
    rightmost,
    root_bound,
    spectral_abscissa,
    stability,
    unstable_count,
)

__all__ = [
    "roots",
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
]
