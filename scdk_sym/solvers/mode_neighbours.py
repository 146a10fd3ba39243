"""Certified modes continued from a neighbouring point's complete root set.

A point's complete set of complex roots (:class:`ModeSeed`) is tracked to a neighbouring
point along an arc through complex parameters (:data:`NEIGHBOUR_GAMMA`); when every path ends
regular at pairwise distinct roots, as many as the start system's, they are all the isolated
roots there (:func:`complete_set`), and the start system is not needed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .mode_report import REAL_TOL
from .start_system import DISTINCT

#: Gamma of the homotopy from a neighbour's root set
#: (:func:`~scdk_sym.solvers.homotopy_modes.modes_from_neighbour`): a fixed non-real one, so
#: the arc between two real parameter points runs through complex ones and misses the real
#: discriminant between them (where two real roots meet).
NEIGHBOUR_GAMMA = complex(np.exp(2j * np.pi * 0.2137))


@dataclass(frozen=True)
class ModeSeed:
    """The complete set of complex roots of a model's algebraic form at one parameter point:
    what the homotopy of a neighbouring point starts from.

    Attributes:
        p: (n_params,) complex parameters of the form (``form.params(theta)``).
        roots: (R, n) complex roots, R the start system's root count, pairwise distinct and
            every one the regular end of its path.
    """

    p: np.ndarray
    roots: np.ndarray


def complete_set(res, root_count: int) -> bool:
    """Every path ended regular, at ``root_count`` pairwise distinct finite roots."""
    return bool(complete_sets([res], root_count)[0])


def complete_sets(results: list, root_count: int, block: int = 1 << 22) -> np.ndarray:
    """:func:`complete_set` of each result (W,) bool, the pairwise distances of up to
    ``block`` entries at once."""
    from ..algebraic.distinct import pair_distances

    out = np.zeros(len(results), dtype=bool)
    full = [
        i for i, res in enumerate(results)
        if len(res.endpoints) == root_count and (res.status == "success").all()
        and np.isfinite(res.endpoints).all()
    ]  # fmt: skip
    if root_count < 2 or not full:
        out[full] = True
        return out
    n = results[full[0]].endpoints.shape[1]
    step = max(1, block // (root_count * root_count * max(n, 1)))
    for a in range(0, len(full), step):
        rows = full[a : a + step]
        z = np.stack([results[i].endpoints for i in rows])  # (S, R, n)
        scale = 1.0 + np.abs(z).max(axis=2)
        least = np.minimum(scale[:, :, None], scale[:, None])
        # the moduli only where a pair may be nearer than DISTINCT (margin: the division)
        d = pair_distances(z, DISTINCT * (1.0 + 1e-9) * least) / least
        diag = np.arange(root_count)
        d[:, diag, diag] = np.inf
        out[rows] = d.min(axis=(1, 2)) >= DISTINCT
    return out


def from_neighbours(
    form, start, neighbours: list[ModeSeed | None], P0: np.ndarray
) -> tuple[list, list[bool]]:
    """Each point's homotopy result from its neighbour's complete set, where that gives a
    complete set (all such points in one batch).

    Args:
        form: the model's scaled algebraic form.
        start: its start system (:func:`~scdk_sym.solvers.start_system.model_start_system`);
            no neighbour is used when it is not proven complete.
        neighbours: W complete root sets of neighbouring points (None where there is none).
        P0: (W, n_params) the points' complex parameters.

    Returns:
        ``(results, continued)``: W homotopy results (None where the point is still to be
        solved from the start system) and whether each came from its neighbour.
    """
    from ..algebraic.homotopy import solve_homotopies

    W = len(P0)
    results: list = [None] * W
    continued = [False] * W
    near = [w for w, nb in enumerate(neighbours) if nb is not None and start.trace_passed]
    if near:
        ends = solve_homotopies(
            form, np.stack([neighbours[w].p for w in near]),  # type: ignore[union-attr]
            np.stack([neighbours[w].roots for w in near]),  # type: ignore[union-attr]
            P0[near], gamma=NEIGHBOUR_GAMMA, real_tol=REAL_TOL,
        )  # fmt: skip
        for w, res, ok in zip(near, ends, complete_sets(ends, start.root_count), strict=True):
            if ok:
                results[w], continued[w] = res, True
    return results, continued
