"""Calibration reports: the figures and tables of the paper's Sections IV–V as one HTML page.

Typical use, with fitted models and held-out data::

    from ftcal.report import build_report, evaluate_run

    runs = [evaluate_run(model, validation, train=train) for model in models]
    build_report(runs, validation, "report.html", train=train)
"""

from .html import build_report
from .runs import ModelRun, default_name, evaluate, evaluate_run

__all__ = ["ModelRun", "build_report", "default_name", "evaluate_run"]
