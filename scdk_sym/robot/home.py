"""A home that a file states but that does not serve as a start as it is: projected onto the
closures with the least change, and moved off a singular configuration.

MJCF files state a home (the keyframe ``home``, else ``qpos0``) that simulators only need to
be close to assembled: MuJoCo's soft equality constraints pull it together in the first steps.
A start of the singularity-consistent method must close to rounding and be regular (the
closure Jacobian over the unknowns of full generic rank), so such a home is

1. projected: minimum-norm Gauss-Newton steps over every joint (inputs included) from the
   stated values, which converge to the assembled configuration nearest to them to first order;
2. moved, when singular there (a four-bar stretched flat, as Cassie's plantar rods at
   ``qpos0``): seeded small perturbations of every joint, each projected again, and the nearest
   one whose closure Jacobian has the generic rank with a margin.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

#: Relative smallest kept singular value of the closure Jacobian that counts as regular (four
#: orders above the rank cut-off of the square reduction, 1e-8).
REGULAR_MARGIN = 1e-4
#: Sizes of the perturbations tried when home is singular [rad or length unit, scaled].
MOVES = (1e-3, 3e-3, 1e-2, 3e-2, 0.1)
#: Perturbations tried per size.
TRIES = 8

Closure = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class Settled:
    """A settled home.

    Attributes:
        y: (m,) unknowns [rad or length unit].
        theta: (k,) inputs.
        note: one line saying what was done (empty when nothing was).
        subset: the independent rows home closes, when the others (redundant rows a file's
            rounding makes inconsistent) cannot close with them; ``None``: every row closes.
        regular: False when home is singular and no regular configuration was found near it.
    """

    y: np.ndarray
    theta: np.ndarray
    note: str
    subset: tuple[int, ...] | None = None
    regular: bool = True


def project(
    rows: Closure,
    y: np.ndarray,
    theta: np.ndarray,
    tol: float,
    steps: int = 60,
    subset: Sequence[int] | None = None,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Minimum-norm Gauss-Newton on the closure rows over every joint.

    Directions the rows see weakly (singular values below 1e-8 of the largest: a redundant
    row that rounding makes slightly inconsistent) take no step, so the projection stays near
    the start instead of leaping to where every row can hold.

    Args:
        rows: ``(y, theta) -> (g, dg/dy, dg/dtheta)``.
        y: (m,) unknowns at the start.
        theta: (k,) inputs at the start.
        tol: stop below this residual.
        steps: most steps.
        subset: the rows projected on (default: all).

    Returns:
        ``(y, theta, residual)``: the projection and its largest closure row (of ``subset``).
    """
    m = y.size
    z = np.concatenate([y, theta])
    best = np.inf
    pick = slice(None) if subset is None else list(subset)
    for _ in range(steps):
        g, Gy, Gt = rows(z[:m], z[m:])
        g, G = g[pick], np.hstack([Gy, Gt])[pick]
        best = float(np.abs(g).max()) if g.size else 0.0
        if best < tol:
            break
        dz = np.linalg.lstsq(G, -g, rcond=1e-8)[0]
        if np.linalg.norm(dz) < 1e-15:
            break
        z = z + dz
    return z[:m], z[m:], best


def independent_rows(G: np.ndarray) -> tuple[int, ...]:
    """Indices of a largest set of independent rows of ``G`` (pivoted Gram-Schmidt, rank cut
    at 1e-8 of the largest row), in order."""
    A = np.array(G, dtype=float)
    norms = np.linalg.norm(A, axis=1)
    top = float(norms.max()) if norms.size else 0.0
    chosen: list[int] = []
    while top > 0:
        norms = np.linalg.norm(A, axis=1)
        norms[chosen] = -1
        i = int(np.argmax(norms))
        if norms[i] <= 1e-8 * top:
            break
        chosen.append(i)
        u = A[i] / norms[i]
        A = A - np.outer(A @ u, u)
    return tuple(sorted(chosen))


def _rank_margin(G: np.ndarray) -> tuple[int, float]:
    """``(rank, margin)`` of G: numerical rank and the smallest kept singular value relative
    to the largest."""
    sv = np.linalg.svd(G, compute_uv=False)
    if not sv.size or sv[0] == 0:
        return 0, 0.0
    rank = int(np.sum(sv > 1e-8 * sv[0]))
    return rank, float(sv[rank - 1] / sv[0])


def settle(
    rows: Closure,
    y: np.ndarray,
    theta: np.ndarray,
    names: Sequence[str],
    tol: float,
    seed: int = 0,
) -> Settled:
    """A home that closes to ``tol`` and is regular, as near as found to ``(y, theta)``.

    Args:
        rows: ``(y, theta) -> (g, dg/dy, dg/dtheta)``: every closure row.
        y: (m,) unknowns as stated.
        theta: (k,) inputs as stated.
        names: the m + k coordinate names (y's, then theta's), for the note.
        tol: closure tolerance [model length unit].
        seed: seed of the perturbations.

    Returns:
        The settled home. Where no projection closes, the best one (its residual says so in
        the note, and the model's own check refuses it).
    """
    y0, th0 = np.asarray(y, dtype=float), np.asarray(theta, dtype=float)
    start = np.concatenate([y0, th0])
    g = rows(y0, th0)[0]
    stated = float(np.abs(g).max()) if g.size else 0.0
    notes = []
    yp, tp = y0, th0
    subset = None
    if stated > tol:
        yp, tp, res = project(rows, y0, th0, 1e-3 * tol)
        if res > tol:  # redundant rows that rounding makes inconsistent: an independent set
            _, Gy, Gt = rows(y0, th0)
            subset = independent_rows(np.hstack([Gy, Gt]))
            yp, tp, res = project(rows, y0, th0, 1e-3 * tol, subset=subset)
        notes.append(
            f"home closed to {stated:.2g} only; projected onto the closures (residual {res:.1e}, "
            + _change(start, np.concatenate([yp, tp]), names)
            + ")"
        )
    m = y0.size
    G = rows(yp, tp)[1]
    rank, margin = _rank_margin(G)
    if rank == min(G.shape) and margin > REGULAR_MARGIN:
        return Settled(yp, tp, "; ".join(notes), subset)
    rng = np.random.default_rng(seed)
    samples = []
    for size in MOVES:
        for _ in range(TRIES):
            d = rng.standard_normal(start.size)
            d *= size / np.linalg.norm(d)
            ys, ts, res = project(rows, yp + d[:m], tp + d[m:], 1e-3 * tol, subset=subset)
            if res > tol:
                continue
            r, mg = _rank_margin(rows(ys, ts)[1])
            samples.append((r, mg, ys, ts))
        generic = max([rank, *(s[0] for s in samples)])
        good = [s for s in samples if s[0] == generic and s[1] > REGULAR_MARGIN]
        if rank == generic and margin > REGULAR_MARGIN:
            break
        if good:
            z = np.concatenate([yp, tp])
            _, _, yb, tb = min(good, key=lambda s: np.linalg.norm(np.concatenate(s[2:]) - z))
            notes.append(
                f"home singular (closure rank {rank} where {generic} is generic); moved to a "
                "regular assembled configuration nearby ("
                + _change(z, np.concatenate([yb, tb]), names)
                + ")"
            )
            yp, tp = yb, tb
            break
    else:
        generic = max([rank, *(s[0] for s in samples)])
        if rank < generic or margin <= REGULAR_MARGIN:
            notes.append(
                f"home singular (closure rank {rank} where {generic} is generic) and no regular "
                f"assembled configuration found within {MOVES[-1]:g} of it"
            )
            return Settled(yp, tp, "; ".join(notes), subset, regular=False)
    return Settled(yp, tp, "; ".join(notes), subset)


def _change(a: np.ndarray, b: np.ndarray, names: Sequence[str]) -> str:
    """``largest change 0.012 (joint)``."""
    d = np.abs(b - a)
    i = int(np.argmax(d)) if d.size else 0
    return f"largest change {d[i]:.3g} ({names[i]})" if d.size else "no change"
