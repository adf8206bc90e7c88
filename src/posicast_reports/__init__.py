"""Reports and seed case studies built on posicast (not part of the library).

``make demo`` runs :mod:`posicast_reports.demo`, which writes ``report/index.html``
with :class:`posicast_reports.html.Report`.  The sections that re-run the seed
papers live here too: :mod:`posicast_reports.seed001` (seed 001 Table 1 and
``PAPER_DELAY``), :mod:`posicast_reports.seed001_report` (its report section) and
:mod:`posicast_reports.identification_report` (identification and calibration).

This package imports posicast; posicast never imports it (``tests/test_layers.py``).
"""
