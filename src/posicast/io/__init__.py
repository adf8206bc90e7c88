"""Output stage: exports of a shaper to a controller (discrete taps as JSON or a C array).

The HTML report writer that lived here is ``posicast_reports.html.Report`` now, in
the repository's reports package (posicast does not import it).
"""

from .export import EXPORT_FORMATS, export_shaper

__all__ = ["export_shaper", "EXPORT_FORMATS"]


def __getattr__(name: str) -> object:
    if name == "Report":
        raise AttributeError("posicast.io.Report moved to posicast_reports.html.Report (issue #14: reports are "
                             "a separate package of the repository, not part of the library)")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
