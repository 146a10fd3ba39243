"""The BKK root bound of a form's homotopy family: the isotropic rewriting, the sparse
supports, and the mixed volume block by block (a multihomogeneous Bezout number where a
block's mixed volume is out of reach)."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ...errors import HomotopyError
from ...graphs import triangular_decomposition
from .bezout import bezout_bound
from .isotropic import isotropic_rows
from .mixedcells import block_mixed_volume
from .sparsify import SPARSIFY_SUBSETS, sparse_supports

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


def _with_origin(points: np.ndarray) -> np.ndarray:
    n = points.shape[1]
    return np.unique(np.vstack([np.zeros((1, n), dtype=int), points]), axis=0)


def _blocks(supports: list[np.ndarray]) -> list[tuple[list[int], list[int]]] | None:
    """Irreducible blocks ``(rows, variables)`` in counting order (each block's rows use only
    its variables and those of earlier blocks); ``None`` without a row-variable matching."""
    uses = [set(np.flatnonzero(np.any(P != 0, axis=0)).tolist()) for P in supports]
    return triangular_decomposition(uses)


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
            (budget, hull size) is bounded by :func:`~.bezout.bezout_bound` instead.

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
                results.append(block_mixed_volume(sub, rng, deadline))
        except HomotopyError:
            if names is None:
                raise
            bezout.append(len(sizes))
            results = [(bezout_bound(sub, [names[c] for c in cols]), 0)] * 2
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
    supports = sparse_supports(polys, list(groups.values()), SPARSIFY_SUBSETS, rng)
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
