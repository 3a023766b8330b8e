"""ftcal: in-situ nonlinear calibration of six-axis strain-gauge F/T sensors.

The packages follow the pipeline, and import only downward (docs/architecture.md):
``cli`` → ``sim`` (demos) → ``insitu`` → ``report`` → ``files`` → ``robot`` → ``payload``
→ ``data`` → ``core`` → ``runtime``.
"""

# Nothing is imported here: the `ftcal` command runs this module before ftcal.cli can note a
# Ctrl-C, so it must take no time.

# The one place the version is declared (pyproject.toml reads it); reading it from the
# installed metadata instead costs ~30 ms of imports on every run.
__version__ = "0.1.0"

# Loaded on first use, so that `ftcal --help` does not pay for numpy and scipy.
_LAZY = {"FtcalError": "runtime.errors", "FtcalWarning": "runtime.errors", "CalibrationModel": "core.model",
         "Dataset": "core.dataset", "MonomialBasis": "core.features", "RegressorLayout": "core.features",
         "n_coefficients": "core.features", "load_dataset": "data.tables", "load_model": "files.model_json",
         "save_model": "files.model_json"}

__all__ = ["CalibrationModel", "Dataset", "FtcalError", "FtcalWarning", "MonomialBasis",
           "RegressorLayout", "load_dataset", "load_model", "n_coefficients", "save_model"]


def __getattr__(name: str):
    if name in _LAZY:
        from importlib import import_module

        return getattr(import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module 'ftcal' has no attribute {name!r}")
