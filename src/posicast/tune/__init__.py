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
from .plots import region_plot, regions_plot, tuning_nyquist_plot

__all__ = [
    "tune_pd", "tune_pi", "tune_pid", "tune", "TuningResult", "Region", "Constraint", "NAMED_CHANNELS",
    "ControllerFamily", "pd_family", "pi_family", "pid_family", "region_plot", "regions_plot", "tuning_nyquist_plot",
]

# Deprecated aliases (issue #14): the region check moved to posicast.testing, a layer above tune; the
# import below runs only when an old name is used (tests/test_layers.py lists it as an allowed alias).
_MOVED = {"sample_check": "sample_check", "RegionCheck": "RegionCheck"}


def __getattr__(name: str) -> object:
    if name in _MOVED:
        import warnings

        from .. import testing

        warnings.warn(f"posicast.tune.{name} moved: use posicast.testing.{_MOVED[name]}", FutureWarning, stacklevel=2)
        return getattr(testing, _MOVED[name])
    if name in ("seed001", "report"):
        raise AttributeError(f"posicast.tune.{name} moved to posicast_reports (issue #14: reports and seed case "
                             "studies are a separate package of the repository, not part of the library)")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
