"""Why a model does not assemble: the least-squares floor of its closures over every joint,
and whether its weld (6d) closures are what cannot hold.

A CAD export may write as welds (6d) loops that only a point (3d) closure fits: its frames can
coincide in position, never in orientation. Least squares over every joint, the inputs
included, then stops at a floor above zero whatever the start, while the same loops as point
closures assemble. Saying so names the fault (the closure types in the YAML) instead of the
symptom (no start assembles).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace

import casadi as ca
import numpy as np

from ..model.spec import Closure
from ..symbolic.system import Symbolic
from .assembly import least_squares

Rows = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


def check_rows(full: Symbolic, c: np.ndarray) -> Rows:
    """``z -> (g_check, dg_check/dz)`` of a symbolic system in the chart ``c`` (``z`` the
    unknowns then the inputs; a weld's whole ``R_a^T R_b - I``, so a half turn is no false
    minimum)."""
    z = ca.vertcat(full.y, full.theta)
    f = ca.Function("check", [full.y, full.theta],
                    [ca.substitute(e, full.c, ca.DM(c))
                     for e in (full.g_check, ca.jacobian(full.g_check, z))])  # fmt: skip
    m = full.m

    def rows(zv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        g, J = f(zv[:m], zv[m:])
        return np.array(g).ravel(), np.array(J)

    return rows


def weld_diagnosis(
    full: Symbolic,
    build: Callable[[Sequence[Closure]], Symbolic],
    closures: Sequence[Closure],
    c: np.ndarray,
    z: np.ndarray,
    tol: float,
) -> str:
    """A sentence on the welds when they are what cannot hold, else empty; the floors are
    where least squares over every coordinate from ``z`` stops
    (:func:`~scdk_sym.robot.assembly.least_squares`).

    Args:
        full: the symbolic system of ``closures``.
        build: closures -> the symbolic system over the same unknowns and inputs.
        closures: the model's closures.
        c: chart of the unknowns.
        z: the start (unknowns then inputs).
        tol: closure tolerance [model length unit].
    """
    welds = [cl for cl in closures if cl.type == "6d"]
    if not welds:
        return ""
    floor = least_squares(check_rows(full, c), z)[1]
    if floor <= tol:
        return ""
    points = [replace(cl, type="3d") if cl.type == "6d" else cl for cl in closures]
    as_points = least_squares(check_rows(build(points), c), z)[1]
    if as_points > tol:
        return ""
    names = ", ".join(cl.label for cl in welds)
    return (
        f"its 6d closures cannot hold at any configuration (least squares over every joint, "
        f"inputs included, stops at {floor:.2g}), while as point (3d) closures the mechanism "
        f"assembles (residual {as_points:.1e}): check the closure types of {names} in the YAML"
    )
