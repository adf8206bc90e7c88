"""Reports and seed case studies built on posicast (not part of the library).

``make demo`` runs :mod:`posicast_reports.demo`, which writes ``report/index.html``
with :class:`posicast_reports.html.Report`; ``make reproduce`` runs
:mod:`posicast_reports.reproduce`, which writes the seed papers' reproductions to
``report/reproduce/index.html`` (the two reports link each other).  The sections
live here too: :mod:`posicast_reports.seed001` (seed 001 Table 1 and
``PAPER_DELAY``), :mod:`posicast_reports.seed001_report` (its report section),
:mod:`posicast_reports.identification_report` (seed 002's identification for the
reproductions, printer calibration for the demo), and the others the two reports import.

This package imports posicast; posicast never imports it (``tests/test_layers.py``).
"""
