"""The mixed volume of ``n`` supports in ``Z^n`` by the fine mixed cells of one random lifting
(Huber and Sturmfels 1995), enumerated depth first, branching on the support with the fewest
compatible edges (Mizutani, Takeda and Kojima 2007), one linear-programming feasibility test
per partial cell."""

from __future__ import annotations

import itertools
import time

import numpy as np

from ...errors import DependencyError, HomotopyError

#: Largest lower hull computed for the bound, as ``points ** ceil(d / 2)`` (the order of the
#: number of facets of a hull in ``d`` dimensions): qhull cannot be interrupted by the budget,
#: and one support of a 12-unknown Gepetto ankle block, 821 points in 7 dimensions, held it 78 s
#: a hull (over 15 minutes in all); larger supports leave the bound to the trace tests.
HULL_MAX_SIZE = 1e9


def _scipy():
    """``(linprog, ConvexHull, QhullError)`` from SciPy, imported on first use."""
    try:
        from scipy.optimize import linprog
        from scipy.spatial import ConvexHull, QhullError
    except ImportError as exc:
        raise DependencyError(
            f"the root bound needs SciPy ({exc}); install it: pip install scipy"
        ) from exc
    return linprog, ConvexHull, QhullError


def _feasible(eq_a, eq_b, ub_a, ub_b) -> bool:
    """Whether ``{x: eq_a x = eq_b, ub_a x <= ub_b}`` is not empty (one LP)."""
    linprog, _, _ = _scipy()

    n = eq_a.shape[1]
    # a quick try: the least-squares point of the equalities
    x = np.linalg.lstsq(eq_a, eq_b, rcond=None)[0] if len(eq_a) else np.zeros(n)
    if np.allclose(eq_a @ x, eq_b, atol=1e-9) and np.all(ub_a @ x <= ub_b - 1e-12):
        return True
    res = linprog(
        np.zeros(n), A_ub=ub_a, b_ub=ub_b, A_eq=eq_a if len(eq_a) else None,
        b_eq=eq_b if len(eq_a) else None, bounds=[(None, None)] * n, method="highs",
    )  # fmt: skip
    return res.status == 0


def _constraints(P: np.ndarray, w: np.ndarray, a: int, b: int):
    """Equality and inequalities on the inner normal ``alpha`` for the edge ``(a, b)`` of the
    lifted support ``(P, w)`` to be its lowest face."""
    eq_a = (P[b] - P[a])[None].astype(float)
    eq_b = np.array([w[a] - w[b]])
    rest = np.array([c for c in range(len(P)) if c not in (a, b)], dtype=int)
    ub_a = -(P[rest] - P[a]).astype(float)
    ub_b = w[rest] - w[a]
    return eq_a, eq_b, ub_a, ub_b


def _lower_edges(P: np.ndarray, w: np.ndarray) -> list[tuple[int, int]]:
    """Edges of the lower hull of the lifted points ``(P, w)`` (a generic lifting: the lower
    hull is a triangulation), from the convex hull in the affine span of ``P``."""
    _, ConvexHull, QhullError = _scipy()
    m = len(P)
    X = (P - P[0]).astype(float)
    _, sv, vt = np.linalg.svd(X, full_matrices=False)
    d = int(np.sum(sv > 1e-9 * max(sv.max(initial=0.0), 1.0)))
    if d == 0:
        return []
    if m == d + 1:
        return list(itertools.combinations(range(m), 2))
    if float(m) ** ((d + 1) // 2) > HULL_MAX_SIZE:
        raise HomotopyError(
            f"a support of {m} points in {d} dimensions: its lower hull is out of reach; the "
            "root bound is not computed"
        )
    lifted = np.hstack([X @ vt[:d].T, w[:, None]])
    try:
        hull = ConvexHull(lifted)
    except QhullError:  # degenerate: every pair, each tested by the cells' programs
        return list(itertools.combinations(range(m), 2))
    edges: set[tuple[int, int]] = set()
    for simplex, eq in zip(hull.simplices, hull.equations, strict=True):
        if eq[-2] < 0:  # outward normal pointing down: a lower facet
            for a, b in itertools.combinations(sorted(simplex.tolist()), 2):
                edges.add((a, b))
    return sorted(edges)


def block_mixed_volume(supports: list[np.ndarray], rng, deadline: float) -> tuple[int, int]:
    """Mixed volume of ``n`` supports in ``Z^n`` (origin included) by fine mixed cells of one
    random lifting.

    Args:
        supports: ``n`` integer arrays (m_i, n) of exponents, the origin among them.
        rng: the random generator of the lifting.
        deadline: ``time.process_time()`` [s] after which the enumeration stops.

    Returns:
        ``(volume, cells)``.

    Raises:
        HomotopyError: out of time, or a lower hull out of reach (:data:`HULL_MAX_SIZE`).
    """
    n = len(supports)
    if n == 1:
        x = supports[0][:, 0]
        return int(x.max() - x.min()), 1
    w = [rng.uniform(0.0, 1.0, len(P)) for P in supports]
    cons = [
        {(a, b): _constraints(P, wi, a, b) for a, b in _lower_edges(P, wi)}
        for P, wi in zip(supports, w, strict=True)
    ]
    volume = cells = nodes = 0
    dirs_of = [
        {e: (P[e[1]] - P[e[0]]).astype(float) for e in c}
        for P, c in zip(supports, cons, strict=True)
    ]

    def compatible(A, Bv, U, Ub, D, i, e) -> bool:
        """Whether edge ``e`` of support ``i`` extends the partial cell ``(A, U)``."""
        nonlocal nodes
        nodes += 1
        if time.process_time() > deadline:
            raise HomotopyError(
                f"mixed volume of a block of {n} variables: out of time after {nodes} "
                "partial cells; the root bound is not computed (raise its time budget)"
            )
        d = dirs_of[i][e]
        if np.linalg.matrix_rank(np.vstack([D, d])) < len(D) + 1:
            return False
        ea, eb, ua, ubb = cons[i][e]
        A2, B2 = np.vstack([A, ea]), np.concatenate([Bv, eb])
        U2, Ub2 = np.vstack([U, ua]), np.concatenate([Ub, ubb])
        if len(A2) == n:  # a vertex: check it
            x = np.linalg.solve(A2, B2)
            return bool(np.all(U2 @ x <= Ub2 + 1e-12))
        return _feasible(A2, B2, U2, Ub2)

    def dfs(remaining: dict[int, list], A, Bv, U, Ub, D) -> None:
        """Dynamic enumeration: branch on the support with the fewest compatible edges."""
        nonlocal volume, cells
        j = min(remaining, key=lambda i: len(remaining[i]))
        for e in remaining[j]:
            d = dirs_of[j][e]
            ea, eb, ua, ubb = cons[j][e]
            A2, B2 = np.vstack([A, ea]), np.concatenate([Bv, eb])
            U2, Ub2 = np.vstack([U, ua]), np.concatenate([Ub, ubb])
            D2 = np.vstack([D, d])
            if len(remaining) == 1:  # compatible() checked this cell's vertex
                volume += int(round(abs(np.linalg.det(D2))))
                cells += 1
                continue
            nxt = {}
            for i, edges in remaining.items():
                if i == j:
                    continue
                keep = [f for f in edges if compatible(A2, B2, U2, Ub2, D2, i, f)]
                if not keep:
                    break
                nxt[i] = keep
            else:
                dfs(nxt, A2, B2, U2, Ub2, D2)

    empty = np.zeros((0, n))
    dfs({i: list(c) for i, c in enumerate(cons)}, empty, np.zeros(0), empty, np.zeros(0), empty)
    return volume, cells
