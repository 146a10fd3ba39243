"""Freedoms the inputs leave undetermined: refused unless idle (the bodies they turn spin in
place and move no joint), and the spin of a rod between two ball joints locked by turning a
ball into a universal joint."""

from __future__ import annotations

import casadi as ca
import numpy as np

from ..errors import NonSquareSystemError
from ..model.edits import ball_to_universal
from ..model.rotations import rot_exp
from ..model.urdf import Tree
from ..symbolic.system import Symbolic
from .mechanism import Mechanism

#: A freedom the actuators leave undetermined is idle when it moves every joint by less than
#: this fraction of the model's size per unit of motion (a spin in place; CAD exports leave
#: offsets of a few 1e-4 m between axes meant to meet) [length unit / (rad or length unit)].
IDLE_TOL = 1e-3


def null_space(G: np.ndarray, rank: int) -> np.ndarray:
    """(columns, columns - rank) orthonormal directions of the unknowns that the closure
    Jacobian ``G`` of rank ``rank`` does not see."""
    _, _, Vt = np.linalg.svd(G)
    return Vt[rank:].T


def judge_idle(
    mech: Mechanism,
    full: Symbolic,
    y0: np.ndarray,
    th0: np.ndarray,
    c0: np.ndarray,
    G: np.ndarray,
    rank: int,
    dropped: list[str],
) -> None:
    """Refuse freedoms the actuators leave undetermined unless they are idle.

    A null direction of the closure Jacobian ``G`` (actuators fixed) is idle when it moves
    no joint of the mechanism: the bodies it turns spin in place about axes through all
    their joints (a rod between two ball joints turning about its own axis, two revolutes
    on one axis at a cut), and so move nothing but themselves. Every joint of the tree is
    judged (the origin of its child link), not one frame. A freedom that moves a joint is a
    real lack of actuation: refused, naming the links it moves. The reported frame must
    not turn either when the workspace has orientations.

    Args:
        mech: the mechanism; its candidates are the columns of ``G``.
        full: its unreduced closure system.
        y0: (m,) unknowns at the start, in the chart ``c0``.
        th0: (k,) actuated values at the start.
        c0: the chart of ``y0``.
        G: the closure Jacobian over the candidates at the start.
        rank: the rank of ``G``.
        dropped: labels of the closure rows the reduction leaves out.

    Raises:
        NonSquareSystemError: a freedom moves a link, or turns the reported frame.
    """
    nrows, ncols = G.shape
    candidates = mech.candidates
    null = null_space(G, rank)
    links = [j.child for j in mech.tree.joints if j.movable]
    origins = ca.vertcat(*[full.placements[lk][:3, 3] for lk in links])
    turn = ca.vec(full.pose[:3, :3])
    jac = ca.Function(
        "idle", [full.y, full.theta, full.c], [ca.jacobian(ca.vertcat(origins, turn), full.y)]
    )
    J = np.array(jac(y0, th0, c0))
    V = (J @ null)[: 3 * len(links)].reshape(len(links), 3, -1)
    speed = np.abs(V).max(axis=(1, 2))
    tol = IDLE_TOL * mech.length_scale
    moved = [lk for lk, v in zip(links, speed, strict=True) if v > tol]
    if moved:  # the reported frame first when the freedom moves it
        jx = ca.Function(
            "frame", [full.y, full.theta, full.c], [ca.jacobian(full.pose[:3, 3], full.y)]
        )
        if np.abs(np.array(jx(y0, th0, c0)) @ null).max() > tol:
            moved = [mech.frame, *(lk for lk in moved if lk != mech.frame)]
    names = [candidates[c] for c in range(ncols) if np.abs(null[c]).max() > 1e-6]
    if moved:
        sv = np.linalg.svd(V.reshape(-1, V.shape[-1]), compute_uv=False)
        real = int(np.sum(sv > tol))
        shown = moved if len(moved) <= 8 else [*moved[:8], f"... {len(moved) - 8} more"]
        raise NonSquareSystemError(
            f"{ncols} unknown joints, {nrows} closure rows, rank {rank}: {real} freedom(s) "
            f"left undetermined by the actuators {list(mech.actuated)} move links {shown} "
            f"(joints {names}; dependent rows {dropped}); the mechanism is under-actuated: "
            "add the missing actuators to 'name_mot' (or inputs=[...]), hold joints "
            "(locked={...}), or add a closure that fixes them",
            nrows,
            ncols,
            rank,
            mech.path,
        )
    rotations = {"roll", "pitch", "yaw", "phi"} & set(mech.workspace)
    if rotations and np.abs(J[3 * len(links) :] @ null).max() > IDLE_TOL:
        raise NonSquareSystemError(
            f"frame {mech.frame!r} turns with idle joints {names} (it spins in place): its "
            f"orientation {sorted(rotations)} is not determined; report another link "
            "(frame=...) or a workspace of positions only",
            nrows,
            ncols,
            rank,
            mech.path,
        )


def lock_spins(
    mech: Mechanism, balls: list[str], null: np.ndarray, canonical: np.ndarray, theta: np.ndarray
) -> tuple[Tree, dict[str, tuple[np.ndarray, np.ndarray]], dict[str, float]]:
    """Lock the spins of rods between two ball joints: each ball joint whose coordinates the
    reduction would lock becomes a universal joint without the spin (its rotation at home
    folded into its origin).

    Args:
        mech: the mechanism; its candidates are the rows of ``null`` and ``canonical``.
        balls: the ball joints to turn.
        null: (candidates, freedoms) the directions the closures leave free at home.
        canonical: (candidates,) the canonical unknowns at home.
        theta: (k,) the actuated values at home.

    Returns:
        ``(tree, spins, values)``: the tree with the balls turned, ball -> (rotation at home
        (3, 3), spin axis (3,)), and every candidate and actuated coordinate at home (the
        start of the reduction of the new tree).
    """
    candidates = mech.candidates
    values = dict(zip(candidates, canonical.tolist(), strict=True))
    values.update(zip(mech.actuated, theta.tolist(), strict=True))
    tree = mech.tree
    spins = {}
    for ball in balls:
        idx = [candidates.index(f"{ball}.{c}") for c in ("rx", "ry", "rz")]
        u, _, _ = np.linalg.svd(null[idx])
        rotation = rot_exp(canonical[idx])
        tree = ball_to_universal(tree, ball, rotation, u[:, 0])
        spins[ball] = (rotation, u[:, 0])
    return tree, spins, values
