"""The fit-ready dataset: inputs, outputs, segments and groups.

A *segment* is a stretch of consecutive samples (one recording): ARX lags are
built inside a segment and never cross into the next one. A *group* is the
unit of validation splits (a load case or a recording): near-duplicate samples
inside a recording make random sample splits over-optimistic, so ftcal only
ever splits by group.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..runtime.checks import check_finite_matrix
from ..runtime.errors import FtcalError, ParameterError
from .columns import DEFAULT_INPUTS, DEFAULT_OUTPUTS


@dataclass(frozen=True)
class Dataset:
    """Samples to fit or evaluate a calibration model on.

    Attributes
    ----------
    inputs : ndarray of shape (n_samples, n_inputs)
    outputs : ndarray of shape (n_samples, n_outputs) or None (prediction only)
    input_names, output_names : column names, in order
    segments : ndarray of shape (n_samples,), int
        Segment id per sample; each segment is one contiguous run.
    groups : ndarray of shape (n_samples,)
        Group label per sample (validation splits never cut a group).
    sources : names of the files the samples came from, one per segment id

    Examples
    --------
    >>> import numpy as np
    >>> data = Dataset.from_arrays(np.zeros((4, 7)), np.zeros((4, 6)), segments=[0, 0, 1, 1])
    >>> data.input_names[-1], data.output_names[0], data.segment_bounds()
    ('T', 'Fx', [(0, 2), (2, 4)])
    """

    inputs: np.ndarray
    outputs: np.ndarray | None
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    segments: np.ndarray
    groups: np.ndarray
    sources: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        n = self.inputs.shape[0]
        if self.inputs.ndim != 2 or self.inputs.shape[1] != len(self.input_names):
            raise FtcalError("Dataset inputs must have one column per input name.")
        if self.outputs is not None and (self.outputs.shape[0] != n
                                         or self.outputs.shape[1] != len(self.output_names)):
            raise FtcalError("Dataset outputs must have one row per sample and one column per output name.")
        if self.segments.shape != (n,) or self.groups.shape != (n,):
            raise FtcalError("Dataset segments and groups must have one entry per sample.")
        if n and np.any(np.diff(self.segments) != 0):
            # Each segment id must label exactly one contiguous run.
            starts = self.segments[np.r_[True, self.segments[1:] != self.segments[:-1]]]
            if len(np.unique(starts)) != len(starts):
                raise FtcalError("Dataset segments must be contiguous runs of samples.")

    @classmethod
    def from_arrays(cls, inputs: np.ndarray, outputs: np.ndarray | None = None, *,
                    input_names: Sequence[str] | None = None,
                    output_names: Sequence[str] | None = None,
                    segments: np.ndarray | None = None,
                    groups: np.ndarray | None = None) -> "Dataset":
        """Build a dataset from arrays, with default names and one segment.

        Parameters
        ----------
        inputs : array-like of shape (n_samples, n_inputs)
            What the sensor reads (``u1..u6`` and ``T`` by default).
        outputs : array-like of shape (n_samples, n_outputs), optional
            Reference wrench (``Fx..Tz`` by default, N and N·m).
        input_names, output_names : sequence of str, optional
        segments : array-like of int, shape (n_samples,), optional
            Contiguous runs (ARX lags never cross them); one segment by default.
        groups : array-like of shape (n_samples,), optional
            Validation groups; the segments by default.

        Returns
        -------
        Dataset

        Raises
        ------
        FtcalError
            On non-finite values or mismatched shapes.
        """
        u = np.asarray(inputs, dtype=np.float64)
        if u.ndim == 1:
            u = u[:, None]
        if u.ndim != 2:
            raise ParameterError("inputs", f"The 'inputs' parameter of Dataset.from_arrays must be an array of "
                                           f"shape (n_samples, n_inputs); got shape {u.shape}.")
        names_in = tuple(input_names) if input_names is not None else default_names(DEFAULT_INPUTS, "u", u.shape[1])
        u = check_finite_matrix(u, "inputs", len(names_in), names_in)
        y = None
        names_out: tuple[str, ...] = tuple(output_names) if output_names is not None else ()
        if outputs is not None:
            y = np.asarray(outputs, dtype=np.float64)
            if y.ndim == 1:
                y = y[:, None]
            if output_names is None:
                names_out = default_names(DEFAULT_OUTPUTS, "y", y.shape[1])
            y = check_finite_matrix(y, "outputs", len(names_out), names_out)
            if y.shape[0] != u.shape[0]:
                raise FtcalError(f"inputs have {u.shape[0]} rows but outputs have {y.shape[0]}.")
        n = u.shape[0]
        seg = np.zeros(n, dtype=np.int64) if segments is None else np.asarray(segments, dtype=np.int64)
        grp = seg.copy() if groups is None else np.asarray(groups)
        return cls(u, y, names_in, names_out, seg, grp)

    @property
    def n_samples(self) -> int:
        return int(self.inputs.shape[0])

    def segment_bounds(self) -> list[tuple[int, int]]:
        """(start, stop) of each contiguous segment, in sample order.

        Returns
        -------
        list of (int, int)
        """
        n = self.n_samples
        if n == 0:
            return []
        cuts = np.flatnonzero(self.segments[1:] != self.segments[:-1]) + 1
        edges = np.r_[0, cuts, n]
        return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]

    def subset(self, mask: np.ndarray) -> "Dataset":
        """Samples where ``mask`` is true (segments stay contiguous runs).

        Parameters
        ----------
        mask : ndarray of bool, shape (n_samples,)

        Returns
        -------
        Dataset
        """
        y = None if self.outputs is None else self.outputs[mask]
        return Dataset(self.inputs[mask], y, self.input_names, self.output_names,
                       self.segments[mask], self.groups[mask], self.sources)

    def select_inputs(self, names: Sequence[str]) -> np.ndarray:
        """Input columns in the order of ``names``, by name."""
        index = {n: i for i, n in enumerate(self.input_names)}
        missing = [n for n in names if n not in index]
        if missing:
            raise FtcalError(f"Dataset has no input column(s) {', '.join(map(repr, missing))}; "
                             f"it has {', '.join(self.input_names)}.")
        if tuple(names) == self.input_names:
            return self.inputs  # already in order: no copy
        return self.inputs[:, [index[n] for n in names]]


def default_names(preferred: tuple[str, ...], prefix: str, count: int) -> tuple[str, ...]:
    """The default column names when there are exactly as many, else prefix1..N."""
    if count == len(preferred):
        return preferred
    if count == len(preferred) - 1 and preferred is DEFAULT_INPUTS:
        return preferred[:-1]
    return tuple(f"{prefix}{i + 1}" for i in range(count))


def concatenate(datasets: Sequence[Dataset]) -> Dataset:
    """Stack datasets, renumbering segments so they stay apart."""
    if not datasets:
        raise FtcalError("No data to concatenate.")
    first = datasets[0]
    for d in datasets[1:]:
        if d.input_names != first.input_names or d.output_names != first.output_names:
            raise FtcalError("Datasets to concatenate must have the same input and output columns.")
    offset = 0
    segments = []
    for d in datasets:
        _, seg = np.unique(d.segments, return_inverse=True)
        segments.append(seg + offset)
        offset += int(seg.max()) + 1 if d.n_samples else 0
    outputs = None if first.outputs is None else np.concatenate([d.outputs for d in datasets])
    groups = np.concatenate([np.asarray(d.groups, dtype=object) for d in datasets])
    sources = tuple(s for d in datasets for s in d.sources)
    return Dataset(np.concatenate([d.inputs for d in datasets]), outputs, first.input_names,
                   first.output_names, np.concatenate(segments), groups, sources)
