"""CasADi Functions of the curve follower (SX, or generated C compiled once and cached).

The curve is ``H(q) = 0`` with ``q = (y, s)``, ``H = g(y, theta1 + s dtheta)`` and
``p = (theta1, dtheta)``; its Jacobian is ``[J_p, -j_s]`` with ``j_s = J_s dtheta``. Lengths along
it are measured in the metric ``|dy|^2 + (|dtheta| ds)^2`` (arc length in joint space).

The oriented tangent has one definition, the bordered solve
``[H'; v^T] t = e_{m+1}``: by Cramer's rule ``t`` is parallel to the SC field
``nu = [adj(J_p) j_s; det J_p]`` (the generalised cross product of the rows of ``H'``) with
``v . t > 0``. It is regular on the singular manifold ``det J_p = 0`` (folds) and only fails
where ``H'`` drops rank (bifurcations, handled by the follower). Along a branch
``sign(t_s) = sign(det J_p) * sign(det [H'; v^T])``: at a fold ``t_s`` and ``det J_p`` change
sign together; at a bifurcation ``det J_p`` changes sign while ``t_s`` does not.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import casadi as ca

from ..errors import InputError
from ..kernels.fastcall import Dense

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
BACKENDS = ("casadi", "compiled")


@dataclass(frozen=True)
class FollowerKernels:
    """CasADi Functions of the follower of one model (``c``: chart of the floating joints).

    Attributes:
        steps: (x[2(m+1)], h, p[2k], c) -> (X[2(m+1), STEPS], info[3, STEPS],
            J[m*m, STEPS]): ``STEPS`` predictor-corrector steps of arc length ``h`` from
            ``x = (q, t)`` (a point of the curve and its unit tangent): RK4 predictor along the
            tangent field, ``CORRECTIONS`` Newton corrections on the plane normal to ``t``;
            ``info`` rows: first and last correction (weighted norm), cosine between the
            tangents before and after; ``J``: ``vec(J_p)`` at each new point (column-major).
        tangent: (q, v, p, c) -> (t, vec(J_p)): unit tangent at ``q`` oriented along ``v``.
        plane: (q0, v, p, c) -> (q, max|g|): Newton on ``[H; v^T W (q - q0)] = 0`` (the curve
            point on the plane through ``q0`` normal to ``v``).
        fold: (q, v, p, c) -> q: Newton on ``[H; t_s] = 0`` (a turning point of ``s``).
        polish: (y, theta, c) -> (y, max|g|): Newton at fixed ``theta``.
        singular: (y, theta, c) -> (g, J_p, J_s, dJ_p/d(y, theta) [m*m, m+k]): what a
            minimum-norm Newton onto the singular manifold ``det J_p = 0`` needs.
    """

    steps: ca.Function
    tangent: ca.Function
    plane: ca.Function
    fold: ca.Function
    polish: ca.Function
    singular: ca.Function

    def all(self) -> list[ca.Function]:
        """Every Function, in declaration order."""
        return [getattr(self, f.name) for f in fields(self)]


def build_follower_kernels(sym) -> FollowerKernels:
    """Build the follower's Functions from a model's symbolic system (``model.symbolic``)."""
    m, k = sym.m, sym.k
    y, c = sym.y, sym.c
    s = ca.SX.sym("s")
    theta1 = ca.SX.sym("theta1", k)
    dtheta = ca.SX.sym("dtheta", k)
    p = ca.vertcat(theta1, dtheta)
    q = ca.vertcat(y, s)
    g, Jp, Js = ca.substitute([sym.g, sym.J_p, sym.J_s], [sym.theta], [theta1 + s * dtheta])
    w2 = ca.dot(dtheta, dtheta)
    w = ca.sqrt(w2 + 1e-300)
    weight = ca.vertcat(ca.DM.ones(m), w2)
    v = ca.SX.sym("v", m + 1)
    # the bordered solve in the balanced variables (y, |dtheta| s): every column of order one
    js_hat = Js @ (dtheta / w)
    A = ca.vertcat(ca.horzcat(Jp, -js_hat), ca.horzcat(v[:m].T, w * v[m]))
    e = ca.DM.zeros(m + 1)
    e[m] = 1.0
    t_hat = ca.solve(A, e)
    t = ca.vertcat(t_hat[:m], t_hat[m] / w) / ca.norm_2(t_hat)
    f_tan = ca.Function(
        "scdk_follow_tangent", [q, v, p, c], [t, ca.vec(Jp)], ["q", "v", "p", "c"], ["t", "J_p"]
    )
    Hq = ca.horzcat(Jp, -(Js @ dtheta))
    f_gH = ca.Function("scdk_follow_gH", [q, p, c], [g, Hq])

    # one predictor-corrector step, mapped STEPS times
    x = ca.SX.sym("x", 2 * (m + 1))
    h = ca.SX.sym("h")
    q0, t1 = x[: m + 1], x[m + 1 :]
    t2 = f_tan(q0 + h / 2 * t1, t1, p, c)[0]
    t3 = f_tan(q0 + h / 2 * t2, t1, p, c)[0]
    t4 = f_tan(q0 + h * t3, t1, p, c)[0]
    q_pred = q0 + h / 6 * (t1 + 2 * t2 + 2 * t3 + t4)
    row = (weight * t1).T
    qk = q_pred
    corrections = []
    for _ in range(CORRECTIONS):
        gk, Hk = f_gH(qk, p, c)
        dq = -ca.solve(ca.vertcat(Hk, row), ca.vertcat(gk, row @ (qk - q_pred)))
        corrections.append(ca.sqrt(ca.dot(weight * dq, dq)))
        qk = qk + dq
    t_new, J_new = f_tan(qk, t1, p, c)
    info = ca.vertcat(corrections[0], corrections[-1], ca.dot(weight * t_new, t1))
    step = ca.Function("scdk_follow_step", [x, h, p, c], [ca.vertcat(qk, t_new), info, J_new])
    f_steps = step.mapaccum("scdk_follow_steps", STEPS)

    # the curve point on the plane through q0 normal to v
    qa = ca.SX.sym("q0", m + 1)
    rowv = (weight * v).T
    qk = qa
    for _ in range(PLANE_STEPS):
        gk, Hk = f_gH(qk, p, c)
        qk = qk - ca.solve(ca.vertcat(Hk, rowv), ca.vertcat(gk, rowv @ (qk - qa)))
    f_plane = ca.Function(
        "scdk_follow_plane",
        [qa, v, p, c],
        [qk, ca.norm_inf(f_gH(qk, p, c)[0])],
        ["q0", "v", "p", "c"],
        ["q", "residual"],
    )

    # a turning point of s: Newton on [g; t_s] (t_s vanishes exactly where det J_p does)
    F = ca.vertcat(g, t_hat[m])
    fold1 = ca.Function("scdk_fold1", [q, v, p, c], [q - ca.solve(ca.jacobian(F, q), F)])
    qk = qa
    for _ in range(FOLD_STEPS):
        qk = fold1(qk, v, p, c)
    f_fold = ca.Function("scdk_follow_fold", [qa, v, p, c], [qk], ["q", "v", "p", "c"], ["q_fold"])

    theta = ca.SX.sym("theta", k)
    g0, J0 = ca.substitute([sym.g, sym.J_p], [sym.theta], [theta])
    newton = ca.Function("scdk_newton1", [y, theta, c], [y - ca.solve(J0, g0)])
    yk = y
    for _ in range(POLISH_STEPS):
        yk = newton(yk, theta, c)
    res = ca.norm_inf(ca.substitute(g0, y, yk))
    f_polish = ca.Function(
        "scdk_follow_polish",
        [y, theta, c],
        [yk, res],
        ["y", "theta", "c"],
        ["y_solved", "residual"],
    )

    z = ca.vertcat(sym.y, sym.theta)
    dJ = ca.jacobian(ca.vec(sym.J_p), z)
    f_sing = ca.Function(
        "scdk_follow_singular",
        [sym.y, sym.theta, c],
        [ca.densify(e) for e in (sym.g, sym.J_p, sym.J_s, dJ)],
        ["y", "theta", "c"],
        ["g", "J_p", "J_s", "dJ_p"],
    )
    return FollowerKernels(f_steps, f_tan, f_plane, f_fold, f_polish, f_sing)


def follower_kernels(model, backend: str = "casadi") -> FollowerKernels:
    """The (cached) follower kernels of a model.

    Args:
        model: the model.
        backend: "casadi" (SX virtual machine) or "compiled" (generated C compiled with the
            system compiler once, cached on disk by content hash).

    Raises:
        InputError: unknown backend.
        BuildError: no C compiler (compiled backend).
    """
    if backend not in BACKENDS:
        raise InputError(f"unknown backend {backend!r}; backends: {', '.join(BACKENDS)}")
    store = model.__dict__.setdefault("_follower_kernels", {})
    if backend not in store:
        kern = build_follower_kernels(model.symbolic)
        if backend == "compiled":
            from ..kernels.compile import cached_library

            target = cached_library(kern.all(), "scdk_follow")
            kern = FollowerKernels(*(ca.external(f.name(), str(target)) for f in kern.all()))
        store[backend] = kern
    return store[backend]


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


def follower_calls(model, backend: str = "casadi") -> FollowerCalls:
    """The (cached) zero-copy callers of :func:`follower_kernels` (same arguments)."""
    store = model.__dict__.setdefault("_follower_calls", {})
    if backend not in store:
        kern = follower_kernels(model, backend)
        store[backend] = FollowerCalls(
            Dense(kern.steps),
            Dense(kern.tangent),
            Dense(kern.plane, scalars=(1,)),
            Dense(kern.fold),
            Dense(kern.polish, scalars=(1,)),
            Dense(kern.singular),
        )
    return store[backend]
