"""An upper bound on the isolated roots of a model's algebraic form: the BKK bound.

Bernstein's theorem (Bernstein 1975, Kushnirenko 1976; Li and Wang 1996 for roots with zero
coordinates): whatever its coefficients, a square system ``f_1 .. f_n`` of Laurent
polynomials has at most ``MV(Q_1, ..., Q_n)`` isolated roots in ``(C*)^a x C^b`` (``a``
variables with negative exponents allowed, ``b`` ordinary ones), where ``Q_i`` is the convex
hull of the exponents of ``f_i`` and the origin and ``MV`` the mixed volume. The bound holds
for every offset ``b`` of the homotopy family ``G(z, p) + b`` at once (the origin stands for
the offset). When a complete-looking set of ``R`` distinct nonsingular roots is known and
``MV = R``, no isolated root is missing: the set is complete, with no random step (beyond
the numerical zero test of coefficients below).

Taken as written the bound of a form is far too large (two circles ``c^2 + s^2 = 1`` count
as two general conics), so the form is first rewritten, keeping its roots one to one:

1. isotropic coordinates: each angle's ``(c, s)`` becomes ``u = c + i s`` in ``C*``, with
   ``c = (u + 1/u) / 2`` and ``s = (u - 1/u) / (2 i)``; the circle row then holds identically
   and is dropped. A product of rotations about one axis keeps only ``u1 u2`` and
   ``1 / (u1 u2)`` where ``(c, s)`` had every cross term.
2. the rows are replaced by an invertible linear combination of sparse vectors of their
   span (``y + i z`` and ``y - i z`` for a planar point; differences of distance rows, which
   cancel ``|t|^2``): the candidates cancel ``k - 1`` monomials of a closure's ``k`` rows in
   every (or a sample of) ways, or are the reduced row echelon forms of all rows with the
   monomials taken densest first and in random orders; the sparsest independent ones are kept.
3. the mixed volume is a product over the irreducible blocks of the system (its block
   triangular form: a block of rows that uses only its own variables and those of blocks
   already counted, projected away), and in each block the sum of ``|det|`` over the fine
   mixed cells of a random lifting (Huber and Sturmfels 1995), enumerated depth first,
   branching on the support with the fewest compatible edges (dynamic enumeration,
   Mizutani, Takeda and Kojima 2007), one linear-programming feasibility test per partial
   cell. Two independent liftings must give the same number.

Where a block's mixed volume is out of reach (its budget spent, or a support whose lower hull
is too large), that block is bounded by a multihomogeneous Bezout number instead
(:func:`multihomogeneous_bezout`: each row multiplied by the monomial that makes its exponents
non-negative, which keeps its roots in the torus; the least over a few partitions of the
block's variables), a weaker bound that always finishes. ``RootBound.bezout`` names those
blocks.

Coefficients below :data:`ZERO_COEFFICIENT` times a row's largest are taken as exact zeros
(the rounding residue of a cancellation such as ``c1 c2 - s1 s2`` in ``u1 / u2``).
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from ..errors import AlgebraicFormError, DependencyError, HomotopyError
from ..graphs import triangular_decomposition

#: Coefficients below this fraction of a row's largest one are rounding residues (zero).
ZERO_COEFFICIENT = 1e-11
#: Most ``(k - 1)``-subsets of monomials cancelled per closure when sparsifying its rows.
SPARSIFY_SUBSETS = 4000
#: Largest product of term counts in one multiplication of the expansion (a larger model's
#: rows are not expanded: no bound).
MAX_TERMS = 200_000
#: Largest lower hull computed for the bound, as ``points ** ceil(d / 2)`` (the order of the
#: number of facets of a hull in ``d`` dimensions): qhull cannot be interrupted by the budget,
#: and one support of a 12-unknown Gepetto ankle block, 821 points in 7 dimensions, held it 78 s
#: a hull (over 15 minutes in all); larger supports leave the bound to the trace tests.
HULL_MAX_SIZE = 1e9
#: Default budget of :func:`root_bound` [s of this process's CPU time, so that a loaded machine
#: does not change the outcome].
BUDGET = 20.0


@dataclass(frozen=True)
class RootBound:
    """An upper bound on the isolated roots of a form's homotopy family ``G(z, p) + b``.

    Attributes:
        bound: the mixed volume: no member ``G(z, p) + b`` (any offsets ``b``) at the given
            ``p`` has more isolated roots in ``C^n``.
        blocks: size (variables) of each irreducible block, in the order counted.
        block_volumes: mixed volume of each block (``bound`` is their product).
        variables: names of the rewritten system's variables.
        cells: fine mixed cells enumerated (first lifting).
        seconds: wall-clock time of the computation [s].
        bezout: indices of the blocks bounded by a multihomogeneous Bezout number (their
            mixed volume out of reach); empty when ``bound`` is the BKK bound.
    """

    bound: int
    blocks: tuple[int, ...]
    block_volumes: tuple[int, ...]
    variables: tuple[str, ...]
    cells: int
    seconds: float
    bezout: tuple[int, ...] = ()

    @property
    def kind(self) -> str:
        """``"BKK root bound"`` or, with a block bounded by Bezout, what bounds it."""
        if not self.bezout:
            return "BKK root bound"
        return f"root bound (multihomogeneous Bezout on block(s) {list(self.bezout)})"


# ---------------------------------------------------------------------------- polynomials


class _Poly:
    """A sparse Laurent polynomial with complex coefficients: exponent tuple -> coefficient."""

    __slots__ = ("terms", "nvars")

    def __init__(self, terms: dict[tuple[int, ...], complex], nvars: int) -> None:
        self.terms = terms
        self.nvars = nvars

    @classmethod
    def constant(cls, value: complex, nvars: int) -> _Poly:
        return cls({(0,) * nvars: complex(value)} if value != 0 else {}, nvars)

    def is_constant(self) -> bool:
        return all(not any(e) for e in self.terms)

    def value(self) -> complex:
        return self.terms.get((0,) * self.nvars, 0j)

    def __add__(self, other: _Poly) -> _Poly:
        out = dict(self.terms)
        for e, c in other.terms.items():
            out[e] = out.get(e, 0j) + c
        return _Poly(out, self.nvars)

    def __neg__(self) -> _Poly:
        return _Poly({e: -c for e, c in self.terms.items()}, self.nvars)

    def __sub__(self, other: _Poly) -> _Poly:
        return self + (-other)

    def __mul__(self, other: _Poly) -> _Poly:
        if len(self.terms) * len(other.terms) > MAX_TERMS:
            raise HomotopyError(
                f"expanding the algebraic form multiplies polynomials of {len(self.terms)} and "
                f"{len(other.terms)} terms (more than {MAX_TERMS}); no root bound for it"
            )
        out: dict[tuple[int, ...], complex] = {}
        for e1, c1 in self.terms.items():
            for e2, c2 in other.terms.items():
                e = tuple(a + b for a, b in zip(e1, e2, strict=True))
                out[e] = out.get(e, 0j) + c1 * c2
        return _Poly(out, self.nvars)

    def __truediv__(self, other: _Poly) -> _Poly:
        if not other.is_constant() or other.value() == 0:
            raise AlgebraicFormError(
                "the algebraic form divides by a non-constant expression; its rows must be "
                "polynomials in the unknowns"
            )
        inv = 1.0 / other.value()
        return _Poly({e: c * inv for e, c in self.terms.items()}, self.nvars)

    def _const_fn(self, f) -> _Poly:
        if not self.is_constant():
            raise AlgebraicFormError(
                "the algebraic form takes cos or sin of an unknown; only parameters may "
                "enter through cos and sin"
            )
        return _Poly.constant(f(self.value()), self.nvars)

    def cos(self) -> _Poly:
        return self._const_fn(np.cos)

    def sin(self) -> _Poly:
        return self._const_fn(np.sin)


def _support(poly: _Poly) -> tuple[list[tuple[int, ...]], np.ndarray]:
    """Monomials and coefficients of a polynomial, rounding residues dropped."""
    if not poly.terms:
        return [], np.zeros(0, dtype=complex)
    mons = list(poly.terms)
    coef = np.array([poly.terms[e] for e in mons])
    keep = np.abs(coef) > ZERO_COEFFICIENT * np.abs(coef).max()
    return [m for m, k in zip(mons, keep, strict=True) if k], coef[keep]


def isotropic_rows(form, p: np.ndarray) -> tuple[list[_Poly], list[str], tuple[str, ...]]:
    """The closure and non-circle structural rows of a form at parameters ``p``, expanded in
    isotropic coordinates (see the module documentation).

    Args:
        form: an :class:`~scdk_sym.algebraic.form.AlgebraicForm` (or a scaled one).
        p: (n_params,) complex parameters.

    Returns:
        ``(rows, labels, variables)``: the rows as sparse polynomials, their labels, and the
        variable names (``joint.u`` for an angle, the form's names otherwise).

    Raises:
        AlgebraicFormError: a row that is no polynomial, or a circle row that does not vanish
            identically.
    """
    from .pairs import replay

    form = getattr(form, "form", form)  # a ScaledForm's rows have the same roots
    rows = form.rows
    variables: list[str] = []
    index: dict[int, int] = {}  # z index -> variable (lengths, floating parts)
    angles: dict[int, tuple[int, int]] = {}  # z index of c -> (variable, z index of s)
    for s in rows.slots:
        if s.kind == "angle":
            angles[s.z[0]] = (len(variables), s.z[1])
            variables.append(f"{s.joint}.u")
        else:
            for zi in s.z:
                index[zi] = len(variables)
                variables.append(rows.names[zi])
    nv = len(variables)

    def var(j: int, power: int = 1) -> _Poly:
        e = [0] * nv
        e[j] = power
        return _Poly({tuple(e): 1.0 + 0j}, nv)

    z: list[_Poly | None] = [None] * form.n
    for zc, (j, zs) in angles.items():
        u, ui = var(j), var(j, -1)
        z[zc] = _Poly.constant(0.5, nv) * (u + ui)
        z[zs] = _Poly.constant(-0.5j, nv) * (u - ui)
    for zi, j in index.items():
        z[zi] = var(j)
    params = [_Poly.constant(complex(v), nv) for v in np.asarray(p, dtype=complex)]
    (G,) = replay(form.G_real, [z, params], lambda v: _Poly.constant(v, nv))
    out, labels = [], []
    for g, label in zip(G, rows.labels, strict=True):
        if label.endswith(".circle"):
            coef = np.array(list(g.terms.values())) if g.terms else np.zeros(1)
            if np.abs(coef).max() > 1e-12:
                raise AlgebraicFormError(
                    f"circle row {label} does not vanish in isotropic coordinates "
                    f"(|coefficient| {np.abs(coef).max():.1e}); the form's angles must be "
                    "(cos, sin) pairs"
                )
            continue
        out.append(g)
        labels.append(label)
    if len(out) != nv:
        raise AlgebraicFormError(
            f"isotropic rewrite has {len(out)} rows for {nv} variables; the form is not square"
        )
    return out, labels, tuple(variables)


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


def _sparse_supports(
    polys: list[_Poly], groups: list[list[int]], subsets: int, rng
) -> list[np.ndarray]:
    """Supports of an invertible combination of ``polys`` made of sparse vectors of their
    span (see the module documentation); each support (m, nvars) int, origin left out.

    Candidates: the rows; in each group of rows (one closure), the vectors of the group's
    span that vanish on ``k - 1`` of its monomials (every choice, or ``subsets`` random
    ones); the reduced row echelon forms of all rows with the monomials taken densest first
    and in random orders. The sparsest independent candidates are kept.
    """
    k = len(polys)
    zero = (0,) * polys[0].nvars
    mons = sorted({e for q in polys for e in _support(q)[0]} - {zero})
    col = {m: i for i, m in enumerate(mons)}
    B = np.zeros((k, len(mons)), dtype=complex)
    for r, q in enumerate(polys):
        for m, c in zip(*_support(q), strict=True):
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


# ---------------------------------------------------------------------------- mixed volume


def _with_origin(points: np.ndarray) -> np.ndarray:
    n = points.shape[1]
    return np.unique(np.vstack([np.zeros((1, n), dtype=int), points]), axis=0)


def _blocks(supports: list[np.ndarray]) -> list[tuple[list[int], list[int]]] | None:
    """Irreducible blocks ``(rows, variables)`` in counting order (each block's rows use only
    its variables and those of earlier blocks); ``None`` without a row-variable matching."""
    uses = [set(np.flatnonzero(np.any(P != 0, axis=0)).tolist()) for P in supports]
    return triangular_decomposition(uses)


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


def _block_mixed_volume(supports: list[np.ndarray], rng, deadline: float) -> tuple[int, int]:
    """Mixed volume of ``n`` supports in ``Z^n`` (origin included) by fine mixed cells of one
    random lifting; returns ``(volume, cells)``."""
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


def _bezout_bound(supports: list[np.ndarray], names: list[str]) -> int:
    """The least multihomogeneous Bezout number over three partitions of a block's variables:
    one group (the total degree), one group per joint (variables named ``joint.*``), one per
    variable."""
    n = len(supports)
    by_joint: dict[str, list[int]] = {}
    for i, name in enumerate(names):
        by_joint.setdefault(name.rsplit(".", 1)[0], []).append(i)
    partitions = [[list(range(n))], list(by_joint.values()), [[i] for i in range(n)]]
    found = [multihomogeneous_bezout(supports, g) for g in partitions]
    return min(b for b in found if b is not None)


def mixed_volume(
    supports: list[np.ndarray],
    seed: int = 0,
    budget: float = BUDGET,
    names: list[str] | None = None,
) -> tuple[int, list[int], list[int], int, list[int]]:
    """The mixed volume of the convex hulls of ``supports`` and the origin.

    Args:
        supports: ``n`` integer arrays (m_i, n) of exponents (negative allowed).
        seed: seed of the random liftings.
        budget: budget [s of CPU time].
        names: the variables' names: with them, a block whose mixed volume is out of reach
            (budget, hull size) is bounded by :func:`_bezout_bound` instead.

    Returns:
        ``(bound, block sizes, block bounds, cells, blocks bounded by Bezout)``.

    Raises:
        HomotopyError: two liftings disagree, or (without ``names``) the budget ran out.
    """
    deadline = time.process_time() + budget
    pts = [_with_origin(np.asarray(P, dtype=int).reshape(-1, len(supports))) for P in supports]
    blocks = _blocks(pts)
    if blocks is None:
        return 0, [], [], 0, []
    sizes: list[int] = []
    vols: list[int] = []
    bezout: list[int] = []
    cells = 0
    total = 1
    for rows, cols in blocks:
        sub = [_with_origin(pts[r][:, cols]) for r in rows]
        results = []
        try:
            for k in range(2):
                rng = np.random.default_rng([seed, k, len(sizes)])
                results.append(_block_mixed_volume(sub, rng, deadline))
        except HomotopyError:
            if names is None:
                raise
            bezout.append(len(sizes))
            results = [(_bezout_bound(sub, [names[c] for c in cols]), 0)] * 2
        if results[0][0] != results[1][0]:
            raise HomotopyError(
                f"mixed volume of a block of {len(rows)} variables: two liftings give "
                f"{results[0][0]} and {results[1][0]}; the root bound is not computed"
            )
        sizes.append(len(rows))
        vols.append(results[0][0])
        cells += results[0][1]
        total *= results[0][0]
    return total, sizes, vols, cells, bezout


def root_bound(form, p: np.ndarray, seed: int = 0, budget: float = BUDGET) -> RootBound:
    """The BKK bound of a form's homotopy family at parameters ``p`` (module documentation).

    Args:
        form: an :class:`~scdk_sym.algebraic.form.AlgebraicForm` (or a scaled one).
        p: (n_params,) complex parameters (the start system's).
        seed: seed of the sparsifying samples and of the liftings.
        budget: budget of the mixed volume [s of CPU time].

    Returns:
        A :class:`RootBound`.

    Raises:
        AlgebraicFormError: the form's rows are not polynomials in the unknowns.
        HomotopyError: the mixed volume could not be computed reliably.
    """
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    polys, labels, variables = isotropic_rows(form, p)
    groups: dict[str, list[int]] = {}
    for i, label in enumerate(labels):
        groups.setdefault(label.rsplit(".", 1)[0], []).append(i)
    supports = _sparse_supports(polys, list(groups.values()), SPARSIFY_SUBSETS, rng)
    volume, sizes, vols, cells, bezout = mixed_volume(supports, seed, budget, list(variables))
    return RootBound(
        bound=volume,
        blocks=tuple(sizes),
        block_volumes=tuple(vols),
        variables=variables,
        cells=cells,
        seconds=time.perf_counter() - t0,
        bezout=tuple(bezout),
    )
