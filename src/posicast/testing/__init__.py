"""Test helpers: synthetic measurement data and a brute-force check of tuning regions.

Neither is part of the design pipeline; both exist to check it, in the suite, the
benchmarks and the reports:

* :mod:`posicast.testing.synthetic_data`: records of known modes through seed 002's
  sensor (:func:`synthetic`, :func:`excitation`, :func:`simulate_modes`) and
  Klipper-format resonance logs (:func:`klipper_log`; ``klipper_dataset`` and
  ``klipper_resonances`` in the module);
* :mod:`posicast.testing.regions`: :func:`sample_check`, sampled gains classified
  directly (dense-frequency ``||S||_inf`` and a certified stability check) against
  a region computed by :func:`posicast.tune_pd` and its siblings.

Layer: above analysis, simulation, tune and identification (it imports them), below
the command line; nothing in posicast's pipeline imports it.
"""

from .regions import RegionCheck, sample_check
from .synthetic_data import EXCITATIONS, SyntheticData, excitation, klipper_log, simulate_modes, synthetic

__all__ = [
    "sample_check", "RegionCheck", "synthetic", "SyntheticData", "simulate_modes", "excitation", "klipper_log",
    "EXCITATIONS",
]
