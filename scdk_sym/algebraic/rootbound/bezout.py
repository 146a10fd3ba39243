"""Multihomogeneous Bezout numbers: a weaker bound on the isolated roots than the mixed volume,
which always finishes."""

from __future__ import annotations

import math

import numpy as np

#: Most states (partial degree counts) of the multihomogeneous Bezout count of one partition.
BEZOUT_MAX_STATES = 5_000


def multihomogeneous_bezout(supports: list[np.ndarray], groups: list[list[int]]) -> int | None:
    """The multihomogeneous Bezout number of ``n`` rows for a partition of the variables.

    Each row is first multiplied by the monomial that makes its exponents non-negative (its
    roots with no zero coordinate are kept), then the number is the coefficient of
    ``prod_j a_j^(n_j)`` in ``prod_i sum_j d_ij a_j``, ``d_ij`` the row's degree in group
    ``j`` of ``n_j`` variables: an upper bound on the isolated roots in ``C^n``, whatever the
    coefficients.

    Args:
        supports: ``n`` integer arrays (m_i, n) of exponents (negative allowed).
        groups: a partition of ``range(n)``.

    Returns:
        The number, or ``None`` when the count would pass :data:`BEZOUT_MAX_STATES` states.
    """
    sizes = [len(g) for g in groups]
    if math.prod(s + 1 for s in sizes) > BEZOUT_MAX_STATES:
        return None
    degrees = []
    for P in supports:
        Q = P - P.min(axis=0)
        degrees.append([int(Q[:, g].sum(axis=1).max()) for g in groups])
    states: dict[tuple[int, ...], int] = {tuple(0 for _ in groups): 1}
    for d in degrees:  # distribute the rows over the groups, one row at a time
        nxt: dict[tuple[int, ...], int] = {}
        for used, count in states.items():
            for j, dj in enumerate(d):
                if dj and used[j] < sizes[j]:
                    key = used[:j] + (used[j] + 1,) + used[j + 1 :]
                    nxt[key] = nxt.get(key, 0) + count * dj
        states = nxt
    return states.get(tuple(sizes), 0)


def bezout_bound(supports: list[np.ndarray], names: list[str]) -> int:
    """The least multihomogeneous Bezout number over three partitions of a block's variables:
    one group (the total degree), one group per joint (variables named ``joint.*``), one per
    variable.

    Args:
        supports: ``n`` integer arrays (m_i, n) of exponents of the block's rows.
        names: the block's ``n`` variable names.

    Returns:
        An upper bound on the block's isolated roots.
    """
    n = len(supports)
    by_joint: dict[str, list[int]] = {}
    for i, name in enumerate(names):
        by_joint.setdefault(name.rsplit(".", 1)[0], []).append(i)
    partitions = [[list(range(n))], list(by_joint.values()), [[i] for i in range(n)]]
    found = [multihomogeneous_bezout(supports, g) for g in partitions]
    return min(b for b in found if b is not None)
