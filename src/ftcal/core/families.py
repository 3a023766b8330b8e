"""Model families as plug-ins: the :class:`ModelFamily` protocol and the :data:`FAMILIES` registry.

A family is a class of calibration models (polynomial, MLP, ...). Its instances
are estimators in scikit-learn's sense: ``__init__`` stores options, ``fit``
learns, attributes ending in ``_`` hold the fitted state. Everything outside
``core`` (model files, ``ftcal predict/evaluate/report/convert``) talks to a
model through this protocol only, so a new family is one module in ``core/``
plus one line in :data:`FAMILIES`:

- the model file keeps the envelope (inputs and outputs with their
  normalization and range, training metrics, creation data, the digest) and
  asks the family for its own fields (:meth:`ModelFamily.to_document`) and to
  rebuild a model from them (:meth:`ModelFamily.from_document`);
- ``ftcal convert`` refuses a target the family does not list in ``exports``.

This module imports no numpy, so the CLI can list the families cheaply.
"""

from __future__ import annotations

import importlib
from typing import Any, ClassVar, Protocol, runtime_checkable

from ..runtime.errors import FtcalError, ParameterError

DEFAULT_FAMILY = "polynomial"
"""The family of a model file without a ``family`` field (every file written before families existed)."""

FAMILIES: dict[str, str] = {
    "polynomial": "ftcal.core.model:CalibrationModel",
    "mlp": "ftcal.core.mlp:MLPModel",
}
"""Family name (the model file's ``family`` field) → ``"module:Class"``, imported only when used."""


@runtime_checkable
class ModelFamily(Protocol):
    """What a model family's class provides.

    Class attributes
    ----------------
    family : str
        The registry name, written to model files.
    exports : frozenset of str
        ``ftcal convert`` targets (:data:`ftcal.files.targets.TARGETS` names) it can be written to.
    streams : bool
        Whether it can also be fitted from streamed sufficient statistics
        (``fit_statistics``, as :class:`~ftcal.core.model.CalibrationModel`); a
        family without it is fitted from a :class:`~ftcal.core.dataset.Dataset`.

    Fitted attributes (the model file's envelope reads them)
    --------------------------------------------------------
    input_names_, output_names_ : tuple of str
    input_normalization_, output_normalization_ : Normalization
    input_range_, output_range_ : ndarray of shape (n, 2), training min and max
    n_samples_fit_ : int
    solver_info_ : dict, at least ``name`` and ``lambda`` (None when it has no λ)
    training_metrics_ : dict (:func:`ftcal.core.metrics.summarize`)
    """

    family: ClassVar[str]
    exports: ClassVar[frozenset[str]]
    streams: ClassVar[bool]

    @property
    def is_static(self) -> bool:
        """True when each prediction depends on its own input sample only (no ARX state)."""

    def fit(self, data: Any, outputs: Any = None) -> Any:
        """Fit on a Dataset (or inputs plus outputs); returns ``self``."""

    def predict(self, data: Any, *, mode: str = "free-run", start: str = "zeros",
                warn_out_of_range: bool = True) -> Any:
        """Predicted outputs, ndarray of shape (n_samples, n_outputs); ``mode``/``start`` matter for ARX only."""

    def metrics(self, data: Any, *, mode: str = "one-step", start: str = "zeros", warmup: str = "drop",
                warn_out_of_range: bool = True) -> dict:
        """:func:`ftcal.core.metrics.summarize` of the prediction plus ``n_out_of_range``."""

    def out_of_range(self, inputs: Any) -> Any:
        """Boolean mask of samples with an input outside the training range."""

    def describe(self) -> dict:
        """Counts for reports: ``n_inputs``, ``n_outputs``, ``n_coefficients``, ``n_nonzero`` and more."""

    def label(self) -> str:
        """A short name for tables, such as ``np4 lasso λ=50`` or ``mlp 32,32 tanh``."""

    def to_document(self) -> dict:
        """The family's own model-file fields as plain JSON values.

        ``"fit"`` (if present) is merged into the file's ``fit`` object; every
        other key becomes a top-level field. Raises FtcalError when the model
        holds non-finite numbers.
        """

    @classmethod
    def from_document(cls, doc: dict, source: str) -> Any:
        """The fitted model of a schema-valid model-file document; one-line FtcalError naming ``source``."""


def family_class(name: str, source: str = "model") -> type:
    """The class registered as family ``name``.

    Parameters
    ----------
    name : str
        A key of :data:`FAMILIES`.
    source : str
        What asked (a file name, an option), for the message.

    Returns
    -------
    type
        A class following :class:`ModelFamily`.

    Raises
    ------
    FtcalError
        Unknown family, or a registered class that does not follow the protocol.

    Examples
    --------
    >>> family_class("polynomial").__name__
    'CalibrationModel'
    """
    try:
        dotted = FAMILIES[name]
    except (KeyError, TypeError):
        raise FtcalError(f"{source}: unknown model family {name!r}; this ftcal knows "
                         f"{', '.join(FAMILIES)}.") from None
    module, _, attribute = dotted.partition(":")
    cls = getattr(importlib.import_module(module), attribute)
    missing = [m for m in ("family", "exports", "streams", "fit", "predict", "metrics", "out_of_range",
                           "describe", "label", "to_document", "from_document") if not hasattr(cls, m)]
    if missing or cls.family != name:
        raise FtcalError(f"Model family {name!r} ({dotted}) does not follow ModelFamily: "
                         + (f"it lacks {', '.join(missing)}." if missing else f"its family is {cls.family!r}."))
    return cls


def family_of(model: object) -> str:
    """The family name of a fitted model (``family`` attribute), checked against the registry."""
    name = getattr(model, "family", None)
    if name not in FAMILIES:
        raise FtcalError(f"{type(model).__name__} is not a registered model family (core.families.FAMILIES).")
    return name


def check_export(model: object, target: str) -> None:
    """Refuse, in one line, a ``ftcal convert`` target the model's family cannot be written to."""
    exports = getattr(model, "exports", frozenset())
    if target not in exports:
        raise ParameterError('to', f"{{to}} {target}: the {getattr(model, 'family', '?')} family cannot be exported there; "
                         f"it exports {', '.join(sorted(exports))}.")
