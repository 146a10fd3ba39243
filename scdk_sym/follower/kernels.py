"""CasADi Functions of the curve follower (SX, or generated C compiled once and cached).

The curve is ``H(q) = 0`` with ``q = (y, s)``, ``H = g(y, theta1 + s dtheta)`` and
``p = (theta1, dtheta)``; its Jacobian is ``[J_p, -j_s]`` with ``j_s = J_s dtheta``. Lengths along
it are measured in the metric ``|dy|^2 + (|dtheta| ds)^2`` (arc length in joint space).

The oriented tangent has one definition in the package,
:func:`~scdk_sym.kernels.curve.bordered_tangent`, the bordered solve
``[H'; v^T] t = e_{m+1}``: by Cramer's rule ``t`` is parallel to the SC field
``nu = [adj(J_p) j_s; det J_p]`` (the generalised cross product of the rows of ``H'``) with
``v . t > 0``. It is regular on the singular manifold ``det J_p = 0`` (folds) and only fails
where ``H'`` drops rank (bifurcations, handled by the follower). Along a branch
``sign(t_s) = sign(det J_p) * sign(det [H'; v^T])``: at a fold ``t_s`` and ``det J_p`` change
sign together; at a bifurcation ``det J_p`` changes sign while ``t_s`` does not.

The symbolic steps (:mod:`scdk_sym.kernels.curve`: the tangent, the Newton correction, the
RK4 step in ``s``) are also what the CVODES field (:mod:`scdk_sym.kernels.functions`) is
built from; the generated C tracker's curve kernels are this module's Functions
(:mod:`scdk_sym.codegen.kernels`).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from ..backends import resolve
from ..kernels.curve import (
    bordered_tangent,
    closure_function,
    function_options,
    newton_correction,
    rk4_in_s,
    solve_by_columns,
)
from ..kernels.fastcall import Dense
from ..kernels.functions import FunctionSet
from ..products import FOLLOWER_CALLS, FOLLOWER_KERNELS
from ..symbolic.system import Symbolic

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
#: The compiled backend's library (:func:`follower_kernels`), one source per group compiled in
#: parallel: the kernels that call the closure Function (its one copy; the steps, called at
#: every predictor-corrector chunk, are the hot kernel), then the locators called a few times
#: per singular point or projection (the plane, the fold, the singular-manifold Newton data).
#: ``newton`` and ``predict``, which only the C tracker calls, are not compiled.
COMPILED_GROUPS = (("steps", "step", "tangent", "polish"), ("plane",), ("fold",), ("singular",))
#: Kernels of :data:`COMPILED_GROUPS` compiled at ``-O0``: called once or twice per singular
#: point, their optimisation costs more compile time than it saves (the fold's Newton step
#: holds the Jacobian of the symbolic bordered solve, half of the library's C; the singular
#: kernel, called at every step of the descent to the singular manifold, stays optimised).
UNOPTIMISED = ("plane", "fold")


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
    """The symbols and inner Functions the follower's kernels share (one model, one build)."""

    sym: Symbolic  # the model's symbolic system
    inline: bool  # kernels written out (else calls of their inner Functions)
    solve_inline: bool  # bordered solves written out (else calls of linear_solver)
    opts: dict  # options of the inner Functions
    closure: ca.Function | None  # the closure Function the kernels call (None: inlined)
    q: ca.SX  # (y, s)
    p: ca.SX  # (theta1, dtheta)
    s: ca.SX
    theta1: ca.SX
    dtheta: ca.SX
    v: ca.SX  # orientation of the tangent
    qc: ca.SX  # a corrector's iterate
    weight: ca.SX  # the arc-length metric's weights (1 per unknown, |dtheta|^2 for s)
    g: ca.SX  # g(y, theta1 + s dtheta)
    t_hat: ca.SX  # the unnormalised tangent
    tangent: ca.Function  # (q, v, p, c) -> (t, vec(J_p)), called by the step
    gH: ca.Function  # (q, p, c) -> (g, H')


def _curve(sym, inline: bool, closure: ca.Function | None, solver_calls: bool | None):
    """The shared symbols and inner Functions, and the exported tangent kernel."""
    solve_inline = not solver_calls if solver_calls is not None else inline
    opts = function_options(inline)
    if inline:
        closure = None
    elif closure is None:
        closure = closure_function(sym)
    m, k = sym.m, sym.k
    y, c = sym.y, sym.c
    s = ca.SX.sym("s")
    theta1 = ca.SX.sym("theta1", k)
    dtheta = ca.SX.sym("dtheta", k)
    p = ca.vertcat(theta1, dtheta)
    q = ca.vertcat(y, s)
    g, Jp, Js = ca.substitute([sym.g, sym.J_p, sym.J_s], [sym.theta], [theta1 + s * dtheta])
    w2 = ca.dot(dtheta, dtheta)
    weight = ca.vertcat(ca.DM.ones(m), w2)
    v = ca.SX.sym("v", m + 1)
    t, t_hat, _w, _ = bordered_tangent(Jp, Js, dtheta, v)
    names_in, names_out = ["q", "v", "p", "c"], ["t", "J_p"]
    if closure is None:
        f_tan = ca.Function(
            "scdk_follow_tangent", [q, v, p, c], [t, ca.vec(Jp)], names_in, names_out
        )
        f_tan_call = f_tan
        gH: tuple[ca.SX, ...] = (g, Jp, Js)
    else:
        # one copy of the tangent: the exported kernel calls the Function the step calls
        gH = tuple(closure(y, theta1 + s * dtheta, c))
        tc = bordered_tangent(gH[1], gH[2], dtheta, v, inline=solve_inline)[0]
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
    qc = ca.SX.sym("q", m + 1)
    cv = _Curve(sym, inline, solve_inline, opts, closure, q, p, s, theta1, dtheta, v, qc,
                weight, g, t_hat, f_tan_call, f_gH)  # fmt: skip
    return cv, f_tan


def _step_kernels(cv: _Curve) -> tuple[ca.Function, ca.Function]:
    """(steps, step): one predictor-corrector step, and ``STEPS`` of them mapped."""
    m, c, p = cv.sym.m, cv.sym.c, cv.p
    x = ca.SX.sym("x", 2 * (m + 1))
    h = ca.SX.sym("h")
    q0, t1 = x[: m + 1], x[m + 1 :]
    t2 = cv.tangent(q0 + h / 2 * t1, t1, p, c)[0]
    t3 = cv.tangent(q0 + h / 2 * t2, t1, p, c)[0]
    t4 = cv.tangent(q0 + h * t3, t1, p, c)[0]
    q_pred = q0 + h / 6 * (t1 + 2 * t2 + 2 * t3 + t4)
    # the corrector on the plane through q_pred normal to t1: one Newton step
    qc, qp = cv.qc, ca.SX.sym("q_pred", m + 1)
    row = (cv.weight * t1).T
    gk, Hk = cv.gH(qc, p, c)
    f_corr = ca.Function(
        "scdk_follow_correct",
        [qc, qp, t1, p, c],
        [
            -solve_by_columns(ca.vertcat(Hk, row), ca.vertcat(gk, row @ (qc - qp)), cv.solve_inline)
        ],  # fmt: skip
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
    m, c, p, v, qc, q = cv.sym.m, cv.sym.c, cv.p, cv.v, cv.qc, cv.q
    qa = ca.SX.sym("q0", m + 1)
    rowv = (cv.weight * v).T
    gk, Hk = cv.gH(qc, p, c)
    plane1 = ca.Function(
        "scdk_plane1",
        [qc, qa, v, p, c],
        [qc - ca.solve(ca.vertcat(Hk, rowv), ca.vertcat(gk, rowv @ (qc - qa)))],
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
    F = ca.vertcat(cv.g, cv.t_hat[m])
    fold1 = ca.Function("scdk_fold1", [q, v, p, c], [q - ca.solve(ca.jacobian(F, q), F)], cv.opts)
    qk = qa
    for _ in range(FOLD_STEPS):
        qk = fold1(qk, v, p, c)
    f_fold = ca.Function("scdk_follow_fold", [qa, v, p, c], [qk], ["q", "v", "p", "c"], ["q_fold"])
    return f_plane, f_fold


def _fixed_theta_kernels(cv: _Curve) -> tuple[ca.Function, ca.Function, ca.Function]:
    """(polish, newton, predict): Newton at fixed theta (one step, iterated by the polish and
    the tracker's corrector), and one RK4 step in ``s`` of ``dy/ds = J_p^-1 j_s``, ``s`` from
    0 to 1."""
    sym, c, m = cv.sym, cv.sym.c, cv.sym.m
    y, theta = sym.y, sym.theta
    newton1 = newton_correction(sym, cv.inline, cv.closure)
    residual = ca.Function("scdk_residual", [y, theta, c], [ca.norm_inf(sym.g)], cv.opts)
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
    last = ca.SX.zeros(m)
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
    f_predict = ca.Function(
        "scdk_follow_predict",
        [y, cv.theta1, cv.dtheta, c],
        [
            rk4_in_s(
                sym, y, 0.0, 1.0, cv.theta1, cv.dtheta, 1, inline=cv.inline, closure=cv.closure
            )
        ],  # fmt: skip
        ["y", "theta1", "dtheta", "c"],
        ["y1"],
    )
    return f_polish, f_newton, f_predict


def _singular_kernel(sym) -> ca.Function:
    """(y, theta, c) -> (g, J_p, J_s, dJ_p/d(y, theta)), dense."""
    z = ca.vertcat(sym.y, sym.theta)
    dJ = ca.jacobian(ca.vec(sym.J_p), z)
    return ca.Function(
        "scdk_follow_singular",
        [sym.y, sym.theta, sym.c],
        [ca.densify(e) for e in (sym.g, sym.J_p, sym.J_s, dJ)],
        ["y", "theta", "c"],
        ["g", "J_p", "J_s", "dJ_p"],
    )


def build_follower_kernels(
    sym,
    inline: bool = True,
    closure: ca.Function | None = None,
    solver_calls: bool | None = None,
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
    """
    cv, f_tan = _curve(sym, inline, closure, solver_calls)
    f_steps, step = _step_kernels(cv)
    f_plane, f_fold = _locator_kernels(cv)
    f_polish, f_newton, f_predict = _fixed_theta_kernels(cv)
    return FollowerKernels(
        f_steps, step, f_tan, f_plane, f_fold, f_polish, f_newton, f_predict,
        _singular_kernel(sym),
    )  # fmt: skip


#: Largest number of unknowns whose SX follower kernels are written out (inlined); larger
#: systems call their inner Functions (the same operations, built in a tenth of the time).
INLINE_MAX_UNKNOWNS = 9


def follower_kernels(model, backend: str = "cvodes") -> FollowerKernels:
    """The (cached) follower kernels of a model.

    Args:
        model: the model.
        backend: "cvodes" (SX virtual machine) or "compiled" (generated C compiled with the
            system compiler once, cached on disk by content hash: the kernels of
            :data:`COMPILED_GROUPS`, the others SX Functions); see :mod:`scdk_sym.backends`.

    Raises:
        InputError: a backend the kernel builders do not offer.
        BuildError: no C compiler (compiled backend).
    """
    backend = resolve(backend, "kernels")

    def build() -> FollowerKernels:
        if backend != "compiled":
            # above INLINE_MAX_UNKNOWNS the written-out kernels take seconds to build (an
            # 18-unknown leg: 3.8 s inlined, 0.3 s as calls of the inner Functions)
            return build_follower_kernels(model.symbolic, inline=model.m <= INLINE_MAX_UNKNOWNS)
        from ..kernels.compile import model_library

        # calls of one closure Function and of each Newton step: the same operations as the
        # inlined kernels, several times less C to compile; the bordered solves written out
        # (calls of one solver cost the steps, the hot kernel, 4-9% of their time)
        kern = build_follower_kernels(model.symbolic, inline=False, solver_calls=False)
        groups = [[getattr(kern, name) for name in group] for group in COMPILED_GROUPS]
        cold = [getattr(kern, name).name() for name in UNOPTIMISED]
        target = model_library(model, "scdk_follow", groups, unoptimised=cold)
        compiled = {f.name() for group in groups for f in group}
        return FollowerKernels(
            *(ca.external(f.name(), str(target)) if f.name() in compiled else f for f in kern.all())
        )

    return model.products.get(FOLLOWER_KERNELS, build, backend)


@dataclass(frozen=True)
class FollowerCalls:
    """Zero-copy callers of :class:`FollowerKernels` (:class:`~scdk_sym.kernels.fastcall.Dense`):
    the same signatures and values as the plain calls, outputs as numpy arrays (the residuals
    of ``plane`` and ``polish`` as floats)."""

    steps: Dense
    tangent: Dense
    plane: Dense
    fold: Dense
    polish: Dense
    singular: Dense


def follower_calls(model, backend: str = "cvodes") -> FollowerCalls:
    """The (cached) zero-copy callers of :func:`follower_kernels` (same arguments)."""
    backend = resolve(backend, "kernels")

    def build() -> FollowerCalls:
        kern = follower_kernels(model, backend)
        return FollowerCalls(
            Dense(kern.steps),
            Dense(kern.tangent),
            Dense(kern.plane, scalars=(1,)),
            Dense(kern.fold),
            Dense(kern.polish, scalars=(1,)),
            Dense(kern.singular),
        )

    return model.products.get(FOLLOWER_CALLS, build, backend)
