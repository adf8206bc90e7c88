"""Stage 2: robustness analysis of shapers."""

from .vibration import (
    Insensitivity,
    SensitivityCurve,
    insensitivity,
    residual_vibration,
    sensitivity_curve,
)
from .plots import impulse_plot, sensitivity_plot

__all__ = [
    "Insensitivity",
    "SensitivityCurve",
    "insensitivity",
    "residual_vibration",
    "sensitivity_curve",
    "impulse_plot",
    "sensitivity_plot",
]
