"""Grouped folds (whole load cases or recordings) and the per-fold statistics cross-validation needs.

A :class:`GroupedStatistics` gives the statistics of each fold; :class:`DatasetStatistics`
is the one of a :class:`~ftcal.core.dataset.Dataset` in memory, and
:class:`ftcal.data.streaming.StreamedStatistics` the one of streamed files. Both go through
the same accumulator (:class:`ftcal.core.statistics.StatisticsAccumulator`).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from ...runtime.checks import check_int
from ...runtime.errors import ParameterError
from ...runtime.progress import progress_bar
from ..dataset import Dataset
from ..model import CalibrationModel, FitFrame
from ..statistics import SufficientStatistics


def grouped_folds(groups: np.ndarray, n_folds: int = 5, seed: int = 0) -> list[np.ndarray]:
    """Validation masks: each fold is a set of whole groups, folds balanced by sample count.

    Parameters
    ----------
    groups : ndarray of shape (n_samples,)
        Group label per sample (load case or recording).
    n_folds : int >= 2
        At most the number of groups.
    seed : int
        Order among groups of equal size.

    Returns
    -------
    list of ndarray of bool, shape (n_samples,)
        One validation mask per fold; every sample is in exactly one.

    Examples
    --------
    >>> folds = grouped_folds(np.array(["a", "a", "b", "c"]), n_folds=2)
    >>> sorted(int(m.sum()) for m in folds)
    [2, 2]
    """
    labels, counts = np.unique(np.asarray(groups, dtype=str), return_counts=True)
    group_fold = fold_of_groups(dict(zip(labels, counts)), n_folds, seed)
    sample_fold = np.array([group_fold[g] for g in np.asarray(groups, dtype=str)])
    return [sample_fold == f for f in range(max(group_fold.values()) + 1)]


def fold_of_groups(sizes: dict[str, int], n_folds: int = 5, seed: int = 0) -> dict[str, int]:
    """The fold of each group, from the groups' sample counts alone (see :func:`grouped_folds`).

    Parameters
    ----------
    sizes : dict of group label (str) -> number of samples
    n_folds, seed : int

    Returns
    -------
    dict of group label -> fold index in 0 .. min(n_folds, number of groups) - 1
    """
    labels = np.array(sorted(sizes), dtype=str)
    counts = np.array([sizes[g] for g in labels])
    if labels.size < 2:
        raise ParameterError("group_by", "Cross-validation needs at least 2 groups (recordings or load cases); "
                               "the data has 1. Pass more files or name a group column with {group_by}.")
    n_folds = check_int(n_folds, "n_folds", "cross_validate", 2)
    n_folds = min(n_folds, labels.size)
    order = np.random.default_rng(seed).permutation(labels.size)
    # Largest groups first, each to the currently lightest fold.
    order = order[np.argsort(-counts[order], kind="stable")]
    load = np.zeros(n_folds)
    fold_of = np.empty(labels.size, dtype=np.int64)
    for g in order:
        f = int(np.argmin(load))
        fold_of[g] = f
        load[f] += counts[g]
    return {str(g): int(f) for g, f in zip(labels, fold_of)}


class GroupedStatistics(Protocol):
    """What cross-validation needs of the data; :class:`DatasetStatistics` for a :class:`Dataset` in memory,
    :class:`ftcal.data.streaming.StreamedStatistics` for files streamed by per-file tasks."""

    output_names: tuple[str, ...]

    def group_sizes(self) -> dict[str, int]:
        """Samples per group label (as str)."""

    def frame(self, model: CalibrationModel) -> FitFrame:
        """``model``'s fit frame over all the data."""

    def fold_statistics(self, frame: FitFrame, fold_of: dict[str, int], n_folds: int) -> list[SufficientStatistics]:
        """Statistics of each fold (the sum of its groups'), for ``frame``'s layout in its solve basis."""

    def full_statistics(self, frame: FitFrame) -> SufficientStatistics:
        """Statistics of all the data for ``frame``'s layout in its solve basis (the refit of ARX selections)."""


class DatasetStatistics:
    """:class:`GroupedStatistics` of a :class:`Dataset` in memory."""

    def __init__(self, data: Dataset):
        self.data = data
        self.output_names = tuple(data.output_names)

    def group_sizes(self) -> dict[str, int]:
        labels, counts = np.unique(np.asarray(self.data.groups, dtype=str), return_counts=True)
        return dict(zip(labels.tolist(), counts.tolist()))

    def frame(self, model: CalibrationModel) -> FitFrame:
        return model.frame(self.data)

    def fold_statistics(self, frame: FitFrame, fold_of: dict[str, int], n_folds: int) -> list[SufficientStatistics]:
        sample_fold = np.array([fold_of[g] for g in np.asarray(self.data.groups, dtype=str)])
        parts = []
        with progress_bar(f"statistics, degree {frame.layout.basis.degree}", n_folds) as advance:
            for f in range(n_folds):
                parts.append(CalibrationModel.statistics(
                    self.data.subset(sample_fold == f), frame.layout, frame.solve_input_normalization,
                    frame.solve_output_normalization))
                advance(1)
        return parts

    def full_statistics(self, frame: FitFrame) -> SufficientStatistics:
        return CalibrationModel.statistics(self.data, frame.layout, frame.solve_input_normalization,
                                           frame.solve_output_normalization)
