"""The steps of the pipeline, for the CLI, the demos and Python users alike.

Each step (build a dataset, fit, select, evaluate, predict, identify a payload, compensate,
check, plan, export, live) takes objects or paths, plus an optional executor for streaming or Dask,
and returns a result object (:class:`ftcal.workflow.result.StepResult`) with ``summary()`` (the
text the CLI prints), ``to_dict()``/``to_json()``, a useful ``repr`` and ``_repr_html_``.
The CLI parses arguments, calls one step and prints its result; the demos call the same steps,
so the defaults are the same everywhere.
May import ``live``, ``check``, ``plan``, ``insitu``, ``report``, ``files``, ``robot``,
``payload``, ``data``, ``core`` and ``runtime``; ``sim`` and ``cli`` import it.
"""

from __future__ import annotations

# name -> module of this package that defines it; loaded on first use (numpy/scipy stay unloaded
# for `ftcal --help`). Each step module adds its public names here.
_STEPS: dict[str, str] = {"StepResult": "result"}
_STEPS.update(identify_payload="payload", retare="payload", rebias_payload="payload", PayloadResult="payload", RebiasResult="payload")
_STEPS.update(compensate="compensation", CompensationResult="compensation")
_STEPS.update(check_sensor="checking", sensor_history="checking", CheckResult="checking")
_STEPS.update(build_dataset="datasets", expected="datasets", DatasetResult="datasets", ExpectedResult="datasets",
              robot_sensors="datasets", SensorsResult="datasets", bag_topics="datasets", TopicsResult="datasets")
_STEPS.update(plan_experiment="planning", PlanResult="planning")
_STEPS.update(convert="export", ConvertResult="export")
_STEPS.update(fit="fitting", FitResult="fitting", ModelSearch="search", fit_candidates="search",
              CandidatesResult="search")
_STEPS.update(evaluate="evaluation", predict="evaluation", EvaluationResult="evaluation", PredictionResult="evaluation")
_STEPS.update(report="evaluation", ReportResult="evaluation")
_STEPS.update(model_info="info", ModelInfoResult="info")
_STEPS.update(LiveSetup="live", live_calibrator="live", replay_live="live", serve_zenoh="live", serve_ros2="live",
              LiveReplayResult="live", replays_a_bag="live")

__all__ = sorted(_STEPS)


def __getattr__(name: str):
    if name in _STEPS:
        from importlib import import_module

        return getattr(import_module(f".{_STEPS[name]}", __name__), name)
    raise AttributeError(f"module 'ftcal.workflow' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
