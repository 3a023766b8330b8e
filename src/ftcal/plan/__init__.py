"""Experiment planning: which poses and loads to record, in which order (``ftcal plan``).

Candidate joint configurations within limits, pins and a minimum height
(:mod:`~ftcal.plan.candidates`), the information each pose adds to a degree-D
calibration or to payload identification (:mod:`~ftcal.plan.information`), a
greedy D-optimal choice by rank-one updates (:mod:`~ftcal.plan.design`), an
execution order (:mod:`~ftcal.plan.order`), the whole run
(:mod:`~ftcal.plan.experiment`) and its page (:mod:`~ftcal.plan.page`).

May import :mod:`ftcal.insitu`, :mod:`ftcal.report`, :mod:`ftcal.files`,
:mod:`ftcal.robot`, :mod:`ftcal.payload`, :mod:`ftcal.data`, :mod:`ftcal.core`
and :mod:`ftcal.runtime`.
"""

from ..runtime.deprecation import deprecated_alias
from .experiment import Plan, PlanRequest, Recorded, design_experiment

# The old name, which the step ftcal.plan_experiment (other arguments) shadowed.
plan_experiment = deprecated_alias(design_experiment, "ftcal.plan.plan_experiment", "ftcal.plan.design_experiment")

__all__ = ["Plan", "PlanRequest", "Recorded", "design_experiment"]
