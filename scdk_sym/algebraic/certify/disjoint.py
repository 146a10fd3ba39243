"""Whether the proven boxes of a set of points are pairwise disjoint, and how many distinct
zeros they hold: a proven box holds exactly one zero, so disjoint boxes hold different ones."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .certificate import CertificateSet


def sets_meeting(fast: list, sizes: list[int]) -> list[bool]:
    """Whether two boxes of a set may meet, the sets of one size compared at once.

    Args:
        fast: the first boxes' certificates of all sets, set after set (``None`` where not
            proven; :func:`~scdk_sym.algebraic.certify.points.first_boxes`).
        sizes: S points per set.

    Returns:
        S flags: False only when every point of the set is proven there and its boxes are
        pairwise disjoint.
    """
    out = [True] * len(sizes)
    if len(sizes) < 2:  # one set: apart in the first coordinate, else its own comparison
        if sizes and all(c is not None for c in fast):
            out[0] = not _apart_in_first(np.array([c.box[0] for c in fast]).reshape(-1, 2))
        return out
    starts = np.concatenate([[0], np.cumsum(sizes)]).astype(int).tolist()
    by_size: dict[int, list[int]] = {}
    for s, size in enumerate(sizes):
        if all(c is not None for c in fast[starts[s] : starts[s + 1]]):
            if size < 2:
                out[s] = False
            else:
                by_size.setdefault(size, []).append(s)
    for size, group in by_size.items():
        B = np.stack([c.box for s in group for c in fast[starts[s] : starts[s + 1]]])
        meet = boxes_meet(B.reshape(len(group), size, *B.shape[1:]))  # (G, size, size)
        diag = np.arange(size)
        meet[:, diag, diag] = False
        for s, m in zip(group, np.any(meet, axis=(1, 2)).tolist(), strict=True):
            out[s] = bool(m)
    return out


def _apart_in_first(first: np.ndarray) -> bool:
    """Whether the intervals ``first`` (P, 2) ``[lo, hi]`` (the boxes' first coordinates)
    are pairwise disjoint, so that the boxes are: sorted by ``lo``, each starts above every
    one before it ends (False where a bound is NaN)."""
    if len(first) < 2:
        return True
    if np.isnan(first).any():
        return False
    order = np.argsort(first[:, 0], kind="stable")
    lo, hi = first[order, 0], first[order, 1]
    return bool(np.all(lo[1:] > np.maximum.accumulate(hi)[:-1]))


def boxes_meet(box: np.ndarray) -> np.ndarray:
    """Which boxes intersect.

    Args:
        box: (..., P, n, 2) ``[lo, hi]`` of P boxes.

    Returns:
        (..., P, P) bool, ``[i, j]`` true when every coordinate's intervals of boxes i and j
        meet (the diagonal true).
    """
    lo, hi = box[..., 0], box[..., 1]
    return np.all(
        (lo[..., :, None, :] <= hi[..., None, :, :]) & (lo[..., None, :, :] <= hi[..., :, None, :]),
        axis=-1,
    )


def certificate_set(certs: tuple, disjoint: bool = False) -> CertificateSet:
    """The :class:`~scdk_sym.algebraic.certify.certificate.CertificateSet` of certificates:
    which are proven, which boxes meet, how many distinct zeros they hold.

    Args:
        certs: the certificates of the points of one set.
        disjoint: their boxes are known to be pairwise disjoint (not compared again).

    Returns:
        The set's certificate.
    """
    proven = [i for i, c in enumerate(certs) if c.proven]
    overlaps, duplicates = [], []
    if len(proven) > 1 and not disjoint:
        box = np.array([certs[i].box for i in proven])  # (P, n, 2)
        dom = np.array([certs[i].domain for i in proven])
        meet = boxes_meet(box)
        for a, b in zip(*np.nonzero(np.triu(meet, 1)), strict=True):
            i, j = proven[a], proven[b]
            overlaps.append((i, j))
            bi, di, bj, dj = box[a], dom[a], box[b], dom[b]
            inside_j = np.all((dj[:, 0] <= bi[:, 0]) & (bi[:, 1] <= dj[:, 1]))
            inside_i = np.all((di[:, 0] <= bj[:, 0]) & (bj[:, 1] <= di[:, 1]))
            if inside_i or inside_j:
                duplicates.append((i, j))
    if overlaps:
        roots = _components(len(certs), overlaps)
        count = len({roots[i] for i in proven})
    else:  # every proven zero its own component
        count = len(proven)
    failed = [i for i, c in enumerate(certs) if not c.proven]
    parts = [f"{len(proven)} of {len(certs)} solutions proven"]
    if failed:
        parts.append(f"not proven: {failed[:10]}{' ...' if len(failed) > 10 else ''}")
    if duplicates:
        parts.append(f"one zero counted twice: pairs {duplicates[:10]}")
    undecided = [e for e in overlaps if e not in duplicates]
    if undecided:
        parts.append(f"overlapping boxes (maybe one zero): pairs {undecided[:10]}")
    if not overlaps:
        parts.append(f"{count} distinct real zeros (boxes pairwise disjoint)")
    else:
        parts.append(f"{count} distinct real zeros{' at least' if undecided else ''}")
    return CertificateSet(
        certificates=certs,
        overlaps=tuple(overlaps),
        duplicates=tuple(duplicates),
        count=count,
        reason="; ".join(parts),
    )


def _components(count: int, edges: Sequence[tuple[int, int]]) -> list[int]:
    parent = list(range(count))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i, j in edges:
        parent[root(i)] = root(j)
    return [root(i) for i in range(count)]
