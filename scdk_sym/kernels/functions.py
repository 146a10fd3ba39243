"""Numeric kernels: the CasADi Functions every solver calls.

The kernels are SX Functions built from a :class:`~scdk_sym.symbolic.system.Symbolic`; they
can be code-generated and compiled to C (:mod:`scdk_sym.kernels.compile`) with identical
signatures. Built for C (``loops``), a large model's field, probe and warm kernel are MX
Functions of calls of the closure Function and of solves in loops
(:func:`~scdk_sym.kernels.curve.compact`): the same mathematics, compact C.

The singularity-consistent field
--------------------------------
With ``q = (y, s)``, ``theta(s) = theta1 + s dtheta`` and ``H = [J_p, -J_s dtheta]``, the SC
vector field ``nu = [adj(J_p) j_s; det J_p]`` is the generalised cross product of the rows
of ``H``. For any reference vector ``v`` with ``v . nu > 0``, Cramer's rule gives
``[H; v^T]^{-1} e = nu / (v . nu)``: the same direction, computed by one linear solve that
stays regular on the singular manifold (``det J_p = 0``) and for any number of unknowns.
The solvers re-centre ``v`` on the current tangent at every chunk, so ``v . nu`` stays
positive. The tangent is normalised in the metric ``|dy|^2 + (|dtheta| ds)^2`` (arc length
in joint space), and the stabilising term ``[H; v^T]^{-1} [-K g; 0]`` makes ``g`` decay as
``exp(-K tau)``. The bordered solve, the Newton correction and the RK4 steps in ``s`` are the
curve follower's (:func:`scdk_sym.kernels.curve.bordered_tangent`, ``newton_correction``,
``rk4_in_s``): one definition of each in the package.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

import casadi as ca

from ..symbolic.system import Symbolic
from .curve import Solves, bordered_tangent, compact, newton_correction, rk4_in_s

#: RK4 steps of the warm (fast-path) kernel: warm solves move little.
WARM_RK_STEPS = 1
NEWTON_STEPS = 4


class FunctionSet:
    """A frozen dataclass whose fields are CasADi Functions (a model's kernels)."""

    def all(self) -> list[ca.Function]:
        """Every Function, in declaration order."""
        return [getattr(self, f.name) for f in fields(self)]  # type: ignore[arg-type]


@dataclass(frozen=True)
class Kernels(FunctionSet):
    """CasADi Functions of one model.

    Attributes:
        Every kernel takes last the chart ``c`` (reference rotations of the floating joints,
        see :func:`~scdk_sym.symbolic.kinematics.floating_motion`; empty without them), and
        ``y`` in that local chart.

        g: (y[m], theta[k], c) -> g[m].
        check: (y, theta, c) -> verification rows.
        jac: (y, theta, c) -> (J_p[m,m], J_s[m,k]).
        pose: (y, theta, c) -> (T[4,4], x[n]).
        field: (q[m+1], p, c) -> dq/dtau, p = (theta1[k], dtheta[k], v[m+1], scale, K).
        probe: (q, p, c) -> (tangent[m+1], vec(J_p)[m*m], x[n]).
        ik_step: (z[m+k], T_target[4,4], c) -> (z_new, max|F|): Newton step on [g; pose error].
        warm: (y1, theta1, theta0, c) -> (y0, max|Newton correction|, max|check| at the start,
            max|check| at the end, vec(J_p) at the start, vec(J_p) at the end, T[4,4], x[n]):
            the whole convergent fast path of a warm solve in one call.
    """

    g: ca.Function
    check: ca.Function
    jac: ca.Function
    pose: ca.Function
    field: ca.Function
    probe: ca.Function
    ik_step: ca.Function
    warm: ca.Function


def _sc_symbols(sym: Symbolic, mx: bool) -> tuple[Any, ...]:
    """``(q, p, c, y, s, theta1, dtheta, v, scale, gain)``: the field's inputs ``q = (y, s)``,
    ``p = (theta1, dtheta, v, scale, gain)`` and the chart, and their parts; the model's own SX
    symbols stacked, or MX ones (an MX Function's inputs are symbols: ``q`` and ``p`` are,
    their parts slices of them)."""
    m, k = sym.m, sym.k
    if mx:
        qm, pm = ca.MX.sym("q", m + 1), ca.MX.sym("p", 2 * k + m + 3)
        vm = pm[2 * k : 2 * k + m + 1]
        cm = ca.MX.sym("c", sym.c.numel())
        return qm, pm, cm, qm[:m], qm[m], pm[:k], pm[k : 2 * k], vm, pm[-2], pm[-1]
    s, theta1, dtheta = ca.SX.sym("s"), ca.SX.sym("theta1", k), ca.SX.sym("dtheta", k)
    v, scale, gain = ca.SX.sym("v", m + 1), ca.SX.sym("scale"), ca.SX.sym("K")
    q = ca.vertcat(sym.y, s)
    p = ca.vertcat(theta1, dtheta, v, scale, gain)
    return q, p, sym.c, sym.y, s, theta1, dtheta, v, scale, gain


def _sc_parts(sym: Symbolic, closure: ca.Function | None = None, loops: bool = False):
    """The SC tangent and the stabilising correction, by the follower's bordered solve (the
    closures evaluated by calls of ``closure`` when given; a large bordered system solved in
    loops with ``loops``, on MX symbols for a :func:`~scdk_sym.kernels.curve.compact`
    model).

    Returns:
        ``(q, p, c, J_p, tangent, correction, scale, gain, theta1, dtheta, s, y)``: the
        Functions' inputs ``q = (y, s)``, ``p`` and the chart, what is computed, and the parts
        of ``q`` and ``p``.
    """
    q, p, c, y, s, theta1, dtheta, v, scale, gain = _sc_symbols(
        sym, closure is not None and compact(sym, loops)
    )
    if closure is None:
        g, Jp, Js = ca.substitute([sym.g, sym.J_p, sym.J_s], [sym.theta], [theta1 + s * dtheta])
    else:
        g, Jp, Js = closure(y, theta1 + s * dtheta, c)
    tangent, _t_hat, _w, corr = bordered_tangent(Jp, Js, dtheta, v, -g, Solves(loops=loops))
    return q, p, c, Jp, tangent, corr, scale, gain, theta1, dtheta, s, y


def ik_step_function(sym: Symbolic, name: str = "scdk", loops: bool = False) -> ca.Function:
    """The inverse kinematics' Newton step on ``[g(y, theta); pose error]`` over
    ``z = (y, theta)`` (square workspaces; else the identity on ``z``).

    Args:
        sym: the model's symbolic system (``model.symbolic``).
        name: prefix of the Function's name.
        loops: True to solve a system larger than
            :data:`~scdk_sym.kernels.curve.WRITTEN_SOLVE_MAX` in loops (kernels built to be
            compiled); else written out.

    Returns:
        (z[m+k], T_target[4,4], c) -> (z_new, max|F|).
    """
    from ..symbolic.kinematics import pose_error

    y, theta, c = sym.y, sym.theta, sym.c
    z = ca.vertcat(y, theta)
    T_target = ca.SX.sym("T_target", 4, 4)
    Fik = ca.vertcat(sym.g, pose_error(sym.workspace, sym.pose, T_target))
    if Fik.numel() != z.numel():
        Fik = ca.vertcat(sym.g)  # not square: IK unavailable, caught by the model
    Jik = ca.jacobian(Fik, z)
    square = Jik.shape[0] == Jik.shape[1]
    return ca.Function(
        f"{name}_ik_step",
        [z, T_target, c],
        [z - Solves(loops=loops).solve(Jik, Fik) if square else z, ca.norm_inf(Fik)],
        ["z", "T_target", "c"],
        ["z_new", "residual"],
    )


def build_kernels(
    sym: Symbolic, name: str = "scdk", closure: ca.Function | None = None, loops: bool = False
) -> Kernels:
    """Build every kernel of a model (a few milliseconds for m <= 6).

    Args:
        sym: the model's symbolic system (``model.symbolic``).
        name: prefix of the Functions' names.
        closure: the :func:`~scdk_sym.kernels.curve.closure_function` that the field, the
            probe and the warm kernel call to evaluate the closures and their Jacobians
            (the same operations, one copy of them in generated C: the compiled backend's
            choice); default: written out in each.
        loops: True to solve the systems larger than
            :data:`~scdk_sym.kernels.curve.WRITTEN_SOLVE_MAX` by calls of
            :func:`~scdk_sym.kernels.curve.loop_solver` (kernels built to be compiled: compact
            C); default: CasADi's symbolic solves written out.
    """
    y, theta, c = sym.y, sym.theta, sym.c
    m, _k = sym.m, sym.k
    yt = ["y", "theta", "c"]
    f_g = ca.Function(f"{name}_g", [y, theta, c], [sym.g], yt, ["g"])
    f_check = ca.Function(f"{name}_check", [y, theta, c], [sym.g_check], yt, ["rows"])
    f_jac = ca.Function(f"{name}_jac", [y, theta, c], [sym.J_p, sym.J_s], yt, ["J_p", "J_s"])
    f_pose = ca.Function(f"{name}_pose", [y, theta, c], [sym.pose, sym.x], yt, ["T", "x"])

    q, p, cq, Jp, tangent, corr, scale, gain, theta1, dtheta, s, yq = _sc_parts(sym, closure, loops)
    dq = scale * tangent + gain * corr
    f_field = ca.Function(f"{name}_field", [q, p, cq], [dq], ["q", "p", "c"], ["dq"])
    if isinstance(q, ca.MX):
        x_s = ca.Function("scdk_x", [y, theta, c], [sym.x])(yq, theta1 + s * dtheta, cq)
    else:
        x_s = ca.substitute(sym.x, sym.theta, theta1 + s * dtheta)
    f_probe = ca.Function(
        f"{name}_probe",
        [q, p, cq],
        [ca.densify(e) for e in (tangent, ca.vec(Jp), x_s)],
        ["q", "p", "c"],
        ["tangent", "J_p", "x"],
    )

    inline = closure is None
    newton = newton_correction(sym, inline, closure, loops)

    def rk_newton(y_a, s_a, th1, dth, cw, rk_steps: int, newton_steps: int):
        """RK4 in s from (y_a, s_a) to s = 1, then Newton at th1 + dth (chart cw);
        (y, max|correction|)."""
        y_pred = rk4_in_s(
            sym, y_a, s_a, 1.0, th1, dth, rk_steps, closure=closure, loops=loops, c=cw
        )
        yk = y_pred
        for _ in range(newton_steps):
            yk = yk - newton(yk, th1 + dth, cw)
        return yk, ca.norm_inf(yk - y_pred)

    f_ik = ik_step_function(sym, name, loops)
    # warm: one RK4-in-s sweep from s = 0 with its Newton polish, and what verifies it (an MX
    # Function of calls on a compact model: its C copies vectors by loops)
    X: Any = ca.MX if isinstance(q, ca.MX) else ca.SX
    y1 = X.sym("y1", m)
    th1 = X.sym("theta1", sym.k)
    th0 = X.sym("theta0", sym.k)
    cw: Any = X.sym("c", c.numel()) if X is ca.MX else c
    y0, corr = rk_newton(y1, 0.0, th1, th0 - th1, cw, WARM_RK_STEPS, NEWTON_STEPS)
    Jp_at = sym.J_p if closure is None else closure(y, theta, c)[1]
    at = ca.Function("at", [y, theta, c], [ca.norm_inf(sym.g_check), ca.vec(Jp_at)])
    res1, J1 = at(y1, th1, cw)
    res0, J0 = at(y0, th0, cw)
    T0, x0 = f_pose(y0, th0, cw)
    f_warm = ca.Function(
        f"{name}_warm",
        [y1, th1, th0, cw],
        [ca.densify(e) for e in (y0, corr, res1, res0, J1, J0, T0, x0)],
        ["y1", "theta1", "theta0", "c"],
        ["y0", "correction", "residual1", "residual0", "J_p1", "J_p0", "T", "x"],
    )
    return Kernels(f_g, f_check, f_jac, f_pose, f_field, f_probe, f_ik, f_warm)
