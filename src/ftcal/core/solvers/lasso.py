"""LASSO on sufficient statistics: the exact path (homotopy), with ADMM plus an active-set solve as fallback.

Objective (the paper's, per output): ½‖Ax − b‖² + λ‖x‖₁ on max-abs scaled
columns, offset included. ``sklearn.linear_model.Lasso(alpha=λ/N,
fit_intercept=False)`` on the same scaled regressor solves the same problem.

The solution is piecewise linear in λ (Osborne, Presnell & Turlach 2000; LARS-LASSO):
on a support S with signs s, x_S(λ) = G_SS⁻¹c_S − λ·G_SS⁻¹s, and it changes only
where a coefficient reaches zero or an inactive correlation reaches ±λ. Following
those events from λ_max down costs one small Cholesky factorization of G_SS per
event, whatever the conditioning of the whole Gram matrix (monomials of degree 5
on real data reach 1e16), where ADMM needed thousands of p × p iterations per λ.
Every requested λ is certified by the optimality conditions on the full gradient;
an output whose path cannot be followed (a singular G_SS, too many events) is
solved by the ADMM below instead.

ADMM splits x = z: the x-step solves (G + ρI) x = c + ρ(z − w), which costs
two small matrix products once G = VΛVᵀ is known, for any ρ; the z-step
soft-thresholds, giving exact zeros. ADMM alone converges slowly to high
accuracy, so every few iterations we guess the active set and signs from z,
solve the reduced system G_SS x_S = c_S − λ·sign, and accept it if it satisfies
the LASSO optimality conditions — then the answer is exact, not approximate.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np

from ...runtime.checks import check_float
from ...runtime.errors import FtcalWarning
from ...runtime.threads import single_threaded_blas
from .base import Conditioning, ScaledProblem, SolverResult

KKT_RTOL = 1e-7
POLISH_EVERY = 20
RHO_EVERY = 10
RELAXATION = 1.6
MAX_ITER = 20000
MAX_ACTIVE_SET_STEPS = 30
# Path events per output before the homotopy hands over to ADMM (each adds or drops one coefficient):
# 4 per column plus 10 per λ asked for.
MAX_PATH_EVENTS_PER_FEATURE = 4
MAX_PATH_EVENTS_PER_LAMBDA = 10
# Events closer than this (relative) to the current λ happen "now"; guards ties and rounding.
EVENT_RTOL = 1e-10


class Lasso:
    """LASSO with exact zeros: x* = argmin ½‖Ax − b‖² + λ‖x‖₁; ``fit_path`` warm-starts over several λ.

    Parameters
    ----------
    lam : float > 0
        LASSO weight λ (on max-abs scaled columns: the paper's scale).
    max_iter : int
        ADMM iterations before giving up (with a warning).

    Examples
    --------
    >>> import numpy as np
    >>> from ftcal.core.statistics import dense_statistics
    >>> a = np.array([[1.0, 0.0], [0.0, 1.0]])
    >>> b = np.array([[3.0], [0.5]])
    >>> problem = ScaledProblem.from_statistics(dense_statistics(a, b))
    >>> Lasso(1.0).fit(problem).coef[:, 0].tolist()  # soft threshold: 3 - 1, and 0.5 -> 0
    [2.0, 0.0]
    """

    name = "lasso"
    penalty = "lasso"

    def __init__(self, lam: float, max_iter: int = MAX_ITER):
        self.lam = lam
        self.max_iter = max_iter

    def fit(self, problem: ScaledProblem) -> SolverResult:
        """The solution at ``lam``; ``info`` has ``"lambda"``, ``"n_nonzero"``, ``"iterations"``.

        Parameters
        ----------
        problem : ScaledProblem

        Returns
        -------
        SolverResult
        """
        return self.fit_path(problem, [self.lam])[0]

    def fit_path(self, problem: ScaledProblem, lams: Sequence[float], *,
                 eigen: tuple[np.ndarray, np.ndarray] | None = None) -> list[SolverResult]:
        """Solutions for each λ in ``lams`` (returned in the given order), warm-started from large to small λ.

        Parameters
        ----------
        problem : ScaledProblem
        lams : sequence of float > 0
        eigen : (values, vectors), optional
            ``numpy.linalg.eigh(problem.gram)`` when the caller has it (cross-validation
            shares it with ridge); rank and condition number then come from these values.

        Returns
        -------
        list of SolverResult, one per λ
        """
        lams = [check_float(lam, "lam", "Lasso", 0.0, low_inclusive=False) for lam in lams]
        with single_threaded_blas(scipy=True):  # the path's factorizations are SciPy's
            return self._fit_path(problem, lams, eigen)

    def _fit_path(self, problem: ScaledProblem, lams: list[float], eigen) -> list[SolverResult]:
        if eigen is None:
            equilibrated = Conditioning.of(problem.gram)
            rank, condition = equilibrated.rank, equilibrated.condition_number
        else:
            rank, condition = _rank_and_condition(eigen[0])
        order = sorted(range(len(lams)), key=lambda i: -lams[i])
        descending = [lams[i] for i in order]
        path, events = _homotopy(problem.gram, problem.cross, descending)
        state = None
        p, ny = problem.cross.shape
        previous = np.zeros((p, ny))
        results: dict[int, SolverResult] = {}
        for step, index in enumerate(order):
            exact = np.array([path[i][step] is not None for i in range(ny)])
            coef = np.column_stack([path[i][step] if exact[i] else np.zeros(p) for i in range(ny)])
            info = {"iterations": 0, "converged": True, "unconverged": [], "events": events[step],
                    "admm_outputs": []}
            if not exact.all():
                if state is None:
                    # ADMM's x-step needs the eigen-decomposition; the path does not.
                    values, vectors = eigen if eigen is not None else np.linalg.eigh(problem.gram)
                    state = _AdmmState.cold(problem, values)
                    # Warm start the outputs ADMM takes over from their last exact solution.
                    for i in np.flatnonzero(~exact):
                        state.z[:, i] = previous[:, i]
                state.rescale_dual(lams[index])
                admm, info = _solve_one_lambda(problem, values, vectors, lams[index], state, self.max_iter,
                                               settled=exact)
                coef[:, ~exact] = admm[:, ~exact]
                info.update(events=events[step], admm_outputs=np.flatnonzero(~exact).tolist())
            previous = coef
            if not info["converged"]:
                warnings.warn(
                    f"LASSO at lambda={lams[index]:g} stopped after {self.max_iter} iterations "
                    f"without meeting the optimality tolerance for output(s) {info['unconverged']}; "
                    "coefficients are approximate. Try a larger lambda or a lower degree.",
                    FtcalWarning, stacklevel=2)
            info["lambda"] = lams[index]
            info["n_nonzero"] = np.count_nonzero(coef, axis=0).tolist()
            results[index] = SolverResult(coef, rank, condition, info)
        return [results[i] for i in range(len(lams))]


def _homotopy(gram: np.ndarray, cross: np.ndarray, lams: Sequence[float]) -> tuple[list[list], int]:
    """Exact LASSO solutions at ``lams`` (descending) per output, following the path from λ_max.

    Returns, per output, one coefficient vector per λ (None where the solution could not be
    certified: the caller solves those otherwise), and the path events taken to reach each λ
    from the one before (all outputs).
    """
    import scipy.linalg

    p, ny = cross.shape
    paths, events = [], np.zeros(len(lams), dtype=int)
    for i in range(ny):
        solutions, counts = _homotopy_one(gram, cross[:, i], lams, scipy.linalg,
                                           MAX_PATH_EVENTS_PER_FEATURE * p + MAX_PATH_EVENTS_PER_LAMBDA * len(lams))
        paths.append(solutions)
        events += counts
    return paths, events.tolist()


def _homotopy_one(gram, c, lams, linalg, max_events):
    """One output of :func:`_homotopy`."""
    p = c.size
    solutions: list = []
    counts = np.zeros(len(lams), dtype=int)
    lam = float(np.abs(c).max())
    targets = iter(lams)
    target = next(targets, None)
    # At and above λ_max (‖c‖∞) x = 0 is optimal exactly.
    while target is not None and target >= lam:
        solutions.append(np.zeros(p))
        target = next(targets, None)
    if target is None:
        return solutions, counts
    first = int(np.argmax(np.abs(c)))
    support, signs = [first], [float(np.sign(c[first]))]
    last = first  # the coefficient that just changed: it cannot trigger an event at the current λ
    events = counted = 0
    inactive = np.ones(p, dtype=bool)
    inactive[first] = False
    while target is not None:
        rows = gram[support]                               # G_S: (k, p), rows = columns (symmetric)
        try:
            factor = linalg.cho_factor(rows[:, support], lower=True, check_finite=False)
        except np.linalg.LinAlgError:
            break
        ud = linalg.cho_solve(factor, np.column_stack([c[support], signs]), check_finite=False)
        u, d = ud[:, 0], ud[:, 1]                          # x_S(λ) = u − λ d
        if not (np.all(np.isfinite(u)) and np.all(np.isfinite(d))):
            break
        r = c - rows.T @ u                                 # gradient g(λ) = r + λ a
        a = rows.T @ d
        # Next event below λ: an inactive g_j reaching ±λ while moving outward (1 ∓ a_j > 0), or an active
        # x_j reaching 0 while moving toward it (d_j·s_j < 0). One already past its event (rounding) goes now.
        s_arr = np.asarray(signs)
        with np.errstate(divide="ignore", invalid="ignore"):
            plus = np.where(inactive & (1.0 - a > 0), np.minimum(r / (1.0 - a), lam), -np.inf)
            minus = np.where(inactive & (1.0 + a > 0), np.minimum(-r / (1.0 + a), lam), -np.inf)
            crossing = np.where(d * s_arr < 0, np.minimum(u / d, lam), -np.inf)
        plus[~(plus > 0)] = -np.inf
        minus[~(minus > 0)] = -np.inf
        crossing[~(crossing > 0)] = -np.inf
        now = lam * (1.0 - EVENT_RTOL)
        if last >= 0:
            # The coefficient that just changed sits exactly at its event: it cannot trigger another at this λ.
            events_of_last = (plus, minus, last) if inactive[last] else (crossing, crossing, support.index(last))
            for array in events_of_last[:2]:
                if array[events_of_last[2]] >= now:
                    array[events_of_last[2]] = -np.inf
        best_join = np.maximum(plus, minus)
        j_join = int(np.argmax(best_join))
        j_drop = int(np.argmax(crossing))
        join_at = best_join[j_join]
        drop_at = crossing[j_drop]
        next_lam = max(join_at, drop_at, 0.0)
        repaired = None
        while target is not None and target >= next_lam:
            x = _certified(gram, c, support, u - target * d, signs, target)
            if x is None:
                # Rounding on an ill-conditioned support took the path off course: repair it by
                # active-set steps at this λ, and resume from the certified support.
                x = _polish(gram, c, _embed(c.size, support, u - target * d), target)
                repaired = (x, target) if x is not None else repaired
            counts[len(solutions)] = events - counted
            counted = events
            solutions.append(x)
            target = next(targets, None)
        if target is None:
            break
        if repaired is not None:
            x, lam = repaired
            support = np.flatnonzero(x).tolist()
            signs = np.sign(x[support]).tolist()
            inactive = x == 0
            last = -1
            continue
        events += 1
        if events > max_events:
            break
        lam = min(next_lam, lam)
        if join_at >= drop_at:
            support.append(j_join)
            signs.append(1.0 if plus[j_join] >= minus[j_join] else -1.0)
            inactive[j_join] = False
            last = j_join
        else:
            last = support.pop(j_drop)
            signs.pop(j_drop)
            inactive[last] = True
    solutions += [None] * (len(lams) - len(solutions))
    return solutions, counts


def _embed(p, support, x_support):
    x = np.zeros(p)
    x[support] = x_support
    return x


def _certified(gram, c, support, x_support, signs, lam):
    """The coefficients with ``x_support`` on ``support``, if they satisfy the LASSO optimality conditions."""
    if np.any(x_support * np.asarray(signs) <= 0):
        return None
    x = np.zeros(c.size)
    x[support] = x_support
    gradient = c - gram @ x
    off = np.abs(gradient)
    off[support] = 0.0
    if np.any(off > lam * (1.0 + KKT_RTOL)):
        return None
    return x


def _rank_and_condition(values: np.ndarray) -> tuple[int, float]:
    """Rank and condition number of A from the eigenvalues of AᵀA (ascending)."""
    top = max(values[-1], 0.0)
    keep = values > top * np.finfo(float).eps * max(values.size, 10) * 10
    smallest = values[0]
    return int(keep.sum()), float(np.sqrt(top / smallest)) if smallest > 0 else float("inf")


class _AdmmState:
    """Warm-start state across λ: z (coefficients), w (scaled dual), ρ per output."""

    def __init__(self, z: np.ndarray, w: np.ndarray, rho: np.ndarray, lam: float | None):
        self.z, self.w, self.rho, self.lam = z, w, rho, lam

    @classmethod
    def cold(cls, problem: ScaledProblem, values: np.ndarray) -> "_AdmmState":
        p, ny = problem.cross.shape
        positive = values[values > values[-1] * 1e-12]
        # Geometric mean of the spectrum's ends: a standard good ADMM step for QPs.
        rho0 = float(np.sqrt(positive[0] * positive[-1])) if positive.size else 1.0
        return cls(np.zeros((p, ny)), np.zeros((p, ny)), np.full(ny, rho0), None)

    def rescale_dual(self, lam: float) -> None:
        # w = y/ρ with y a subgradient of λ‖z‖₁; keep it consistent with the new λ.
        if self.lam is not None:
            self.w *= lam / self.lam
        self.lam = lam


def _solve_one_lambda(problem, values, vectors, lam, state, max_iter, settled=None):
    """ADMM for the outputs not ``settled`` (a mask; those are left to the caller) at one λ."""
    gram, cross = problem.gram, problem.cross
    p, ny = cross.shape
    coef = np.zeros((p, ny))
    done = np.zeros(ny, dtype=bool) if settled is None else settled.copy()
    # λ >= ‖c‖∞ makes x = 0 optimal exactly.
    zero = np.abs(cross).max(axis=0) <= lam
    done |= zero
    z, w, rho = state.z, state.w, state.rho
    c_vt = vectors.T @ cross
    # Polish only when the sign pattern has settled and differs from the last failure.
    tried = [None] * ny
    previous_signs = np.sign(z)
    iterations = 0
    while not done.all() and iterations < max_iter:
        todo = np.flatnonzero(~done)
        for step in range(POLISH_EVERY):
            rhs = c_vt[:, todo] + rho[todo] * (vectors.T @ (z[:, todo] - w[:, todo]))
            x = vectors @ (rhs / (values[:, None] + rho[todo]))
            z_old = z[:, todo]
            # Over-relaxation (α = 1.6) speeds ADMM up on QPs at no cost.
            x_hat = RELAXATION * x + (1.0 - RELAXATION) * z_old
            v = x_hat + w[:, todo]
            z_new = np.sign(v) * np.maximum(np.abs(v) - lam / rho[todo], 0.0)
            w[:, todo] = v - z_new
            z[:, todo] = z_new
            iterations += 1
            if step % RHO_EVERY == RHO_EVERY - 1:
                # Residual balancing keeps primal and dual progress comparable.
                primal = np.linalg.norm(x - z_new, axis=0)
                dual = rho[todo] * np.linalg.norm(z_new - z_old, axis=0)
                factor = np.where(primal > 10 * dual, 2.0, np.where(dual > 10 * primal, 0.5, 1.0))
                rho[todo] *= factor
                w[:, todo] /= factor
        signs = np.sign(z)
        for i in todo:
            pattern = signs[:, i]
            settled = np.array_equal(pattern, previous_signs[:, i])
            if not settled or (tried[i] is not None and np.array_equal(pattern, tried[i])):
                continue
            polished = _polish(gram, cross[:, i], z[:, i], lam)
            if polished is None:
                tried[i] = pattern.copy()
                continue
            coef[:, i] = polished
            done[i] = True
            # Exact primal/dual pair as the warm start for the next λ.
            z[:, i] = polished
            w[:, i] = (cross[:, i] - gram @ polished) / rho[i]
        previous_signs = signs
    for i in np.flatnonzero(~done):
        coef[:, i] = z[:, i]
    coef[:, zero] = 0.0
    z[:, zero] = 0.0
    w[:, zero] = (cross[:, zero] / rho[zero]) if zero.any() else 0.0
    info = {"iterations": iterations, "converged": bool(done.all()),
            "unconverged": np.flatnonzero(~done).tolist()}
    return coef, info


def _polish(gram: np.ndarray, c: np.ndarray, z: np.ndarray, lam: float) -> np.ndarray | None:
    """Exact LASSO solution from the support and signs of ``z``, or None.

    Starting from z's support, a few active-set corrections (drop coefficients
    whose sign flips, add the most violated inactive ones) fix a support that
    ADMM has nearly, but not exactly, found. The answer is returned only when
    it satisfies the optimality conditions, so it is exact, never approximate.
    """
    support = np.flatnonzero(z)
    signs = np.sign(z[support])
    tolerance = lam * (1.0 + KKT_RTOL)
    for _ in range(MAX_ACTIVE_SET_STEPS):
        x = np.zeros_like(z)
        if support.size:
            x_s = _reduced_solve(gram, c, support, signs, lam)
            if x_s is None:
                return None
            flipped = x_s * signs <= 0
            if flipped.any():
                support, signs = support[~flipped], signs[~flipped]
                continue
            x[support] = x_s
        gradient = c - gram @ x
        violation = np.abs(gradient) - tolerance
        violation[support] = -np.inf
        if not np.any(violation > 0):
            return x
        # Add the worst offenders (a few at a time keeps the number of steps small).
        worst = np.argsort(-violation)[:max(1, int(np.sum(violation > 0)) // 4)]
        worst = worst[violation[worst] > 0]
        support = np.concatenate([support, worst])
        signs = np.concatenate([signs, np.sign(gradient[worst])])
    return None


def _reduced_solve(gram, c, support, signs, lam):
    """Solve G_SS x_S = c_S − λ·signs; None if the system is inconsistent."""
    block = gram[np.ix_(support, support)]
    rhs = c[support] - lam * signs
    try:
        import scipy.linalg

        factor = scipy.linalg.cho_factor(block, check_finite=False)
        return scipy.linalg.cho_solve(factor, rhs, check_finite=False)
    except np.linalg.LinAlgError:
        # Duplicate columns in the support: the optimum is not unique; take
        # the minimum-norm one if the reduced system is consistent.
        x_s = np.linalg.lstsq(block, rhs, rcond=None)[0]
        if np.linalg.norm(block @ x_s - rhs) > KKT_RTOL * max(np.linalg.norm(rhs), lam):
            return None
        return x_s
