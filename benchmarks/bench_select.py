"""Which ``--select-per`` wins on load cases the selection never saw (held out before the search).

``python -m benchmarks.bench_select [N]``: the 8-channel load-case sensor of
:func:`benchmarks.load_cases.make_load_cases` with 90 load cases; the search runs on 60 of them
(grouped 5-fold CV inside), and each mode's refitted selection is scored on the other 30, force
(N) and torque (N·m) error-norm RMSE, beside the affine model. Prints one JSON line per mode.
"""

from __future__ import annotations

import json
import sys
import time
import warnings

import numpy as np

from benchmarks.load_cases import make_load_cases


def main(n: int = 30_000) -> None:
    from ftcal.core.dataset import Dataset
    from ftcal.core.model import CalibrationModel
    from ftcal.core.select import fit_best, select_model

    warnings.simplefilter("ignore")
    u, y, groups = make_load_cases(n, n_groups=90)
    names = [f"s{i + 1}" for i in range(u.shape[1])]
    held = np.isin(groups, [f"case{g:02d}" for g in range(60, 90)])
    train = Dataset.from_arrays(u[~held], y[~held], input_names=names, groups=groups[~held])
    test = Dataset.from_arrays(u[held], y[held], input_names=names, groups=groups[held])

    def scores(model):
        p = model.predict(test, warn_out_of_range=False)
        return {"force_N": float(np.sqrt(np.mean(np.sum((test.outputs[:, :3] - p[:, :3]) ** 2, axis=1)))),
                "torque_Nm": float(np.sqrt(np.mean(np.sum((test.outputs[:, 3:] - p[:, 3:]) ** 2, axis=1))))}

    print(json.dumps({"mode": "affine", **scores(CalibrationModel(1).fit(train))}), flush=True)
    for mode in ("output", "block", "model"):
        start = time.process_time()
        result = select_model(train, degrees=(1, 2, 3, 4), select_per=mode)
        model = fit_best(train, result)
        print(json.dumps({"mode": mode, **scores(model), "selection": result.describe_selection(),
                          "cpu_seconds": round(time.process_time() - start, 1)}), flush=True)


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:]))
