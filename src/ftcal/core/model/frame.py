"""What a fit takes from the data and the model's parameters before any solver runs: the fit frame,
the size and well-posedness checks, the data helpers and the dense regressor (OSQP only)."""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ...runtime.errors import FtcalError, IllPosedFitWarning, IllPosedParameterWarning, ParameterError
from ..dataset import Dataset
from ..features import RegressorLayout
from ..limits import MAX_GRAM_BYTES
from ..normalization import Normalization

# The OSQP comparison path builds the dense regressor; refuse beyond this many cells.
DENSE_LIMIT_CELLS = 200_000_000
# Least squares is solved in this basis whatever the stored one (it is the best conditioned).
SOLVE_BASIS = "center"


@dataclass(frozen=True)
class FitFrame:
    """What a fit takes from the data and the model's parameters, before any solver runs.

    Attributes
    ----------
    layout : RegressorLayout
    normalization : str
        The stored basis, one of :data:`ftcal.core.limits.NORMALIZATIONS`.
    input_normalization, output_normalization : Normalization
        The stored basis's normalizations.
    solve_input_normalization, solve_output_normalization : Normalization
        The basis the solver works in (differs from the stored one only for least squares).
    input_names, output_names : tuple of str
    input_range, output_range : ndarray of shape (n, 2)
        Training min and max per column.
    n_rows : int
        Regressor rows (samples minus ARX warm-up rows per segment).
    """

    layout: RegressorLayout
    normalization: str
    input_normalization: Normalization
    output_normalization: Normalization
    solve_input_normalization: Normalization
    solve_output_normalization: Normalization
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    input_range: np.ndarray
    output_range: np.ndarray
    n_rows: int

    @property
    def solves_in_stored_basis(self) -> bool:
        return self.solve_input_normalization is self.input_normalization


def check_gram_size(layout: RegressorLayout) -> None:
    """Refuse, before anything is allocated, a fit whose Gram matrix exceeds :data:`MAX_GRAM_BYTES`.

    Raises
    ------
    FtcalError
        Naming the coefficient count, the memory the Gram matrix needs and what to lower.
    """
    p = layout.n_features
    need = 8 * p * p
    if need > MAX_GRAM_BYTES:
        arx = "" if layout.is_static else f", na={layout.na}, nb={layout.nb}"
        lower = "{degree}" if layout.is_static else "{degree}, {na} or {nb}"
        raise ParameterError(("degree", "na", "nb"), f"degree {layout.basis.degree}{arx} over {layout.basis.n_inputs} inputs has {p:,} "
                         f"coefficients per output ({p * layout.n_outputs:,} in all); its Gram matrix alone needs "
                         f"{need / 1e9:.1f} GB, above the limit of {MAX_GRAM_BYTES / 1e9:.0f} GB: lower {lower}.")


def warn_if_ill_posed(input_names: Sequence[str], span: np.ndarray, layout: RegressorLayout,
                      n_rows: int) -> None:
    """Warn (:class:`~ftcal.runtime.errors.IllPosedFitWarning`): fewer rows than coefficients, or a constant input."""
    p = layout.n_features
    if n_rows < p:
        warnings.warn(IllPosedParameterWarning(
            ("lasso", "ridge"), f"The fit is under-determined: {n_rows} samples for {p} coefficients per output. "
            "Lower the degree, add recordings, or use {lasso}/{ridge}."), stacklevel=5)
    for name, width in zip(input_names, span):
        if width == 0:
            warnings.warn(IllPosedParameterWarning(
                "inputs", f"Input {name!r} is constant in the training data, so its terms duplicate the "
                "offset; drop it with {inputs} or record data where it varies."), stacklevel=5)


def dense_regressor(data: Dataset, frame: FitFrame) -> tuple[np.ndarray, np.ndarray]:
    """The dense regressor and targets of ``data`` in ``frame``'s solve basis, segment by segment (OSQP only)."""
    layout = frame.layout
    if frame.n_rows * layout.n_features > DENSE_LIMIT_CELLS:
        raise ParameterError('solver', f"The OSQP solver needs the dense {frame.n_rows} × {layout.n_features} regressor "
            f"({frame.n_rows * layout.n_features * 8 / 1e9:.1f} GB); use {{solver}} lstsq, which never builds it.")
    u_norm = frame.solve_input_normalization.apply(data.inputs)
    y_norm = frame.solve_output_normalization.apply(data.outputs)
    blocks, targets = [], []
    for a, b in data.segment_bounds():
        blocks.append(layout.evaluate_segment(u_norm[a:b], y_norm[a:b]))
        targets.append(data.outputs[a + layout.max_lag:b])
    return np.concatenate(blocks), np.concatenate(targets)


def as_dataset(data, outputs=None, input_names: Sequence[str] | None = None, owner: str = "the model") -> Dataset:
    """``data`` as a Dataset: itself, or an inputs array (with ``outputs`` and ``input_names`` when given).

    An array must have one column per name of ``input_names`` (``owner``'s inputs, named in the message);
    sparse and complex arrays are refused.
    """
    if isinstance(data, Dataset):
        return data
    arrays = []
    for value, name in ((data, "inputs"), (outputs, "outputs")):
        if value is not None and (hasattr(value, "toarray") or type(value).__module__.startswith("scipy.sparse")):
            raise FtcalError(f"The {name} are a sparse matrix; sparse input is not supported (the regressor's "
                             "monomials of a sparse column are dense): convert it with .toarray().")
        array = None if value is None else np.asarray(value)
        if array is not None and array.dtype.kind == "c":
            raise FtcalError(f"Complex data not supported: the {name} hold complex numbers; a calibration needs "
                             "real ones.")
        arrays.append(array)
    u = np.asarray(arrays[0], dtype=np.float64)
    if u.ndim == 1:
        u = u[:, None]
    if u.ndim != 2 or u.shape[1] == 0:
        raise FtcalError(f"Found array with 0 feature(s) (shape={u.shape}) while a minimum of 1 is required: "
                         "the inputs need one column per input channel.")
    if input_names is not None and len(input_names) != u.shape[1]:
        raise FtcalError(f"X has {u.shape[1]} features, but {owner} is expecting {len(input_names)} features as "
                         f"input: one column per input {', '.join(input_names)}.")
    names = tuple(input_names) if input_names is not None else None
    return Dataset.from_arrays(u, arrays[1], input_names=names)


def outputs_in_order(data: Dataset, names: Sequence[str]) -> np.ndarray:
    """The outputs of ``data`` in the order of ``names``; refused in one line when one is missing."""
    index = {n: i for i, n in enumerate(data.output_names)}
    missing = [n for n in names if n not in index]
    if missing:
        raise FtcalError(f"The data has no output column(s) {', '.join(map(repr, missing))} "
                         "that the model predicts.")
    return data.outputs[:, [index[n] for n in names]]
