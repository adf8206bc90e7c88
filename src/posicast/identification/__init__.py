"""Stage 5: identify lightly damped modes from measured data and recommend a shaper.

``identify(t, u, y)`` fits modes with 95 % intervals (output-error by default;
seed 002's ARX and frequency-domain methods as baselines; free decay; output-only
PSD) and refuses with :class:`NoModeFound` when the data show no mode;
``calibrate(paths)`` reads Klipper resonance logs or PSD files (or input/output
CSV), identifies the modes and recommends what each printer firmware should run
(:mod:`posicast.firmware`), plus posicast's own optimum.
"""

from .estimators import METHODS, Identification, Interval, identify, whiteness
from .significance import ModeTest, NoModeFound
from .excitation import ResonanceTest
from .data import Dataset, load_csv
from .recommend import Candidate, ModeBox, Recommendation, klipper_smoothing, mode_boxes, recommend_setting
from .calibration import Calibration, FileResult, Schedule, calibrate

__all__ = [
    "identify", "Identification", "Interval", "METHODS", "whiteness", "NoModeFound", "ModeTest",
    "ResonanceTest",
    "load_csv", "Dataset", "calibrate", "Calibration", "FileResult", "Schedule", "Candidate", "ModeBox",
    "Recommendation", "mode_boxes", "recommend_setting", "klipper_smoothing",
]

# Deprecated aliases (issue #14): the synthetic-data generator moved to posicast.testing, a layer above
# identification, with unambiguous names (INPUTS and simulate meant other things than posicast.loops.INPUTS
# and posicast.simulate); the import below runs only when an old name is used (tests/test_layers.py lists it).
_MOVED = {"synthetic": "synthetic", "SyntheticData": "SyntheticData", "simulate": "simulate_modes",
          "excitation": "excitation", "klipper_log": "klipper_log", "INPUTS": "EXCITATIONS"}


def __getattr__(name: str) -> object:
    if name in _MOVED:
        import warnings

        from .. import testing

        warnings.warn(f"posicast.identification.{name} moved: use posicast.testing.{_MOVED[name]}", FutureWarning,
                      stacklevel=2)
        return getattr(testing, _MOVED[name])
    if name == "report":
        raise AttributeError("posicast.identification.report moved to posicast_reports.identification_report "
                             "(issue #14: reports are a separate package of the repository)")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
