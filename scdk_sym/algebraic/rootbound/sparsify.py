"""Sparse supports of a square system: its rows replaced by an invertible combination of the
sparsest independent vectors of their span (fewer monomials, a smaller mixed volume, the same
roots)."""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable

import numpy as np

from .laurent import ZERO_COEFFICIENT, LaurentPolynomial, support

#: Most ``(k - 1)``-subsets of monomials cancelled per closure when sparsifying its rows.
SPARSIFY_SUBSETS = 4000


def _nonzero(v: np.ndarray) -> np.ndarray:
    return np.abs(v) > ZERO_COEFFICIENT * max(float(np.abs(v).max(initial=0.0)), 1e-300)


def _eliminated(B: np.ndarray, order: np.ndarray) -> list[np.ndarray]:
    """Combinations (rows of ``L``) of the rows of ``B`` in reduced row echelon form, the
    columns taken in ``order`` (partial pivoting)."""
    k = len(B)
    A = np.hstack([B[:, order], np.eye(k, dtype=complex)])
    row = 0
    for c in range(len(order)):
        if row == k:
            break
        piv = row + int(np.argmax(np.abs(A[row:, c])))
        if abs(A[piv, c]) <= 1e-9 * max(float(np.abs(A[:, c]).max()), 1e-300) or A[piv, c] == 0:
            continue
        A[[row, piv]] = A[[piv, row]]
        A[row] /= A[row, c]
        others = np.arange(k) != row
        A[others] -= A[others, c][:, None] * A[row][None]
        row += 1
    return list(A[:, len(order) :])


def sparse_supports(
    polys: list[LaurentPolynomial], groups: list[list[int]], subsets: int, rng
) -> list[np.ndarray]:
    """Supports of an invertible combination of ``polys`` made of sparse vectors of their
    span (see the module docs); each support (m, nvars) int, origin left out.

    Candidates: the rows; in each group of rows (one closure), the vectors of the group's
    span that vanish on ``k - 1`` of its monomials (every choice, or ``subsets`` random
    ones); the reduced row echelon forms of all rows with the monomials taken densest first
    and in random orders. The sparsest independent candidates are kept.

    Args:
        polys: the k rows.
        groups: the rows of each closure (indices into ``polys``).
        subsets: most ``(k - 1)``-subsets of monomials cancelled per group.
        rng: the random generator of the samples and orders.

    Returns:
        k integer arrays (m_i, nvars) of exponents.
    """
    k = len(polys)
    zero = (0,) * polys[0].nvars
    mons = sorted({e for q in polys for e in support(q)[0]} - {zero})
    col = {m: i for i, m in enumerate(mons)}
    B = np.zeros((k, len(mons)), dtype=complex)
    for r, q in enumerate(polys):
        for m, c in zip(*support(q), strict=True):
            if m != zero:
                B[r, col[m]] = c
    B /= np.maximum(np.abs(B).max(axis=1, keepdims=True), 1e-300)
    cands = list(np.eye(k, dtype=complex))
    cols = len(mons)
    for rows in groups:
        g = len(rows)
        if not 1 < g <= cols + 1:
            continue
        picks: Iterable[tuple[int, ...]]
        if math.comb(cols, g - 1) <= subsets:
            picks = itertools.combinations(range(cols), g - 1)
        else:
            picks = (tuple(rng.choice(cols, g - 1, replace=False)) for _ in range(subsets))
        for T in picks:
            u, sv, _ = np.linalg.svd(B[np.ix_(rows, list(T))], full_matrices=True)
            if sv[-1] <= 1e-9 * max(sv[0], 1e-300):
                continue  # the columns do not fix a unique vector
            lam = np.zeros(k, dtype=complex)
            lam[rows] = u[:, -1].conj()
            cands.append(lam)
    density = (np.abs(B) > 0).sum(axis=0)
    orders = [np.argsort(-density, kind="stable")] + [rng.permutation(cols) for _ in range(4)]
    for order in orders:
        cands.extend(_eliminated(B, order))
    cands.sort(key=lambda lam: int(_nonzero(lam @ B).sum()))
    chosen: list[np.ndarray] = []
    for lam in cands:
        if np.linalg.matrix_rank(np.vstack([*chosen, lam]), tol=1e-8) == len(chosen) + 1:
            chosen.append(lam)
        if len(chosen) == k:
            break
    out = []
    for lam in chosen:
        S = np.array([mons[i] for i in np.flatnonzero(_nonzero(lam @ B))], dtype=int)
        out.append(S.reshape(-1, len(zero)))
    return out
