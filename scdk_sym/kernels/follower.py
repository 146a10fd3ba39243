"""The CasADi Functions of the curve follower, built from a model's symbolic system.

The curve is ``H(q) = 0`` with ``q = (y, s)``, ``H = g(y, theta1 + s dtheta)`` and
``p = (theta1, dtheta)``; :func:`build_follower_kernels` builds its steps, locators and Newton
iterations from the package's one definition of each symbolic step
(:mod:`scdk_sym.kernels.curve`). What a model keeps of them, per backend, and the zero-copy
callers the follower calls are :mod:`scdk_sym.follower.calls`; the compiled backend's library
(:func:`scdk_sym.kernels.compile.compiled_library`) and the generated C tracker
(:mod:`scdk_sym.kernels.tracker_functions`) are built from these Functions.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import casadi as ca

from ..symbolic.system import Symbolic
from .curve import (
    Solves,
    bordered_matrix,
    bordered_tangent,
    closure_function,
    compact,
    function_options,
    model_inputs,
    newton_correction,
    rk4_in_s,
)
from .functions import FunctionSet

#: Predictor-corrector steps evaluated per call of the step function.
STEPS = 16
#: Newton corrections per step.
CORRECTIONS = 3
#: Newton steps of the polish at fixed theta.
POLISH_STEPS = 8
#: Newton steps of the corrector on a plane (step over a bifurcation, projections).
PLANE_STEPS = 8
#: Newton steps locating a fold (``[g; t_s] = 0``).
FOLD_STEPS = 8
#: Newton iterations of the ``newton`` kernel (its callers call it again if needed).
NEWTON_ITERATIONS = 2


@dataclass(frozen=True)
class FollowerKernels(FunctionSet):
    """CasADi Functions of the follower of one model (``c``: chart of the floating joints).

    Attributes:
        steps: (x[2(m+1)], h, p[2k], c) -> (X[2(m+1), STEPS], info[3, STEPS],
            J[m*m, STEPS]): ``STEPS`` successive ``step`` calls (``mapaccum``).
        step: (x[2(m+1)], h, p[2k], c) -> (x_new[2(m+1)], info[3], J[m*m]): one
            predictor-corrector step of arc length ``h`` from ``x = (q, t)`` (a point of the
            curve and its unit tangent): RK4 predictor along the tangent field,
            ``CORRECTIONS`` Newton corrections on the plane normal to ``t``; ``info``: first and
            last correction (weighted norm), cosine between the tangents before and after;
            ``J``: ``vec(J_p)`` at the new point (column-major).
        tangent: (q, v, p, c) -> (t, vec(J_p)): unit tangent at ``q`` oriented along ``v``.
        plane: (q0, v, p, c) -> (q, max|g|): Newton on ``[H; v^T W (q - q0)] = 0`` (the curve
            point on the plane through ``q0`` normal to ``v``).
        fold: (q, v, p, c) -> q: Newton on ``[H; t_s] = 0`` (a turning point of ``s``).
        polish: (y, theta, c) -> (y, max|g|): ``POLISH_STEPS`` Newton steps at fixed ``theta``.
        newton: (y, theta, c) -> (y_new, max|g(y_new)|, max|last correction|):
            ``NEWTON_ITERATIONS`` Newton steps at fixed ``theta`` (the same step as ``polish``).
        predict: (y, theta1[k], dtheta[k], c) -> y1: one RK4 step of
            ``dy/ds = J_p^{-1} J_s dtheta`` from ``s = 0`` to ``s = 1`` (the curve with ``s`` as
            the independent variable, valid off the singular manifold).
        singular: (y, theta, c) -> (g, J_p, J_s, dJ_p/d(y, theta) [m*m, m+k]): what a
            minimum-norm Newton onto the singular manifold ``det J_p = 0`` needs.
    """

    steps: ca.Function
    step: ca.Function
    tangent: ca.Function
    plane: ca.Function
    fold: ca.Function
    polish: ca.Function
    newton: ca.Function
    predict: ca.Function
    singular: ca.Function


@dataclass(frozen=True)
class _Curve:
    """The symbols and inner Functions the follower's kernels share (one model, one build).

    On a :func:`~scdk_sym.kernels.curve.compact` model the symbols are MX (kernels of calls,
    their generated C moving vectors by loops) and the written-out expressions are ``None``.
    """

    sym: Symbolic  # the model's symbolic system
    inline: bool  # kernels written out (else calls of their inner Functions)
    solves: Solves  # how the tangent's and the corrector's bordered systems are solved
    loops: bool  # large systems solved in loops (kernels built to be compiled)
    compact: bool  # MX Functions of calls, the fold and dJ_p by their compact forms
    opts: dict  # options of the inner Functions
    closure: ca.Function | None  # the closure Function the kernels call (None: inlined)
    y: Any  # the unknowns, an input of the (y, theta, c) kernels
    theta: Any  # the actuated values, likewise
    c: Any  # the chart, an input of every kernel
    q: Any  # (y, s)
    p: Any  # (theta1, dtheta)
    yq: Any  # the unknowns of q
    s: Any
    theta1: Any
    dtheta: Any
    v: Any  # orientation of the tangent
    qc: Any  # a corrector's iterate
    weight: Any  # the arc-length metric's weights (1 per unknown, |dtheta|^2 for s)
    written: tuple[ca.SX, ca.SX, ca.SX] | None  # (g, J_p, J_s) at (y, theta1 + s dtheta)
    tangent: ca.Function  # (q, v, p, c) -> (t, vec(J_p)), called by the step
    gH: ca.Function  # (q, p, c) -> (g, H')

    @property
    def X(self):
        """The class of the symbols (``casadi.SX`` or ``casadi.MX``)."""
        return ca.MX if self.compact else ca.SX


def _curve_symbols(sym, mx: bool) -> tuple[Any, ...]:
    """``(y, theta, c, q, p, yq, s, theta1, dtheta)``: the model's own SX symbols with
    ``q = (y, s)`` and ``p = (theta1, dtheta)`` stacked, or MX ones (an MX Function's inputs
    are symbols: ``q`` and ``p`` are, and their parts slices of them)."""
    m, k = sym.m, sym.k
    if not mx:
        s, theta1, dtheta = ca.SX.sym("s"), ca.SX.sym("theta1", k), ca.SX.sym("dtheta", k)
        q, p = ca.vertcat(sym.y, s), ca.vertcat(theta1, dtheta)
        return sym.y, sym.theta, sym.c, q, p, sym.y, s, theta1, dtheta
    y, theta, c = model_inputs(sym, True)
    qm, pm = ca.MX.sym("q", m + 1), ca.MX.sym("p", 2 * k)
    return y, theta, c, qm, pm, qm[:m], qm[m], pm[:k], pm[k:]


def _curve(sym, inline: bool, closure: ca.Function | None, solver_calls: bool | None, loops: bool):
    """The shared symbols and inner Functions, and the exported tangent kernel."""
    solve_inline = not solver_calls if solver_calls is not None else inline
    solves = Solves(calls=not solve_inline, loops=loops)
    opts = function_options(inline)
    if inline:
        closure = None
    elif closure is None:
        closure = closure_function(sym)
    mx = closure is not None and compact(sym, loops)
    X: Any = ca.MX if mx else ca.SX
    m = sym.m
    y, theta, c, q, p, yq, s, theta1, dtheta = _curve_symbols(sym, mx)
    written = None
    if not mx:
        subs = ca.substitute([sym.g, sym.J_p, sym.J_s], [sym.theta], [theta1 + s * dtheta])
        written = (subs[0], subs[1], subs[2])
    weight = ca.vertcat(ca.DM.ones(m), ca.dot(dtheta, dtheta))
    v = X.sym("v", m + 1)
    names_in, names_out = ["q", "v", "p", "c"], ["t", "J_p"]
    if closure is None:
        assert written is not None
        t = bordered_tangent(written[1], written[2], dtheta, v)[0]
        f_tan = ca.Function(
            "scdk_follow_tangent", [q, v, p, c], [t, ca.vec(written[1])], names_in, names_out
        )
        f_tan_call = f_tan
        gH = written
    else:
        # one copy of the tangent: the exported kernel calls the Function the step calls
        gH = tuple(closure(yq, theta1 + s * dtheta, c))
        tc = bordered_tangent(gH[1], gH[2], dtheta, v, solves=solves)[0]
        f_tan_call = ca.Function(
            "scdk_follow_tangent_call", [q, v, p, c], [tc, ca.vec(gH[1])], opts
        )
        f_tan = ca.Function(
            "scdk_follow_tangent",
            [q, v, p, c],
            list(f_tan_call(q, v, p, c)),
            names_in,
            names_out,
        )
    Hq = ca.horzcat(gH[1], -(gH[2] @ dtheta))
    # inlined where it is used: with calls of the closure, it is a call and a product
    f_gH = ca.Function("scdk_follow_gH", [q, p, c], [gH[0], Hq])
    qc = X.sym("q", m + 1)
    cv = _Curve(sym, inline, solves, loops, mx, opts, closure, y, theta, c, q, p, yq, s, theta1,
                dtheta, v, qc, weight, written, f_tan_call, f_gH)  # fmt: skip
    return cv, f_tan


def _step_kernels(cv: _Curve) -> tuple[ca.Function, ca.Function]:
    """(steps, step): one predictor-corrector step, and ``STEPS`` of them mapped."""
    m, c, p = cv.sym.m, cv.c, cv.p
    x = cv.X.sym("x", 2 * (m + 1))
    h = cv.X.sym("h")
    q0, t1 = x[: m + 1], x[m + 1 :]
    t2 = cv.tangent(q0 + h / 2 * t1, t1, p, c)[0]
    t3 = cv.tangent(q0 + h / 2 * t2, t1, p, c)[0]
    t4 = cv.tangent(q0 + h * t3, t1, p, c)[0]
    q_pred = q0 + h / 6 * (t1 + 2 * t2 + 2 * t3 + t4)
    # the corrector on the plane through q_pred normal to t1: one Newton step
    qc, qp, tc = cv.qc, cv.X.sym("q_pred", m + 1), cv.X.sym("t", m + 1)
    row = (cv.weight * tc).T
    gk, Hk = cv.gH(qc, p, c)
    f_corr = ca.Function(
        "scdk_follow_correct",
        [qc, qp, tc, p, c],
        [-cv.solves.solve(ca.vertcat(Hk, row), ca.vertcat(gk, row @ (qc - qp)))],
        cv.opts,
    )
    qk = q_pred
    corrections = []
    for _ in range(CORRECTIONS):
        dq = f_corr(qk, q_pred, t1, p, c)
        corrections.append(ca.sqrt(ca.dot(cv.weight * dq, dq)))
        qk = qk + dq
    t_new, J_new = cv.tangent(qk, t1, p, c)
    info = ca.vertcat(corrections[0], corrections[-1], ca.dot(cv.weight * t_new, t1))
    step = ca.Function(
        "scdk_follow_step",
        [x, h, p, c],
        [ca.vertcat(qk, t_new), info, J_new],
        ["x", "h", "p", "c"],
        ["x_new", "info", "J_p"],
    )
    return step.mapaccum("scdk_follow_steps", STEPS), step


def _locator_kernels(cv: _Curve) -> tuple[ca.Function, ca.Function]:
    """(plane, fold): the curve point on the plane through ``q0`` normal to ``v``, and a
    turning point of ``s`` (Newton on ``[g; t_s]``: ``t_s`` vanishes exactly where ``det J_p``
    does)."""
    m, c, p, v, qc, q = cv.sym.m, cv.c, cv.p, cv.v, cv.qc, cv.q
    qa = cv.X.sym("q0", m + 1)
    rowv = (cv.weight * v).T
    gk, Hk = cv.gH(qc, p, c)
    solves = Solves(loops=cv.loops)
    plane1 = ca.Function(
        "scdk_plane1",
        [qc, qa, v, p, c],
        [qc - solves.solve(ca.vertcat(Hk, rowv), ca.vertcat(gk, rowv @ (qc - qa)))],
        cv.opts,
    )
    qk = qa
    for _ in range(PLANE_STEPS):
        qk = plane1(qk, qa, v, p, c)
    f_plane = ca.Function(
        "scdk_follow_plane",
        [qa, v, p, c],
        [qk, ca.norm_inf(cv.gH(qk, p, c)[0])],
        ["q0", "v", "p", "c"],
        ["q", "residual"],
    )
    if cv.written is not None:
        g, Jp, Js = cv.written
        t_hat = bordered_tangent(Jp, Js, cv.dtheta, v)[1]
        F = ca.vertcat(g, t_hat[m])
        fold_step = q - ca.solve(ca.jacobian(F, q), F)
    else:
        fold_step = _fold_step_by_adjoint(cv, solves)
    fold1 = ca.Function("scdk_fold1", [q, v, p, c], [fold_step], cv.opts)
    qk = qa
    for _ in range(FOLD_STEPS):
        qk = fold1(qk, v, p, c)
    f_fold = ca.Function("scdk_follow_fold", [qa, v, p, c], [qk], ["q", "v", "p", "c"], ["q_fold"])
    return f_plane, f_fold


def _fold_row(sym) -> ca.Function:
    """(q[m+1], p[2k], c, u[m], d[m+1]) -> ``grad_q (u . (dg/dq) d)`` with
    ``g = g(y, theta1 + s dtheta)``, ``q = (y, s)``, ``p = (theta1, dtheta)``: one reverse sweep
    over one forward sweep of the closures (SX, its calls stay calls)."""
    m, k = sym.m, sym.k
    s, theta1, dtheta = ca.SX.sym("s"), ca.SX.sym("theta1", k), ca.SX.sym("dtheta", k)
    q, p = ca.vertcat(sym.y, s), ca.vertcat(theta1, dtheta)
    g = ca.substitute(sym.g, sym.theta, theta1 + s * dtheta)
    u, d = ca.SX.sym("u", m), ca.SX.sym("d", m + 1)
    row = ca.gradient(ca.dot(u, ca.jtimes(g, q, d)), q)
    return ca.Function("scdk_fold_row", [q, p, sym.c, u, d], [row], function_options(False))


def _fold_step_by_adjoint(cv: _Curve, solves: Solves):
    """One Newton step on ``F = [g; t_hat_s] = 0`` at ``q`` (the fold kernel's), its
    Jacobian's last row by the adjoint of the bordered solve instead of the derivative of the
    solve's operations: the same matrix, its code proportional to the closures'.

    With ``A t_hat = e`` (:func:`~scdk_sym.kernels.curve.bordered_matrix`, whose last row is
    constant) and ``A^T u = e``, ``d t_hat_s / dq = -u^T (dA/dq) t_hat``, and the first ``m``
    rows of ``A t_hat`` are the derivative of ``g(y, theta1 + s dtheta)`` along
    ``d = (t_hat_y, t_hat_s / w)``: the row is ``-grad_q (u_y . (dg/dq) d)`` at fixed ``u``
    and ``d``, one reverse sweep over one forward sweep of ``g`` (:func:`_fold_row`).
    """
    m, c, p, v, q = cv.sym.m, cv.c, cv.p, cv.v, cv.q
    assert cv.closure is not None  # compact kernels are built from closure calls
    g, Jp, Js = cv.closure(cv.yq, cv.theta1 + cv.s * cv.dtheta, c)
    A, w = bordered_matrix(Jp, Js, cv.dtheta, v)
    e = ca.DM.zeros(m + 1)
    e[m] = 1.0
    t_hat = solves.solve(A, e)
    u = solves.solve(A.T, e)
    row = -_fold_row(cv.sym)(q, p, c, u[:m], ca.vertcat(t_hat[:m], t_hat[m] / w)).T
    H = ca.horzcat(Jp, -(Js @ cv.dtheta))
    return q - solves.solve(ca.vertcat(H, row), ca.vertcat(g, t_hat[m]))


def _fixed_theta_kernels(cv: _Curve) -> tuple[ca.Function, ca.Function, ca.Function]:
    """(polish, newton, predict): Newton at fixed theta (one step, iterated by the polish and
    the tracker's corrector), and one RK4 step in ``s`` of ``dy/ds = J_p^-1 j_s``, ``s`` from
    0 to 1."""
    sym, m, y, theta, c = cv.sym, cv.sym.m, cv.y, cv.theta, cv.c
    newton1 = newton_correction(sym, cv.inline, cv.closure, cv.loops)
    g = cv.closure(y, theta, c)[0] if cv.compact and cv.closure is not None else sym.g
    residual = ca.Function("scdk_residual", [y, theta, c], [ca.norm_inf(g)], cv.opts)
    yk = y
    for _ in range(POLISH_STEPS):
        yk = yk - newton1(yk, theta, c)
    f_polish = ca.Function(
        "scdk_follow_polish",
        [y, theta, c],
        [yk, residual(yk, theta, c)],
        ["y", "theta", "c"],
        ["y_solved", "residual"],
    )
    yk = y
    last = cv.X.zeros(m)
    for _ in range(NEWTON_ITERATIONS):
        last = newton1(yk, theta, c)
        yk = yk - last
    f_newton = ca.Function(
        "scdk_follow_newton",
        [y, theta, c],
        [yk, residual(yk, theta, c), ca.norm_inf(last)],
        ["y", "theta", "c"],
        ["y_new", "residual", "correction"],
    )
    theta1, dtheta = cv.X.sym("theta1", sym.k), cv.X.sym("dtheta", sym.k)
    y1 = rk4_in_s(sym, y, 0.0, 1.0, theta1, dtheta, 1, closure=cv.closure, loops=cv.loops, c=c)
    f_predict = ca.Function(
        "scdk_follow_predict",
        [y, theta1, dtheta, c],
        [y1],
        ["y", "theta1", "dtheta", "c"],
        ["y1"],
    )
    return f_polish, f_newton, f_predict


def _singular_kernel(sym, closure: ca.Function | None = None) -> ca.Function:
    """(y, theta, c) -> (g, J_p, J_s, dJ_p/d(y, theta)), dense.

    With ``closure`` (kernels built to be compiled), the closures are a call of it and
    ``dJ_p/d(y, theta)`` is ``m + k`` calls of one Function, the derivative of ``J_p`` along
    one direction of ``(y, theta)`` (one forward sweep): generated C proportional to the
    closures', where the Jacobian written out is ``m + k`` times longer.
    """
    names = (["y", "theta", "c"], ["g", "J_p", "J_s", "dJ_p"])
    y, theta, c = sym.y, sym.theta, sym.c
    z = ca.vertcat(y, theta)
    if closure is None:
        outs = [sym.g, sym.J_p, sym.J_s, ca.jacobian(ca.vec(sym.J_p), z)]
        dense = [ca.densify(e) for e in outs]
        return ca.Function("scdk_follow_singular", [y, theta, c], dense, *names)
    dz = ca.SX.sym("dz", z.numel())
    along = ca.Function(
        "scdk_dJ_p", [y, theta, c, dz], [ca.jtimes(ca.vec(sym.J_p), z, dz)],
        function_options(False),
    )  # fmt: skip
    # an MX Function of calls: its generated C copies each call's outputs by loops
    ym, thm, cm = model_inputs(sym, True)
    eye = ca.DM.eye(z.numel())
    dJ = ca.horzcat(*[along(ym, thm, cm, eye[:, i]) for i in range(z.numel())])
    outs = [*closure(ym, thm, cm), dJ]
    dense = [ca.densify(e) for e in outs]
    return ca.Function("scdk_follow_singular", [ym, thm, cm], dense, *names)


def build_follower_kernels(
    sym,
    inline: bool = True,
    closure: ca.Function | None = None,
    solver_calls: bool | None = None,
    loops: bool = False,
) -> FollowerKernels:
    """Build the follower's Functions from a model's symbolic system (``model.symbolic``).

    Args:
        sym: the model's symbolic system.
        inline: False to build the kernels from calls of their inner Functions (the closure
            system and its Jacobians, tangent, corrector, Newton steps, residual, ``dy/ds``)
            instead of inlined copies: the same operations, several times less generated C to
            compile (the C tracker's choice).
        closure: with ``inline`` False, the :func:`closure_function` every kernel calls
            (default: a new one; pass the one other kernels call for one copy in C).
        solver_calls: the tangent's and the corrector's bordered solves by calls of
            :func:`linear_solver` (one copy in C) instead of written out in each; default:
            ``not inline``. With ``inline`` False and written-out solves (the compiled
            backend's choice) the steps take the time of the inlined ones for a tenth more C.
        loops: for kernels built to be compiled: the systems larger than
            :data:`~scdk_sym.kernels.curve.WRITTEN_SOLVE_MAX` solved by calls of
            :func:`~scdk_sym.kernels.curve.loop_solver`, and on such a model the fold's
            Newton matrix by the adjoint of the bordered solve and ``dJ_p/d(y, theta)`` by
            calls of one directional derivative (with ``inline`` False): generated C
            proportional to the closures', not to the symbolic solves and their derivatives.
    """
    cv, f_tan = _curve(sym, inline, closure, solver_calls, loops)
    f_steps, step = _step_kernels(cv)
    f_plane, f_fold = _locator_kernels(cv)
    f_polish, f_newton, f_predict = _fixed_theta_kernels(cv)
    f_singular = _singular_kernel(sym, cv.closure if cv.compact else None)
    return FollowerKernels(
        f_steps, step, f_tan, f_plane, f_fold, f_polish, f_newton, f_predict, f_singular
    )
