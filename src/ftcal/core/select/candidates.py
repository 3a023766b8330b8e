"""The points of the selection grid: a degree, a penalty and its λ, and the grids' reference λ."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..limits import PAPER_LAMBDAS
from ..solvers.base import ScaledProblem, Solver
from ..solvers.lasso import Lasso
from ..solvers.least_squares import LeastSquares, Ridge

DEFAULT_DEGREES = (1, 2, 3, 4, 5)
DEFAULT_PENALTIES = ("lasso", "ridge")
LASSO_POINTS, LASSO_DECADES = 10, 3.0
RIDGE_POINTS, RIDGE_DECADES = 13, 6.0
MAX_EXTENSIONS = 2  # times the grid grows past an edge where the best λ sits


@dataclass(frozen=True)
class Candidate:
    """One point of the selection grid.

    Parameters
    ----------
    degree : int
        Polynomial degree.
    penalty : {"none", "ridge", "lasso"}
        One of :data:`ftcal.core.limits.PENALTIES`.
    lam : float or None
        The penalty weight λ (None for least squares), absolute: the solver's λ.
    reference : float or None
        The λ its grid is relative to (λ_max for LASSO, trace(AᵀA)/p for ridge, on all
        the data), when the grid came from the data; not part of the candidate's identity.

    Examples
    --------
    >>> Candidate(3, "lasso", 50.0).label
    'np3 lasso λ=50'
    >>> Candidate(3, "lasso", 50.0, reference=5000.0).label
    'np3 lasso λ=0.01·λmax'
    """

    degree: int
    penalty: str
    lam: float | None
    reference: float | None = field(default=None, compare=False)

    @property
    def relative_lam(self) -> float | None:
        """λ over its grid's reference (λ_max or λ_ref), or None."""
        return None if self.lam is None or self.reference is None else self.lam / self.reference

    @property
    def label(self) -> str:
        if self.penalty == "none":
            return f"np{self.degree}"
        if self.reference is not None:
            unit = "λmax" if self.penalty == "lasso" else "λref"
            return f"np{self.degree} {self.penalty} λ={self.relative_lam:.3g}·{unit}"
        return f"np{self.degree} {self.penalty} λ={self.lam:g}"

    def solver(self) -> Solver:
        """A solver for this candidate's penalty and λ."""
        if self.penalty == "lasso":
            return Lasso(self.lam)
        if self.penalty == "ridge":
            return Ridge(self.lam)
        return LeastSquares()

    def as_dict(self) -> dict:
        return {"degree": self.degree, "penalty": self.penalty, "lambda": self.lam,
                "lambda_relative": self.relative_lam}


AFFINE = Candidate(1, "none", None)


def default_candidates(degrees: Sequence[int] = (1, 2, 3, 4, 5), lams: Sequence[float] = PAPER_LAMBDAS,
                       penalty: str | None = "lasso") -> list[Candidate]:
    """Least squares at every degree, plus ``penalty`` at every (degree, λ) when given.

    Parameters
    ----------
    degrees : sequence of int
    lams : sequence of float
    penalty : {"ridge", "lasso"} or None

    Returns
    -------
    list of Candidate

    Examples
    --------
    >>> [c.label for c in default_candidates((1, 2), lams=(10.0,))]
    ['np1', 'np2', 'np1 lasso λ=10', 'np2 lasso λ=10']
    """
    out = [Candidate(d, "none", None) for d in degrees]
    if penalty is not None:
        out += [Candidate(d, penalty, float(lam)) for d in degrees for lam in lams]
    return out


def lasso_lambda_max(problem: ScaledProblem) -> float:
    """The smallest λ at which every non-offset coefficient of the LASSO is zero (offset penalized too).

    With only the offset x₀ active, x₀ = (c₀ − λ·s)/G₀₀ (s = sign c₀), and column j
    stays at zero while |c_j − G_j0·x₀| <= λ; solving that for λ gives a bound
    per column and output, and λ_max is the largest.

    Parameters
    ----------
    problem : ScaledProblem
        The offset is its last column.

    Returns
    -------
    float

    Examples
    --------
    >>> import numpy as np
    >>> from ftcal.core.statistics import dense_statistics
    >>> a = np.c_[[1.0, -1.0, 1.0, -1.0], np.ones(4)]   # a zero-mean column and the offset
    >>> y = np.array([[3.0], [1.0], [3.0], [1.0]])      # y = 2 + 1·a
    >>> lasso_lambda_max(ScaledProblem.from_statistics(dense_statistics(a, y)))  # |Σ a·y| = 4
    4.0
    """
    g, c = problem.gram, problem.cross
    g00 = g[-1, -1]
    if g00 <= 0:
        return float(np.abs(c[:-1]).max())
    sign = np.sign(c[-1])                       # (n_outputs,)
    a = c[:-1] - np.outer(g[:-1, -1], c[-1]) / g00
    b = np.outer(g[:-1, -1], sign) / g00
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = np.where(a > 0, a / (1.0 - b), -a / (1.0 + b))
    # Columns equal to ± the offset (b = ±1) never leave zero alone; skip them.
    bound = np.where(np.abs(b) < 1.0 - 1e-12, bound, 0.0)
    return float(max(np.nanmax(bound), np.finfo(float).tiny))
