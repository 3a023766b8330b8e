"""Inputs outside the training range: which channels, how far, and what it did to the error.

A model extrapolates where an input leaves the box its training data spanned. How far
is measured in units of that channel's training span (``high − low``), so 0.1 means
"10 % of the training range beyond its edge". :class:`RangeSums` adds up, block by
block, what one warning needs to say it once per command: the count per channel, the
largest excursion per channel and, when the reference wrench is known, the force- and
torque-norm errors of the samples inside and outside the range (docs/metrics.md).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from . import metrics

# Relative slack at the range edges: values within it of an edge count as inside (rounding).
RANGE_TOLERANCE = 1e-9


# Rows folded into one line by column_extremes: long inner loops instead of one as short as a row.
_FOLDED_ROWS = 64


def column_extremes(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Minimum and maximum of each column of a C-ordered ``values`` (n_rows >= 1, n_columns), NaN-free.

    The same numbers as ``values.min(axis=0)`` and ``values.max(axis=0)`` (min and max are exact),
    about eight times faster on a few columns: numpy reduces a row-major array over its rows with
    an inner loop as long as one row, so whole blocks of rows are reduced as one line first.

    >>> import numpy as np
    >>> x = np.random.default_rng(0).normal(size=(1000, 3))
    >>> low, high = column_extremes(x)
    >>> bool((low == x.min(axis=0)).all() and (high == x.max(axis=0)).all())
    True
    """
    values = np.ascontiguousarray(values)
    n_rows, n_columns = values.shape
    whole = n_rows - n_rows % _FOLDED_ROWS
    lows, highs = [], []
    if whole:
        lines = values[:whole].reshape(-1, _FOLDED_ROWS * n_columns)
        lows.append(lines.min(axis=0).reshape(_FOLDED_ROWS, n_columns).min(axis=0))
        highs.append(lines.max(axis=0).reshape(_FOLDED_ROWS, n_columns).max(axis=0))
    if whole < n_rows:
        lows.append(values[whole:].min(axis=0))
        highs.append(values[whole:].max(axis=0))
    return np.min(lows, axis=0), np.max(highs, axis=0)


def range_widths(input_range: np.ndarray) -> np.ndarray:
    """The training span of each input, ``high − low``; 1 for a constant input (no span to compare to)."""
    width = input_range[:, 1] - input_range[:, 0]
    return np.where(width > 0, width, 1.0)


def outside_by_channel(inputs: np.ndarray, input_range: np.ndarray) -> np.ndarray:
    """Boolean (n_samples, n_inputs): the input is outside its training range (beyond the slack)."""
    low, high = input_range[:, 0], input_range[:, 1]
    slack = RANGE_TOLERANCE * np.maximum(high - low, 1.0)
    return (inputs < low - slack) | (inputs > high + slack)


def excursions(inputs: np.ndarray, input_range: np.ndarray) -> np.ndarray:
    """How far each input lies beyond its training range, in training spans; 0 inside.

    Parameters
    ----------
    inputs : ndarray of shape (n_samples, n_inputs)
    input_range : ndarray of shape (n_inputs, 2), columns (low, high)

    Returns
    -------
    ndarray of shape (n_samples, n_inputs)

    Examples
    --------
    >>> import numpy as np
    >>> excursions(np.array([[-1.0], [0.5], [3.0]]), np.array([[0.0, 2.0]])).ravel().tolist()
    [0.5, 0.0, 0.5]
    """
    low, high = input_range[:, 0], input_range[:, 1]
    beyond = np.maximum(np.maximum(low - inputs, inputs - high), 0.0)
    return np.where(outside_by_channel(inputs, input_range), beyond / range_widths(input_range), 0.0)


@dataclass
class RangeSums:
    """Additive out-of-range statistics of consecutive blocks of samples (``a + b``).

    Attributes
    ----------
    n : samples seen
    n_out : samples with at least one input outside the training range
    count : ndarray (n_inputs,), samples outside the range per input
    worst : ndarray (n_inputs,), largest excursion per input, in training spans
    norm_sq_in, norm_sq_out : ndarray (2,)
        Σ (‖v‖ − ‖v̂‖)² for forces and torques over the scored samples inside / outside
        the range; NaN when the reference is unknown or the outputs hold no such triple.
    n_scored_in, n_scored_out : int
        The scored samples inside / outside the range (ARX metrics leave out each
        segment's first max(na, nb) rows).
    """

    n: int
    n_out: int
    count: np.ndarray
    worst: np.ndarray
    norm_sq_in: np.ndarray
    norm_sq_out: np.ndarray
    n_scored_in: int = 0
    n_scored_out: int = 0
    n_span: int = 0  # samples inside the range but outside the span of the training inputs
    loads: "LoadSums | None" = None  # loads beyond the training loads (given ``loads`` and ``output_range``)

    @classmethod
    def of(cls, inputs: np.ndarray, input_range: np.ndarray, y: np.ndarray | None = None,
           prediction: np.ndarray | None = None, output_names: Sequence[str] = (),
           scored: np.ndarray | None = None, outside_span: np.ndarray | None = None,
           loads: np.ndarray | None = None, output_range: np.ndarray | None = None,
           load_rows: np.ndarray | None = None) -> "RangeSums":
        """Statistics of one block.

        Parameters
        ----------
        inputs : ndarray of shape (m, n_inputs)
        input_range : ndarray of shape (n_inputs, 2)
        y, prediction : ndarray of shape (m, n_outputs), optional
            The reference and the prediction, for the error inside and outside the range.
        output_names : names of the outputs, to find the force and torque triples
        scored : boolean ndarray of shape (m,), optional
            The rows the error counts (default all).
        outside_span : boolean ndarray of shape (m,), optional
            The rows outside the span of the training inputs (:func:`span_of`); those also
            outside the range are counted there only.
        loads : ndarray of shape (m, n_outputs), optional
            The reference or predicted wrench, counted against ``output_range`` (the training loads'
            min and max, shape (n_outputs, 2)) with ``output_names`` in :attr:`loads`; only the
            ``load_rows`` (boolean, shape (m,)) when given.
        """
        far = excursions(inputs, input_range)
        outside = far > 0
        any_out = outside.any(axis=1)
        scored = np.ones(len(inputs), dtype=bool) if scored is None else scored
        norm_in, norm_out = np.full(2, np.nan), np.full(2, np.nan)
        if y is not None and prediction is not None:
            for k, columns in enumerate(metrics.force_torque_columns(output_names)):
                if columns is not None:
                    d = np.linalg.norm(y[:, columns], axis=1) - np.linalg.norm(prediction[:, columns], axis=1)
                    norm_in[k] = np.sum(d[scored & ~any_out] ** 2)
                    norm_out[k] = np.sum(d[scored & any_out] ** 2)
        worst = far.max(axis=0) if len(far) else np.zeros(inputs.shape[1])
        n_span = 0 if outside_span is None else int(np.sum(outside_span & ~any_out))
        beyond = None if loads is None or output_range is None else \
            LoadSums.of(loads, output_range, output_names, load_rows)
        return cls(len(inputs), int(any_out.sum()), outside.sum(axis=0), worst, norm_in, norm_out,
                   int(np.sum(scored & ~any_out)), int(np.sum(scored & any_out)), n_span, beyond)

    def __add__(self, other: "RangeSums") -> "RangeSums":
        return RangeSums(self.n + other.n, self.n_out + other.n_out, self.count + other.count,
                         np.maximum(self.worst, other.worst), self.norm_sq_in + other.norm_sq_in,
                         self.norm_sq_out + other.norm_sq_out, self.n_scored_in + other.n_scored_in,
                         self.n_scored_out + other.n_scored_out, self.n_span + other.n_span,
                         None if self.loads is None or other.loads is None else self.loads + other.loads)

    def summary(self, input_names: Sequence[str]) -> dict:
        """Deprecated: :meth:`to_dict`."""
        metrics._renamed("RangeSums.summary", "RangeSums.to_dict")
        return self.to_dict(input_names)

    def to_dict(self, input_names: Sequence[str]) -> dict:
        """JSON-ready: per input outside the range its count and largest excursion, and the split errors.

        Keys: ``n_samples``, ``n_out_of_range``, ``inputs`` ({name: {"samples", "max_excursion"}},
        only the inputs that leave the range), and, when the reference was known,
        ``force_norm_rmse_in_range``, ``force_norm_rmse_out_of_range``, the torque
        pair (None where undefined) and the scored sample counts ``n_scored_in_range``,
        ``n_scored_out_of_range`` they average over.
        """
        out: dict = {"n_samples": self.n, "n_out_of_range": self.n_out,
                     "inputs": {name: {"samples": int(c), "max_excursion": float(w)}
                                for name, c, w in zip(input_names, self.count, self.worst) if c}}
        for k, kind in enumerate(("force", "torque")):
            for where, sums, rows in (("in_range", self.norm_sq_in, self.n_scored_in),
                                      ("out_of_range", self.norm_sq_out, self.n_scored_out)):
                value = sums[k]
                out[f"{kind}_norm_rmse_{where}"] = (None if np.isnan(value) or rows == 0
                                                    else float(np.sqrt(value / rows)))
        out["n_scored_in_range"], out["n_scored_out_of_range"] = self.n_scored_in, self.n_scored_out
        out["n_outside_span"] = self.n_span
        return out


def describe(summary: dict) -> str | None:
    """One sentence for a warning: how many samples, which inputs, how far, the error inside vs outside.

    ``summary`` is :meth:`RangeSums.summary`; returns None when every sample is in range.

    Examples
    --------
    >>> describe({"n_samples": 10, "n_out_of_range": 1,
    ...           "inputs": {"T": {"samples": 1, "max_excursion": 0.25}}})
    '1 of 10 samples has inputs outside the training range: T up to 25 % of its training span beyond it (1 sample); predictions there are extrapolations.'
    """
    n_out, n, n_span = summary["n_out_of_range"], summary["n_samples"], summary.get("n_outside_span", 0)
    parts = []
    if n_out:
        effects = effect_text(summary)
        parts.append(f"{n_out} of {n} samples {'has' if n_out == 1 else 'have'} inputs outside the training range: "
                     f"{channel_text(summary)}; predictions there are extrapolations"
                     + (f" ({effects})" if effects else ""))
    if n_span:
        parts.append(out_of_span_text(n_span, n))
    return "; ".join(parts) + "." if parts else None


def out_of_span_text(n_span: int, n_samples: int) -> str:
    """How many samples lie inside the training range but outside the span of the training inputs."""
    verb = "lies" if n_span == 1 else "lie"
    return (f"{n_span} of {n_samples} sample(s) inside the training range {verb} outside the span of the training "
            "inputs (combinations of inputs the training data never had, e.g. a load direction its loads and poses "
            "lacked); predictions there are extrapolations")


def span_of(model, inputs: np.ndarray) -> np.ndarray | None:
    """The model's out-of-span mask where its family records the training inputs' spread, else None."""
    check = getattr(model, "out_of_span", None)
    return None if check is None else check(inputs)


def channel_text(summary: dict) -> str:
    """``"T up to 3.2 % of its training span beyond it (138 samples), u2 ..."``, farthest first."""
    channels = sorted(summary["inputs"].items(), key=lambda item: -item[1]["max_excursion"])
    return ", ".join(f"{name} up to {100 * info['max_excursion']:.2g} % of its training span beyond it "
                     f"({plural(info['samples'], 'sample')})" for name, info in channels)


def effect_text(summary: dict) -> str:
    """The force- and torque-norm RMSE on the samples outside vs inside the range; "" without a reference."""
    effects = []
    for kind, unit in (("force", metrics.FORCE_UNIT), ("torque", metrics.TORQUE_UNIT)):
        outside, inside = summary.get(f"{kind}_norm_rmse_out_of_range"), summary.get(f"{kind}_norm_rmse_in_range")
        if outside is not None:
            effects.append(f"{kind}-norm RMSE {outside:.4g} {unit} on them"
                           + (f" vs {inside:.4g} {unit} on the {summary['n_scored_in_range']} inside"
                              if inside is not None else ""))
    return "; ".join(effects)


def plural(count: int, noun: str) -> str:
    """``"1 sample"``, ``"2 samples"``."""
    return f"{count} {noun}{'' if count == 1 else 's'}"


# A load counts as beyond the training loads when it passes their min or max by more than this fraction of
# the widest training span of its block (forces, torques): noise on an axis the data never loaded is no load.
LOAD_MARGIN_FRACTION = 0.05


def load_margins(output_range: np.ndarray, output_names: Sequence[str]) -> np.ndarray:
    """How far (in the output's unit) a load may pass its training min/max before it counts as beyond them.

    :data:`LOAD_MARGIN_FRACTION` of the widest training span among the outputs of the same block (``F*``
    forces, ``T*`` torques; any other output is its own block), so an axis the training data hardly
    loaded is judged against the loads the sensor did carry.

    Parameters
    ----------
    output_range : ndarray of shape (n_outputs, 2), training min and max
    output_names : names of the outputs

    Returns
    -------
    ndarray of shape (n_outputs,)

    Examples
    --------
    >>> import numpy as np
    >>> load_margins(np.array([[-20.0, 20.0], [-0.1, 0.1], [-1.0, 1.0]]), ["Fx", "Fz", "Tx"]).tolist()
    [2.0, 2.0, 0.1]
    """
    width = output_range[:, 1] - output_range[:, 0]
    block = [str(n)[:1] if str(n)[:1] in ("F", "T") else str(n) for n in output_names]
    widest = {b: max(float(width[j]) for j in range(len(block)) if block[j] == b) for b in set(block)}
    return np.array([LOAD_MARGIN_FRACTION * widest[b] for b in block])


@dataclass
class LoadSums:
    """Additive counts of loads beyond the training loads, per output, for consecutive blocks (``a + b``).

    The loads are the reference wrench (``evaluate``) or the predicted one (``predict``). A model's
    cross-validated error was measured on held-out loads inside the training data's span; data that
    load an axis beyond it (a new axis, a larger load) can err far more (52× on a real sensor whose
    evaluation loaded a new axis), so the commands say so.

    Attributes
    ----------
    n : samples seen
    n_beyond : samples with at least one output beyond its training loads (:func:`load_margins`)
    count : ndarray (n_outputs,), samples beyond per output
    low, high : ndarray (n_outputs,), smallest and largest load seen per output
    """

    n: int
    n_beyond: int
    count: np.ndarray
    low: np.ndarray
    high: np.ndarray

    @classmethod
    def of(cls, loads: np.ndarray, output_range: np.ndarray, output_names: Sequence[str],
           rows: np.ndarray | None = None) -> "LoadSums":
        """Counts of one block; ``loads`` is (m, n_outputs), ``output_range`` (n_outputs, 2); only the
        ``rows`` (boolean, shape (m,)) count when given, all of them otherwise."""
        loads = np.asarray(loads, dtype=np.float64)
        margin = load_margins(output_range, output_names)
        beyond = (loads < output_range[:, 0] - margin) | (loads > output_range[:, 1] + margin)
        if rows is not None:
            beyond &= np.asarray(rows, dtype=bool)[:, None]
        empty = loads.shape[0] == 0
        return cls(loads.shape[0], int(beyond.any(axis=1).sum()), beyond.sum(axis=0),
                   np.full(loads.shape[1], np.inf) if empty else loads.min(axis=0),
                   np.full(loads.shape[1], -np.inf) if empty else loads.max(axis=0))

    def __add__(self, other: "LoadSums") -> "LoadSums":
        return LoadSums(self.n + other.n, self.n_beyond + other.n_beyond, self.count + other.count,
                        np.minimum(self.low, other.low), np.maximum(self.high, other.high))

    def summary(self, output_range: np.ndarray, output_names: Sequence[str]) -> dict:
        """Deprecated: :meth:`to_dict`."""
        metrics._renamed("LoadSums.summary", "LoadSums.to_dict")
        return self.to_dict(output_range, output_names)

    def to_dict(self, output_range: np.ndarray, output_names: Sequence[str]) -> dict:
        """JSON-ready: ``n_samples``, ``n_beyond`` and, per output with loads beyond its training loads,
        ``{"samples", "low", "high", "training_low", "training_high"}`` under ``outputs``."""
        return {"n_samples": self.n, "n_beyond": self.n_beyond,
                "outputs": {name: {"samples": int(c), "low": float(lo), "high": float(hi),
                                   "training_low": float(r[0]), "training_high": float(r[1])}
                            for name, c, lo, hi, r in zip(output_names, self.count, self.low, self.high,
                                                          output_range) if c}}


def loads_text(summary: dict, what: str = "the reference loads") -> str | None:
    """One sentence: which outputs ``what`` drive beyond the training loads, and what that means for the
    cross-validated error; None when none do. ``summary`` is :meth:`LoadSums.summary`.

    Examples
    --------
    >>> loads_text({"n_samples": 10, "n_beyond": 4, "outputs": {"Fz": {"samples": 4, "low": -30.0, "high": 0.0,
    ...             "training_low": -0.1, "training_high": 0.1}}})  # doctest: +NORMALIZE_WHITESPACE
    '4 of 10 samples: the reference loads go beyond the training loads on Fz (-30..0 against -0.1..0.1 in
    training, 4 samples); the cross-validated error of the fit was measured inside the training loads and does
    not forecast the error there.'
    """
    if not summary or not summary["n_beyond"]:
        return None
    axes = ", ".join(f"{name} ({info['low']:.3g}..{info['high']:.3g} against {info['training_low']:.3g}.."
                     f"{info['training_high']:.3g} in training, {plural(info['samples'], 'sample')})"
                     for name, info in summary["outputs"].items())
    return (f"{summary['n_beyond']} of {summary['n_samples']} samples: {what} go beyond the training loads on "
            f"{axes}; the cross-validated error of the fit was measured inside the training loads and does not "
            "forecast the error there.")
