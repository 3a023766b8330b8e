"""The MLP's grouped cross-validation judges every block it writes (issue 44): force and torque fold
scores at the iteration count the *other* folds chose, so a fold never scores the count it picked.

Truth: the per-output mean squared errors the search stores, recombined by hand (√Σ over a block): each
block's score and the force score the guard compares come from the same held-out fits.
"""

import numpy as np

from ftcal.core.dataset import Dataset
from ftcal.core.mlp import MLPModel


def test_block_scores_are_taken_at_the_count_the_other_folds_chose():
    rng = np.random.default_rng(3)
    cases = rng.uniform(-1, 1, (12, 4))
    u = np.repeat(cases, 15, axis=0) + 0.02 * rng.standard_normal((180, 4))
    w = np.c_[u @ rng.normal(size=(4, 3)) * 10, np.tanh(u @ rng.normal(size=(4, 3)))]
    data = Dataset.from_arrays(u, w + 0.01 * rng.standard_normal(w.shape), input_names=("a", "b", "c", "d"),
                               output_names=("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"),
                               groups=np.repeat([f"c{g}" for g in range(12)], 15))
    cv = MLPModel((6,), max_iter=60, n_folds=4, check_every=10, seed=0).fit(data).cv_
    mse = np.asarray(cv["held_out_fold_mse"])
    assert mse.shape == (4, 6)
    np.testing.assert_allclose(cv["held_out_block_scores"]["force"], np.sqrt(mse[:, :3].sum(axis=1)), rtol=1e-12)
    np.testing.assert_allclose(cv["held_out_block_scores"]["torque"], np.sqrt(mse[:, 3:].sum(axis=1)), rtol=1e-12)
    # The force score of each fold is its force block at the count chosen without it.
    np.testing.assert_allclose(cv["held_out_fold_scores"], cv["held_out_block_scores"]["force"], rtol=1e-12)
    assert len(cv["fold_scores"]) == 4 and cv["iterations"] in cv["checkpoints"]
