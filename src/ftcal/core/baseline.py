"""A model against a baseline on the same held-out samples: per-axis error ratios and a grouped, paired verdict.

Each group of the held-out data (a load case, a recording) is one fold: the model's and the baseline's
RMS errors on it form a pair, and the verdict is the fold-by-fold comparison of
:class:`ftcal.core.select.Comparison` (the log ratio's mean against t x its standard error, the rule
``ftcal fit --degree auto`` keeps the affine model by): *better* or *worse* beyond the spread of the
folds, *ties* within it. One ratio over all samples can hide a model that wins on one load and loses
on two; the verdict cannot.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .metrics import force_torque_columns, output_units

# Printed ratios and spreads: 3 significant digits; errors: 4.
RATIO_DIGITS = 3
# Log ratios within this are ties whatever the spread (rounding, not a difference).
LOG_TIE = 1e-9


@dataclass(frozen=True)
class AxisVerdict:
    """One row of a comparison: an axis (or an error norm) scored on every fold.

    Attributes
    ----------
    name, unit : the axis (``Fx``) or norm (``force error norm``) and its unit
    model_rmse, baseline_rmse : float, over all samples
    model_folds, baseline_folds : ndarray of shape (n_folds,), the RMS error on each group
    verdict : ``"better"``, ``"ties"`` or ``"worse"`` (the model against the baseline)
    log_margin, log_noise : mean fold log ratio log(baseline / model) and its t x standard error (None
        with fewer than two folds or a zero error)
    """

    name: str
    unit: str
    model_rmse: float
    baseline_rmse: float
    model_folds: np.ndarray
    baseline_folds: np.ndarray
    verdict: str
    log_margin: float | None
    log_noise: float | None

    @property
    def ratio(self) -> float | None:
        """Model RMSE / baseline RMSE over all samples (None when the baseline's is 0)."""
        return self.model_rmse / self.baseline_rmse if self.baseline_rmse > 0 else None

    def as_dict(self) -> dict:
        return {"name": self.name, "unit": self.unit, "model_rmse": self.model_rmse,
                "baseline_rmse": self.baseline_rmse, "ratio": self.ratio, "verdict": self.verdict,
                "fold_ratios": [float(m / b) if b > 0 else None
                                for m, b in zip(self.model_folds, self.baseline_folds)],
                "log_margin": self.log_margin, "log_noise": self.log_noise}


@dataclass(frozen=True)
class BaselineComparison:
    """:func:`compare_to_baseline`'s result.

    Attributes
    ----------
    baseline : its name (``identity``: the inputs read as the wrench; or a model file)
    tare : how each recording's offset was removed from both (``none``, ``first-hold``, ``per-file``)
    folds : the group names, one fold each
    rows : one :class:`AxisVerdict` per output, then the force and torque error norms
    """

    baseline: str
    tare: str
    folds: tuple[str, ...]
    rows: tuple[AxisVerdict, ...]

    def lines(self, model: str = "model") -> list[str]:
        """The printed table: RMSE of both, their ratio, the fold ratios' range and the verdict per axis."""
        tare = "" if self.tare == "none" else (f", tared ({self.tare})" if "only" in self.tare
                                                  else f", both tared ({self.tare})")
        out = [f"against baseline {self.baseline}{tare}: {len(self.folds)} fold(s) = the groups "
               f"({', '.join(self.folds)})",
               f"{'output':<20}{model[:12]:>12}{'baseline':>12}{'ratio':>8}{'fold ratios':>16}"
               f"{'log ratio ± spread':>20}  verdict  unit"]
        for row in self.rows:
            ratios = [m / b for m, b in zip(row.model_folds, row.baseline_folds) if b > 0]
            spread = (f"{min(ratios):.{RATIO_DIGITS}g}-{max(ratios):.{RATIO_DIGITS}g}" if len(ratios) > 1
                      else "n/a")
            ratio = "n/a" if row.ratio is None else f"{row.ratio:.{RATIO_DIGITS}g}"
            # log(baseline / model) over the folds: > 0 the model is better; the spread is t x its standard error
            margin = ("n/a" if row.log_margin is None
                      else f"{row.log_margin:+.2f} ± {row.log_noise:.2f}")
            out.append(f"{row.name:<20}{_error(row.model_rmse):>12}{_error(row.baseline_rmse):>12}{ratio:>8}"
                       f"{spread:>16}{margin:>20}  {row.verdict:<7}  {row.unit}")
        out.append("  verdict: the fold-by-fold log ratio log(baseline/model)'s mean against its spread, t x its "
                   "standard error (better/worse "
                   "beyond the folds' spread, ties within it" + ("; one fold: no spread, ties)" if len(self.folds)
                                                                    < 2 else ")"))
        return out

    def as_dict(self) -> dict:
        return {"baseline": self.baseline, "tare": self.tare, "folds": list(self.folds),
                "rows": [r.as_dict() for r in self.rows]}


def _error(value: float) -> str:
    return f"{value:.4g}"


def fold_rmse(error: np.ndarray, folds: np.ndarray) -> tuple[list, np.ndarray]:
    """(fold names in order of appearance, RMS error of each column on each fold, shape (n_folds, n_columns))."""
    labels = np.asarray(folds)
    _, first, codes = np.unique(labels, return_index=True, return_inverse=True)
    order = np.argsort(first)  # folds in order of appearance
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    codes = rank[codes.ravel()]
    sizes = np.bincount(codes, minlength=order.size).astype(float)
    squares = np.column_stack([np.bincount(codes, error[:, j] ** 2, order.size) for j in range(error.shape[1])])
    return [labels[first[i]] for i in order], np.sqrt(squares / sizes[:, None])


def paired_verdict(scores, reference_scores) -> tuple[str, float | None, float | None]:
    """(verdict, margin, noise) of paired errors (folds, seeds): ``better`` when the mean log ratio
    log(reference / score) exceeds t x its standard error, ``worse`` below minus that, else ``ties``
    (inclusive: identical scores tie); ``ties`` with no spread to judge by (fewer than two pairs, a zero
    error): margin and noise are then None.

    Examples
    --------
    >>> paired_verdict([1.0, 1.1, 0.9], [2.0, 2.1, 1.9])[0], paired_verdict([1.0, 2.0], [2.0, 1.0])[0]
    ('better', 'ties')
    """
    from .select import Comparison

    comparison = Comparison.of(None, np.asarray(reference_scores, float), np.asarray(scores, float))
    if comparison.n_folds < 2 or comparison.log_standard_error is None:
        return "ties", None, None
    # at least a relative 1e-9: two computations of the same number differ in their last digits
    margin, noise = comparison.log_margin, max(comparison.quantile * comparison.log_standard_error, LOG_TIE)
    return ("better" if margin > noise else ("worse" if margin < -noise else "ties")), margin, noise


def compare_to_baseline(model_error: np.ndarray, baseline_error: np.ndarray, folds: np.ndarray,
                        outputs: Sequence[str], baseline: str, tare: str = "none") -> BaselineComparison:
    """Per-axis and error-norm comparison of two predictions' errors on the same samples, fold by fold.

    Parameters
    ----------
    model_error, baseline_error : ndarray of shape (n_samples, n_outputs), prediction minus reference
    folds : ndarray of shape (n_samples,), the group of each sample (one fold per group)
    outputs : output names
    baseline, tare : names kept in the result

    Returns
    -------
    BaselineComparison

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> base = rng.normal(0.0, 1.0, (300, 1))
    >>> c = compare_to_baseline(0.5 * base, base, np.repeat(["a", "b", "c"], 100), ["Fx"], "identity")
    >>> round(c.rows[0].ratio, 3), c.rows[0].verdict
    (0.5, 'better')
    """
    model_error, baseline_error = np.asarray(model_error, float), np.asarray(baseline_error, float)
    names = list(outputs)
    units = output_units(names)
    columns = [(name, unit, model_error[:, [j]], baseline_error[:, [j]]) for j, (name, unit) in
               enumerate(zip(names, units))]
    forces, torques = force_torque_columns(names)
    for label, block in (("force error norm", forces), ("torque error norm", torques)):
        if block:
            columns.append((label, units[block[0]],
                            np.linalg.norm(model_error[:, block], axis=1, keepdims=True),
                            np.linalg.norm(baseline_error[:, block], axis=1, keepdims=True)))
    fold_names, _ = fold_rmse(model_error[:, :1], folds)
    rows = []
    for name, unit, m, b in columns:
        _, m_folds = fold_rmse(m, folds)
        _, b_folds = fold_rmse(b, folds)
        m_folds, b_folds = m_folds[:, 0], b_folds[:, 0]
        verdict, margin, noise = paired_verdict(m_folds, b_folds)
        rows.append(AxisVerdict(name, unit, float(np.sqrt(np.mean(m ** 2))), float(np.sqrt(np.mean(b ** 2))),
                                m_folds, b_folds, verdict, margin, noise))
    return BaselineComparison(baseline, tare, tuple(str(f) for f in fold_names), tuple(rows))
