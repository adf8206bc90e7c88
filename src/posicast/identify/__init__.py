"""Stage 5: identify lightly damped modes from measured data and recommend a shaper.

``identify(t, u, y)`` fits modes with 95 % intervals (output-error by default;
seed 002's ARX and frequency-domain methods as baselines; free decay; output-only
PSD); ``calibrate(path)`` reads a CSV or Klipper log, identifies, scores every
shaper family over the modes' uncertainty and writes firmware config lines.
"""

from .estimators import METHODS, Identification, Interval, identify, whiteness
from .synthetic import INPUTS, SyntheticData, excitation, klipper_log, simulate, synthetic

__all__ = [
    "identify", "Identification", "Interval", "METHODS", "whiteness",
    "synthetic", "SyntheticData", "simulate", "excitation", "klipper_log", "INPUTS",
]

from .data import Dataset, load_csv  # noqa: E402
from .recommend import Calibration, Candidate, calibrate, klipper_smoothing, recommend  # noqa: E402

__all__ += ["load_csv", "Dataset", "calibrate", "recommend", "Calibration", "Candidate", "klipper_smoothing"]
