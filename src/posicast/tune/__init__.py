"""Stage 6: robust fixed-structure controllers for loops with shapers (seed 001, H-infinity regions).

>>> import posicast
>>> r = posicast.tune_pi(([1.0], [1.0, 2.0, 1.0]), ms=1.4)
>>> r.stable, r.family.describe()
(True, 'Kp + Ki/s')
"""

from .constraints import NAMED_CHANNELS, Constraint
from .design import tune, tune_pd, tune_pi, tune_pid
from .family import ControllerFamily, pd_family, pi_family, pid_family
from .regions import Region
from .result import TuningResult
from .check import RegionCheck, sample_check
from .plots import region_plot, regions_plot, tuning_nyquist_plot

__all__ = [
    "tune_pd", "tune_pi", "tune_pid", "tune", "TuningResult", "Region", "Constraint", "NAMED_CHANNELS",
    "ControllerFamily", "pd_family", "pi_family", "pid_family", "sample_check", "RegionCheck",
    "region_plot", "regions_plot", "tuning_nyquist_plot",
]
