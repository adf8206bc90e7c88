"""Time-domain simulation of loops with shapers, sampled or continuous, and real-time shaper filters (issue #4)."""

from .engine import DivergenceWarning, simulate
from .response import SimulationResponse
from .sampled_spectrum import SampledLoop, sampled_loop
from .sparse import InverseStability, SparseTaps, inverse_stability
from .streaming import FRACTIONAL, DiscreteShaper, ShaperFilter, discretize, shape_signal, shortest_delay

__all__ = [
    "simulate",
    "SimulationResponse",
    "DivergenceWarning",
    "ShaperFilter",
    "shape_signal",
    "discretize",
    "DiscreteShaper",
    "shortest_delay",
    "FRACTIONAL",
    "SampledLoop",
    "sampled_loop",
    "SparseTaps",
    "InverseStability",
    "inverse_stability",
]
