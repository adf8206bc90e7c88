"""posicast: time-delay signal shapers for flexible machines.

Design a shaper for a lightly damped mode, analyse its robustness, and work
with the exact delay transfer functions of the loops it sits in.

>>> import posicast
>>> S = posicast.design("zvd", posicast.Mode(5.49, 0.008))
>>> S.n_impulses, round(S.duration, 4)
(3, 1.1445)
"""

from .analysis import (
    Insensitivity,
    SensitivityCurve,
    impulse_plot,
    insensitivity,
    residual_vibration,
    sensitivity_curve,
    sensitivity_plot,
)
from .core import QuasiPolynomial, TransferFunction, as_transfer, delay
from .loops import Loop, control_action, feedforward, inverse_shaper
from .identification import Calibration, Identification, Interval, NoModeFound, calibrate, identify
from .modes import Mode
from .shapers import KINDS, ZERO_VIBRATION_KINDS, DistributedPart, Kernel, Shaper, design
from . import cases
from .simulation import ShaperFilter, SimulationResponse, shape_signal, simulate
from .spectra import Roots, difference_spectrum, rightmost, roots, spectral_abscissa, stability
from .tune import Constraint, Region, TuningResult, tune_pd, tune_pi, tune_pid

__version__ = "0.1.0"

__all__ = [
    "tune_pd",
    "tune_pi",
    "tune_pid",
    "TuningResult",
    "Region",
    "Constraint",
    "identify",
    "calibrate",
    "Identification",
    "Interval",
    "Calibration",
    "NoModeFound",
    "simulate",
    "SimulationResponse",
    "ShaperFilter",
    "shape_signal",
    "cases",
    "roots",
    "Roots",
    "stability",
    "spectral_abscissa",
    "rightmost",
    "difference_spectrum",
    "Mode",
    "QuasiPolynomial",
    "TransferFunction",
    "as_transfer",
    "delay",
    "Shaper",
    "Kernel",
    "DistributedPart",
    "design",
    "KINDS",
    "ZERO_VIBRATION_KINDS",
    "residual_vibration",
    "sensitivity_curve",
    "SensitivityCurve",
    "insensitivity",
    "Insensitivity",
    "sensitivity_plot",
    "impulse_plot",
    "feedforward",
    "control_action",
    "inverse_shaper",
    "Loop",
]
