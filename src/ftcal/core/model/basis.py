"""The same polynomial in another normalized basis (exact algebra): least squares is solved in the
best-conditioned basis and stored in another; a prior or a selection is moved between bases."""

from __future__ import annotations

import numpy as np

from ..features import MonomialBasis, RegressorLayout, substitution_matrix
from ..normalization import Normalization


def change_basis(layout: RegressorLayout, coef: np.ndarray, from_inputs: Normalization,
                 from_outputs: Normalization, to_inputs: Normalization, to_outputs: Normalization) -> np.ndarray:
    """The same polynomial's coefficients in another normalized basis (exact algebra).

    Parameters
    ----------
    layout : RegressorLayout
    coef : ndarray of shape (n_features, n_outputs)
        Coefficients of ``layout``'s columns evaluated at ``from_*``-normalized values.
    from_inputs, from_outputs, to_inputs, to_outputs : Normalization

    Returns
    -------
    ndarray of shape (n_features, n_outputs)
        Coefficients for ``to_*``-normalized values.

    Examples
    --------
    >>> import numpy as np
    >>> layout = RegressorLayout(MonomialBasis(1, 2), 1)
    >>> center = Normalization(np.array([3.0]), np.array([2.0]))   # z = (u - 3) / 2
    >>> raw = Normalization.identity(1)
    >>> change_basis(layout, np.array([[0.0], [1.0], [0.0]]), center, raw, raw, raw).ravel().tolist()  # z² = (u² - 6u + 9) / 4
    [-1.5, 0.25, 2.25]
    """
    # z = (v − o_to)/s_to and x = (v − o_from)/s_from give x = (z − (o_from − o_to)/s_to) / (s_from/s_to).
    t = substitution_matrix(layout, (from_inputs.offset - to_inputs.offset) / to_inputs.scale,
                            from_inputs.scale / to_inputs.scale,
                            (from_outputs.offset - to_outputs.offset) / to_outputs.scale,
                            from_outputs.scale / to_outputs.scale)
    return np.asarray(t @ coef)
