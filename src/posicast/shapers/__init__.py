"""Stage 1: shaper design (lumped, distributed and IIR)."""

from .base import DistributedPart, Kernel, Shaper
from .optimal import ActiveConstraint, Optimality, OptimalShaper, shortest_shaper
from .registry import KINDS, ZERO_VIBRATION_KINDS, design
from .sampled import OrderChoice, highest_multiplicity, zplane_shaper

__all__ = ["DistributedPart", "Kernel", "Shaper", "KINDS", "ZERO_VIBRATION_KINDS", "design",
           "shortest_shaper", "OptimalShaper", "Optimality", "ActiveConstraint",
           "zplane_shaper", "highest_multiplicity", "OrderChoice"]
