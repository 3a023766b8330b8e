"""One scan per file: :func:`scan` reads a table chunk by chunk, once, and feeds accumulators.

An accumulator is one quantity a pass computes (:class:`Summary`: ranges, segments and
fingerprints; :class:`Statistics` and :class:`GroupStatistics`, :class:`FoldStatistics`:
sufficient statistics; :class:`PoseCells`, :class:`InputSpread`; :class:`Errors`: additive
:class:`ErrorSums` for ``evaluate`` and ``fit``'s training metrics). The partial results of
two files merge with ``+`` (``b``'s rows after ``a``'s), so the executor maps :func:`scan`
over the files and adds the results (:func:`add_scans`) in a tree that keeps their order.
Fusing two passes is putting their accumulators in one scan. ARX models carry history
across rows: their accumulators take the file whole (one :class:`~ftcal.core.dataset.Dataset`).

The per-file functions of earlier releases (:func:`file_summary`, :func:`file_statistics`, ...)
are scans of fixed accumulators, kept with their signatures and results; :func:`predict_part`
writes a part file and is not a scan.
"""

from __future__ import annotations

import copy
import functools
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.metrics import POSE_CELL_CAP, ErrorSums, capped_union
from ..core.excitation import Spread
from ..core.features import MonomialBasis, RegressorLayout
from ..core.normalization import Normalization
from ..core.ranges import RangeSums, column_extremes, span_of
from ..core.statistics import CHUNK_SAMPLES, StatisticsAccumulator, SufficientStatistics, sum_statistics
from ..runtime.errors import FtcalError
from ..runtime.executors import releases_gil
from ..runtime.threads import map_ranges, single_threaded_blas
from .table_chunks import TableChunk, iter_table_chunks, table_has_columns


# ---------------------------------------------------------------------------------------------- the scan
class Accumulator:
    """One quantity computed from a file's rows; a subclass says what it reads and how it adds up.

    An instance built by the caller is a recipe: :func:`scan` takes a fresh copy per file
    (:meth:`start`), feeds it the chunks (:meth:`add`, or :meth:`add_dataset` for a whole-file
    accumulator), then :meth:`finish` leaves only :attr:`value`. Finished accumulators of
    consecutive files merge with ``+``.

    Attributes
    ----------
    inputs, outputs : column names read (outputs None: none); accumulators of one scan read the same inputs
    labels : dict of label column -> role in messages ("group", "segment")
    whole_file : bool, take the file as one Dataset (``segment_by``, ``group_by``) instead of chunks
    small_products : bool, the work per chunk is small products: BLAS limited to one thread during the scan
    value : the result, once finished
    """

    inputs: tuple = ()
    outputs: tuple | None = None
    labels: dict = {}
    whole_file = False
    small_products = False
    segment_by: str | None = None
    group_by: str | None = None
    value = None

    def start(self, path: str) -> "Accumulator":
        """A fresh copy for one file, nothing added yet."""
        fresh = copy.copy(self)
        fresh.path = path
        fresh._begin()
        return fresh

    def _begin(self) -> None:
        """Set up the working state of one file (subclasses)."""

    def add(self, chunk: TableChunk) -> None:
        """Add the next chunk of rows."""
        raise NotImplementedError

    def add_dataset(self, data) -> None:
        """Add the whole file (whole-file accumulators)."""
        raise NotImplementedError

    def finish(self) -> "Accumulator":
        """Set :attr:`value` from the working state and drop that state; returns self."""
        self.value = self._finish()
        self._drop()
        return self

    def _finish(self):
        return self.value

    def _drop(self) -> None:
        """Forget what need not travel back from a worker with the value (subclasses)."""

    def __add__(self, other: "Accumulator") -> "Accumulator":
        merged = copy.copy(self)
        merged.value = self._merge(self.value, other.value)
        return merged

    @staticmethod
    def _merge(a, b):
        return a + b


def scan(path: str, accumulators: Sequence[Accumulator]) -> tuple[Accumulator, ...]:
    """Read one file once and feed every accumulator; the finished accumulators, in order.

    Parameters
    ----------
    path : CSV or Parquet file
    accumulators : recipes (not changed); chunked ones must read the same inputs

    Returns
    -------
    tuple of finished accumulators (their ``value``); the tuples of consecutive files add with :func:`add_scans`.

    Not marked :func:`~ftcal.runtime.executors.releases_gil`: the per-file functions below that are
    measured to gain from threads are, and keep their mark.
    """
    parts = [accumulator.start(path) for accumulator in accumulators]
    chunked = [a for a in parts if not a.whole_file]
    whole = [a for a in parts if a.whole_file]
    inputs = {a.inputs for a in chunked}
    if len(inputs) > 1:
        raise ValueError(f"one scan reads one set of inputs; got {sorted(inputs)}")
    with single_threaded_blas() if any(a.small_products for a in parts) else _nothing():
        datasets: dict = {}
        for accumulator in whole:
            key = (accumulator.inputs, accumulator.outputs, accumulator.segment_by, accumulator.group_by)
            if key not in datasets:
                from .tables import load_dataset

                datasets[key] = load_dataset([path], inputs=list(key[0]), outputs=key[1] and list(key[1]),
                                             segment_by=key[2], group_by=key[3])
            accumulator.add_dataset(datasets[key])
        if chunked:
            outputs = next((a.outputs for a in chunked if a.outputs is not None), None)
            labels = {column: role for a in chunked for column, role in a.labels.items()}
            data = next((d for (i, o, _, _), d in datasets.items() if i == next(iter(inputs))
                         and (outputs is None or o == outputs)), None)
            # Chunked accumulators beside whole-file ones take the file read already as one chunk.
            chunks = [TableChunk(0, data.inputs, data.outputs)] if data is not None and not labels else \
                iter_table_chunks(path, next(iter(inputs)), outputs, labels=labels)
            for chunk in chunks:
                for accumulator in chunked:
                    accumulator.add(chunk)
    return tuple(accumulator.finish() for accumulator in parts)


class _nothing:
    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return False


def add_scans(a: tuple, b: tuple) -> tuple:
    """Two files' :func:`scan` results, ``b``'s after ``a``'s (the combine of the tree reduction)."""
    return tuple(x + y for x, y in zip(a, b))


class Summary(Accumulator):
    """:class:`FileSummary`: ranges, segment lengths and fingerprints, group sizes, spreads (a fit's first pass).

    Parameters
    ----------
    inputs, outputs : column names
    segment_by : label column separating segments, or None (the file is one segment)
    group_by : group label column, checked (present, no empty cell) as a whole-table read does
    input_spread : whether to take the inputs' Spread (False: a static fit takes it from its statistics)
    """

    small_products = True  # the spreads' small products: no BLAS threads to wake per chunk

    def __init__(self, inputs: Sequence[str], outputs: Sequence[str], segment_by: str | None = None,
                 group_by: str | None = None, input_spread: bool = True):
        self.inputs, self.outputs = tuple(inputs), tuple(outputs)
        self.segment_by, self.group_by, self.input_spread = segment_by, group_by, input_spread
        self.labels = {column: role for column, role in ((group_by, "group"), (segment_by, "segment")) if column}

    def _begin(self) -> None:
        self._sums = _SummaryAccumulator(self.path, self.inputs, self.outputs, self.segment_by, self.group_by,
                                         self.input_spread)

    def add(self, chunk: TableChunk) -> None:
        self._sums.add(chunk)

    def _finish(self) -> "FileSummary":
        return self._sums.result()

    def _drop(self) -> None:
        del self._sums


class Statistics(Accumulator):
    """Sufficient statistics of one layout in the basis ``in_norm``/``out_norm``: a list, in row order.

    Static layouts take the file chunk by chunk (one entry). ARX layouts take it whole and give
    one entry per segment (lags stay inside a segment), so that the lists of all files, concatenated
    by ``+`` and summed left to right, add in exactly the order of the in-memory fit: ARX normal
    equations are often ill-conditioned enough (κ² ~ 1e7) that another order shows in the 10th digit.
    """

    def __init__(self, layout: RegressorLayout, in_norm: Normalization, out_norm: Normalization | None,
                 inputs: Sequence[str], outputs: Sequence[str], segment_by: str | None = None):
        self.layout, self.in_norm, self.out_norm = layout, in_norm, out_norm
        self.inputs, self.outputs, self.segment_by = tuple(inputs), tuple(outputs), segment_by
        self.whole_file = not layout.is_static

    def _begin(self) -> None:
        if self.layout.is_static:
            self._total = StatisticsAccumulator(RegressorLayout(self.layout.basis, len(self.outputs)), self.in_norm)

    def add(self, chunk: TableChunk) -> None:
        self._total.add(chunk.inputs, chunk.outputs)

    def add_dataset(self, data) -> None:
        self.value = segment_statistics(data, self.layout, self.in_norm, self.out_norm)

    def _finish(self) -> list:
        return [self._total.statistics()] if self.layout.is_static else self.value

    def _drop(self) -> None:
        self.__dict__.pop("_total", None)


class GroupStatistics(Accumulator):
    """Sufficient statistics of a static model per group label (or per fold): dict label -> statistics.

    Parameters
    ----------
    basis, normalization, inputs, outputs : as :class:`Statistics`
    group_by : group label column, or None (the whole file is the group named by its path)
    fold_of : dict of group label -> fold, optional
        Accumulate per fold instead of per group: memory per task is then one p × p
        Gram per fold, not per group (60 load cases at degree 5 over 8 inputs is 0.8 GB).
    """

    def __init__(self, basis: MonomialBasis, normalization: Normalization, inputs: Sequence[str],
                 outputs: Sequence[str], group_by: str | None = None, fold_of: dict[str, int] | None = None):
        self.layout, self.normalization = RegressorLayout(basis, len(outputs)), normalization
        self.inputs, self.outputs, self.group_by, self.fold_of = tuple(inputs), tuple(outputs), group_by, fold_of
        self.labels = {group_by: "group"} if group_by else {}

    def _begin(self) -> None:
        self._totals: dict = {}

    def add(self, chunk: TableChunk) -> None:
        rows = _group_rows(self.path, chunk, self.group_by)
        if self.fold_of is not None:  # one selection per fold: the union of its groups' rows
            fold_of, folds = self.fold_of, {}
            for label, selection in rows.items():
                mask = np.zeros(chunk.n_rows, dtype=bool)
                mask[selection] = True
                folds[fold_of[label]] = folds[fold_of[label]] | mask if fold_of[label] in folds else mask
            rows = folds
        for label, selection in rows.items():
            if label not in self._totals:
                self._totals[label] = StatisticsAccumulator(self.layout, self.normalization)
            self._totals[label].add(chunk.inputs[selection], chunk.outputs[selection])

    def _finish(self) -> dict:
        return {label: total.statistics() for label, total in self._totals.items()}

    def _drop(self) -> None:
        del self._totals

    @staticmethod
    def _merge(a, b):
        return add_group_statistics(a, b)


class FoldStatistics(Accumulator):
    """Per cross-validation fold, the per-segment statistics of an ARX layout (the file whole).

    A fold's rows are those of its groups (``fold_of``: group label -> fold), taken as
    :meth:`ftcal.core.dataset.Dataset.subset` takes them in memory, so that the lists of all files
    concatenated and summed give the in-memory fold statistics in the same order. Value: a list of
    ``n_folds`` lists of SufficientStatistics (empty for a fold without rows here).
    """

    whole_file = True

    def __init__(self, layout: RegressorLayout, in_norm: Normalization, out_norm: Normalization,
                 inputs: Sequence[str], outputs: Sequence[str], fold_of: dict[str, int], n_folds: int,
                 segment_by: str | None = None, group_by: str | None = None):
        self.layout, self.in_norm, self.out_norm = layout, in_norm, out_norm
        self.inputs, self.outputs, self.fold_of, self.n_folds = tuple(inputs), tuple(outputs), fold_of, n_folds
        self.segment_by, self.group_by = segment_by, group_by

    def add_dataset(self, data) -> None:
        sample_fold = np.array([self.fold_of[g] for g in np.asarray(data.groups, dtype=str)])
        self.value = [segment_statistics(data.subset(sample_fold == f), self.layout, self.in_norm, self.out_norm)
                      if np.any(sample_fold == f) else [] for f in range(self.n_folds)]

    @staticmethod
    def _merge(a, b):
        return add_fold_parts(a, b)


class PoseCells(Accumulator):
    """The cells of the pose grid over ``input_range`` that the rows occupy (:func:`ftcal.core.select.pose_cells`,
    at most ``POSE_CELL_CAP``): a frozenset, for ``fit``'s saturation warning."""

    small_products = True

    def __init__(self, inputs: Sequence[str], input_range: np.ndarray):
        self.inputs, self.input_range = tuple(inputs), input_range

    def _begin(self) -> None:
        self._cells: set = set()

    def add(self, chunk: TableChunk) -> None:
        from ..core.select import pose_cells

        if len(self._cells) < POSE_CELL_CAP:
            self._cells |= pose_cells(chunk.inputs, self.input_range)

    def _finish(self) -> frozenset:
        return frozenset(self._cells)

    def _drop(self) -> None:
        del self._cells

    _merge = staticmethod(capped_union)


class InputSpread(Accumulator):
    """The :class:`~ftcal.core.excitation.Spread` of the inputs (a static fit whose statistics cannot give it
    to 1e-10, :func:`ftcal.core.statistics.input_spread`)."""

    small_products = True

    def __init__(self, inputs: Sequence[str]):
        self.inputs = tuple(inputs)

    def _begin(self) -> None:
        self.value = Spread.of(np.zeros((0, len(self.inputs))))

    def add(self, chunk: TableChunk) -> None:
        self.value = self.value + Spread.of(chunk.inputs)


class Errors(Accumulator):
    """:class:`ErrorSums` of ``model`` on rows with reference outputs (``evaluate``, ``fit``'s training metrics).

    Static models take the file chunk by chunk. ARX models take it whole and give a pair: the sums
    for ``mode`` and for the other prediction mode, without the first max(na, nb) rows of each
    segment when ``warmup`` is ``"drop"`` (as :meth:`CalibrationModel.metrics`); None when no row
    is left. ``fingerprints`` (the model file's training segments) found whole inside the file are
    reported in ``training_segments``. Merged with :func:`add_error_sums`.
    """

    def __init__(self, model, fingerprints: Sequence[dict] = (), mode: str = "one-step", start: str = "zeros",
                 warmup: str = "drop", segment_by: str | None = None):
        self.model, self.fingerprints = model, list(fingerprints)
        self.mode, self.start_from, self.warmup, self.segment_by = mode, start, warmup, segment_by
        self.inputs, self.outputs = tuple(model.input_names_), tuple(model.output_names_)
        self.whole_file = not model.is_static

    def _begin(self) -> None:
        self._finder = SegmentFinder(self.fingerprints)

    def add(self, chunk: TableChunk) -> None:
        import warnings

        from ..runtime.errors import OutOfRangeWarning

        model = self.model

        def rows_sums(begin: int, end: int) -> ErrorSums:
            inputs, outputs = chunk.inputs[begin:end], chunk.outputs[begin:end]
            prediction = model.predict(inputs, warn_out_of_range=False)
            ranges = RangeSums.of(inputs, model.input_range_, outputs, prediction, model.output_names_,
                                  outside_span=span_of(model, inputs), loads=outputs,
                                  output_range=getattr(model, "output_range_", None))
            # outside the range or its span: CalibrationModel.metrics' n_out_of_range
            return ErrorSums.of(outputs, prediction, model.output_names_, ranges.n_out + ranges.n_span, ranges)

        # Overflowing predictions give inf/NaN metrics, which the command refuses in one line.
        with warnings.catch_warnings(), np.errstate(over="ignore", invalid="ignore"):
            warnings.simplefilter("ignore", OutOfRangeWarning)  # counted instead
            # Row ranges in parallel threads; their sums combine in row order.
            part = functools.reduce(add_error_sums, map_ranges(rows_sums, chunk.n_rows, CHUNK_SAMPLES))
        if self.fingerprints:
            self._finder.feed(np.concatenate([chunk.inputs, chunk.outputs], axis=1))
        self.value = part if self.value is None else self.value + part

    def add_dataset(self, data) -> None:
        model = self.model
        rows = np.ones(data.n_samples, dtype=bool)
        if self.warmup == "drop":
            for a, b in data.segment_bounds():
                rows[a:a + model.layout_.max_lag] = False
        if not rows.any():
            return
        self._finder.feed(np.concatenate([data.inputs, data.outputs], axis=1))
        n_out = int(model.out_of_range(data.inputs).sum())
        pair = []
        for which in (self.mode, "free-run" if self.mode == "one-step" else "one-step"):
            with np.errstate(over="ignore", invalid="ignore"):
                prediction = model.predict(data, mode=which, start=self.start_from, warn_out_of_range=False)
                ranges = RangeSums.of(data.inputs, model.input_range_, data.outputs, prediction, model.output_names_,
                                      scored=rows, outside_span=span_of(model, data.inputs), loads=data.outputs,
                                      output_range=getattr(model, "output_range_", None))
                pair.append(ErrorSums.of(data.outputs[rows], prediction[rows], model.output_names_, n_out, ranges))
        self.value = (pair[0], pair[1])

    def _finish(self):
        if self.value is not None:
            (self.value[0] if isinstance(self.value, tuple) else self.value).training_segments = \
                frozenset(self._finder.found)
        return self.value

    def _drop(self) -> None:
        self.model, self._finder = None, None  # the model stays with the caller: only the sums travel back

    @staticmethod
    def _merge(a, b):
        return add_error_sums(a, b)


# ---------------------------------------------------------------------------------------------- the passes
@releases_gil
def file_summary(path: str, inputs: Sequence[str], outputs: Sequence[str], segment_by: str | None = None,
                 group_by: str | None = None, input_spread: bool = True) -> FileSummary:
    """The :class:`FileSummary` of one file: a :func:`scan` with :class:`Summary`.

    Returns
    -------
    FileSummary, whose fingerprints equal those of the file read whole.
    """
    return scan(path, [Summary(inputs, outputs, segment_by, group_by, input_spread)])[0].value


@releases_gil
def file_statistics(path: str, basis: MonomialBasis, normalization: Normalization, inputs: Sequence[str],
                    outputs: Sequence[str]) -> SufficientStatistics:
    """Sufficient statistics of a static model over one file: a :func:`scan` with :class:`Statistics`.

    Parameters
    ----------
    path : CSV or Parquet file
    basis : the model's monomial basis (n_inputs = len(inputs))
    normalization : maps raw inputs to the basis's normalized inputs
    inputs, outputs : column names

    Returns
    -------
    SufficientStatistics with p = basis.n_terms features and len(outputs) targets.
    """
    layout = RegressorLayout(basis, len(outputs))
    return scan(path, [Statistics(layout, normalization, None, inputs, outputs)])[0].value[0]


def file_group_statistics(path: str, basis: MonomialBasis, normalization: Normalization, inputs: Sequence[str],
                          outputs: Sequence[str], group_by: str | None = None,
                          fold_of: dict[str, int] | None = None) -> dict:
    """:class:`GroupStatistics` of one file: dict of group label (str), or fold (int) with ``fold_of``,
    -> SufficientStatistics."""
    return scan(path, [GroupStatistics(basis, normalization, inputs, outputs, group_by, fold_of)])[0].value


def file_layout_statistics(path: str, layout: RegressorLayout, in_norm: Normalization, out_norm: Normalization,
                           inputs: Sequence[str], outputs: Sequence[str],
                           segment_by: str | None = None) -> list[SufficientStatistics]:
    """:class:`Statistics` of one file for any layout: a list in row order; lists of files concatenate with ``+``."""
    return scan(path, [Statistics(layout, in_norm, out_norm, inputs, outputs, segment_by)])[0].value


@releases_gil
def file_statistics_and_poses(path: str, basis: MonomialBasis, normalization: Normalization,
                              inputs: Sequence[str], outputs: Sequence[str],
                              input_range: np.ndarray) -> tuple[list[SufficientStatistics], frozenset]:
    """:func:`file_statistics` of a static model and its :class:`PoseCells`, in one scan, so that a static fit,
    whose training errors come from the statistics, needs no pass after this one.

    Returns
    -------
    ([SufficientStatistics], frozenset of cells); combine with :func:`add_statistics_and_poses`.
    """
    statistics, cells = scan(path, [Statistics(RegressorLayout(basis, len(outputs)), normalization, None, inputs,
                                               outputs), PoseCells(inputs, input_range)])
    return statistics.value, cells.value


@releases_gil
def file_summary_statistics_and_poses(path: str, inputs: Sequence[str], outputs: Sequence[str],
                                      segment_by: str | None, group_by: str | None, basis: MonomialBasis,
                                      normalization: Normalization, input_range: np.ndarray,
                                      input_spread: bool = True) -> tuple:
    """:func:`file_summary` and :func:`file_statistics_and_poses` in one scan of the file.

    For a fit whose normalization is known before the data are read (from the Parquet footers,
    :func:`ftcal.data.parquet_checks.footer_ranges`): the caller keeps the statistics only when
    the summary's ranges give the same normalization, and reads the files again otherwise. The
    chunks are those of the two passes, so the sums are the same to the last bit.

    Returns
    -------
    (FileSummary, ([SufficientStatistics], frozenset of cells)); combine with
    :func:`add_summary_statistics_and_poses`.
    """
    summary, statistics, cells = scan(path, [
        Summary(inputs, outputs, segment_by, group_by, input_spread),
        Statistics(RegressorLayout(basis, len(outputs)), normalization, None, inputs, outputs),
        PoseCells(inputs, input_range)])
    return summary.value, (statistics.value, cells.value)


def file_input_spread(path: str, inputs: Sequence[str]) -> Spread:
    """The :class:`InputSpread` of one file; combine with :func:`add_statistics`."""
    return scan(path, [InputSpread(inputs)])[0].value


def file_fold_statistics(path: str, layout: RegressorLayout, in_norm: Normalization, out_norm: Normalization,
                         inputs: Sequence[str], outputs: Sequence[str], fold_of: dict[str, int], n_folds: int,
                         segment_by: str | None = None, group_by: str | None = None) -> list[list]:
    """:class:`FoldStatistics` of one file; combine with :func:`add_fold_parts`."""
    return scan(path, [FoldStatistics(layout, in_norm, out_norm, inputs, outputs, fold_of, n_folds, segment_by,
                                      group_by)])[0].value


def file_error_sums(path: str, model, fingerprints: Sequence[dict] = (), mode: str = "one-step",
                    start: str = "zeros", warmup: str = "drop", segment_by: str | None = None,
                    count_poses: bool = False):
    """:class:`Errors` of ``model`` on one file with reference outputs (an :class:`ErrorSums`, or for ARX
    models a pair or None); with ``count_poses`` its :class:`PoseCells` too, in the same scan, in
    ``pose_cells`` (for ``fit``'s saturation warning, without another pass)."""
    wanted = [Errors(model, fingerprints, mode, start, warmup, segment_by)]
    if count_poses:
        wanted.append(PoseCells(model.input_names_, model.input_range_))
    errors, *cells = scan(path, wanted)
    sums = errors.value
    if sums is not None and (cells or model.is_static):
        (sums[0] if isinstance(sums, tuple) else sums).pose_cells = cells[0].value if cells else frozenset()
    return sums


# The combiners of the per-file functions above (tree-reduction tasks), each the ``+`` of its accumulator.
def add_statistics(a: SufficientStatistics, b: SufficientStatistics) -> SufficientStatistics:
    """``a + b`` as a plain function (a task for the tree reduction; also for lists and :class:`FileSummary`)."""
    return a + b


def add_group_statistics(a: dict[str, SufficientStatistics],
                         b: dict[str, SufficientStatistics]) -> dict[str, SufficientStatistics]:
    """Per-group statistics of two sets of files together (a task for the tree reduction)."""
    total = dict(a)
    for label, stats in b.items():
        total[label] = stats if label not in total else total[label] + stats
    return total


def add_fold_parts(a: list[list], b: list[list]) -> list[list]:
    """Per-fold lists of two sets of files, ``b``'s after ``a``'s (a task for the tree reduction)."""
    return [x + y for x, y in zip(a, b)]


def add_statistics_and_poses(a: tuple[list, frozenset], b: tuple[list, frozenset]) -> tuple[list, frozenset]:
    """Two files' :func:`file_statistics_and_poses`, ``b``'s after ``a``'s (the lists keep the row order)."""
    return a[0] + b[0], capped_union(a[1], b[1])


def add_summary_statistics_and_poses(a: tuple, b: tuple) -> tuple:
    """Two files' :func:`file_summary_statistics_and_poses`, ``b``'s after ``a``'s."""
    return a[0] + b[0], add_statistics_and_poses(a[1], b[1])


def add_error_sums(a, b):
    """``a + b`` as a plain function (a task for the tree reduction).

    Also adds the (mode, other mode) pairs of ARX models, and skips None (a
    file whose segments are all shorter than the ARX warm-up).
    """
    if a is None or b is None:
        return b if a is None else a
    if isinstance(a, tuple):
        return tuple(x + y for x, y in zip(a, b))
    return a + b


@dataclass
class FileSummary:
    """What the first pass of a streamed fit learns from consecutive files: ranges, sizes, fingerprints.

    Attributes
    ----------
    input_range, output_range : ndarray of shape (n_inputs, 2), (n_outputs, 2), min and max per column
    segment_lengths : list of int, samples per segment, in file order
    fingerprints : list of dict, :func:`ftcal.core.fingerprint.segment_fingerprints` of those segments
    group_sizes : dict of group label (str) -> samples (a file without group column is one group, its path)
    output_spread : Spread of the outputs (mean, covariance: the excitation check)
    input_spread : Spread of the inputs (the span check), or None when not taken (a static fit takes it from
        its statistics' moments, :func:`ftcal.core.statistics.input_spread`)
    group_output_ranges : dict of group label -> ndarray (n_outputs, 2), min and max of each output in
        the group (what grouped cross-validation's folds held out)
    """

    input_range: np.ndarray
    output_range: np.ndarray
    segment_lengths: list
    fingerprints: list
    group_sizes: dict
    output_spread: Spread | None = None
    input_spread: Spread | None = None
    group_output_ranges: dict | None = None

    def __add__(self, other: "FileSummary") -> "FileSummary":
        def widen(a, b):
            return np.c_[np.minimum(a[:, 0], b[:, 0]), np.maximum(a[:, 1], b[:, 1])]

        sizes = dict(self.group_sizes)
        for label, n in other.group_sizes.items():
            sizes[label] = sizes.get(label, 0) + n
        ranges = None
        if self.group_output_ranges is not None and other.group_output_ranges is not None:
            ranges = dict(self.group_output_ranges)
            for label, r in other.group_output_ranges.items():
                ranges[label] = r if label not in ranges else widen(ranges[label], r)

        def add(a, b):
            return None if a is None or b is None else a + b

        return FileSummary(widen(self.input_range, other.input_range), widen(self.output_range, other.output_range),
                           self.segment_lengths + other.segment_lengths, self.fingerprints + other.fingerprints,
                           sizes, add(self.output_spread, other.output_spread),
                           add(self.input_spread, other.input_spread), ranges)


class _SummaryAccumulator:
    """:func:`file_summary` of the chunks of one file, added in file order."""

    def __init__(self, path: str, inputs: Sequence[str], outputs: Sequence[str], segment_by: str | None,
                 group_by: str | None, input_spread: bool = True):
        self.path, self.n_inputs, self.segment_by, self.group_by = path, len(inputs), segment_by, group_by
        self.labels = {column: role for column, role in ((group_by, "group"), (segment_by, "segment")) if column}
        self.ranges = None
        self.output_spread = Spread.of(np.zeros((0, len(outputs))))
        self.input_spread = Spread.of(np.zeros((0, len(inputs)))) if input_spread else None
        self.lengths, self.fingerprints, self.sizes, self.group_ranges = [], [], {}, {}
        self.digest, self.last_label = None, None

    def add(self, chunk) -> None:
        import hashlib

        from ..core.fingerprint import row_hashes

        if chunk.n_rows == 0:  # an empty Parquet row group
            return
        path, group_by, segment_by = self.path, self.group_by, self.segment_by
        values = np.ascontiguousarray(np.concatenate([chunk.inputs, chunk.outputs], axis=1), dtype="<f8")
        for label, n in _group_counts(path, chunk, group_by).items():
            self.sizes[label] = self.sizes.get(label, 0) + n
        low, high = column_extremes(values)
        for label, rows in _group_rows(path, chunk, group_by).items():
            # without a group column the chunk is one group: its output extremes are the chunk's
            here = np.c_[low, high][self.n_inputs:] if group_by is None else np.c_[column_extremes(chunk.outputs[rows])]
            old = self.group_ranges.get(label)
            self.group_ranges[label] = here if old is None else np.c_[np.minimum(old[:, 0], here[:, 0]),
                                                                      np.maximum(old[:, 1], here[:, 1])]
        self.output_spread = self.output_spread + Spread.of(chunk.outputs)
        if self.input_spread is not None:
            self.input_spread = self.input_spread + Spread.of(chunk.inputs)
        ranges = self.ranges
        self.ranges = np.c_[low, high] if ranges is None else np.c_[np.minimum(ranges[:, 0], low),
                                                                    np.maximum(ranges[:, 1], high)]
        digest, lengths, fingerprints = self.digest, self.lengths, self.fingerprints
        if segment_by:
            label = chunk.labels[segment_by]
            starts = np.flatnonzero(np.r_[digest is None or label[0] != self.last_label, label[1:] != label[:-1]])
            self.last_label = label[-1]
        else:
            starts = np.array([0] if digest is None else [], dtype=np.intp)
        bounds = [*starts.tolist(), len(values)]
        if bounds[0] > 0:  # the segment open from the previous chunk continues
            digest.update(values[:bounds[0]])  # contiguous rows: hashed in place, no copy
            lengths[-1] += bounds[0]
        for begin, end in zip(bounds[:-1], bounds[1:]):
            if digest is not None:
                fingerprints[-1]["sha256"] = digest.hexdigest()
            digest = hashlib.sha256(values[begin:end])
            lengths.append(end - begin)
            fingerprints.append({"rows": 0, "first_row": f"{int(row_hashes(values[begin:begin + 1])[0]):016x}",
                                 "sha256": ""})
        self.digest = digest

    def result(self) -> FileSummary:
        self.fingerprints[-1]["sha256"] = self.digest.hexdigest()
        for fingerprint, rows in zip(self.fingerprints, self.lengths):
            fingerprint["rows"] = rows
        n_in, ranges = self.n_inputs, self.ranges
        return FileSummary(ranges[:n_in], ranges[n_in:], self.lengths, self.fingerprints, self.sizes,
                           self.output_spread, self.input_spread, self.group_ranges)


def _group_rows(path: str, chunk, group_by: str | None) -> dict:
    """Rows of ``chunk`` per group label (a slice for a whole chunk), labelled as :func:`_group_counts`."""
    if group_by is None:
        return {str(Path(path)): slice(None)}
    labels = chunk.labels[group_by].astype(str)
    return {label: labels == label for label in np.unique(labels).tolist()}


def _group_counts(path: str, chunk, group_by: str | None) -> dict[str, int]:
    """Rows of ``chunk`` per group label, labelled as :func:`ftcal.data.tables.load_dataset` does (str)."""
    if group_by is None:
        return {str(Path(path)): chunk.n_rows}
    labels, counts = np.unique(chunk.labels[group_by].astype(str), return_counts=True)
    return dict(zip(labels.tolist(), counts.tolist()))


class StreamedStatistics:
    """:class:`ftcal.core.select.GroupedStatistics` of files streamed by :func:`scan`.

    Each (degree, basis) the search asks for is one scan of the files with one accumulator
    (:class:`GroupStatistics` per fold, :class:`FoldStatistics` for ARX, :class:`Statistics`).

    Parameters
    ----------
    executor : LocalExecutor or DaskExecutor
    paths : the files
    inputs, outputs : column names
    summary : FileSummary of all the files (the first pass)
    group_by : group label column, or None (one group per file)
    segment_by : segment label column, or None (one segment per file); ARX lags stay inside segments
    """

    def __init__(self, executor, paths: Sequence[str], inputs: Sequence[str], outputs: Sequence[str],
                 summary: FileSummary, group_by: str | None, segment_by: str | None = None):
        self.executor = executor
        self.paths = list(paths)
        self.inputs, self.output_names = tuple(inputs), tuple(outputs)
        self.summary = summary
        self.group_by = group_by
        self.segment_by = segment_by

    def group_sizes(self) -> dict[str, int]:
        return dict(self.summary.group_sizes)

    def frame(self, model):
        return model.frame_from_ranges(self.summary.input_range, self.summary.output_range, self.inputs,
                                       self.output_names, self.summary.segment_lengths)

    def fold_statistics(self, frame, fold_of: dict[str, int], n_folds: int) -> list[SufficientStatistics]:
        description = f"statistics, degree {frame.layout.basis.degree}"
        if not frame.layout.is_static:
            wanted = FoldStatistics(frame.layout, frame.solve_input_normalization, frame.solve_output_normalization,
                                    self.inputs, self.output_names, fold_of, n_folds, self.segment_by,
                                    self.group_by)
            return [sum_statistics(parts) for parts in self._scan(wanted, description)]
        wanted = GroupStatistics(frame.layout.basis, frame.solve_input_normalization, self.inputs, self.output_names,
                                 self.group_by, fold_of)
        folds = self._scan(wanted, description)
        return [folds[f] for f in range(n_folds)]

    def full_statistics(self, frame) -> SufficientStatistics:
        wanted = Statistics(frame.layout, frame.solve_input_normalization, frame.solve_output_normalization,
                            self.inputs, self.output_names, self.segment_by)
        return sum_statistics(self._scan(wanted, "statistics"))

    def _scan(self, accumulator: Accumulator, description: str):
        """The value of one accumulator over all the files (a scan per file, merged in file order)."""
        task = scan if accumulator.whole_file else scan_chunks
        return self.executor.map_reduce(task, self.paths, [accumulator], combine=add_scans,
                                        description=description)[0].value


@releases_gil
def scan_chunks(path: str, accumulators: Sequence[Accumulator]) -> tuple:
    """:func:`scan` of accumulators that read chunks (static statistics): like the marked per-file functions,
    threads under ``local:N`` (grouped statistics, 2 files x 400k rows: 0.78-0.80x the sequential wall)."""
    return scan(path, accumulators)


def segment_statistics(data, layout: RegressorLayout, in_norm: Normalization,
                       out_norm: Normalization) -> list[SufficientStatistics]:
    """Statistics of an ARX layout per segment of ``data`` (a Dataset), in row order; lags stay inside segments.

    The accumulator's parts (:meth:`ftcal.core.statistics.StatisticsAccumulator.parts`): the
    in-memory fit (:func:`ftcal.core.statistics.dataset_statistics`) sums the same parts.
    """
    accumulator = StatisticsAccumulator(layout, in_norm, out_norm)
    accumulator.add(data.inputs, data.outputs, data.segment_bounds())
    return accumulator.parts()


class SegmentFinder:
    """:func:`ftcal.core.fingerprint.find_training_segments` over rows that arrive chunk by chunk.

    Every row whose hash matches a fingerprint's first row starts a sha256 of
    the following ``rows`` rows, carried across chunks.
    """

    def __init__(self, fingerprints: Sequence[dict]):
        self.fingerprints = list(fingerprints)
        self.heads = np.array([int(fp["first_row"], 16) for fp in self.fingerprints], dtype=np.uint64)
        self.found: set[int] = set()
        self._open: list[tuple[int, int, object]] = []  # (fingerprint, rows still to hash, sha256) across chunks

    def feed(self, values: np.ndarray) -> None:
        """Add the next rows, shape (m, n_inputs + n_outputs), inputs then outputs."""
        import hashlib

        from ..core.fingerprint import MAX_CANDIDATES, row_hashes

        if not self.fingerprints:
            return
        values = np.ascontiguousarray(values, dtype="<f8")
        hashes = row_hashes(values)
        # (fingerprint, first row in this chunk, rows still to hash, sha256): carried ones continue at row 0
        pending = [(index, 0, left, digest) for index, left, digest in self._open]
        for start in np.flatnonzero(np.isin(hashes, self.heads))[:MAX_CANDIDATES]:
            for index in np.flatnonzero(self.heads == hashes[start]):
                if int(index) not in self.found:
                    pending.append((int(index), int(start), int(self.fingerprints[index]["rows"]),
                                    hashlib.sha256()))
        self._open = []
        for index, begin, left, digest in pending:
            take = min(left, len(values) - begin)
            digest.update(values[begin:begin + take].tobytes())
            if left > take:
                self._open.append((index, left - take, digest))
            elif digest.hexdigest() == self.fingerprints[index]["sha256"]:
                self.found.add(index)


def predict_part(path: str, part: str, model, mode: str = "free-run", segment_by: str | None = None,
                 start: str = "zeros") -> tuple[int, int]:
    """Predict one file into the part file ``part`` (CSV or Parquet by suffix).

    Static models read the file chunk by chunk; ARX models (whose rows depend
    on the previous ones) read it whole, as one or more segments.

    Parameters
    ----------
    path : CSV or Parquet file with the model's inputs (and outputs for one-step ARX)
    part : the part file to write
    model : fitted CalibrationModel
    mode, segment_by, start : ARX prediction mode, segment column and free-run start (see ``ftcal predict``)

    Returns
    -------
    (n_rows, ranges) : int and :class:`~ftcal.core.ranges.RangeSums` (inputs outside the training range)

    Raises
    ------
    FtcalError
        A prediction overflows (inf or NaN): names the input file and row.
    """
    names = list(model.output_names_)
    n_rows, ranges = 0, None
    writer = None
    try:
        for first_row, inputs, prediction in _predictions(path, model, mode, segment_by, start):
            bad = ~np.isfinite(prediction).all(axis=1)
            if bad.any():
                raise FtcalError(f"{path}: the prediction of row {first_row + int(np.flatnonzero(bad)[0])} "
                                 "holds non-finite value(s) (inf or NaN); nothing written. Inputs far outside the "
                                 "training range can overflow a high-degree model.")
            import pyarrow as pa

            batch = pa.RecordBatch.from_arrays([pa.array(prediction[:, j]) for j in range(len(names))], names=names)
            writer = writer or _part_writer(part, batch.schema)
            writer.write(batch)
            n_rows += len(prediction)
            # The predicted loads where the model extrapolates (inputs outside the training range or span):
            # beyond the training loads there, the fit's cross-validated error does not apply. (Inside, a
            # prediction past the training loads is the model's own error, which the CV error does measure;
            # and not an ARX free run from zeros: its warm-up rows predict 0, which need not be a training load.)
            warm_zeros = not model.is_static and mode == "free-run" and start == "zeros"
            outside_span = span_of(model, inputs)
            block = RangeSums.of(inputs, model.input_range_, output_names=model.output_names_,
                                 outside_span=outside_span, loads=None if warm_zeros else prediction,
                                 output_range=getattr(model, "output_range_", None),
                                 load_rows=model.out_of_range(inputs))
            ranges = block if ranges is None else ranges + block
    finally:
        if writer is not None:
            writer.close()
    return n_rows, ranges


def _predictions(path: str, model, mode: str, segment_by: str | None, start: str):
    """(first row, inputs, predictions) per chunk of a static model, or once for the whole file (ARX)."""
    with np.errstate(over="ignore", invalid="ignore"):  # overflow is refused by the caller, in one line
        if model.is_static:
            for chunk in iter_table_chunks(path, model.input_names_):
                yield chunk.first_row, chunk.inputs, model.predict(chunk.inputs, warn_out_of_range=False)
            return
        from .tables import load_dataset

        # Measured outputs: one-step needs them; a "measured" free-run start uses them when the file has them.
        wants_outputs = mode == "one-step" or (start == "measured" and table_has_columns(path, model.output_names_))
        data = load_dataset([path], inputs=model.input_names_,
                            outputs=model.output_names_ if wants_outputs else None, segment_by=segment_by)
        yield 0, data.inputs, model.predict(data, mode=mode, start=start, warn_out_of_range=False)


def _part_writer(part: str, schema):
    if part.endswith(".csv"):
        import pyarrow.csv as pv

        return pv.CSVWriter(part, schema)
    import pyarrow.parquet as pq

    from .tables import parquet_write_options

    return pq.ParquetWriter(part, schema, **parquet_write_options(schema))


def join_parts(parts: Sequence[str], target: Path) -> None:
    """Concatenate part files, in order, into ``target`` (same format), one chunk in memory at a time."""
    from ..runtime.atomic import atomic_path

    with atomic_path(target) as tmp:
        if target.suffix.lower() == ".csv":
            with open(tmp, "wb") as out:
                for index, part in enumerate(parts):
                    with open(part, "rb") as source:
                        header = source.readline()
                        if index == 0:
                            out.write(header)
                        while block := source.read(1 << 20):
                            out.write(block)
            return
        import pyarrow.parquet as pq

        from .tables import parquet_write_options

        writer = None
        try:
            for part in parts:
                with pq.ParquetFile(part, page_checksum_verification=True) as parquet:
                    for batch in parquet.iter_batches():
                        writer = writer or pq.ParquetWriter(os.fspath(tmp), batch.schema,
                                                            **parquet_write_options(batch.schema))
                        writer.write_batch(batch)
        finally:
            if writer is not None:
                writer.close()

