"""Prediction and scoring of a fitted polynomial model: static (compiled kernel or numpy, chunk by chunk),
ARX one-step or free-run (the paper's zero start or ftcal's measured start), range and span checks."""

from __future__ import annotations

import warnings

import numpy as np

from ...runtime.checks import check_choice, check_finite_matrix
from ...runtime.errors import FtcalError, OutOfRangeWarning
from ...runtime.threads import map_ranges, single_threaded_blas
from .. import metrics
from ..dataset import Dataset
from ..excitation import SpanTest, span_limit
from ..features import FeatureCombination
from ..kernels import compiled, step_table
from ..limits import ARX_WARMUP, FREE_RUN_STARTS, PREDICTION_MODES
from ..ranges import RANGE_TOLERANCE, RangeSums, describe, outside_by_channel
from .frame import as_dataset, outputs_in_order

PREDICT_CHUNK = 4096


class PredictionMixin:
    """``predict``, ``metrics`` and the range checks of :class:`~ftcal.core.model.CalibrationModel`.

    Reads only the fitted state (``layout_``, ``coef_``, the normalizations, names, ranges and
    ``input_spread_``) and ``_check_fitted``, which the model class provides.
    """

    def out_of_range(self, inputs: np.ndarray) -> np.ndarray:
        """Boolean mask of samples outside the training data: any input outside its range, or outside the span.

        See :meth:`out_of_span`.
        """
        self._check_fitted()
        return np.any(outside_by_channel(inputs, self.input_range_), axis=1) | self.out_of_span(inputs)

    def out_of_span(self, inputs: np.ndarray) -> np.ndarray:
        """Boolean mask of samples outside the span of the training inputs, even inside their range.

        Their squared Mahalanobis distance from the training inputs
        (:func:`ftcal.core.excitation.span_distance`) exceeds
        :func:`ftcal.core.excitation.span_limit`: a combination of inputs the
        training data never had, such as a push along a direction that one rigid
        tool turned through poses never applies. All False without
        ``input_spread_`` (model files from before ftcal recorded it).
        """
        self._check_fitted()
        inputs = np.asarray(inputs, dtype=np.float64)
        if self.input_spread_ is None:
            return np.zeros(inputs.shape[0], dtype=bool)
        return self._span_test().distance(inputs) > span_limit(inputs.shape[1])

    def _span_test(self) -> SpanTest:
        # Decomposed once per fitted spread: a live loop tests one sample at a time.
        cached = getattr(self, "_span_test_cache", None)
        if cached is None or cached.spread is not self.input_spread_:
            cached = self._span_test_cache = SpanTest(self.input_spread_)
        return cached

    def row_range_test(self):
        """A function telling whether one sample is outside the training range or span.

        :meth:`out_of_range` of one row, with its thresholds and the span's decomposition made
        once: for loops that test sample by sample (:class:`ftcal.live.LiveCalibrator`).

        Examples
        --------
        >>> import numpy as np
        >>> from ftcal import CalibrationModel, Dataset
        >>> u = np.random.default_rng(0).uniform(-1, 1, size=(200, 2))
        >>> outside = CalibrationModel(1).fit(Dataset.from_arrays(u, u, output_names=["Fx", "Fy"])).row_range_test()
        >>> outside([0.0, 0.1]), outside([3.0, 0.0])
        (False, True)
        """
        self._check_fitted()
        low, high = self.input_range_[:, 0], self.input_range_[:, 1]
        slack = RANGE_TOLERANCE * np.maximum(high - low, 1.0)  # as outside_by_channel
        lows, highs = (low - slack).tolist(), (high + slack).tolist()
        span = None if self.input_spread_ is None else self._span_test()
        limit = span_limit(len(lows))

        def outside(u) -> bool:
            if any(x < lo or x > hi for x, lo, hi in zip(u, lows, highs)):
                return True
            return span is not None and bool(span.distance(np.array([u], dtype=np.float64))[0] > limit)

        return outside

    def row_predictor(self):
        """A function that predicts one sample of a static model: a sequence of n_inputs floats → (n_outputs,).

        The arithmetic of :meth:`predict` on one row (the compiled kernel, or numpy), without its
        per-call checks and dispatch: for loops that check their inputs themselves, sample by sample
        (:class:`ftcal.live.LiveCalibrator`). None for ARX models, whose prediction has a history.

        Examples
        --------
        >>> import numpy as np
        >>> from ftcal import CalibrationModel, Dataset
        >>> u = np.random.default_rng(0).normal(size=(200, 2))
        >>> model = CalibrationModel(2).fit(Dataset.from_arrays(u, u ** 2, output_names=["Fx", "Fy"]))
        >>> one = model.row_predictor()
        >>> bool(np.array_equal(one([0.5, -1.0]), model.predict(np.array([[0.5, -1.0]]))[0]))
        True
        """
        self._check_fitted()
        if not self.layout_.is_static:
            return None
        basis = self.layout_.basis
        coef_t = np.ascontiguousarray(self.coef_.T)
        offset, inv_scale = self.input_normalization_.offset, 1.0 / self.input_normalization_.scale
        kernels = compiled()
        if kernels is None:
            return lambda u: self._predict_static(np.array([u], dtype=np.float64))[0]
        steps = step_table(basis.n_inputs, basis.degree)

        def one(u) -> np.ndarray:
            out = np.empty((1, coef_t.shape[0]))
            kernels.predict(np.array([u], dtype=np.float64), offset, inv_scale, coef_t, steps, out)
            return out[0]

        return one

    def predict(self, data: Dataset | np.ndarray, *, mode: str = "free-run", start: str = "zeros",
                warn_out_of_range: bool = True) -> np.ndarray:
        """Predicted outputs.

        Parameters
        ----------
        data : Dataset, or ndarray of shape (n_samples, n_inputs)
            Raw inputs (and, for one-step ARX prediction, measured outputs).
        mode : {"free-run", "one-step"}
            Matters only for ARX models: ``"free-run"`` feeds back past
            predictions (deployment on the robot), ``"one-step"`` uses the
            measured past outputs in ``data`` (the paper's evaluation).
        start : {"zeros", "measured"}
            Free-run history at each segment start. ``"zeros"`` (the paper's
            code): past outputs are zero, so the first max(na, nb) rows are 0
            and the recursion starts at row max(na, nb). ``"measured"``
            (ftcal's): every row is predicted, with the first measured output
            (or, without outputs, the steady state for the first input) as
            history. Models with na = 0 have no feedback: free-run is one-step.
        warn_out_of_range : bool
            Warn (:class:`~ftcal.runtime.errors.OutOfRangeWarning`) about inputs outside the training
            range: which inputs, how far (in training spans), how many samples.

        Returns
        -------
        ndarray of shape (n_samples, n_outputs)
            Rows before max(na, nb) within a segment see their first input
            sample repeated as input history.

        Raises
        ------
        FtcalError
            On non-finite inputs, missing columns, or one-step without outputs.
        """
        self._check_fitted()
        check_choice(mode, "mode", "CalibrationModel.predict", PREDICTION_MODES)
        check_choice(start, "start", "CalibrationModel.predict", FREE_RUN_STARTS)
        data = as_dataset(data, None, self.input_names_, type(self).__name__)
        u = check_finite_matrix(data.select_inputs(self.input_names_), "inputs",
                                len(self.input_names_), self.input_names_)
        if warn_out_of_range:
            self._warn_out_of_range(RangeSums.of(u, self.input_range_, outside_span=self.out_of_span(u)),
                                    stacklevel=3)
        if self.layout_.is_static:
            return self._predict_static(u)
        u_norm = self.input_normalization_.apply(u)
        if mode == "one-step" and data.outputs is None:
            raise FtcalError("One-step-ahead prediction needs the measured outputs in the data.")
        measured = None if data.outputs is None else outputs_in_order(data, self.output_names_)
        # One BLAS thread: results must not depend on thread scheduling (bit-identical reruns).
        with single_threaded_blas():
            return np.concatenate([self._predict_arx_segment(u_norm[a:b], None if measured is None else measured[a:b],
                                                             mode, start)
                                   for a, b in data.segment_bounds()])

    def _warn_out_of_range(self, ranges: RangeSums, stacklevel: int) -> None:
        """One warning for one cause: inputs outside the training range, and those outside its span."""
        message = describe(ranges.to_dict(self.input_names_))
        if message:
            warnings.warn(message, OutOfRangeWarning, stacklevel=stacklevel)

    def _predict_static(self, u: np.ndarray) -> np.ndarray:
        basis = self.layout_.basis
        coef_t = np.ascontiguousarray(self.coef_.T)
        out = np.empty((u.shape[0], coef_t.shape[0]))
        offset, inv_scale = self.input_normalization_.offset, 1.0 / self.input_normalization_.scale
        kernels = compiled()
        if kernels is not None:
            u, steps = np.ascontiguousarray(u, dtype=np.float64), step_table(basis.n_inputs, basis.degree)
            map_ranges(lambda begin, end: kernels.predict(u[begin:end], offset, inv_scale, coef_t, steps,
                                                          out[begin:end]), u.shape[0], PREDICT_CHUNK)
            return out
        offset, inv_scale = offset[:, None], inv_scale[:, None]  # per input, across a chunk's samples

        def work(begin: int, end: int) -> None:
            combine = FeatureCombination(basis, coef_t, PREDICT_CHUNK)
            for start in range(begin, end, PREDICT_CHUNK):
                stop = min(start + PREDICT_CHUNK, end)
                # Normalize per chunk, in cache, instead of a full pass over u.
                # A contiguous copy (never a view: it is modified in place) with contiguous rows.
                u_t = np.array(u[start:stop].T, order="C")
                u_t -= offset
                u_t *= inv_scale
                out[start:stop] = combine(u_t).T

        map_ranges(work, u.shape[0], PREDICT_CHUNK)
        return out

    def _predict_arx_segment(self, u_norm: np.ndarray, y_measured: np.ndarray | None, mode: str,
                             start: str) -> np.ndarray:
        layout, lag = self.layout_, self.layout_.max_lag
        ny = len(self.output_names_)
        padded_u = np.concatenate([np.repeat(u_norm[:1], lag, axis=0), u_norm])
        if layout.na == 0:
            return self._arx_product(padded_u, np.zeros((padded_u.shape[0], ny)))
        if mode == "one-step":
            y_norm = self.output_normalization_.apply(y_measured)
            padded_y = np.concatenate([np.repeat(y_norm[:1], lag, axis=0), y_norm])
            return self._arx_product(padded_u, padded_y)
        # Free run: the input part once for all samples, then the output recursion.
        exogenous = self._arx_product(padded_u, np.zeros((padded_u.shape[0], ny)))
        feedback = [self.coef_[(j - 1) * ny:j * ny] for j in range(1, layout.na + 1)]
        scale = self.output_normalization_.scale
        offset = self.output_normalization_.offset
        result = np.empty_like(exogenous)
        first = 0
        if start == "zeros":
            # The paper's predictor: zero outputs before row max(na, nb), recursion from there.
            first = min(lag, exogenous.shape[0])
            result[:first] = 0.0
            history = [self.output_normalization_.apply(np.zeros(ny))] * layout.na
        elif y_measured is not None:
            history = [self.output_normalization_.apply(y_measured[0])] * layout.na
        else:
            history = [self.output_normalization_.apply(self._steady_state(exogenous[0], feedback))] * layout.na
        for k in range(first, exogenous.shape[0]):
            value = exogenous[k].copy()
            for j, block in enumerate(feedback):
                value += history[-1 - j] @ block
            result[k] = value
            history.append((value - offset) / scale)
            history.pop(0)
        return result

    def _arx_product(self, padded_u: np.ndarray, padded_y: np.ndarray) -> np.ndarray:
        """Regressor rows times coefficients, ``PREDICT_CHUNK`` rows at a time (never the whole N × p)."""
        lag = self.layout_.max_lag
        n = padded_u.shape[0] - lag
        out = np.empty((n, self.coef_.shape[1]))
        for start in range(0, n, PREDICT_CHUNK):
            stop = min(start + PREDICT_CHUNK, n)
            rows = self.layout_.evaluate_segment(padded_u[start:stop + lag], padded_y[start:stop + lag])
            out[start:stop] = rows @ self.coef_
        return out

    def _steady_state(self, exogenous: np.ndarray, feedback: list[np.ndarray]) -> np.ndarray:
        """Output y with y = g + Σ_j ((y − o)/s) S_j, i.e. the fixed point for constant input."""
        ny = exogenous.size
        inv_scale = np.diag(1.0 / self.output_normalization_.scale)
        s_total = sum(feedback) if feedback else np.zeros((ny, ny))
        system = np.eye(ny) - (inv_scale @ s_total).T
        rhs = exogenous - (self.output_normalization_.offset / self.output_normalization_.scale) @ s_total
        try:
            return np.linalg.solve(system, rhs)
        except np.linalg.LinAlgError:
            return exogenous

    def metrics(self, data: Dataset, *, mode: str = "one-step", start: str = "zeros", warmup: str = "drop",
              warn_out_of_range: bool = True) -> dict:
        """Metrics of :func:`ftcal.core.metrics.summarize` plus ``n_out_of_range``.

        Parameters
        ----------
        data : Dataset
            With reference outputs.
        mode, start : str
            ARX prediction (see :meth:`predict`); the default is the paper's
            evaluation, one-step-ahead.
        warmup : {"drop", "keep"}
            ``"drop"`` (the paper's code) leaves the first max(na, nb) rows of
            each segment out of the metrics; no effect on static models.
        warn_out_of_range : bool
            Warn once about inputs outside the training range, with the force- and
            torque-norm errors on those samples next to those inside.

        Returns
        -------
        dict
            For ARX models also the other mode's metrics, under ``"free_run"``
            or ``"one_step"``.
        """
        self._check_fitted()
        check_choice(warmup, "warmup", "CalibrationModel.metrics", ARX_WARMUP)
        if data.outputs is None:
            raise FtcalError("Evaluating needs reference outputs in the data.")
        y = outputs_in_order(data, self.output_names_)
        rows = np.ones(data.n_samples, dtype=bool)
        if warmup == "drop" and self.layout_.max_lag:
            for a, b in data.segment_bounds():
                rows[a:a + self.layout_.max_lag] = False
        if not rows.any():
            raise FtcalError(f"Nothing to evaluate: every segment is shorter than the ARX warm-up "
                             f"max(na, nb) = {self.layout_.max_lag} rows.")
        prediction = self.predict(data, mode=mode, start=start, warn_out_of_range=False)
        summary = metrics.summarize(y[rows], prediction[rows], self.output_names_)
        inputs = data.select_inputs(self.input_names_)
        summary["n_out_of_range"] = int(self.out_of_range(inputs).sum())
        if warn_out_of_range and summary["n_out_of_range"]:
            self._warn_out_of_range(RangeSums.of(inputs, self.input_range_, y, prediction, self.output_names_,
                                                 scored=rows, outside_span=self.out_of_span(inputs)),
                                    stacklevel=3)
        if not self.layout_.is_static and data.outputs is not None:
            other = "free-run" if mode == "one-step" else "one-step"
            second = self.predict(data, mode=other, start=start, warn_out_of_range=False)
            summary[other.replace("-", "_")] = metrics.summarize(y[rows], second[rows], self.output_names_)
        return summary
