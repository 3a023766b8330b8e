"""ftcal: in-situ nonlinear calibration of six-axis strain-gauge F/T sensors.

The packages follow the pipeline, and import only downward (docs/architecture.md):
``cli`` → ``sim`` (demos) → ``insitu`` → ``report`` → ``files`` → ``robot`` → ``payload``
→ ``data`` → ``core`` → ``runtime``.
"""

import os
import sys

# Ctrl-Cs noted while the `ftcal` command starts; ftcal.cli.main takes over and exits 130.
_INTERRUPTS: list[int] = []


def _note_interrupt(signum, frame) -> None:
    _INTERRUPTS.append(signum)


def _command_starting() -> bool:
    """Whether this import starts the `ftcal` command: its console script, or ``python -m ftcal``."""
    argv = getattr(sys, "orig_argv", [])
    by_module = any(a == "-m" and b == "ftcal" for a, b in zip(argv, argv[1:]))
    return by_module or os.path.basename(sys.argv[0]) == "ftcal"


# The command imports this package first, outside any `try`: a Ctrl-C during the imports that
# follow would end in a traceback. So it is only noted until ftcal.cli.main() runs. Nothing else
# is imported here: this is the only ftcal code that runs before the guard.
if _command_starting():
    import signal

    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _note_interrupt)

# The one place the version is declared (pyproject.toml reads it); reading it from the
# installed metadata instead costs ~30 ms of imports on every run.
__version__ = "0.1.0"

# Loaded on first use, so that `ftcal --help` does not pay for numpy and scipy: name -> "module:attribute".
# ``load_model`` reads every model file the CLI reads (native JSON of any family, the paper's XML).
_LAZY = {"FtcalError": "runtime.errors:FtcalError", "FtcalWarning": "runtime.errors:FtcalWarning",
         "CalibrationModel": "core.model:CalibrationModel", "Dataset": "core.dataset:Dataset",
         "MonomialBasis": "core.features:MonomialBasis", "RegressorLayout": "core.features:RegressorLayout",
         "n_coefficients": "core.features:n_coefficients", "load_dataset": "data.tables:load_dataset",
         "load_model": "files.model_files:load_model", "save_model": "files.model_files:save_model"}
# The steps of the pipeline (ftcal.workflow): build a dataset, fit, evaluate, predict, identify a payload,
# compensate, check, plan, convert.
_LAZY.update({name: f"workflow.{module}:{name}" for module, names in (
    ("datasets", ("build_dataset", "DatasetResult")), ("fitting", ("fit", "FitResult")),
    ("search", ("ModelSearch",)),
    ("evaluation", ("evaluate", "EvaluationResult", "predict", "PredictionResult")),
    ("payload", ("identify_payload", "PayloadResult")),
    ("compensation", ("compensate", "CompensationResult")), ("checking", ("check_sensor", "CheckResult")),
    ("planning", ("plan_experiment", "PlanResult")), ("export", ("convert", "ConvertResult"))) for name in names})

__all__ = ["CalibrationModel", "Dataset", "FtcalError", "FtcalWarning", "MonomialBasis",
           "RegressorLayout", "load_dataset", "load_model", "n_coefficients", "save_model"]
__all__ += ["CheckResult", "CompensationResult", "ConvertResult", "DatasetResult", "PayloadResult", "PlanResult",
            "build_dataset", "check_sensor", "compensate", "convert", "identify_payload", "plan_experiment"]
__all__ += ["EvaluationResult", "FitResult", "ModelSearch", "PredictionResult", "evaluate", "fit", "predict"]


def __getattr__(name: str):
    if name in _LAZY:
        from importlib import import_module

        module, attribute = _LAZY[name].split(":")
        return getattr(import_module(f".{module}", __name__), attribute)
    raise AttributeError(f"module 'ftcal' has no attribute {name!r}")


def __dir__() -> list[str]:
    # Tab completion lists the public API (the lazy names) beside the module's own attributes.
    return sorted(set(globals()) - {"os", "sys"} | set(__all__))
