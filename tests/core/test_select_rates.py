"""Both error rates of the default selection (``--degree auto``, per block) on simulated sensors with a
known truth: a richer model chosen when the truth is affine, and the share of the oracle degree's
held-out gain kept when the sensor is nonlinear at the paper's level.

Truth: :func:`benchmarks.load_cases.make_paper_sensor` (40 load cases of 30 samples, a reference
mis-measured by a constant per load case); the gain is measured on 100 new load cases of the same kind
against least squares of every degree fitted on the same data. Seeds here are not the benchmark's
(``make bench`` reports more seed sets, BENCHMARKS.md).
"""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.bench_select_rates import one_seed, rates

SEEDS = range(100, 108)
DEGREES = (1, 2, 3, 4)  # the default grid to degree 4 (degree 5 only costs time here: it never wins)


def test_an_affine_truth_keeps_the_affine_model():
    summary = rates([one_seed(s, 0.0, degrees=DEGREES) for s in SEEDS])
    assert summary["richer"] <= 0.05, summary
    assert max(summary["worst_vs_affine"]) <= 1.02, summary
    low, median, high = summary["cv_over_held_out"]
    assert 0.6 <= median <= 1.2 and 0.5 <= low and high <= 1.5, summary


def test_a_paper_level_nonlinearity_keeps_most_of_the_oracle_gain():
    summary = rates([one_seed(s, 1.0, degrees=DEGREES) for s in SEEDS])
    # The paper's degree-4 gain on force was 54 % (4.58 N -> 2.09 N); the simulation is at that level.
    assert all(0.3 <= g <= 0.7 for g in summary["oracle_gain"]), summary
    # Both blocks keep nine tenths of the oracle's gain (issue 44's target). The rule before (t test at 5 %,
    # ties within one standard error to fewer nonzeros), judging the same folds, kept about four fifths on
    # force: one seed in eight kept affine on folds that disagree (a fold of edge load cases).
    force, torque = summary["gain_share"]
    assert torque >= 0.9 and force >= 0.9, summary
    assert force > summary["previous_gain_share"][0] + 0.05, summary
    assert torque >= summary["previous_gain_share"][1] - 0.02, summary
    low, median, high = summary["cv_over_held_out"]
    assert 0.6 <= median <= 1.2 and 0.5 <= low and high <= 2.0, summary


@pytest.mark.slow
def test_per_output_selection_on_few_load_cases_rarely_leaves_an_affine_truth():
    # 12 load cases in 4 folds, six outputs each judged alone: a richer model on some output in 4 of seeds 0-19
    # before an output had to pass its block's test first (BENCHMARKS.md); 1 of 20 now.
    rows = [one_seed(s, 0.0, degrees=DEGREES, n_groups=12, select_per="output", n_folds=4) for s in range(20)]
    assert sum(r["richer"] for r in rows) <= 1, [r["selection"] for r in rows if r["richer"]]


@pytest.mark.slow
def test_few_load_cases_a_fold_are_judged_by_the_t_test_over_the_degrees():
    # 12 load cases in 5 folds (2-3 a fold), affine truth: the one-standard-error rule would let through a best
    # candidate whose fold log ratio is heavy-tailed (4.7 standard errors in one seed of 40); there the t test
    # with the degrees searched as a Bonferroni factor judges, and chooses a richer model less often than the
    # t test alone did (BENCHMARKS.md: 10 % against 20 % on seeds 0-19).
    rows = [one_seed(s, 0.0, degrees=DEGREES, n_groups=12) for s in range(20)]
    now, before = sum(r["richer"] for r in rows), sum(r["previous_richer"] for r in rows)
    assert now <= 2 and now < before, [(r["selection"], r["previous_richer"]) for r in rows]


@pytest.mark.slow
def test_nested_cross_validation_on_few_load_cases_a_fold_keeps_an_affine_truth_and_most_of_a_real_gain():
    # 12 load cases in 5 folds (2-3 a fold): the best candidate's own test let a richer model through on an
    # affine truth in 4 of 58 seeds (0-57, BENCHMARKS.md); the selection procedure must now also beat affine on
    # the outer folds it never saw. Seeds 200-239, not the benchmark's: issue 44's bar (<= 5 %, 2 of 40 seeds),
    # and no more often than the same folds judged without the nested test.
    rows = [one_seed(s, 0.0, degrees=DEGREES, n_groups=12) for s in range(200, 240)]
    assert all(r["nested"] for r in rows)
    now, flat = sum(r["richer"] for r in rows), sum(r["flat_richer"] for r in rows)
    assert now <= 2 and now <= flat, [(r["seed"], r["selection"]) for r in rows if r["richer"]]
    # A paper-level nonlinearity: the nested test costs little of the gain the rule before it kept on the same
    # folds (offline, seeds 0-42: force 54 % -> 47 % of the oracle's, torque 68 % -> 68 %).
    # Each block anchored at the whole model's choice (scoring.anchored_choice) keeps more of it than each block
    # chosen alone on the same folds (offline, these seeds: force 97 % against 86 %, torque 90 % against 73 %).
    summary = rates([one_seed(s, 1.0, degrees=DEGREES, n_groups=12) for s in range(200, 220)])
    for block in (0, 1):
        assert summary["gain_share"][block] >= 0.75 * summary["flat_gain_share"][block], summary
        assert summary["gain_share"][block] > 0.2, summary
        assert summary["gain_share"][block] > summary["alone_gain_share"][block] + 0.05, summary
