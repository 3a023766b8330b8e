"""Solvers: each turns the statistics of a scaled least-squares problem into coefficients."""

from .base import ScaledProblem, Solver, SolverResult
from .lasso import Lasso
from .least_squares import LeastSquares, Ridge
from .osqp_qp import OsqpLasso, OsqpLeastSquares

__all__ = ["Lasso", "LeastSquares", "OsqpLasso", "OsqpLeastSquares", "Ridge", "ScaledProblem", "Solver",
           "SolverResult"]
