"""Numeric kernels: the CasADi Functions every solver calls.

All kernels are SX Functions built from a :class:`~scdk_sym.symbolic.system.Symbolic`; they
can be code-generated and compiled to C (:mod:`scdk_sym.kernels.compile`) with identical
signatures.

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

import casadi as ca

from ..symbolic.system import Symbolic
from .curve import bordered_tangent, newton_correction, rk4_in_s

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


def _sc_parts(sym: Symbolic, closure: ca.Function | None = None):
    """The SC tangent and the stabilising correction, by the follower's bordered solve (the
    closures evaluated by calls of ``closure`` when given)."""
    m, k = sym.m, sym.k
    s = ca.SX.sym("s")
    theta1 = ca.SX.sym("theta1", k)
    dtheta = ca.SX.sym("dtheta", k)
    v = ca.SX.sym("v", m + 1)
    scale = ca.SX.sym("scale")
    gain = ca.SX.sym("K")
    if closure is None:
        g, Jp, Js = ca.substitute([sym.g, sym.J_p, sym.J_s], [sym.theta], [theta1 + s * dtheta])
    else:
        g, Jp, Js = closure(sym.y, theta1 + s * dtheta, sym.c)
    tangent, _t_hat, _w, corr = bordered_tangent(Jp, Js, dtheta, v, -g)
    q = ca.vertcat(sym.y, s)
    p = ca.vertcat(theta1, dtheta, v, scale, gain)
    return q, p, Jp, tangent, corr, scale, gain, theta1, dtheta, s


def build_kernels(sym: Symbolic, name: str = "scdk", closure: ca.Function | None = None) -> Kernels:
    """Build every kernel of a model (a few milliseconds for m <= 6).

    Args:
        sym: the model's symbolic system (``model.symbolic``).
        name: prefix of the Functions' names.
        closure: the :func:`~scdk_sym.kernels.curve.closure_function` that the field, the
            probe and the warm kernel call to evaluate the closures and their Jacobians
            (the same operations, one copy of them in generated C: the compiled backend's
            choice); default: written out in each.
    """
    y, theta, c = sym.y, sym.theta, sym.c
    m, _k = sym.m, sym.k
    yt = ["y", "theta", "c"]
    f_g = ca.Function(f"{name}_g", [y, theta, c], [sym.g], yt, ["g"])
    f_check = ca.Function(f"{name}_check", [y, theta, c], [sym.g_check], yt, ["rows"])
    f_jac = ca.Function(f"{name}_jac", [y, theta, c], [sym.J_p, sym.J_s], yt, ["J_p", "J_s"])
    f_pose = ca.Function(f"{name}_pose", [y, theta, c], [sym.pose, sym.x], yt, ["T", "x"])

    q, p, Jp, tangent, corr, scale, gain, theta1, dtheta, s = _sc_parts(sym, closure)
    dq = scale * tangent + gain * corr
    f_field = ca.Function(f"{name}_field", [q, p, c], [dq], ["q", "p", "c"], ["dq"])
    x_s = ca.substitute(sym.x, sym.theta, theta1 + s * dtheta)
    f_probe = ca.Function(
        f"{name}_probe",
        [q, p, c],
        [ca.densify(e) for e in (tangent, ca.vec(Jp), x_s)],
        ["q", "p", "c"],
        ["tangent", "J_p", "x"],
    )

    inline = closure is None
    newton = newton_correction(sym, inline, closure)

    def rk_newton(y_a, s_a, th1, dth, rk_steps: int, newton_steps: int):
        """RK4 in s from (y_a, s_a) to s = 1, then Newton at th1 + dth; (y, max|correction|)."""
        y_pred = rk4_in_s(sym, y_a, s_a, 1.0, th1, dth, rk_steps, inline=inline, closure=closure)
        yk = y_pred
        for _ in range(newton_steps):
            yk = yk - newton(yk, th1 + dth, c)
        return yk, ca.norm_inf(yk - y_pred)

    # ik_step: Newton step on [g(y, theta); pose error] over z = (y, theta)
    from ..symbolic.kinematics import pose_error

    z = ca.vertcat(y, theta)
    T_target = ca.SX.sym("T_target", 4, 4)
    workspace = sym.workspace
    Fik = ca.vertcat(sym.g, pose_error(workspace, sym.pose, T_target))
    if Fik.numel() != z.numel():
        Fik = ca.vertcat(sym.g)  # not square: IK unavailable, caught by the model
    Jik = ca.jacobian(Fik, z)
    f_ik = ca.Function(
        f"{name}_ik_step",
        [z, T_target, c],
        [z - ca.solve(Jik, Fik) if Jik.shape[0] == Jik.shape[1] else z, ca.norm_inf(Fik)],
        ["z", "T_target", "c"],
        ["z_new", "residual"],
    )
    # warm: one RK4-in-s sweep from s = 0 with its Newton polish, and what verifies it
    y1 = ca.SX.sym("y1", m)
    th1 = ca.SX.sym("theta1", sym.k)
    th0 = ca.SX.sym("theta0", sym.k)
    y0, corr = rk_newton(y1, 0.0, th1, th0 - th1, WARM_RK_STEPS, NEWTON_STEPS)
    Jp_at = sym.J_p if closure is None else closure(y, theta, c)[1]
    at = ca.Function("at", [y, theta, c], [ca.norm_inf(sym.g_check), ca.vec(Jp_at)])
    res1, J1 = at(y1, th1, c)
    res0, J0 = at(y0, th0, c)
    T0, x0 = f_pose(y0, th0, c)
    f_warm = ca.Function(
        f"{name}_warm",
        [y1, th1, th0, c],
        [ca.densify(e) for e in (y0, corr, res1, res0, J1, J0, T0, x0)],
        ["y1", "theta1", "theta0", "c"],
        ["y0", "correction", "residual1", "residual0", "J_p1", "J_p0", "T", "x"],
    )
    return Kernels(f_g, f_check, f_jac, f_pose, f_field, f_probe, f_ik, f_warm)
