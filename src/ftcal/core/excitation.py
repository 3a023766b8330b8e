"""What the data can determine: the spread of a fit's reference wrenches and of its inputs.

A calibration fit learns the map from raw inputs to the wrench only along the
directions the reference wrenches vary in: data from one rigid tool turned
through many poses spans 3 of the 6 wrench directions (the torque is the lever
arm times the force), and the fitted model predicts nonsense for a push along
any other. :func:`output_excitation` measures it from the outputs' covariance:
the reference wrenches are centred, forces and torques are each scaled by their
block's RMS spread (so N and N·m weigh alike whatever the tool's lever arm),
and the singular values of the result, relative to the largest, say how far
each direction is excited. A direction below :data:`UNEXCITED` of the largest
is not determined, one below :data:`WEAK` hardly; each is named by its largest
components, with the kind of load that would excite it.

:class:`Spread` holds the count, mean and centred cross-products of columns,
merged exactly across chunks and files (Chan's formula), so streamed fits get
it in their first pass. :func:`span_distance` is the Mahalanobis distance of
new inputs from the training inputs: large along directions the training data
hardly vary even when every input stays inside its training range.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..runtime.errors import FtcalError
from .directions import order_by_size
from .limits import ZERO_REFERENCE_WRENCH
from .precision import SPECTRUM, settle

# Relative singular values below these: the direction is not excited / hardly excited.
UNEXCITED = 1e-3
WEAK = 0.005
# A block whose spread is below this fraction of its mean's size is constant (rounding only).
CONSTANT_RELATIVE = 1e-9
# A component this large (of a unit direction) is named in the message.
NAMED_COMPONENT = 0.1
# Squared Mahalanobis distance beyond which an input is outside the training span: far beyond any
# plausible training sample (chi-square tail 1e-6 for 7 inputs is 38; corners of a uniform box give 3 per input).
SPAN_LIMIT_PER_INPUT = 6.0
SPAN_LIMIT_MIN = 40.0
# Input directions with less variance than this fraction of the largest are treated as fixed by the training data.
SPAN_RELATIVE_FLOOR = 1e-12


@dataclass(frozen=True)
class Spread:
    """Count, mean and centred cross-product matrix Σ (x − mean)(x − mean)ᵀ of some columns."""

    n: int
    mean: np.ndarray
    m2: np.ndarray

    @classmethod
    def of(cls, x: np.ndarray) -> "Spread":
        """The spread of the rows of ``x`` (n_samples, n_columns)."""
        x = np.asarray(x, dtype=np.float64)
        if x.shape[0] == 0:
            return cls(0, np.zeros(x.shape[1]), np.zeros((x.shape[1], x.shape[1])))
        mean = x.mean(axis=0)
        centred = x - mean
        return cls(int(x.shape[0]), mean, centred.T @ centred)

    def __add__(self, other: "Spread") -> "Spread":
        if self.n == 0:
            return other
        if other.n == 0:
            return self
        n = self.n + other.n
        delta = other.mean - self.mean
        mean = self.mean + delta * (other.n / n)
        return Spread(n, mean, self.m2 + other.m2 + np.outer(delta, delta) * (self.n * other.n / n))

    def take(self, columns: slice) -> "Spread":
        """The spread of some of the columns."""
        return Spread(self.n, self.mean[columns].copy(), self.m2[columns, columns].copy())

    @property
    def covariance(self) -> np.ndarray:
        return self.m2 / max(self.n, 1)

    def to_json(self) -> dict:
        return {"n": self.n, "mean": self.mean.tolist(), "covariance": self.covariance.tolist()}

    @classmethod
    def from_json(cls, doc: dict) -> "Spread":
        n = int(doc["n"])
        return cls(n, np.asarray(doc["mean"], dtype=np.float64), np.asarray(doc["covariance"], dtype=np.float64) * n)


@dataclass(frozen=True)
class OutputExcitation:
    """How far the reference wrenches excite each direction.

    Attributes
    ----------
    singular_values : ndarray, relative to the largest, descending, to :data:`~ftcal.core.precision.SPECTRUM`
    n_excited : int, directions at or above :data:`UNEXCITED`
    missing : tuple of str, the directions not excited (named)
    weak : tuple of str, the directions hardly excited (named)
    hints : tuple of str, what to record to excite them
    """

    singular_values: np.ndarray
    n_excited: int
    missing: tuple[str, ...]
    weak: tuple[str, ...]
    hints: tuple[str, ...]

    def summary(self) -> str:
        values = ", ".join(f"{v:.2g}" for v in self.singular_values)
        return (f"excitation: reference wrenches span {self.n_excited} of {len(self.singular_values)} directions "
                f"(relative singular values of the centred outputs, forces and torques scaled alike: {values})")

    def warning(self) -> str | None:
        """The warning text, or None when every direction is well excited."""
        if not self.missing and not self.weak:
            return None
        parts = []
        if self.missing:
            parts.append(f"reference wrenches span {self.n_excited} of {len(self.singular_values)} directions; "
                         f"{'; '.join(m + ' never excited' for m in self.missing)}")
        if self.weak:
            parts.append("; ".join(w + " hardly excited" for w in self.weak))
        return (f"{'; '.join(parts)}: the model cannot be trusted for wrenches along "
                f"{'them' if len(self.missing) + len(self.weak) > 1 else 'it'} — {'; '.join(self.hints)}.")


_AXIS_WORDS = {"Fx": "force along x", "Fy": "force along y", "Fz": "force along z",
               "Tx": "torque about x", "Ty": "torque about y", "Tz": "torque about z"}


def _block(name: str) -> str:
    return name[:1] if name[:1] in ("F", "T") else name


def output_excitation(spread: Spread, names: Sequence[str]) -> OutputExcitation:
    """The excitation of a fit's outputs (reference wrenches) from their spread.

    Parameters
    ----------
    spread : Spread of the outputs
    names : output names; those starting with F are forces, with T torques (scaled as blocks),
        any other output is scaled on its own.

    Returns
    -------
    OutputExcitation

    Raises
    ------
    FtcalError
        When no output varies at all: nothing can be estimated.
    """
    cov = spread.covariance
    k = len(names)
    scale = np.ones(k)
    for block in dict.fromkeys(_block(n) for n in names):
        members = [j for j, n in enumerate(names) if _block(n) == block]
        rms = np.sqrt(np.trace(cov[np.ix_(members, members)]) / len(members))
        # Rounding leaves a constant column a spread of ~1e-16 of its value: that is no variation.
        constant = rms <= CONSTANT_RELATIVE * np.abs(spread.mean[members]).max()
        # Forces (N) and torques (N m) a millionth of a unit apart are zero: a reference wrench of
        # ~1e-12 everywhere is a missing payload, not a calibration load (issue 27).
        constant = constant or (block in ("F", "T") and rms < ZERO_REFERENCE_WRENCH)
        scale[members] = 0.0 if rms == 0 or constant else 1.0 / rms
    if not np.any(scale):
        size = float(np.abs(spread.mean).max(initial=0.0))
        raise FtcalError(f"the reference outputs {','.join(names)} are constant"
                         + (f" and ~0 (largest mean {size:.2g})" if size < ZERO_REFERENCE_WRENCH else "")
                         + ": nothing to fit a calibration to; record several loads or poses"
                         + (" (a zero reference is a load case with no payload: see `ftcal dataset --payload-file`)"
                            if size < ZERO_REFERENCE_WRENCH else "") + ".")
    scaled = cov * scale[:, None] * scale[None, :]
    values, vectors = np.linalg.eigh(0.5 * (scaled + scaled.T))
    order = np.argsort(values)[::-1]
    values, vectors = np.maximum(values[order], 0.0), vectors[:, order]
    # Stated to their precision: a direction zero in exact arithmetic is 0 on every machine.
    singular = settle(np.sqrt(values / values[0]), SPECTRUM, 1.0)
    missing, weak, hints = [], [], []
    for found, chosen in ((missing, singular < UNEXCITED), (weak, (singular >= UNEXCITED) & (singular < WEAK))):
        for direction in _readable_basis(vectors[:, chosen]):
            words, hint = _describe(direction, names)
            found.append(words)
            if hint not in hints:
                hints.append(hint)
    return OutputExcitation(singular, int(np.sum(singular >= UNEXCITED)), tuple(missing), tuple(weak), tuple(hints))


def _readable_basis(basis: np.ndarray) -> list[np.ndarray]:
    """Sparse unit vectors spanning the columns of ``basis`` (its reduced row echelon form, transposed).

    Any orthonormal basis of a degenerate eigenspace is as good as another; the
    echelon form gives vectors with few nonzero components, e.g. "torque about z"
    alone rather than a blend of three null directions.
    """
    rows = basis.T.copy()
    pivot_row = 0
    for column in range(rows.shape[1]):
        if pivot_row == rows.shape[0]:
            break
        best = pivot_row + int(np.argmax(np.abs(rows[pivot_row:, column])))
        if abs(rows[best, column]) < 1e-9:
            continue
        rows[[pivot_row, best]] = rows[[best, pivot_row]]
        rows[pivot_row] /= rows[pivot_row, column]
        others = np.arange(rows.shape[0]) != pivot_row
        rows[others] -= np.outer(rows[others, column], rows[pivot_row])
        pivot_row += 1
    rows[np.abs(rows) < 1e-9] = 0.0
    return [row / np.linalg.norm(row) for row in rows[:pivot_row]]


def _describe(direction: np.ndarray, names: Sequence[str]) -> tuple[str, str]:
    """A direction of the output space in words, and the kind of data that excites it."""
    order = order_by_size(direction)
    named = [j for j in order if abs(direction[j]) >= NAMED_COMPONENT] or [int(order[0])]
    words = [_AXIS_WORDS.get(names[j], names[j]) for j in named]
    blocks = {_block(names[j]) for j in named}
    if len(named) == 1:
        text = words[0]
    else:
        text = " and ".join([", ".join(words[:-1]), words[-1]]) + " (only in a fixed ratio)"
    if blocks == {"T"}:
        hint = "add loads or poses that twist the sensor"
    elif blocks == {"F"}:
        hint = "add loads or poses that push along other directions"
    elif blocks <= {"F", "T"}:
        hint = "add loads with other centres of mass (other lever arms), so torque varies apart from force"
    else:
        hint = "add data where these outputs vary independently"
    return text, hint


def regressor_excitation(gram: np.ndarray) -> tuple[np.ndarray, int]:
    """Relative singular values of a regressor from its Gram matrix AᵀA, columns scaled to unit norm.

    Scaling the columns makes parameters of different units (kg, kg·m, N, N·m)
    comparable: the values then say how far the data separate the parameters,
    not how large their units are.

    Parameters
    ----------
    gram : ndarray of shape (p, p)

    Returns
    -------
    (ndarray of shape (p,), descending, relative to the largest, to :data:`~ftcal.core.precision.SPECTRUM`
    (:func:`~ftcal.core.precision.settle`); int, how many are at or above :data:`UNEXCITED`)
    """
    diagonal = np.sqrt(np.maximum(np.diag(gram), 0.0))
    unit = np.where(diagonal > 0, diagonal, 1.0)
    scaled = gram / unit[:, None] / unit[None, :]
    values = np.clip(np.linalg.eigvalsh(0.5 * (scaled + scaled.T))[::-1], 0.0, None)
    singular = settle(np.sqrt(values / values[0]), SPECTRUM, 1.0) if values[0] > 0 else np.zeros_like(values)
    return singular, int(np.sum(singular >= UNEXCITED))


def span_distance(spread: Spread, inputs: np.ndarray) -> np.ndarray:
    """Squared Mahalanobis distance of each row of ``inputs`` from the training inputs' mean.

    Directions the training inputs do not vary in at all (below
    :data:`SPAN_RELATIVE_FLOOR` of the largest variance, after scaling each input
    by its own spread) count any departure as infinitely far.

    Parameters
    ----------
    spread : Spread of the training inputs
    inputs : ndarray of shape (n_samples, n_inputs)

    Returns
    -------
    ndarray of shape (n_samples,)

    Examples
    --------
    >>> import numpy as np
    >>> x = np.random.default_rng(0).normal(size=(1000, 2))
    >>> float(span_distance(Spread.of(x), x.mean(axis=0, keepdims=True))[0])
    0.0
    """
    return SpanTest(spread).distance(inputs)


class SpanTest:
    """:func:`span_distance` with its eigendecomposition done once, for callers that test sample by sample.

    Parameters
    ----------
    spread : Spread of the training inputs
    """

    def __init__(self, spread: Spread) -> None:
        self.spread = spread
        cov = spread.covariance
        std = np.sqrt(np.maximum(np.diag(cov), 0.0))
        self.unit = np.where(std > 0, std, 1.0)
        corr = cov / self.unit[:, None] / self.unit[None, :]
        values, self.vectors = np.linalg.eigh(0.5 * (corr + corr.T))
        self.kept = values > SPAN_RELATIVE_FLOOR * max(values.max(), 0.0)
        self.values = values
        self.scale = np.sqrt(max(values.max(), 1e-300))

    def distance(self, inputs: np.ndarray) -> np.ndarray:
        """Squared Mahalanobis distance of each row of ``inputs`` (n_samples, n_inputs), as :func:`span_distance`."""
        projected = ((np.asarray(inputs, dtype=np.float64) - self.spread.mean) / self.unit) @ self.vectors
        kept = self.kept
        distance = np.sum(projected[:, kept] ** 2 / self.values[kept], axis=1)
        if not kept.all():
            # Any move along a direction the training data never varied in is outside the span.
            off = np.abs(projected[:, ~kept]).max(axis=1) > 1e-6 * self.scale
            distance = np.where(off, np.inf, distance)
        return distance


def span_limit(n_inputs: int) -> float:
    """The squared Mahalanobis distance beyond which an input is outside the training span."""
    return max(SPAN_LIMIT_MIN, SPAN_LIMIT_PER_INPUT * n_inputs)


# A held-out fold whose loads reach beyond the other folds' span by less than this fraction of an
# output's whole span only interpolated along it.
EXTRAPOLATION_FRACTION = 0.05


def group_output_ranges(outputs: np.ndarray, groups: np.ndarray) -> dict:
    """Min and max of each output per group label (str): ``{label: ndarray (n_outputs, 2)}``."""
    labels = np.asarray(groups, dtype=str)
    return {label: np.c_[outputs[labels == label].min(axis=0), outputs[labels == label].max(axis=0)]
            for label in np.unique(labels).tolist()}


@dataclass(frozen=True)
class HeldOutSpan:
    """What grouped cross-validation measured: whether any held-out fold loaded an output beyond the other
    folds' span (:meth:`of`); its text (``str()``) is one line of ``ftcal fit``'s report.

    The cross-validated error is an honest forecast for new load cases like the held-out ones. When no
    fold ever reached beyond what the rest of the data covered, it only measured interpolation: loads
    beyond the training span (a larger load, an axis the data hardly load) can err far more (52× on a
    real sensor whose evaluation loaded a new axis).

    Attributes
    ----------
    names : tuple of str, the outputs
    low, high : ndarray of shape (n_outputs,), each output's training span (all groups)
    probed : tuple of str
        Outputs some held-out fold loaded beyond the other folds' span by at least
        :data:`EXTRAPOLATION_FRACTION` of their width.
    unloaded : tuple of str
        Outputs whose span is under :data:`EXTRAPOLATION_FRACTION` of their block's widest (hardly loaded).
    """

    names: tuple[str, ...]
    low: np.ndarray
    high: np.ndarray
    probed: tuple[str, ...]
    unloaded: tuple[str, ...]

    @classmethod
    def of(cls, ranges: dict, fold_of: dict, names: Sequence[str]) -> "HeldOutSpan":
        """The span measured by folds ``fold_of`` (group label (str) -> fold index) over ``ranges`` (group
        label (str) -> ndarray (n_outputs, 2), each output's min and max in the group:
        :func:`group_output_ranges`)."""
        names = tuple(str(n) for n in names)
        labels = sorted(ranges)
        fold = np.array([fold_of[g] for g in labels])
        lows = np.array([ranges[g][:, 0] for g in labels])
        highs = np.array([ranges[g][:, 1] for g in labels])
        low, high = lows.min(axis=0), highs.max(axis=0)
        # An axis is judged against the widest of its block (forces, torques): noise on an unloaded axis is no load.
        block = [n[:1] if n[:1] in ("F", "T") else n for n in names]
        widest = {b: max(high[j] - low[j] for j in range(len(names)) if block[j] == b) for b in set(block)}
        width = np.maximum(np.array([max(high[j] - low[j], EXTRAPOLATION_FRACTION * widest[block[j]])
                                     for j in range(len(names))]), 1e-300)
        unloaded = tuple(n for j, n in enumerate(names) if high[j] - low[j] < EXTRAPOLATION_FRACTION * widest[block[j]])
        reach = np.zeros(len(names))
        for k in np.unique(fold):
            held, rest = fold == k, fold != k
            if not rest.any():
                continue
            beyond = np.maximum(highs[held].max(axis=0) - highs[rest].max(axis=0),
                                lows[rest].min(axis=0) - lows[held].min(axis=0))
            reach = np.maximum(reach, beyond / width)
        probed = tuple(n for n, r in zip(names, reach) if r >= EXTRAPOLATION_FRACTION and n not in unloaded)
        return cls(names, low, high, probed, unloaded)

    def __str__(self) -> str:
        spans = ", ".join(f"{n} {a:.3g}..{b:.3g}" for n, a, b in zip(self.names, self.low, self.high))
        hardly = ("; the data hardly load " + ", ".join(self.unloaded) + " (span under "
                  f"{100 * EXTRAPOLATION_FRACTION:g} % of their block's widest): no fold measured an error for loads "
                  "along them") if self.unloaded else ""
        if not self.probed:
            return ("cross-validated error: measured inside the training loads' span (" + spans + "); no held-out "
                    "fold reached beyond the other folds' loads, so it does not forecast loads beyond that span"
                    + hardly)
        inside = [n for n in self.names if n not in self.probed and n not in self.unloaded]
        return ("cross-validated error: held-out folds reached beyond the other folds' loads on "
                + ", ".join(self.probed) + (f" (only interpolated on {', '.join(inside)})" if inside else "")
                + "; training span " + spans + hardly)


def held_out_span(ranges: dict, fold_of: dict, names: Sequence[str]) -> str:
    """The text of :class:`HeldOutSpan` ``.of(ranges, fold_of, names)`` (one line)."""
    return str(HeldOutSpan.of(ranges, fold_of, names))
