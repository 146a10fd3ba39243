"""The derivative kernel of the generated C transmission: the closures in each loop's frame.

The model's closures ``g`` are written in the world frame: the position rows of a loop are
``p_a - p_b`` in world coordinates, which a joint above the loop (a hip motor over the knee
loop, the knee over the ankle) rotates. Their derivatives in such a joint vanish only at the
solution (``R' R^T (p_a - p_b)``), not structurally: ``J_s`` and ``J_p`` then hold columns
that cost as much as the rest and contribute nothing at ``g = 0``.

:func:`loop_jacobians` builds the same closures with each loop's placements relative to its
root (the deepest link both of its frames hang from): ``g' = S g``, ``S`` block diagonal per
closure with ``R_root^T`` on its position rows and the identity on its rotation rows
(``R_a^T R_b`` does not depend on the frame) and distance rows. ``S`` is invertible, so
``g' = 0`` is the same solution set, and at a solution ``J_p' = S J_p``, ``J_s' = S J_s``
(the terms ``(dS) g`` vanish): ``J_p'^-1 J_s' = J_p^-1 J_s`` (the implicit function theorem
on either system gives the derivative of the same solution map), and each stage of the
block-triangular ``J_p`` (:func:`~scdk_sym.robot.blocks.triangular_blocks`) keeps its
singular values (``S`` is orthogonal on the rows of a stage). A closure is rewritten only
where that holds: a 3d, 6d or distance closure whose position rows are all kept by the square
reduction and whose kept rows lie in one stage; and the whole rewrite only if its ``J_p``,
``J_s`` involve no entry the world-frame ones do not (the stages and their inputs hold as
they are). Otherwise the kernel is the world-frame ``J_p``, ``J_s``.

The derivatives themselves are written from the joints' screw axes
(:mod:`scdk_sym.symbolic.screws`: one cross product per joint and loop instead of the chain
rule through each product of placements; on digit_like 2378 operations instead of 4404) for
the closures that allows, the others differentiated; both are the exact Jacobian of ``g'``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import casadi as ca
import numpy as np

from ..robot import Model
from ..robot.blocks import Block, row_closures
from ..symbolic.kinematics import closure_residual, link_placements
from ..symbolic.screws import closure_joint_jacobian

#: Closure types whose residual is frame-covariant: position rows rotate with the frame,
#: rotation and distance rows do not change (a "2d" closure keeps world x-y: not rewritten).
COVARIANT = ("3d", "6d", "distance")


def loop_jacobians(model: Model, stages: Sequence[Block]) -> tuple[ca.SX, ca.SX]:
    """``(J_p', J_s')`` of the closures in each loop's root frame (see the module docstring),
    or the world-frame ``(J_p, J_s)``; written from the joints' screw axes where
    :func:`~scdk_sym.symbolic.screws.closure_joint_jacobian` applies (the same derivatives in
    about half the operations), by differentiation elsewhere."""
    sym = model.symbolic
    g, screws = _loop_closures(model, stages)
    P, S = ca.jacobian_sparsity(g, sym.y), ca.jacobian_sparsity(g, sym.theta)
    if not (_within(P, sym.J_p.sparsity()) and _within(S, sym.J_s.sparsity())):
        return sym.J_p, sym.J_s
    S_p, S_s = _screw_rows(model, screws, g, list(model.rows))
    return ca.project(S_p, P), ca.project(-S_s, S)


def derivative_kernel(model: Model, J_p: ca.SX, J_s: ca.SX, name: str) -> ca.Function:
    """``(y, theta, c) -> (J_p, J_s)``, dense column-major (the C source's kernel)."""
    sym = model.symbolic
    return ca.Function(
        name,
        [sym.y, sym.theta, sym.c],
        [ca.densify(J_p), ca.densify(J_s)],
        ["y", "theta", "c"],
        ["J_p", "J_s"],
        {"cse": True},
    )


def _loop_closures(
    model: Model, stages: Sequence[Block]
) -> tuple[ca.SX, list[dict[str, ca.SX] | None]]:
    """The kept closure rows ``g'``, each eligible closure in its loop's root frame, and per
    closure its rows' derivative in each joint coordinate from the screw axes (``None``
    where not written so)."""
    sym, tree = model.symbolic, model.tree
    stage_of = {r: i for i, st in enumerate(stages) for r in st.rows}
    kept = {int(r): i for i, r in enumerate(model.rows)}
    parent = {j.child: j.parent for j in tree.joints}
    frames = {tree.root: sym.placements}
    rows, screws, start = [], [], 0
    for cl in model.closures:
        span = range(start, start + cl.rows)
        start += cl.rows
        root = tree.root
        if cl.type in COVARIANT and _eligible(cl.type, span, kept, stage_of):
            root = _common_ancestor(parent, cl.frame_a, cl.frame_b)
        if root not in frames:
            frames[root] = link_placements(tree, sym.values, sym.charts, base=root)
        T = frames[root]
        rows.append(closure_residual(cl, T[cl.frame_a], T[cl.frame_b], sym.values))
        screws.append(closure_joint_jacobian(tree, cl, T, root))
    return ca.vertcat(*rows)[list(model.rows)], screws


def _screw_rows(
    model: Model, screws: Sequence[dict[str, ca.SX] | None], g: ca.SX, rows: Sequence[int]
) -> tuple[ca.SX, ca.SX]:
    """``(dg'/dy, dg'/dtheta)`` on the kept rows: each closure's joint columns by the chain
    rule through the joints' values, and the rows of the closures without screw columns
    differentiated (``g`` holds the kept rows)."""
    sym = model.symbolic
    names = sorted({name for cols in screws if cols for name in cols})
    values = ca.vertcat(*[ca.SX(sym.values[n]) for n in names]) if names else ca.SX(0, 1)
    dq_dy, dq_dt = ca.jacobian(values, sym.y), ca.jacobian(values, sym.theta)
    blocks = [
        ca.SX(cl.rows, len(names)) if cols is None
        else ca.horzcat(*[cols.get(n, ca.SX(cl.rows, 1)) for n in names])
        for cl, cols in zip(model.closures, screws, strict=True)
    ]  # fmt: skip
    D = ca.vertcat(*blocks)[list(rows), :]
    S_p, S_s = D @ dq_dy, D @ dq_dt
    owner = row_closures(model)
    plain = [i for i, r in enumerate(rows) if screws[owner[r]] is None]
    if plain:
        S_p[plain, :] = ca.jacobian(g[plain], sym.y)
        S_s[plain, :] = ca.jacobian(g[plain], sym.theta)
    return S_p, S_s


def _eligible(kind: str, span: range, kept: Mapping[int, int], stage_of: Mapping) -> bool:
    """A closure whose position rows are all kept or all dropped, its kept rows in one stage."""
    position = list(span)[: 1 if kind == "distance" else 3]
    if 0 < sum(r in kept for r in position) < len(position):
        return False
    return len({stage_of.get(kept[r], -1) for r in span if r in kept}) <= 1


def _common_ancestor(parent: Mapping[str, str], a: str, b: str) -> str:
    """The deepest link that both ``a`` and ``b`` are (or hang from)."""
    above = [a]
    while above[-1] in parent:
        above.append(parent[above[-1]])
    seen = {b}
    while b in parent:
        b = parent[b]
        seen.add(b)
    return next(link for link in above if link in seen)


def _within(new: ca.Sparsity, old: ca.Sparsity) -> bool:
    """1 if every structural nonzero of ``new`` is one of ``old``."""
    mine = set(zip(*new.get_triplet(), strict=True))
    return mine <= set(zip(*old.get_triplet(), strict=True))


def pattern(expr: ca.SX) -> np.ndarray:
    """The structural nonzeros of an expression, as a boolean matrix."""
    return np.array(ca.DM(expr.sparsity(), 1), dtype=bool)
