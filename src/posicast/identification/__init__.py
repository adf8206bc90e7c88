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
from .synthetic import INPUTS, SyntheticData, excitation, klipper_log, simulate, synthetic
from .excitation import ResonanceTest
from .data import Dataset, load_csv
from .recommend import Candidate, ModeBox, Recommendation, klipper_smoothing, mode_boxes, recommend_setting
from .calibration import Calibration, FileResult, Schedule, calibrate

__all__ = [
    "identify", "Identification", "Interval", "METHODS", "whiteness", "NoModeFound", "ModeTest",
    "synthetic", "SyntheticData", "simulate", "excitation", "klipper_log", "INPUTS", "ResonanceTest",
    "load_csv", "Dataset", "calibrate", "Calibration", "FileResult", "Schedule", "Candidate", "ModeBox",
    "Recommendation", "mode_boxes", "recommend_setting", "klipper_smoothing",
]
