"""The calibration model: a monomial basis (optionally ARX), an input normalization and coefficients.

The model evaluates in the normalized basis it stores (inputs mapped by
``(u − offset) / scale``); converting to raw-input monomials (the paper's XML)
is done only on export, by :mod:`ftcal.core.conversion`, which measures what that
loses.

Which basis a fit is solved in: least squares does not depend on the basis, so
it is always solved in the best-conditioned one (``center``) and its
coefficients mapped exactly into the stored basis. A penalty does depend on the
basis: ridge and LASSO are solved in the stored basis, by default the paper's
(raw monomials scaled by their max-abs, ``maxabs``).

One module per job:

- ``state``: :class:`CalibrationModel`, its parameters and fitted state, fitting from data or
  summed statistics, and :func:`model_from_fitted`;
- ``frame``: :class:`FitFrame` (what a fit takes from the data before a solver runs), size and
  well-posedness checks, the dense regressor;
- ``basis``: :func:`change_basis`, the same polynomial in another normalized basis;
- ``prediction``: ``predict`` and ``score``, static and ARX, range and span checks;
- ``document``: the polynomial's fields of the model file, to and from a document.
"""

from .basis import change_basis
from .frame import DENSE_LIMIT_CELLS, SOLVE_BASIS, FitFrame, check_gram_size, warn_if_ill_posed
from .frame import as_dataset as _as_dataset
from .frame import outputs_in_order as _outputs_in_order
from .prediction import PREDICT_CHUNK
from .state import CONDITION_WARNING, CalibrationModel, model_from_fitted

__all__ = ["CalibrationModel", "FitFrame", "change_basis", "check_gram_size", "model_from_fitted"]
