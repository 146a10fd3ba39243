"""Distinct rows of point sets: pairwise distances screened by the first coordinates, and the
removal of near-copies (one row per cluster, relative distance)."""

from __future__ import annotations

import numpy as np

#: Machine epsilon of binary64.
EPS = float(np.finfo(float).eps)


def pair_distances(z: np.ndarray, bound: np.ndarray | float) -> np.ndarray:
    """``max_k |z[g, i, k] - z[g, j, k]|`` (G, M, M) of complex (or real) rows ``z``
    (G, M, n) wherever it may be at most ``bound`` (broadcast to (G, M, M)); ``inf`` where it
    is surely above.

    The full moduli are computed only for the pairs whose first coordinates' real parts, a
    lower bound of the distance, are not already farther apart than ``bound``; those pairs
    get the values the full computation gives, bit for bit (NaN included; the others are
    ``inf`` even where a later coordinate is NaN), so a test ``<= bound`` (or with a larger
    bound) answers as on the full matrix. When every two rows are apart so
    (:func:`pairs_apart` with the largest bound), only the diagonal is computed.
    """
    if pairs_apart(z, float(np.max(bound))):
        out = np.full(z.shape[:-1] + z.shape[-2:-1], np.inf)
        with np.errstate(invalid="ignore"):
            diag = np.abs(z - z).max(axis=-1)  # 0, or NaN in a row with a NaN
        i = np.arange(z.shape[-2])
        out[:, i, i] = diag
        return out
    with np.errstate(invalid="ignore"):
        x = np.ascontiguousarray(z[..., 0].real)
        lower = np.abs(x[:, :, None] - x[:, None])  # |z| >= (1 - 2 eps) |Re z| after rounding
        near = ~(lower * (1.0 - 4.0 * EPS) > bound)  # NaN: computed
        out = np.full(lower.shape, np.inf)
        g, i, j = np.nonzero(near)
        out[g, i, j] = np.abs(z[g, i] - z[g, j]).max(axis=1)
    return out


def pairs_apart(z: np.ndarray, bound: float) -> bool:
    """Whether every two rows of each group of ``z`` (G, M, n) are surely farther apart than
    ``bound``: their first coordinates' real parts are (sorted, neighbours compared; False
    where one is NaN). :func:`pair_distances` with any bound up to ``bound`` is then
    ``inf`` off the diagonal."""
    x = np.sort(z[..., 0].real, axis=-1)
    with np.errstate(invalid="ignore"):  # a NaN gap (a NaN entry, inf - inf): not apart
        return bool(((x[..., 1:] - x[..., :-1]) * (1.0 - 4.0 * EPS) > bound).all())


def dedup_groups(xs: list[np.ndarray], tol: float, block: int = 1 << 20) -> list[np.ndarray]:
    """:func:`dedup` of each of several arrays (each (M_g, n)), the pairs of all groups
    compared at once (about ``block`` entries at a time); a group runs :func:`dedup` itself
    only where two of its rows meet."""
    out: list[np.ndarray] = [np.zeros((0, 0))] * len(xs)
    small = [g for g, x in enumerate(xs) if len(x) <= 1]
    for g in small:
        out[g] = dedup(xs[g], tol)
    by_size: dict[tuple, list[int]] = {}
    for g, x in enumerate(xs):
        if len(x) > 1:
            by_size.setdefault(x.shape, []).append(g)
    for (M, n), groups in by_size.items():
        step = max(1, block // (M * M * max(n, 1)))
        for a in range(0, len(groups), step):
            rows = groups[a : a + step]
            x = np.stack([xs[g] for g in rows])  # (G, M, n)
            scale = 1.0 + np.abs(x).max(axis=2)
            with np.errstate(invalid="ignore"):
                # the distances only where a pair may be near (margin: the division)
                d = pair_distances(x, tol * (1.0 + 1e-9) * scale[:, None, :])
                close = d / scale[:, None, :] <= tol  # as dedup: relative to the column's row
            diag = np.arange(M)
            close[:, diag, diag] = False
            meet = close.any(axis=(1, 2))
            for g, m, xg in zip(rows, meet.tolist(), x, strict=True):
                out[g] = dedup(xs[g], tol) if m else xg[np.lexsort(xg.real.T[::-1])]
    return out


def dedup(x: np.ndarray, tol: float, block: int = 256) -> np.ndarray:
    """Distinct rows of x (M, n), relative distance ``tol``; sorted lexicographically.

    A row is kept unless it lies within ``tol`` of a row kept before it, the distance relative
    to the kept row (``max|row - k| / (1 + max|k|)``); NaN distances never match. The
    distances are computed ``block`` rows at a time.
    """
    x = np.asarray(x)
    if len(x) <= 1:  # nothing to merge
        return np.zeros((0, x.shape[1]), dtype=x.dtype) if not len(x) else x.copy()
    scale = 1.0 + np.abs(x).max(axis=1)
    close = np.zeros((len(x), len(x)), dtype=bool)
    with np.errstate(invalid="ignore"):
        for a in range(0, len(x), block):
            d = np.abs(x[a : a + block, None] - x[None, : a + block]).max(axis=2)
            close[a : a + block, : a + block] = d / scale[None, : a + block] <= tol
    np.fill_diagonal(close, False)
    kept = list(range(len(x)))
    if close.any() and np.tril(close).any():  # in order: an earlier match counts if kept
        rows, kept = close.tolist(), []
        for i, row in enumerate(rows):
            if not any(row[j] for j in kept):
                kept.append(i)
    out = x[kept]
    return out[np.lexsort(out.real.T[::-1])]
