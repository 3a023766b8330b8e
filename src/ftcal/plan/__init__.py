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

from .experiment import Plan, PlanRequest, Recorded, plan_experiment

__all__ = ["Plan", "PlanRequest", "Recorded", "plan_experiment"]
