"""Sweeps that outgrow one machine: robustness maps, Monte Carlo and batch calibration on Dask (issue #19).

:func:`sweep` maps a function over a parameter grid or seeded draws, in batches, on
Dask's distributed scheduler (local worker processes by default, any cluster by its
scheduler address), persisting every batch in a Zarr store as it arrives so that an
interrupted sweep resumes without recomputing.  The result is labelled
(:class:`SweepResult`: parameters, values, a status and an error message per point).

>>> import posicast
>>> r = posicast.sweep(lambda x: 1.0 / x, {"x": [1.0, 2.0, 0.0]}, client="serial")
>>> list(r.status), r.failures[0].message
([np.str_('ok'), np.str_('ok'), np.str_('error')], 'ZeroDivisionError: float division by zero')
"""

from .engine import SchedulerUnreachable, WorkerFailure, default_batch_size, local_cluster, sweep
from .result import Failure, SweepResult, Timing
from .space import Space, make_space
from .store import StoreMismatch, load

__all__ = ["sweep", "local_cluster", "load", "SweepResult", "Failure", "Timing", "Space", "make_space", "default_batch_size",
           "SchedulerUnreachable", "WorkerFailure", "StoreMismatch"]
