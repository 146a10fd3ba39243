"""The symbolic loop-closure system ``g(y, theta) = 0`` and its derivatives.

``y`` (m unknown joint coordinates) and ``theta`` (k actuated ones) are CasADi SX symbols;
locked joints (idle freedoms removed by the square reduction) are constants.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from ..model.rotations import rot_exp
from ..model.spec import Closure
from ..model.urdf import Tree
from .kinematics import closure_check, closure_residual, link_placements, workspace_coordinates


@dataclass(frozen=True)
class Symbolic:
    """Symbolic kinematics of a closed-chain model (CasADi SX expressions).

    Attributes:
        y: (m,) unknown joint coordinates.
        theta: (k,) actuated joint coordinates.
        c: (9 f,) reference rotations (column-major 3x3) of the charts of the f floating and
            spherical joints, in tree order (empty without them).
        g: (m,) closure residual rows kept by the square reduction.
        g_all: (r,) every closure residual row.
        g_check: verification rows (6d closures with their full rotation matrix).
        J_p: (m, m) ``dg/dy``.
        J_s: (m, k) ``-dg/dtheta``.
        pose: (4, 4) placement of the platform (or reported) frame.
        x: (n,) workspace coordinates of ``pose``.
        placements: link name -> (4, 4) world placement.
        workspace: names of the coordinates of ``x``.
        values: every joint coordinate -> its symbol or constant (what couplings read).
        charts: rotation joint -> the reference rotation (3x3) of its chart: a block of ``c``
            for an unknown rotation, the constant rotation of a held one.
    """

    y: ca.SX
    theta: ca.SX
    c: ca.SX
    g: ca.SX
    g_all: ca.SX
    g_check: ca.SX
    J_p: ca.SX
    J_s: ca.SX
    pose: ca.SX
    x: ca.SX
    placements: Mapping[str, ca.SX]
    workspace: tuple[str, ...] = ()
    values: Mapping[str, ca.SX | float] = field(default_factory=dict)
    charts: Mapping[str, ca.SX] = field(default_factory=dict)

    @property
    def m(self) -> int:
        return int(self.y.numel())

    @property
    def k(self) -> int:
        return int(self.theta.numel())


def build_symbolic(
    tree: Tree,
    closures: Sequence[Closure],
    actuated: Sequence[str],
    unknowns: Sequence[str],
    locked: Mapping[str, float],
    rows: Sequence[int] | None,
    frame: str,
    workspace: tuple[str, ...],
    unchecked: Sequence[int] = (),
) -> Symbolic:
    """Build the symbolic system.

    Args:
        tree: URDF tree.
        closures: loop closures.
        actuated: actuated joint names (theta order).
        unknowns: unknown joint coordinate names (y order).
        locked: joints held constant -> value [rad or model length unit].
        rows: indices of ``g_all`` rows kept in ``g`` (``None``: all).
        frame: link whose placement is ``pose``.
        workspace: workspace coordinate names of ``x``.
        unchecked: rows of ``g_all`` whose verification rows are zero (redundant rows a
            file's rounding makes slightly inconsistent; a weld's rotation row takes its
            rotation matrix rows with it).
    """
    y = ca.SX.sym("y", len(unknowns))
    theta = ca.SX.sym("theta", len(actuated))
    # rotation joints whose rotation is unknown get a chart; a held one (a joint of another
    # block, see :mod:`scdk_sym.robot.blocks`) is the constant rotation of its rotation vector
    known = set(unknowns)
    rotating = [n for n in tree.rotation_joints if f"{n}.rx" in known]
    c = ca.SX.sym("c", 9 * len(rotating))
    charts: dict[str, ca.SX] = {
        n: ca.reshape(c[9 * i : 9 * i + 9], 3, 3) for i, n in enumerate(rotating)
    }
    values: dict[str, ca.SX | float] = dict(locked)
    for n in tree.rotation_joints:
        if n not in charts and f"{n}.rx" in locked:
            w = np.array([locked[f"{n}.{a}"] for a in ("rx", "ry", "rz")])
            charts[n] = ca.SX(ca.DM(rot_exp(w)))
            values.update({f"{n}.{a}": 0.0 for a in ("rx", "ry", "rz")})
    values.update({n: y[i] for i, n in enumerate(unknowns)})
    values.update({n: theta[i] for i, n in enumerate(actuated)})
    T = link_placements(tree, values, charts)
    g_all = ca.vertcat(
        *[closure_residual(cl, T[cl.frame_a], T[cl.frame_b], values) for cl in closures]
    )
    checks, start = [], 0
    for cl in closures:
        rows_c = closure_check(cl, T[cl.frame_a], T[cl.frame_b], values)
        off = [r - start for r in unchecked if start <= r < start + cl.rows]
        if cl.type == "6d" and any(r >= 3 for r in off):
            off += list(range(6, 15))
        for r in off:
            rows_c[r] = 0
        checks.append(rows_c)
        start += cl.rows
    g_check = ca.vertcat(*checks)
    g = g_all if rows is None else g_all[list(rows)]
    return Symbolic(
        y=y,
        theta=theta,
        c=c,
        g=g,
        g_all=g_all,
        g_check=g_check,
        J_p=ca.jacobian(g, y),
        J_s=-ca.jacobian(g, theta),
        pose=T[frame],
        x=workspace_coordinates(workspace, T[frame]),
        placements=T,
        workspace=tuple(workspace),
        values=values,
        charts=charts,
    )
