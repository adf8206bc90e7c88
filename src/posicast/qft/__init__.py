"""QFT: robust inner-loop model matching over an uncertain plant set (seed 003).

``PlantSet`` (uncertain plants, templates), :func:`qft_design` (automatic loop shaping of
the inner controller ``G`` with the prefilter ``F``, checked over every plant), the paper's
analyses (:func:`percent_vibration`, Fig. 6-7, bandwidth) and the Fig. 1 architecture
(:func:`model_matching`).
"""

from .analyses import (
    Bandwidth,
    ShaperLengths,
    ShortestShaper,
    UncertaintyLengths,
    bandwidth,
    length_vs_uncertainty,
    length_vs_vibration,
    percent_vibration,
    shortest_zvdk,
    zvdk,
)
from .architecture import deviated_two_mass, inner_closed_loop, inner_loop, model_matching
from .design import DEFAULT_STRUCTURE, QFTResult, qft_design
from .figures import ControlEffort, RootLocus, control_effort, root_locus
from .plantset import PlantSet
from .specs import Verification, nichols_bounds, verify
from .structure import SECTIONS, Structure

__all__ = [
    "PlantSet", "qft_design", "QFTResult", "DEFAULT_STRUCTURE", "Structure", "SECTIONS", "verify", "Verification",
    "nichols_bounds", "percent_vibration", "zvdk", "length_vs_vibration", "ShaperLengths", "shortest_zvdk",
    "ShortestShaper", "length_vs_uncertainty", "UncertaintyLengths", "bandwidth", "Bandwidth", "model_matching",
    "inner_loop", "inner_closed_loop", "deviated_two_mass", "root_locus", "RootLocus", "control_effort",
    "ControlEffort",
]
