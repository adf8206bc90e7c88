"""Stage 1: shaper design (lumped, distributed and IIR)."""

from .base import DistributedPart, Kernel, Shaper
from .registry import KINDS, ZERO_VIBRATION_KINDS, design
from .sampled import OrderChoice, highest_multiplicity, zplane_shaper

__all__ = ["DistributedPart", "Kernel", "Shaper", "KINDS", "ZERO_VIBRATION_KINDS", "design",
           "zplane_shaper", "highest_multiplicity", "OrderChoice"]
