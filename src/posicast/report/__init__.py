"""The user-first report: your resonance test → your shaper, your plant → your loop (issue #20).

``posicast report DATA`` (and :func:`write_report`) writes one HTML page for a user's own data:

- resonance tests (what :func:`posicast.calibrate` reads): the spectrum and the modes with 95 %
  intervals, each firmware's candidate settings beside its own tool's pick, the lines to paste and
  the vibration each setting leaves (:mod:`.machine`);
- a plant file (JSON: plant, load, controller, mode, shaper, architecture, tuning; :mod:`.plantfile`):
  certified stability verdicts, the tuned PD or PI with and without the shaper, step responses
  (:mod:`.plant`).

Every result is printed with the command and the Python code that give it.  The page writer
(:mod:`.page`: parts and sections with a table of contents, one number format per table column,
tables that scroll instead of widening the page) is also the demo report's (``make demo``).
"""

from .build import ReportSummary, is_plant_file, write_report
from .page import format_column, format_number
from .plant import PlantAnalysis, analyse_plant
from .plantfile import PlantSpec, load_plant, plant_spec

__all__ = ["write_report", "ReportSummary", "is_plant_file", "analyse_plant", "PlantAnalysis", "PlantSpec",
           "load_plant", "plant_spec", "format_column", "format_number"]
