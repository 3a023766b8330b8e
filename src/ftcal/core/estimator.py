"""The scikit-learn estimator contract for parameters, shared by every model family.

Parameters are the constructor's keyword arguments, stored unchanged by ``__init__``
(validation happens in ``fit``); :meth:`EstimatorParams.get_params`,
:meth:`~EstimatorParams.set_params` and :meth:`~EstimatorParams.clone` read them from the
constructor's signature, so ``sklearn.base.clone`` and grid searches work on ftcal models.
"""

from __future__ import annotations

import inspect
from typing import Any

from ..runtime.errors import FtcalError


class EstimatorParams:
    """Mixin: ``get_params``/``set_params``/``clone`` from the subclass's ``__init__`` signature.

    Examples
    --------
    >>> from ftcal.core.model import CalibrationModel
    >>> model = CalibrationModel(2).set_params(na=1)
    >>> model.get_params()["na"], model.clone(degree=3).get_params()["degree"]
    (1, 3)
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
