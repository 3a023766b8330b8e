"""Widest grouped jackknife: each standard error the largest over coarser partitions, hand-computed."""

import numpy as np
from scipy import stats

from ftcal.core.jackknife import merged_partitions, widest_covariance


def cr3(refits):
    """(G − 1)/G Σ (θ₋b − θ̄)² times (t_{G−1, .975} / z_{.975})², written out with SciPy's quantiles."""
    refits = np.asarray(refits, dtype=float)
    g = len(refits)
    scale = (stats.t.ppf(0.975, g - 1) / stats.norm.ppf(0.975)) ** 2
    return scale * (g - 1) / g * np.sum((refits - refits.mean(axis=0)) ** 2, axis=0)


def test_each_error_is_the_largest_of_the_partitions_and_the_finest_correlations_stay():
    rng = np.random.default_rng(3)
    fine = rng.normal(size=(20, 2)) @ np.array([[1.0, 0.6], [0.0, 0.8]])
    coarse = rng.normal(size=(5, 2)) * np.array([3.0, 0.1])  # wider on the first parameter only
    widened = widest_covariance([list(fine), list(coarse)])
    se = np.sqrt(np.diag(widened.covariance))
    np.testing.assert_allclose(se, np.sqrt(np.maximum(cr3(fine), cr3(coarse))), rtol=1e-10)
    finest = np.cov(fine.T)
    np.testing.assert_allclose(widened.covariance[0, 1] / se[0] / se[1],
                               finest[0, 1] / np.sqrt(finest[0, 0] * finest[1, 1]), rtol=1e-10)
    np.testing.assert_allclose(widened.ratio, np.sqrt(cr3(coarse) / cr3(fine)), rtol=1e-10)
    assert widened.blocks == (20, 5)


def test_partitions_are_contiguous_runs_of_at_least_three():
    assert [e.tolist() for e in merged_partitions(12, (6, 4, 2))] == [[0, 2, 4, 6, 8, 10, 12], [0, 3, 6, 9, 12]]
    assert merged_partitions(4, (10, 5)) == []  # no partition coarser than 4 blocks with 3 or more runs
    assert widest_covariance([]) is None and widest_covariance([[np.zeros(2)]]) is None
