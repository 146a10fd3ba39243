"""CasADi SX forward kinematics of a URDF tree and loop-closure residuals.

Built directly from the joint origins, axes and types (the pip ``pin`` wheel has no
``pinocchio.casadi``); :mod:`scdk_sym.verify.pinocchio` checks it against Pinocchio.
"""

from __future__ import annotations

from collections.abc import Mapping

import casadi as ca
import numpy as np

from ..model.rotations import axis_rotation, cayley, vee
from ..model.spec import Closure
from ..model.urdf import Tree


def joint_motion(kind: str, axis: np.ndarray, q: ca.SX | float) -> ca.SX:
    """4x4 transform of a one-coordinate joint about/along ``axis`` by ``q``."""
    T = ca.SX.eye(4)
    if kind == "prismatic":
        T[:3, 3] = ca.DM(axis) * q
    else:
        T[:3, :3] = axis_rotation(axis, ca.cos(q), ca.sin(q))
    return T


def floating_motion(coords: ca.SX, R_ref: ca.SX) -> ca.SX:
    """4x4 transform of a floating joint in its local chart: ``[R_ref cayley(rho), p]``.

    The chart: position ``p = coords[:3]`` and Rodrigues parameters ``rho = coords[3:]`` of the
    rotation relative to a reference rotation ``R_ref``. The solvers re-centre ``R_ref`` on the
    current orientation as the platform moves, so ``rho`` stays small and the chart never adds
    a singularity of its own (unlike Euler angles): every ``det J_p = 0`` reported is one of
    the mechanism.
    """
    T = ca.SX.eye(4)
    T[:3, :3] = R_ref @ cayley(coords[3:6])
    T[:3, 3] = coords[:3]
    return T


def spherical_motion(rho: ca.SX, R_ref: ca.SX) -> ca.SX:
    """4x4 transform of a spherical (ball) joint in its local chart: ``[R_ref cayley(rho), 0]``
    (the chart of :func:`floating_motion` without the translation)."""
    T = ca.SX.eye(4)
    T[:3, :3] = R_ref @ cayley(rho)
    return T


def link_placements(
    tree: Tree,
    joint_values: Mapping[str, ca.SX | float],
    charts: Mapping[str, ca.SX] | None = None,
    base: str | None = None,
) -> dict[str, ca.SX]:
    """World placements (4x4 SX) of every link, or the placements relative to ``base`` of
    ``base`` and the links below it.

    Args:
        tree: the URDF tree.
        joint_values: a value (symbolic or numeric) for every joint coordinate (floating
            joints: ``name.x`` ... ``name.rz``).
        charts: floating or spherical joint name -> reference rotation (3x3) of its chart
            (identity if absent).
        base: the link placed at the origin (default: the tree's root).
    """
    out: dict[str, ca.SX] = {tree.root if base is None else base: ca.SX.eye(4)}
    for j in tree.joints:
        if j.parent not in out:  # not below the base
            continue
        T = out[j.parent] @ ca.DM(j.origin)
        if j.type == "floating":
            coords = ca.vertcat(*[joint_values[c] for c in j.coordinates])
            R_ref = (charts or {}).get(j.name, ca.SX.eye(3))
            T = T @ floating_motion(coords, R_ref)
        elif j.type == "spherical":
            rho = ca.vertcat(*[joint_values[c] for c in j.coordinates])
            T = T @ spherical_motion(rho, (charts or {}).get(j.name, ca.SX.eye(3)))
        elif j.movable:
            T = T @ joint_motion(j.type, j.axis, joint_values[j.name])
        out[j.child] = T
    return out


def rotation_error(R_a: ca.SX, R_b: ca.SX) -> ca.SX:
    """Rotation error vee(skew part of R_a^T R_b): zero when equal, = log3 to first order."""
    return 0.5 * vee(R_a.T @ R_b)


def closure_residual(
    closure: Closure,
    T_a: ca.SX,
    T_b: ca.SX,
    values: Mapping[str, ca.SX | float] | None = None,
    *,
    polynomial: bool = False,
) -> ca.SX:
    """Residual rows of one closure (length unit of the model; radians for 6d rotations).

    Args:
        closure: the closure.
        T_a: (4, 4) placement of its frame ``a``.
        T_b: (4, 4) placement of its frame ``b``.
        values: joint coordinate -> value: the length of a distance closure whose length is
            a joint.
        polynomial: the distance row as ``|d|^2 - L^2`` [length^2] (a polynomial when the
            placements are) instead of ``(|d|^2 - L^2) / (2 L)`` [length] (the distance
            error to first order).
    """
    if closure.type == "coupling":
        return coupling_residual(closure, values or {})
    d = T_a[:3, 3] - T_b[:3, 3]
    if closure.type == "3d":
        return d
    if closure.type == "2d":
        return d[:2]
    if closure.type == "distance":
        L = values[closure.length_joint] if closure.length_joint and values else closure.length
        return ca.dot(d, d) - L * L if polynomial else (ca.dot(d, d) - L * L) / (2 * L)
    return ca.vertcat(d, rotation_error(T_a[:3, :3], T_b[:3, :3]))


def coupling_residual(closure: Closure, values: Mapping[str, ca.SX | float]) -> ca.SX:
    """The row of a joint coupling: ``a - a0 - sum(p_i (b - b0)^i)`` with ``a``, ``b`` linear
    combinations of joint coordinates (MJCF's joint and fixed-tendon equalities) [rad or
    length unit]."""
    a = sum((c * values[j] for j, c in closure.terms_a), ca.SX(0)) - closure.offset_a
    if not closure.terms_b:
        return ca.SX(a - closure.polycoef[0])
    b = sum((c * values[j] for j, c in closure.terms_b), ca.SX(0)) - closure.offset_b
    poly, power = ca.SX(0), ca.SX(1)
    for p in closure.polycoef:
        if p:
            poly = poly + p * power
        power = power * b
    return ca.SX(a - poly)


def closure_check(
    closure: Closure, T_a: ca.SX, T_b: ca.SX, values: Mapping[str, ca.SX | float] | None = None
) -> ca.SX:
    """Rows that vanish only at a true closure (used to verify solutions).

    For 6d closures the whole matrix ``R_a^T R_b - I`` is included, so a half-turn (where the
    skew part vanishes too) is not mistaken for a closure.
    """
    rows = closure_residual(closure, T_a, T_b, values)
    if closure.type == "6d":
        E = T_a[:3, :3].T @ T_b[:3, :3] - ca.SX.eye(3)
        rows = ca.vertcat(rows, ca.reshape(E, 9, 1))
    return rows


def workspace_coordinates(names: tuple[str, ...], T: ca.SX) -> ca.SX:
    """Workspace coordinates of a placement: x, y, z, roll, pitch, yaw (URDF rpy), phi."""
    R = T[:3, :3]
    values = {
        "x": T[0, 3],
        "y": T[1, 3],
        "z": T[2, 3],
        "phi": ca.atan2(R[1, 0], R[0, 0]),
        "yaw": ca.atan2(R[1, 0], R[0, 0]),
        "pitch": ca.atan2(-R[2, 0], ca.sqrt(R[0, 0] ** 2 + R[1, 0] ** 2)),
        "roll": ca.atan2(R[2, 1], R[2, 2]),
    }
    return ca.vertcat(*[values[n] for n in names])


def pose_error(names: tuple[str, ...], T: ca.SX, T_target: ca.SX) -> ca.SX:
    """Rows that vanish when ``T`` has the target's workspace coordinates.

    Positions are compared directly; orientations through a rotation error expressed in the
    world frame (no Euler-angle singularity): ``phi`` uses its z component, a spatial
    workspace (roll, pitch, yaw) all three.
    """
    rows = []
    for i, axis in enumerate("xyz"):
        if axis in names:
            rows.append(T[i, 3] - T_target[i, 3])
    w = 0.5 * vee(T[:3, :3] @ T_target[:3, :3].T)
    rot = {"roll", "pitch", "yaw"} & set(names)
    if "phi" in names or rot == {"yaw"}:
        rows.append(w[2])
    elif rot:
        rows.extend([w[0], w[1], w[2]])
    return ca.vertcat(*rows)
