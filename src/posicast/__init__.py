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
    ``design``, ``KINDS``, ``ZERO_VIBRATION_KINDS``, ``Shaper``, ``Kernel``, ``DistributedPart``,
    ``shortest_shaper``, ``OptimalShaper``, ``Optimality`` (issue #17: SI, UM and limited-impulse shapers),
    ``zplane_shaper``, ``highest_multiplicity``, ``OrderChoice`` (z-plane shapers, seed 002 eq. 4-12).
Spectra (:mod:`posicast.spectra`) -- each verb is also a method of every object
    ``roots``, ``poles``, ``zeros``, ``stability``, ``spectral_abscissa``, ``rightmost``,
    ``difference_spectrum``, ``Roots``.
Loops (:mod:`posicast.loops`)
    ``Loop``, ``feedforward``, ``control_action``, ``inverse_shaper``.
Analysis (:mod:`posicast.analysis`)
    ``residual_vibration``, ``sensitivity_curve``, ``insensitivity``, ``SensitivityCurve``,
    ``Insensitivity``, ``sensitivity_plot``, ``impulse_plot``.
Simulation (:mod:`posicast.simulation`)
    ``simulate``, ``SimulationResponse``, ``ShaperFilter``, ``shape_signal``, ``sampled_loop``,
    ``SampledLoop`` (the loop's poles at the sample rate).
Tuning (:mod:`posicast.tune`)
    ``tune_pd``, ``tune_pi``, ``tune_pid``, ``TuningResult``, ``Region``, ``Constraint``.
QFT inner-loop model matching (:mod:`posicast.qft`, seed 003)
    ``PlantSet``, ``qft_design``, ``QFTResult``, ``percent_vibration``, ``model_matching``.
Identification and printer calibration (:mod:`posicast.identification`)
    ``identify``, ``calibrate``, ``Identification``, ``Interval``, ``Calibration``, ``NoModeFound``.
Export (:mod:`posicast.io`)
    ``export_shaper`` (sparse or dense taps, forward or inverse, JSON or compilable C).
Sweeps (:mod:`posicast.sweeps`; Dask and Zarr are imported when a sweep runs)
    ``sweep``: a function over a grid or seeded draws, on local processes or a Dask cluster,
    persisted as results arrive and resumable.
Case studies
    :mod:`posicast.cases` (the seeds' plants, each with its source).

A function never hides a package: ``posicast.identify`` is the function, its package is
``posicast.identification``; ``posicast.simulate`` the function, ``posicast.simulation``
the package; ``posicast.design`` the function, ``posicast.shapers.registry`` its module.

Every public name is loaded on first use (:mod:`posicast._lazy`): ``import posicast``
costs about as much as ``import numpy``, and scipy and matplotlib are imported only by
the functions that need them.  To add a public name, add ONE line to ``_PUBLIC`` below
(``"name": ".module",``), and the same name to the ``TYPE_CHECKING`` imports (read by type
checkers, which cannot run the table), to ``__all__`` and to the list above;
tests/test_api.py checks that the table, the imports and ``__all__`` agree.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ._lazy import lazy_names

__version__ = "0.1.0"

# public name -> module that defines it (a name equal to the module's last part is the module itself)
_PUBLIC: dict[str, str] = {
    # systems
    "QuasiPolynomial": ".core", "TransferFunction": ".core", "as_transfer": ".core", "delay": ".core",
    "Mode": ".modes",
    # shapers
    "design": ".shapers", "KINDS": ".shapers", "ZERO_VIBRATION_KINDS": ".shapers", "Shaper": ".shapers",
    "Kernel": ".shapers", "DistributedPart": ".shapers",
    "shortest_shaper": ".shapers", "OptimalShaper": ".shapers", "Optimality": ".shapers",
    "zplane_shaper": ".shapers", "highest_multiplicity": ".shapers", "OrderChoice": ".shapers",
    # spectra
    "roots": ".spectra", "poles": ".spectra", "zeros": ".spectra", "stability": ".spectra",
    "spectral_abscissa": ".spectra", "rightmost": ".spectra", "difference_spectrum": ".spectra",
    "Roots": ".spectra",
    # loops
    "Loop": ".loops", "feedforward": ".loops", "control_action": ".loops", "inverse_shaper": ".loops",
    # analysis
    "residual_vibration": ".analysis", "sensitivity_curve": ".analysis", "insensitivity": ".analysis",
    "SensitivityCurve": ".analysis", "Insensitivity": ".analysis", "sensitivity_plot": ".analysis",
    "impulse_plot": ".analysis",
    # simulation
    "simulate": ".simulation", "SimulationResponse": ".simulation", "ShaperFilter": ".simulation",
    "shape_signal": ".simulation", "sampled_loop": ".simulation", "SampledLoop": ".simulation",
    # tuning
    "tune_pd": ".tune", "tune_pi": ".tune", "tune_pid": ".tune", "TuningResult": ".tune", "Region": ".tune",
    "Constraint": ".tune",
    # QFT inner-loop model matching (seed 003)
    "PlantSet": ".qft", "qft_design": ".qft", "QFTResult": ".qft", "percent_vibration": ".qft",
    "model_matching": ".qft",
    # identification and calibration
    "identify": ".identification", "calibrate": ".identification", "Identification": ".identification",
    "Interval": ".identification", "Calibration": ".identification", "NoModeFound": ".identification",
    # export
    "export_shaper": ".io",
    # sweeps
    "sweep": ".sweeps",
    # case studies
    "cases": ".cases",
}

if TYPE_CHECKING:  # the same names, for type checkers and IDEs (never executed)
    from . import cases
    from .analysis import (Insensitivity, SensitivityCurve, impulse_plot, insensitivity, residual_vibration,
                           sensitivity_curve, sensitivity_plot)
    from .core import QuasiPolynomial, TransferFunction, as_transfer, delay
    from .identification import Calibration, Identification, Interval, NoModeFound, calibrate, identify
    from .loops import Loop, control_action, feedforward, inverse_shaper
    from .modes import Mode
    from .qft import PlantSet, QFTResult, model_matching, percent_vibration, qft_design
    from .shapers import KINDS, ZERO_VIBRATION_KINDS, DistributedPart, Kernel, Shaper, design
    from .shapers import Optimality, OptimalShaper, OrderChoice, highest_multiplicity, shortest_shaper, zplane_shaper
    from .io import export_shaper
    from .simulation import SampledLoop, ShaperFilter, SimulationResponse, sampled_loop, shape_signal, simulate
    from .sweeps import sweep
    from .spectra import Roots, difference_spectrum, poles, rightmost, roots, spectral_abscissa, stability, zeros
    from .tune import Constraint, Region, TuningResult, tune_pd, tune_pi, tune_pid


def _moved(name: str) -> object:
    if name == "demo":
        raise AttributeError("posicast.demo moved to posicast_reports.demo (run: python -m posicast_reports.demo); "
                             "issue #14: reports are a separate package of the repository")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__getattr__, __dir__, _names = lazy_names(__name__, _PUBLIC, _moved)

__all__ = [
    "QuasiPolynomial", "TransferFunction", "as_transfer", "delay", "Mode",
    "design", "KINDS", "ZERO_VIBRATION_KINDS", "Shaper", "Kernel", "DistributedPart",
    "shortest_shaper", "OptimalShaper", "Optimality",
    "zplane_shaper", "highest_multiplicity", "OrderChoice",
    "roots", "poles", "zeros", "stability", "spectral_abscissa", "rightmost", "difference_spectrum", "Roots",
    "Loop", "feedforward", "control_action", "inverse_shaper",
    "residual_vibration", "sensitivity_curve", "insensitivity", "SensitivityCurve", "Insensitivity",
    "sensitivity_plot", "impulse_plot",
    "simulate", "SimulationResponse", "ShaperFilter", "shape_signal", "sampled_loop", "SampledLoop",
    "tune_pd", "tune_pi", "tune_pid", "TuningResult", "Region", "Constraint",
    "PlantSet", "qft_design", "QFTResult", "percent_vibration", "model_matching",
    "identify", "calibrate", "Identification", "Interval", "Calibration", "NoModeFound",
    "export_shaper",
    "sweep",
    "cases",
]

