"""Time-domain simulation of loops with shapers, sampled or continuous, and real-time shaper filters (issue #4)."""

from .engine import DivergenceWarning, simulate
from .response import SimulationResponse
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
]
