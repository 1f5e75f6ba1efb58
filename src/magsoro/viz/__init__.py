"""Visual output: the self-contained HTML report of a run or a sweep (:func:`build_report`)."""

from magsoro.viz.report import ReportError, build_report

__all__ = ["build_report", "ReportError"]
