"""``make demo``: the main job's report, ``report/index.html``, on built-in example data.

Run as ``python -m posicast_reports.demo --out report``.  Its parts, in order: "Your data → your
shaper" and "Your plant → your loop" (from :mod:`posicast.report`), printer calibration (a synthetic
Klipper test and the repository's real resonance files), a pointer to the seed reproductions and
"Beyond the seeds" (optimal shapers, sweeps).  The seed papers' reproductions are a separate report,
``make reproduce`` (:mod:`posicast_reports.reproduce`, ``report/reproduce/index.html``).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

if __name__ == "__main__":
    from posicast_reports.job import one_blas_thread

    one_blas_thread()  # before numpy loads its BLAS

from posicast.identification.calibration import Calibration, calibrate
from posicast.report import analyse_plant, load_plant
from posicast.report.machine import machine_part
from posicast.report.plant import plant_part

from .html import NUMBER_FORMATS, Report
from .identification_report import calibration_section
from .job import Progress, command_line, finish
from .optimal_report import optimal_section
from .sweep_report import sweep_section

__all__ = ["build_report", "user_first", "Progress", "REPRODUCE_LINK"]

REPOSITORY = Path(__file__).resolve().parents[2]  # src/posicast_reports/ -> the repository
#: The user-first parts' example data: a real Klipper resonance test and a plant file (paths in the repository).
EXAMPLE_LOG = "tests/data/real/iconoclastxyz_v24_resonances_y_20220507.csv"
EXAMPLE_LOG_ABOUT = ("A real resonance test: a Voron 2.4 (Formbot kit), Y axis, Klipper's <code>TEST_RESONANCES</code> "
                     "output from the IconoclastXYZ/Voron repository (CC0; <code>tests/data/real/MANIFEST.md</code>). "
                     "Its owner published Klipper's recommendation for this run: mzv @ 40.8 Hz.")
EXAMPLE_PLANT = "examples/plant_two_mass.json"
EXAMPLE_PLANT_ABOUT = ("An example plant file: seed 003's two-mass plant (force on the first mass to the position "
                       "of the second) with the seed's PI and a ZVD² shaper inside the loop.")

#: The seed reproductions seen from this report (both in their default folders: report/ and report/reproduce/).
REPRODUCE_LINK = "reproduce/index.html"
#: Where the seed reproductions are, as the report says it (near the top and in their own part).
REPRODUCE_WHERE = (f"a separate report, <a href=\"{REPRODUCE_LINK}\">{REPRODUCE_LINK}</a>, written by "
                   "<code>make reproduce</code>")

INTRO = (
    "<p>The first two parts show what posicast does with <i>your</i> data, on built-in examples, each result with "
    "the command and the Python code that produce it; <code>posicast report FILE --out DIR</code> writes them for "
    "your own resonance test or plant file (README, \"A report for your own data\"). Then printer calibration "
    "and what goes beyond the seed papers. The seed papers' reproductions are " + REPRODUCE_WHERE + ".</p>"
    + NUMBER_FORMATS)


def user_first(report: Report) -> Calibration | None:
    """The parts "Your data → your shaper" and "Your plant → your loop" on the example data (about 2 s).

    Returns the example log's calibration (None when the repository's data are not there)."""
    log, plant = REPOSITORY / EXAMPLE_LOG, REPOSITORY / EXAMPLE_PLANT
    cal = None
    if log.is_file():
        cal = calibrate(log)
        machine_part(report, cal, [EXAMPLE_LOG], about=EXAMPLE_LOG_ABOUT)
    else:
        report.part("Your data → your shaper", f"The example log {EXAMPLE_LOG} is not in this installation.")
    if plant.is_file():
        plant_part(report, analyse_plant(load_plant(plant)), EXAMPLE_PLANT, about=EXAMPLE_PLANT_ABOUT)
    else:
        report.part("Your plant → your loop", f"The example plant file {EXAMPLE_PLANT} is not in this installation.")
    return cal


def build_report(out: str | Path, progress: Progress | None = None) -> Path:
    """Build the demo report in ``out`` and return the path of ``index.html``.

    ``progress`` (default: lines on stderr) reports each section as it finishes.
    """
    t0 = time.perf_counter()
    say = (progress or Progress()).done
    report = Report("posicast demo report", out)
    report.intro = INTRO
    example = user_first(report)
    say("your data → your shaper, your plant → your loop")
    report.part("Printer calibration",
                "posicast's calibration on a synthetic Klipper test and on every real resonance file in the "
                "repository beside Klipper's own pick.")
    calibration_section(report, calibrations=None if example is None else {REPOSITORY / EXAMPLE_LOG: example})
    say("printer calibration")
    report.part("Seed reproductions: a separate report",
                "The seed papers' tables and figures re-computed (seed 002's identification trials, every shaper "
                "kind for a seed 001 and a seed 000 mode, seed 000's spectra and responses, seed 001's tuning, "
                "seed 003's QFT inner loop) are " + REPRODUCE_WHERE + ".")
    report.part("Beyond the seeds", "Optimal shapers (specified insensitivity, unity magnitude, firmware limits) and "
                "sweeps over parameter spaces.")
    optimal_section(report)
    say("optimal shapers")
    sweep_section(report)
    say("sweeps (seed 000 stability chart)")
    return finish(report, t0, say)


def main(argv: list[str] | None = None) -> int:
    """``python -m posicast_reports.demo [--out DIR]``."""
    return command_line(build_report, "report", __doc__, argv)


if __name__ == "__main__":
    sys.exit(main())
