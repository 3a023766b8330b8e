"""The scikit-learn estimator contract, shared by every model family.

Parameters are the constructor's keyword arguments, stored unchanged by ``__init__``
(validation happens in ``fit``); :meth:`EstimatorParams.get_params`,
:meth:`~EstimatorParams.set_params` and :meth:`~EstimatorParams.clone` read them from the
constructor's signature, so ``sklearn.base.clone`` and grid searches work on ftcal models.
:meth:`~EstimatorParams.score` is a regressor's score (R², a float, as scikit-learn's); the
paper's metrics of a model on a dataset are the family's ``metrics`` method.
scikit-learn is not needed at run time: only ``__sklearn_tags__`` imports it, and only
scikit-learn calls that.
"""

from __future__ import annotations

import inspect
from typing import Any

import numpy as np

from ..runtime.errors import FtcalError


class EstimatorParams:
    """Mixin: ``get_params``/``set_params``/``clone`` from the subclass's ``__init__`` signature, the
    regressor ``score`` and scikit-learn's tags, for every model family.

    Examples
    --------
    >>> import numpy as np
    >>> from ftcal.core.model import CalibrationModel
    >>> model = CalibrationModel(2).set_params(na=1)
    >>> model.get_params()["na"], model.clone(degree=3).get_params()["degree"]
    (1, 3)
    >>> u = np.linspace(-1.0, 1.0, 11)[:, None]
    >>> CalibrationModel(2).fit(u, u ** 2).score(u, u ** 2)
    1.0
    >>> CalibrationModel(2, na=1)
    CalibrationModel(degree=2, na=1)
    """

    @classmethod
    def _param_names(cls) -> list[str]:
        signature = inspect.signature(cls.__init__)
        return [p.name for p in signature.parameters.values()
                if p.name != "self" and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """The constructor arguments, as a dict (``deep`` adds ``name__sub`` entries of nested estimators)."""
        params = {name: getattr(self, name) for name in self._param_names()}
        if deep:
            for name, value in list(params.items()):
                if hasattr(value, "get_params") and not isinstance(value, type):
                    params.update({f"{name}__{k}": v for k, v in value.get_params().items()})
        return params

    def set_params(self, **params: Any) -> "EstimatorParams":
        """Set constructor arguments (``name__sub`` sets a nested estimator's); returns ``self``."""
        names = self._param_names()
        for key, value in params.items():
            name, _, sub = key.partition("__")
            if name not in names:
                raise FtcalError(f"{type(self).__name__} has no parameter {name!r}; "
                                 f"its parameters are {', '.join(names)}.")
            if sub:
                getattr(self, name).set_params(**{sub: value})
            else:
                setattr(self, name, value)
        return self

    def clone(self, **changes: Any) -> "EstimatorParams":
        """An unfitted model with the same parameters, except ``changes`` (like ``sklearn.base.clone``)."""
        unknown = set(changes) - set(self._param_names())
        if unknown:
            raise FtcalError(f"{type(self).__name__} has no parameter(s) {', '.join(sorted(unknown))}.")
        return type(self)(**{**self.get_params(deep=False), **changes})

    def __repr__(self) -> str:
        """``CalibrationModel(degree=2, na=1)``: the class and the parameters that differ from their defaults."""
        defaults = {p.name: p.default for p in inspect.signature(type(self).__init__).parameters.values()}
        changed = []
        for name, value in self.get_params(deep=False).items():
            default = defaults.get(name, inspect.Parameter.empty)
            try:
                same = value is default or (type(value) is type(default) and bool(value == default))
            except (TypeError, ValueError):  # values without a plain equality (arrays) count as changed
                same = False
            if not same:
                changed.append(f"{name}={value!r}")
        return f"{type(self).__name__}({', '.join(changed)})"

    @property
    def n_features_in_(self) -> int:
        """Number of inputs seen by ``fit`` (scikit-learn's name); absent before fit."""
        return len(self.input_names_)

    def score(self, X, y=None, sample_weight=None) -> float:
        """Coefficient of determination R² of ``predict(X)`` against ``y``, averaged over the outputs.

        scikit-learn's regressor score (``sklearn.metrics.r2_score`` with uniform weights over outputs);
        an output that is constant in ``y`` scores 1 when predicted exactly, else 0. For the paper's
        metrics (RMSE, BestFit, force/torque-norm errors) use the model's ``metrics(dataset)``.

        Parameters
        ----------
        X : Dataset, or ndarray of shape (n_samples, n_inputs)
        y : ndarray of shape (n_samples,) or (n_samples, n_outputs); default the Dataset's outputs
        sample_weight : ndarray of shape (n_samples,), optional

        Returns
        -------
        float

        Raises
        ------
        FtcalError
            No reference outputs, or ``y`` of another shape than the predictions.
        """
        from .dataset import Dataset
        from .model.frame import outputs_in_order

        if y is None:
            if not isinstance(X, Dataset) or X.outputs is None:
                raise FtcalError(f"{type(self).__name__}.score needs reference outputs: y, or a Dataset with outputs.")
            y = outputs_in_order(X, self.output_names_)
        prediction = np.asarray(self.predict(X, warn_out_of_range=False), dtype=float)
        y = np.asarray(y, dtype=float)
        if y.ndim == 1:
            y = y[:, None]
        prediction = prediction.reshape(prediction.shape[0], -1)
        if y.shape != prediction.shape:
            raise FtcalError(f"{type(self).__name__}.score: y has shape {y.shape}; the predictions have "
                             f"{prediction.shape}.")
        weight = np.ones(y.shape[0]) if sample_weight is None else np.asarray(sample_weight, dtype=float)
        mean = np.average(y, axis=0, weights=weight)
        residual = np.einsum("i,ij->j", weight, (y - prediction) ** 2)
        total = np.einsum("i,ij->j", weight, (y - mean) ** 2)
        with np.errstate(divide="ignore", invalid="ignore"):
            r2 = np.where(total > 0, 1.0 - residual / np.where(total > 0, total, 1.0),
                          np.where(residual == 0, 1.0, 0.0))
        return float(np.mean(r2))

    def __sklearn_tags__(self):
        """scikit-learn's tags: a multi-output regressor on dense float arrays (called by scikit-learn only)."""
        from sklearn.utils import InputTags, RegressorTags, Tags, TargetTags

        return Tags(estimator_type="regressor", target_tags=TargetTags(required=True, multi_output=True),
                    regressor_tags=RegressorTags(), input_tags=InputTags(two_d_array=True))
