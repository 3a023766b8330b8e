"""The MLP family against a degree-4 polynomial on the same grouped data: fit time, predict time, held-out error.

Data: :func:`benchmarks.load_cases.make_load_cases` (8 strain channels, 60 load cases, a mildly
nonlinear inverse map). The last 12 load cases are held out; both models train on the
other 48 and are scored on the held-out ones (force error-norm RMSE, N). The MLP fit
includes its early stopping on 5 grouped folds (six L-BFGS runs); the polynomial is
least squares. Prediction is timed on all ``n`` samples, one thread for both.
"""

from __future__ import annotations

import time


def mlp_vs_polynomial(n: int, hidden: str = "32,32", max_iter: int = 400, degree: int = 4) -> dict:
    import numpy as np

    from benchmarks.load_cases import make_load_cases
    from ftcal.core.dataset import Dataset
    from ftcal.core.metrics import error_norm_rmse
    from ftcal.core.mlp import MLPModel
    from ftcal.core.model import CalibrationModel
    from ftcal.runtime.threads import single_threaded_blas

    u, y, groups = make_load_cases(n)
    held = np.isin(groups, np.unique(groups)[-12:])
    names = tuple(f"s{i}" for i in range(u.shape[1]))
    train = Dataset.from_arrays(u[~held], y[~held], input_names=names, groups=groups[~held])
    result = {"n": n, "n_train": int((~held).sum()), "hidden": hidden, "degree": degree}
    models = {}
    for key, make in (("mlp", lambda: MLPModel(tuple(int(h) for h in hidden.split(",")), max_iter=max_iter)),
                      ("polynomial", lambda: CalibrationModel(degree))):
        start, cpu = time.perf_counter(), time.process_time()
        models[key] = make().fit(train)
        result[f"{key}_fit_s"] = time.perf_counter() - start
        result[f"{key}_fit_cpu_s"] = time.process_time() - cpu  # all threads: what a loaded machine cannot inflate
    for key, model in models.items():
        with single_threaded_blas():
            model.predict(u[:1000], warn_out_of_range=False)  # warm-up
            start = time.perf_counter()
            model.predict(u, warn_out_of_range=False)
            result[f"{key}_predict_samples_per_s"] = n / (time.perf_counter() - start)
        prediction = model.predict(u[held], warn_out_of_range=False)
        result[f"{key}_held_out_force_error_norm_rmse"] = error_norm_rmse(y[held, :3], prediction[:, :3])
    result["mlp_iterations"] = models["mlp"].n_iter_
    result["mlp_weights"] = models["mlp"].describe()["n_coefficients"]
    result["seconds"] = result["mlp_fit_s"]
    return result


CASES = {"mlp_vs_polynomial": mlp_vs_polynomial}
