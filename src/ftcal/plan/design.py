"""Greedy D-optimal selection of poses, by rank-r updates of the inverse information.

Adding a pose with rows ``Y`` (r × p) to the information ``M`` multiplies its
determinant by ``det(I + Y M⁻¹ Yᵀ)`` (matrix determinant lemma). The greedy
design starts from the prior (plus any recorded data) and adds, one at a time,
the candidate with the largest factor. After each choice ``M⁻¹`` and every
candidate's ``S = Y M⁻¹ Yᵀ`` are updated by the Woodbury identity, one matrix
product over the candidates per step: no refit, no inversion of ``M``.
"""

from __future__ import annotations

import numpy as np

from ..runtime.errors import FtcalError
from ..runtime.threads import map_ranges


def _log_det_identity_plus(s: np.ndarray) -> np.ndarray:
    """log det(I + S) for a stack of symmetric positive semi-definite S, stored (r, r, n); reads S[i, j], i >= j.

    A Cholesky factorisation written over the stack (r is at most 6 here): one
    vector operation per entry, on contiguous vectors, instead of one LAPACK
    call per candidate.
    """
    r = s.shape[0]
    if r == 1:
        return np.log1p(np.maximum(s[0, 0], 0.0))
    low: list[list[np.ndarray]] = [[] for _ in range(r)]  # low[i][k], k < i: the factor's entries
    out = np.zeros(s.shape[2])
    for j in range(r):
        d = s[j, j] + 1.0
        for k in range(j):
            d = d - low[j][k] * low[j][k]
        d = np.sqrt(np.maximum(d, 1e-300))
        out += np.log(d)
        for i in range(j + 1, r):
            e = s[i, j]
            for k in range(j):
                e = e - low[i][k] * low[j][k]
            low[i].append(e / d)
    return 2.0 * out


# Candidates per block of the largest products: Ctrl-C and SIGTERM are acted upon between blocks.
BLOCK_CANDIDATES = 1024


def greedy_design(rows: np.ndarray, n: int, start: np.ndarray) -> np.ndarray:
    """Indices of ``n`` distinct candidates chosen greedily for the largest log det of the information.

    Parameters
    ----------
    rows : ndarray of shape (n_candidates, r, p)
        Each candidate's rows (see :mod:`ftcal.plan.information`).
    n : int, how many to choose (<= n_candidates)
    start : ndarray of shape (p, p)
        Information before the design (prior + recorded data), positive definite.

    Returns
    -------
    ndarray of shape (n,), int, in the order they were chosen.
    """
    c, r, p = rows.shape
    if n > c:
        raise FtcalError(f"{n} poses asked for but only {c} candidates to choose from.")
    inverse = np.linalg.inv(start)
    inverse = 0.5 * (inverse + inverse.T)
    flat = rows.reshape(c * r, p)
    # S_c = Y_c M⁻¹ Y_cᵀ for every candidate, in blocks so a signal is acted upon between them
    s = np.empty((c, r, r))
    for a in range(0, c, BLOCK_CANDIDATES):
        block = rows[a:a + BLOCK_CANDIDATES]
        s[a:a + BLOCK_CANDIDATES] = np.einsum("crp,csp->crs", (block.reshape(-1, p) @ inverse).reshape(block.shape),
                                              block)
    chosen = np.empty(n, dtype=np.int64)
    taken = np.zeros(c, dtype=bool)
    for step in range(n):
        gain = _log_det_identity_plus(s.transpose(1, 2, 0))
        gain[taken] = -np.inf
        best = int(np.argmax(gain))
        chosen[step], taken[best] = best, True
        y = rows[best]                      # (r, p)
        v = inverse @ y.T                   # (p, r)
        # Woodbury: M⁻¹ ← M⁻¹ − V K⁻¹ Vᵀ with K = I + Y V = L Lᵀ; W = V L⁻ᵀ gives V K⁻¹ Vᵀ = W Wᵀ
        w = np.linalg.solve(np.linalg.cholesky(np.eye(r) + y @ v), v.T).T
        inverse -= w @ w.T
        inverse = 0.5 * (inverse + inverse.T)
        b = (flat @ w).reshape(c, r, r)     # Y_c W
        s -= b * b if r == 1 else b @ b.transpose(0, 2, 1)
    return chosen


def greedy_design_factored(features: np.ndarray, groups: np.ndarray, blocks: np.ndarray, n: int,
                           start: np.ndarray) -> np.ndarray:
    """:func:`greedy_design` for rows linear in a few features within each group (same choices, faster).

    Candidate ``c`` has rows ``Y_c = Σ_a features[c, a] · blocks[groups[c], a]`` (the payload
    objective: features (1, gx, gy, gz), one group per load). Then every
    ``S_c = Y_c M⁻¹ Y_cᵀ`` is a quadratic form in the features, so each step needs
    one small product per group and one (n_candidates, k²) × (k², r²) product,
    instead of a rank-r update of every candidate.

    Parameters
    ----------
    features : ndarray of shape (n_candidates, k)
    groups : ndarray of shape (n_candidates,), int in [0, n_groups)
    blocks : ndarray of shape (n_groups, k, r, p)
    n : int, how many to choose
    start : ndarray of shape (p, p), the information before the design

    Returns
    -------
    ndarray of shape (n,), int, in the order they were chosen.
    """
    c, k = features.shape
    n_groups, _, r, p = blocks.shape
    if n > c:
        raise FtcalError(f"{n} poses asked for but only {c} candidates to choose from.")
    # Candidates sorted by group, so each group's quadratic forms fill one contiguous slice.
    order = np.argsort(groups, kind="stable")
    bounds = np.searchsorted(groups[order], np.arange(n_groups + 1))
    x = features[order]
    pairs = (x[:, :, None] * x[:, None, :]).reshape(c, k * k)
    stacked = blocks.reshape(n_groups, k * r, p)
    inverse = np.linalg.inv(start)
    inverse = 0.5 * (inverse + inverse.T)
    s = np.zeros((r * r, c))  # S of every candidate, entry-major: contiguous vectors for the gain
    lower = np.array([i * r + j for i in range(r) for j in range(i + 1)])  # S is symmetric: the gain reads these
    chosen = np.empty(n, dtype=np.int64)
    taken = np.zeros(c, dtype=bool)
    for step in range(n):
        for g in range(n_groups):
            e = stacked[g]
            t = (e @ inverse @ e.T).reshape(k, r, k, r).transpose(0, 2, 1, 3).reshape(k * k, r * r)
            s[lower, bounds[g]:bounds[g + 1]] = t[:, lower].T @ pairs[bounds[g]:bounds[g + 1]].T
        stack = s.reshape(r, r, c)
        gain = np.concatenate(map_ranges(lambda a, b: _log_det_identity_plus(stack[:, :, a:b]), c, 4096))
        gain[taken] = -np.inf
        best = int(np.argmax(gain))
        chosen[step], taken[best] = order[best], True
        y = np.tensordot(features[order[best]], blocks[groups[order[best]]], axes=1)  # (r, p)
        v = inverse @ y.T
        w = np.linalg.solve(np.linalg.cholesky(np.eye(r) + y @ v), v.T).T
        inverse -= w @ w.T
        inverse = 0.5 * (inverse + inverse.T)
    return chosen


def random_design(n_candidates: int, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` distinct candidate indices drawn uniformly (the baseline a plan is compared with)."""
    return rng.choice(n_candidates, size=n, replace=False)
