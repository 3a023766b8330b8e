"""CalibrationModel: normalizations, range checks, ARX recursion and segments, input validation."""

import warnings

import numpy as np
import pytest

from ftcal.core.dataset import Dataset, concatenate
from ftcal.core.model import CalibrationModel, model_from_fitted
from ftcal.runtime.errors import FtcalError, IllPosedFitWarning, NotFittedError, OutOfRangeWarning


def _signed(make_sensor_data, rng, n, n_channels=3):
    u, y = make_sensor_data(rng, n, n_channels=n_channels)
    return u - np.r_[np.full(n_channels, 5000.0), 0.0], y


# ------------------------------------------------------------------ normalization
@pytest.mark.parametrize("degree", [1, 2, 3])
@pytest.mark.parametrize("offset", [0.0, 5000.0])
def test_maxabs_and_center_give_the_same_least_squares_predictions(rng, make_sensor_data, degree, offset):
    u, y = _signed(make_sensor_data, rng, 800)
    u = u + np.r_[np.full(3, offset), 0.0]
    data = Dataset.from_arrays(u, y)
    center = CalibrationModel(degree, normalization="center").fit(data)
    maxabs = CalibrationModel(degree, normalization="maxabs").fit(data)
    u_val = u[:200] * 0.999 + u.mean(axis=0) * 0.001  # stays inside the training box
    np.testing.assert_allclose(maxabs.predict(u_val), center.predict(u_val),
                               rtol=0, atol=1e-6 * np.abs(y).max())


def test_maxabs_on_large_offsets_is_either_accurate_or_warns(rng, make_sensor_data, ref_features):
    # Degree 4 of ADC counts ~5000 scaled by max |u| is badly conditioned; ftcal may lose accuracy
    # there, but only with an IllPosedFitWarning, never silently.
    u, y = make_sensor_data(rng, 1200, n_channels=3)
    mean, std = u.mean(axis=0), u.std(axis=0)
    a = ref_features((u - mean) / std, 4)
    expected = a @ np.linalg.lstsq(a, y, rcond=None)[0]
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        model = CalibrationModel(4, normalization="maxabs").fit(Dataset.from_arrays(u, y))
    warned = any(issubclass(w.category, IllPosedFitWarning) for w in record)
    accurate = np.allclose(model.predict(u), expected, rtol=0, atol=1e-6 * np.abs(y).max())
    assert warned or accurate


def test_least_squares_is_exact_in_the_paper_basis_at_degree_5(rng, make_sensor_data, ref_features):
    # ADC counts ~5000 scaled by max |u|: normal equations in that basis lost ~0.02 N before.
    # Least squares is now solved in the centred basis and mapped exactly into the stored maxabs one.
    u, y = make_sensor_data(rng, 3000, n_channels=3)
    mean, std = u.mean(axis=0), u.std(axis=0)
    a = ref_features((u - mean) / std, 5)
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)  # numpy: SVD of the well-conditioned dense regressor
    model = CalibrationModel(5, normalization="maxabs").fit(Dataset.from_arrays(u, y))
    assert model.normalization_ == "maxabs" and not model.input_normalization_.offset.any()
    np.testing.assert_allclose(model.predict(u), a @ coef, rtol=0, atol=1e-8 * np.abs(y).max())
    # The stored coefficients multiply raw monomials over max |u|, as the paper's would.
    paper = ref_features(u / np.abs(u).max(axis=0), 5) @ model.coef_
    np.testing.assert_allclose(paper, a @ coef, rtol=0, atol=1e-8 * np.abs(y).max())


def test_bad_normalization_and_mode_raise(rng):
    u = rng.uniform(-1, 1, size=(30, 2))
    data = Dataset.from_arrays(u, u @ [[1.0], [2.0]])
    with pytest.raises(FtcalError, match="'normalization' parameter"):
        CalibrationModel(1, normalization="zscore").fit(data)
    model = CalibrationModel(1).fit(data)
    with pytest.raises(FtcalError, match="'mode' parameter"):
        model.predict(u, mode="two-step")
    with pytest.raises(FtcalError, match="'degree' parameter of CalibrationModel"):
        CalibrationModel(0).fit(data)


# -------------------------------------------------------------------- range checks
def test_out_of_range_counts_samples_outside_training_range(rng):
    u = np.c_[np.linspace(0.0, 10.0, 50), rng.uniform(-5.0, 5.0, 50)]
    u[[3, 9], 1] = [-5.0, 5.0]
    y = u @ [[1.0], [-1.0]] + 3.0
    model = CalibrationModel(1).fit(Dataset.from_arrays(u, y))
    test = np.array([[0.0, -5.0],    # both on the boundary: inside
                     [10.0, 5.0],    # inside
                     [10.5, 0.0],    # first input above
                     [5.0, -5.2],    # second input below
                     [-1.0, 6.0],    # both out: still one sample
                     [3.0, 1.0]])    # inside
    np.testing.assert_array_equal(model.out_of_range(test), [False, False, True, True, True, False])
    with pytest.warns(OutOfRangeWarning, match="3 of 6 samples"):
        prediction = model.predict(test)
    np.testing.assert_allclose(prediction, test @ [[1.0], [-1.0]] + 3.0, rtol=1e-12)
    score = model.metrics(Dataset.from_arrays(test, test @ [[1.0], [-1.0]] + 3.0), warn_out_of_range=False)
    assert score["n_out_of_range"] == 3


def test_inputs_inside_range_do_not_warn(rng):
    u = rng.uniform(-1, 1, size=(100, 2))
    model = CalibrationModel(2).fit(Dataset.from_arrays(u, u[:, :1] ** 2))
    model.predict(u)  # any warning fails the test (filterwarnings = error)
    assert not model.out_of_range(u).any()


# ------------------------------------------------------------------- fitted state
def test_unfitted_model_raises_and_has_no_fitted_attributes(rng):
    model = CalibrationModel(2)
    assert not hasattr(model, "coef_")
    with pytest.raises(NotFittedError):
        model.predict(np.zeros((3, 2)))
    with pytest.raises(NotFittedError):
        model.out_of_range(np.zeros((3, 2)))


def test_fit_returns_self_and_counts_coefficients(rng):
    u = rng.uniform(-1, 1, size=(200, 7))
    y = rng.normal(size=(200, 6))
    model = CalibrationModel(2)
    assert model.fit(Dataset.from_arrays(u, y)) is model
    assert model.n_coefficients == 216  # paper Table II, np = 2
    assert model.describe()["n_coefficients"] == 216
    assert model.coef_.shape == (36, 6)


def test_fit_without_outputs_raises(rng):
    with pytest.raises(FtcalError, match="reference outputs"):
        CalibrationModel(1).fit(Dataset.from_arrays(rng.uniform(size=(10, 2))))


def test_predict_selects_inputs_by_name(rng):
    u = rng.uniform(-1, 1, size=(200, 3))
    y = np.c_[u[:, 0] + 2 * u[:, 1] ** 2 - u[:, 2], u[:, 2]]
    model = CalibrationModel(2).fit(Dataset.from_arrays(u, y, input_names=["a", "b", "c"]))
    shuffled = Dataset.from_arrays(u[:, [2, 0, 1]], input_names=["c", "a", "b"])
    np.testing.assert_allclose(model.predict(shuffled), y, atol=1e-10)
    with pytest.raises(FtcalError, match="'b'"):
        model.predict(Dataset.from_arrays(u[:, :2], input_names=["a", "c"]))


def test_predict_on_many_samples_matches_reference(rng, ref_features):
    # More than 8 prediction chunks, which takes the two-thread path.
    u = rng.uniform(-1, 1, size=(400, 3))
    u[:2] = [[-1, -1, -1], [1, 1, 1]]
    true = rng.normal(size=(10, 2))
    model = CalibrationModel(2).fit(Dataset.from_arrays(u, ref_features(u, 2) @ true))
    big = rng.uniform(-1, 1, size=(6001, 3))
    np.testing.assert_allclose(model.predict(big), ref_features(big, 2) @ true, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("column, name", [(0, "u1"), (2, "T")])
def test_predict_on_nan_input_names_the_column(rng, column, name):
    u = rng.uniform(-1, 1, size=(50, 3))
    model = CalibrationModel(1).fit(Dataset.from_arrays(u, u[:, :1], input_names=["u1", "u2", "T"]))
    bad = u.copy()
    bad[7, column] = np.nan
    with pytest.raises(FtcalError, match=f"'{name}'"):
        model.predict(bad)
    # A Dataset built directly (bypassing from_arrays' checks) is rejected too.
    dataset = Dataset(bad, None, ("u1", "u2", "T"), (), np.zeros(50, dtype=int), np.zeros(50, dtype=int))
    with pytest.raises(FtcalError, match=f"'{name}'"):
        model.predict(dataset)


def test_model_from_fitted_reproduces_predictions(rng):
    u = rng.uniform(-1, 1, size=(150, 2))
    y = np.c_[u[:, 0] * u[:, 1], u[:, 1]]
    model = CalibrationModel(2, normalization="maxabs").fit(Dataset.from_arrays(u, y))
    rebuilt = model_from_fitted(
        degree=2, na=0, nb=0, normalization="maxabs", coef=model.coef_,
        input_normalization=model.input_normalization_, output_normalization=model.output_normalization_,
        input_names=model.input_names_, output_names=model.output_names_,
        input_range=model.input_range_, output_range=model.output_range_)
    np.testing.assert_allclose(rebuilt.predict(u), y, atol=1e-10)
    with pytest.raises(FtcalError, match="shape"):
        model_from_fitted(
            degree=3, na=0, nb=0, normalization="maxabs", coef=model.coef_,
            input_normalization=model.input_normalization_, output_normalization=model.output_normalization_,
            input_names=model.input_names_, output_names=model.output_names_,
            input_range=model.input_range_, output_range=model.output_range_)


# ------------------------------------------------------------------------------ ARX
A1 = np.array([[0.5, 0.1], [-0.2, 0.3]])   # y_i(k) gets A_j[i, l] · y_l(k − j)
A2 = np.array([[0.1, 0.0], [0.05, -0.1]])
B0 = np.array([[2.0, -1.0], [0.5, 1.0]])    # y_i(k) gets B_j[i, m] · u_m(k − j)
B1 = np.array([[0.3, 0.0], [-0.4, 0.2]])
C = np.array([1.5, -0.7])


def _simulate(u, y_init):
    """Run the true ARX(2, 1) system over one recording; y_init holds y(−2), y(−1) (u(−1) = u(0))."""
    y = np.empty((len(u), 2))
    history = list(y_init)
    for k in range(len(u)):
        u_prev = u[k - 1] if k else u[0]
        y[k] = A1 @ history[-1] + A2 @ history[-2] + B0 @ u[k] + B1 @ u_prev + C
        history.append(y[k])
    return y


def _hand_predict(u, y_measured, mode, initial=None, begin="measured"):
    """The documented ARX predictions: history before the segment start repeats sample 0.

    ``begin="zeros"`` is the paper's free-run: ŷ = 0 for k < max(na, nb) = 2, recursion from k = 2.
    """
    def at(seq, i):
        return seq[max(i, 0)]

    out = np.empty((len(u), 2))
    for k in range(len(u)):
        if mode == "free-run" and begin == "zeros" and k < 2:
            out[k] = 0.0
            continue
        if mode == "one-step":
            past = [at(y_measured, k - 1), at(y_measured, k - 2)]
        else:
            start = y_measured[0] if initial is None else initial
            past = [out[k - j] if k - j >= 0 else start for j in (1, 2)]
        out[k] = A1 @ past[0] + A2 @ past[1] + B0 @ u[k] + B1 @ at(u, k - 1) + C
    return out


def _arx_data(rng, lengths):
    parts = []
    for n in lengths:
        u = rng.uniform(-1, 1, size=(n, 2))
        y = _simulate(u, rng.normal(size=(2, 2)))
        parts.append(Dataset.from_arrays(u, y, input_names=["u1", "u2"], output_names=["Fx", "Fy"]))
    return concatenate(parts)


def test_arx_fit_recovers_the_system(rng):
    data = _arx_data(rng, [300])
    model = CalibrationModel(1, na=2, nb=1).fit(data)
    assert model.layout_.n_features == 2 * 2 + 2 * 2 + 1
    # Columns: y(k−1), y(k−2) [normalized outputs], u(k), u(k−1) [normalized inputs], offset.
    s_out, s_in = model.output_normalization_.scale, model.input_normalization_.scale
    coef = model.coef_
    np.testing.assert_allclose(coef[0:2].T / s_out, A1, atol=1e-9)
    np.testing.assert_allclose(coef[2:4].T / s_out, A2, atol=1e-9)
    np.testing.assert_allclose(coef[4:6].T / s_in, B0, atol=1e-9)
    np.testing.assert_allclose(coef[6:8].T / s_in, B1, atol=1e-9)


@pytest.mark.parametrize("mode,start", [("one-step", "zeros"), ("free-run", "measured"), ("free-run", "zeros")])
def test_arx_predictions_follow_the_hand_written_recursion(rng, mode, start):
    model = CalibrationModel(1, na=2, nb=1).fit(_arx_data(rng, [300]))
    fresh = _arx_data(rng, [60])
    got = model.predict(fresh, mode=mode, start=start, warn_out_of_range=False)
    expected = _hand_predict(fresh.inputs, fresh.outputs, mode, begin=start)
    np.testing.assert_allclose(got, expected, atol=1e-8)
    if mode == "one-step":
        # With measured history available (k >= 2) one-step prediction is the system itself.
        np.testing.assert_allclose(got[2:], fresh.outputs[2:], atol=1e-8)


def test_arx_free_run_without_outputs_starts_at_steady_state(rng):
    model = CalibrationModel(1, na=2, nb=1).fit(_arx_data(rng, [300]))
    u = rng.uniform(-0.9, 0.9, size=(40, 2))
    steady = np.linalg.solve(np.eye(2) - A1 - A2, (B0 + B1) @ u[0] + C)
    got = model.predict(Dataset.from_arrays(u, input_names=["u1", "u2"]), start="measured")
    np.testing.assert_allclose(got, _hand_predict(u, None, "free-run", initial=steady), atol=1e-8)
    with pytest.raises(FtcalError, match="measured outputs"):
        model.predict(Dataset.from_arrays(u, input_names=["u1", "u2"]), mode="one-step")


def test_arx_fit_honours_segments(rng):
    # Three independent recordings: exact only if no lag reaches into the previous recording.
    data = _arx_data(rng, [80, 50, 70])
    model = CalibrationModel(1, na=2, nb=1).fit(data)
    assert model.n_samples_fit_ == 200 - 3 * 2
    one_step = model.predict(data, mode="one-step")
    for a, b in data.segment_bounds():
        np.testing.assert_allclose(one_step[a + 2:b], data.outputs[a + 2:b], atol=1e-8)
        expected = _hand_predict(data.inputs[a:b], data.outputs[a:b], "free-run")
        np.testing.assert_allclose(model.predict(data, start="measured", warn_out_of_range=False)[a:b], expected,
                                   atol=1e-8)


def test_arx_fit_across_glued_recordings_is_not_exact(rng):
    # Control for the test above: the same samples as one segment cannot be fitted exactly.
    data = _arx_data(rng, [80, 50, 70])
    glued = Dataset.from_arrays(data.inputs, data.outputs, input_names=["u1", "u2"], output_names=["Fx", "Fy"])
    model = CalibrationModel(1, na=2, nb=1).fit(glued)
    residual = model.predict(glued, mode="one-step")[2:] - glued.outputs[2:]
    assert np.abs(residual).max() > 1e-3


def test_nonlinear_arx_one_step_recovery(rng):
    u = rng.uniform(-1, 1, size=(250, 2))
    y = np.zeros((250, 1))
    for k in range(1, 250):
        y[k] = 0.6 * y[k - 1] + u[k, 0] ** 2 - 0.5 * u[k - 1, 0] * u[k - 1, 1] + 0.2
    model = CalibrationModel(2, na=1, nb=1).fit(Dataset.from_arrays(u, y))
    np.testing.assert_allclose(model.predict(Dataset.from_arrays(u, y), mode="one-step")[1:], y[1:],
                               atol=1e-8)


def test_arx_segments_shorter_than_lag_raise(rng):
    u = rng.uniform(size=(2, 2))
    with pytest.raises(FtcalError, match="No regressor rows"), warnings.catch_warnings():
        warnings.simplefilter("ignore", IllPosedFitWarning)
        CalibrationModel(1, na=2, nb=0).fit(Dataset.from_arrays(u, u))


@pytest.mark.parametrize("mode", ["one-step", "free-run"])
def test_arx_predict_selects_measured_outputs_by_name(rng, mode):
    model = CalibrationModel(1, na=2, nb=1).fit(_arx_data(rng, [300]))
    fresh = _arx_data(rng, [40])
    swapped = Dataset.from_arrays(fresh.inputs, fresh.outputs[:, ::-1], input_names=["u1", "u2"],
                                  output_names=["Fy", "Fx"])
    expected = _hand_predict(fresh.inputs, fresh.outputs, mode)
    np.testing.assert_allclose(model.predict(swapped, mode=mode, start="measured", warn_out_of_range=False),
                               expected, atol=1e-8)


def test_arx_metrics_drop_the_warmup_rows_by_default(rng):
    # The paper's code leaves the first max(na, nb) = 2 rows of each segment out of its metrics.
    model = CalibrationModel(1, na=2, nb=1).fit(_arx_data(rng, [300]))
    data = _arx_data(rng, [40, 30])
    kept_rows = np.r_[np.arange(2, 40), np.arange(42, 70)]
    y = data.outputs
    for warmup, rows in (("drop", kept_rows), ("keep", np.arange(70))):
        for mode in ("one-step", "free-run"):
            summary = model.metrics(data, mode=mode, warmup=warmup, warn_out_of_range=False)
            prediction = model.predict(data, mode=mode, warn_out_of_range=False)
            expected = np.sqrt(np.mean((y[rows] - prediction[rows]) ** 2, axis=0))
            np.testing.assert_allclose(summary["rmse"], expected, rtol=1e-12)
            assert summary["n_samples"] == len(rows)
    # The default is the paper's evaluation: one-step, with the free-run figures beside it.
    default = model.metrics(data, warn_out_of_range=False)
    assert "free_run" in default and default["rmse"] == model.metrics(data, mode="one-step")["rmse"]


def test_input_lags_only_model_is_a_fir_filter(rng):
    u = rng.uniform(-1, 1, size=(120, 2))
    y = np.zeros((120, 1))
    y[2:, 0] = u[2:, 0] - 0.5 * u[1:-1, 1] + 0.25 * u[:-2, 0] + 0.1
    model = CalibrationModel(1, nb=2).fit(Dataset.from_arrays(u, y))
    fresh = rng.uniform(-1, 1, size=(30, 2))
    padded = np.r_[fresh[:1], fresh[:1], fresh]  # documented: history repeats the first sample
    expected = padded[2:, 0] - 0.5 * padded[1:-1, 1] + 0.25 * padded[:-2, 0] + 0.1
    for mode in ("free-run", "one-step"):
        got = model.predict(Dataset.from_arrays(fresh, np.zeros((30, 1))), mode=mode, warn_out_of_range=False)
        np.testing.assert_allclose(got[:, 0], expected, atol=1e-9)


@pytest.mark.parametrize("n_inputs", [1, 3])
def test_predict_leaves_the_callers_inputs_untouched(n_inputs):
    # A one-input chunk transposed is already contiguous; normalizing it in place
    # would overwrite the caller's array.
    rng = np.random.default_rng(5)
    u = rng.uniform(20.0, 40.0, (50, n_inputs))
    y = np.column_stack([u.sum(axis=1) ** 2, u[:, 0]])
    model = CalibrationModel(2).fit(Dataset.from_arrays(u, y))
    before = u.copy()
    model.predict(u)
    np.testing.assert_array_equal(u, before)


def test_arx_one_step_is_exact_across_prediction_chunks():
    # A noise-free linear ARX system, longer than a prediction chunk: every one-step
    # prediction after the first sample must equal the system's output, so the lag
    # history has to be carried correctly across chunk boundaries.
    from ftcal.core import model as model_module

    rng = np.random.default_rng(11)
    n = 3 * model_module.PREDICT_CHUNK + 123
    u = rng.uniform(-1.0, 1.0, (n, 2))
    y = np.zeros((n, 1))
    for k in range(1, n):
        y[k, 0] = 0.6 * y[k - 1, 0] + 2.0 * u[k, 0] - 1.5 * u[k - 1, 1] + 0.3
    data = Dataset.from_arrays(u, y, input_names=("a", "b"), output_names=("Fx",))
    model = CalibrationModel(1, na=1, nb=1).fit(data)
    one_step = model.predict(data, mode="one-step")
    np.testing.assert_allclose(one_step[1:], y[1:], rtol=0, atol=1e-9)
