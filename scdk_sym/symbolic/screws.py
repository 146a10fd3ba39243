"""Closure Jacobians from the joints' screw axes, instead of differentiating the expressions.

A revolute joint ``j`` turns every link below it about its axis ``w_j`` through its origin
``o_j`` (both where the placements put them): a point ``p`` below it moves by
``w_j x (p - o_j)`` per radian and a rotation ``R`` by ``[w_j]_x R``; a prismatic joint moves
the points below it by ``w_j`` per unit length. The derivative of a closure's residual in a
joint's coordinate follows in a few operations from the placements the residual is built of:

- position rows ``p_a - p_b``: ``w_j x (p_a - o_j)`` for a joint above frame ``a`` (minus the
  same at ``p_b`` for a joint above ``b``);
- rotation rows ``r = 1/2 vee(R_a^T R_b)``: ``(s_b - s_a) G w_j``, with ``G`` the 3 x 3 matrix
  of the linear map ``w -> 1/2 vee(R_a^T [w]_x R_b)`` (``s_a``, ``s_b`` = 1 for a joint above
  ``a``, ``b``);
- a distance row ``(|d|^2 - L^2) / (2 L)``: ``d . d'(q) / L``.

These are the exact derivatives (not an approximation near a solution), so the Jacobian is
the one CasADi's differentiation gives, with about half its operations on a leg's loops:
the chain rule through each product of placements is replaced by one cross product per
joint and row block. Only closures between frames hanging from one-coordinate joints
(revolute, continuous, prismatic) below the placements' base are written so; the caller
differentiates the others.
"""

from __future__ import annotations

from collections.abc import Mapping

import casadi as ca
import numpy as np

from ..model.rotations import skew, vee
from ..model.spec import Closure
from ..model.urdf import Joint, Tree

#: Closure types whose Jacobian rows :func:`closure_joint_jacobian` writes.
SUPPORTED = ("3d", "6d", "distance")
#: Joint types with one coordinate whose motion is a screw about or along their axis.
SCREW_JOINTS = ("revolute", "continuous", "prismatic")


def closure_joint_jacobian(
    tree: Tree, closure: Closure, placements: Mapping[str, ca.SX], base: str
) -> dict[str, ca.SX] | None:
    """The derivative of a closure's residual rows in each joint coordinate that moves them.

    Args:
        tree: the URDF tree.
        closure: the closure (its residual as :func:`~scdk_sym.symbolic.kinematics.
            closure_residual` writes it, frames ``a`` and ``b`` below ``base``).
        placements: link -> 4 x 4 placement relative to ``base`` (``link_placements`` with
            that base).
        base: the link the placements are relative to.

    Returns:
        joint name -> column of the residual's rows (a ``closure.rows`` x 1 SX), for the
        joints between ``base`` and either frame (a joint above both: the sum of its motions of
        both, which cancel in the rotation rows); ``None`` where this closure is not
        written so (its type, a length given by a joint, or a joint on its paths that is not
        a one-coordinate screw).
    """
    if closure.type not in SUPPORTED or (closure.type == "distance" and closure.length_joint):
        return None
    paths = [_path(tree, closure.frame_a, base), _path(tree, closure.frame_b, base)]
    if any(p is None or any(j.type not in SCREW_JOINTS for j in p) for p in paths):
        return None
    T_a, T_b = placements[closure.frame_a], placements[closure.frame_b]
    p_a, p_b = T_a[:3, 3], T_b[:3, 3]
    if closure.type == "6d":
        R_a, R_b = T_a[:3, :3], T_b[:3, :3]
        G = ca.horzcat(*[0.5 * vee(R_a.T @ skew(ca.DM(e)) @ R_b) for e in np.eye(3)])
    columns: dict[str, ca.SX] = {}
    for sign, point, path in ((1.0, p_a, paths[0]), (-1.0, p_b, paths[1])):
        for joint in path or ():
            T = placements[joint.child]
            w = T[:3, :3] @ ca.DM(joint.axis)
            if joint.type == "prismatic":
                dp, dr = sign * w, ca.SX(3, 1)
            else:
                dp = sign * ca.cross(w, point - T[:3, 3])
                dr = -sign * (G @ w) if closure.type == "6d" else ca.SX(3, 1)
            column = _rows(closure, dp, dr, p_a - p_b)
            columns[joint.name] = columns[joint.name] + column if joint.name in columns else column
    return columns


def _rows(closure: Closure, dp: ca.SX, dr: ca.SX, d: ca.SX) -> ca.SX:
    """The residual rows' derivative from the motion of ``d = p_a - p_b`` (``dp``) and of the
    rotation rows (``dr``)."""
    if closure.type == "3d":
        return dp
    if closure.type == "distance":
        return ca.dot(d, dp) / closure.length
    return ca.vertcat(dp, dr)


def _path(tree: Tree, link: str, base: str) -> list[Joint] | None:
    """The joints from ``base`` down to ``link`` (``None`` if ``link`` is not below it)."""
    joint_of = {j.child: j for j in tree.joints}
    out: list[Joint] = []
    while link != base:
        if link not in joint_of:
            return None
        joint = joint_of[link]
        if joint.movable:
            out.append(joint)
        link = joint.parent
    return out
