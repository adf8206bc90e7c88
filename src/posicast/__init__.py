"""posicast: time-delay signal shapers for flexible machines.

Design a shaper for a lightly damped mode, analyse its robustness, and work
with the exact delay transfer functions of the loops it sits in.

>>> import posicast
>>> S = posicast.design("zvd", posicast.Mode(5.49, 0.008))
>>> S.n_impulses, round(S.duration, 4)
(3, 1.1445)

The public names, by pipeline stage (each package has the full list):

Systems (:mod:`posicast.core`)
    ``QuasiPolynomial``, ``TransferFunction``, ``as_transfer``, ``delay``, ``Mode``.
    One rule for coefficients: a polynomial given alone is in numpy's *descending* powers
    (``TransferFunction.from_poly``, ``(num, den)`` tuples, ``QuasiPolynomial.from_poly``,
    ``from_terms``, the CLI's ``--num/--den``); a coefficient *matrix* given with its delays
    is in *ascending* powers, ``coeffs[i, k]`` multiplying ``s^k exp(-s delays[i])``
    (``QuasiPolynomial(coeffs, delays)``, a ``(coeffs, delays)`` pair, ``.coeffs``).
Shapers (:mod:`posicast.shapers`)
    ``design``, ``KINDS``, ``ZERO_VIBRATION_KINDS``, ``Shaper``, ``Kernel``, ``DistributedPart``.
Spectra (:mod:`posicast.spectra`) -- each verb is also a method of every object
    ``roots``, ``poles``, ``zeros``, ``stability``, ``spectral_abscissa``, ``rightmost``,
    ``difference_spectrum``, ``Roots``.
Loops (:mod:`posicast.loops`)
    ``Loop``, ``feedforward``, ``control_action``, ``inverse_shaper``.
Analysis (:mod:`posicast.analysis`)
    ``residual_vibration``, ``sensitivity_curve``, ``insensitivity``, ``SensitivityCurve``,
    ``Insensitivity``, ``sensitivity_plot``, ``impulse_plot``.
Simulation (:mod:`posicast.simulation`)
    ``simulate``, ``SimulationResponse``, ``ShaperFilter``, ``shape_signal``.
Tuning (:mod:`posicast.tune`)
    ``tune_pd``, ``tune_pi``, ``tune_pid``, ``TuningResult``, ``Region``, ``Constraint``.
Identification and printer calibration (:mod:`posicast.identification`)
    ``identify``, ``calibrate``, ``Identification``, ``Interval``, ``Calibration``, ``NoModeFound``.
Sweeps (:mod:`posicast.sweeps`, loaded on first use; Dask, Zarr)
    ``sweep``: a function over a grid or seeded draws, on local processes or a Dask cluster,
    persisted as results arrive and resumable.
Case studies
    :mod:`posicast.cases` (the seeds' plants, each with its source).

A function never hides a package: ``posicast.identify`` is the function, its package is
``posicast.identification``; ``posicast.simulate`` the function, ``posicast.simulation``
the package; ``posicast.design`` the function, ``posicast.shapers.registry`` its module.
"""

from . import cases
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
from .identification import Calibration, Identification, Interval, NoModeFound, calibrate, identify
from .loops import Loop, control_action, feedforward, inverse_shaper
from .modes import Mode
from .shapers import KINDS, ZERO_VIBRATION_KINDS, DistributedPart, Kernel, Shaper, design
from .simulation import ShaperFilter, SimulationResponse, shape_signal, simulate
from .spectra import Roots, difference_spectrum, poles, rightmost, roots, spectral_abscissa, stability, zeros
from .tune import Constraint, Region, TuningResult, tune_pd, tune_pi, tune_pid

__version__ = "0.1.0"


def __getattr__(name: str) -> object:
    if name == "sweep":  # issue #19: posicast.sweeps on first use (the lead's lazy table replaces this at merge)
        from .sweeps import sweep

        return sweep
    if name == "demo":
        raise AttributeError("posicast.demo moved to posicast_reports.demo (run: python -m posicast_reports.demo); "
                             "issue #14: reports are a separate package of the repository")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

__all__ = [
    # systems
    "QuasiPolynomial", "TransferFunction", "as_transfer", "delay", "Mode",
    # shapers
    "design", "KINDS", "ZERO_VIBRATION_KINDS", "Shaper", "Kernel", "DistributedPart",
    # spectra
    "roots", "poles", "zeros", "stability", "spectral_abscissa", "rightmost", "difference_spectrum", "Roots",
    # loops
    "Loop", "feedforward", "control_action", "inverse_shaper",
    # analysis
    "residual_vibration", "sensitivity_curve", "insensitivity", "SensitivityCurve", "Insensitivity",
    "sensitivity_plot", "impulse_plot",
    # simulation
    "simulate", "SimulationResponse", "ShaperFilter", "shape_signal",
    # tuning
    "tune_pd", "tune_pi", "tune_pid", "TuningResult", "Region", "Constraint",
    # identification and calibration
    "identify", "calibrate", "Identification", "Interval", "Calibration", "NoModeFound",
    # sweeps
    "sweep",
    # case studies
    "cases",
]
