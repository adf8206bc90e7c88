"""Output stage: reports (and, in later issues, exports to machines)."""

from .report import Report

__all__ = ["Report"]
