"""Symbolic steps along the SC curve ``H(q) = 0``, ``q = (y, s)``, ``H = g(y, theta1 + s dtheta)``.

One definition of each, built on a model's symbolic closure: the oriented tangent
(:func:`bordered_tangent`, the bordered solve ``[H'; v^T] t = e_{m+1}``, parallel to the SC
field ``nu = [adj(J_p) j_s; det J_p]``), the Newton correction at fixed ``theta``
(:func:`newton_correction`), the RK4 step in ``s`` (:func:`rk4_in_s`), the closure as one
Function (:func:`closure_function`) and the linear solve of one matrix pattern
(:func:`linear_solver`). The CVODES field (:mod:`scdk_sym.kernels.functions`), the curve
follower's kernels (:mod:`scdk_sym.follower.kernels`) and the generated C (tracker, solves
and the atlas sweep) are built from them.
"""

from __future__ import annotations

import hashlib

import casadi as ca


def bordered_tangent(
    Jp: ca.SX,
    Js: ca.SX,
    dtheta: ca.SX,
    v: ca.SX,
    rhs: ca.SX | None = None,
    inline: bool = True,
) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX | None]:
    """The oriented SC tangent by the bordered solve: the package's one definition of it.

    ``[H'; v^T] t = e_{m+1}`` with ``H' = [J_p, -J_s dtheta]``, solved in the balanced variables
    ``(y, |dtheta| s)`` (every column of order one: CasADi's symbolic QR has no pivoting and
    loses digits on the badly scaled ``[J_p, -j_s; v^T]`` when ``dtheta`` is small).

    Args:
        Jp: (m, m) ``J_p`` at the point.
        Js: (m, k) ``J_s`` at the point.
        dtheta: (k,) direction of the line in joint space.
        v: (m+1,) orientation: the tangent has ``v . t > 0`` (in the balanced variables).
        rhs: optional (m,) right-hand side ``r``: also solve ``[H'; v^T] d = [r; 0]`` with the
            same matrix (the stabilising correction of the SC field, ``r = -g``).
        inline: False to solve by calls of :func:`linear_solver` (compact generated C).

    Returns:
        ``(t, t_hat, w, d)``: the unit tangent in ``(y, s)`` (metric ``|dy|^2 + (|dtheta| ds)^2``)
        [(m+1,)]; the balanced solution before normalisation (its last entry vanishes exactly
        where ``det J_p`` does) [(m+1,)]; ``w = |dtheta|``; ``d`` in ``(y, s)`` (None without
        ``rhs``).
    """
    m = Jp.size1()
    w = ca.sqrt(ca.dot(dtheta, dtheta) + 1e-300)
    js_hat = Js @ (dtheta / w)
    A = ca.vertcat(ca.horzcat(Jp, -js_hat), ca.horzcat(v[:m].T, w * v[m]))
    e = ca.DM.zeros(m + 1)
    e[m] = 1.0
    d = None
    if rhs is None:
        t_hat = solve_by_columns(A, e, inline)
    else:
        sol = solve_by_columns(A, ca.horzcat(e, ca.vertcat(rhs, 0)), inline)
        t_hat = sol[:, 0]
        d = ca.vertcat(sol[:m, 1], sol[m, 1] / w)
    t = ca.vertcat(t_hat[:m], t_hat[m] / w) / ca.norm_2(t_hat)
    return t, t_hat, w, d


def function_options(inline: bool) -> dict:
    """Options of an inner Function: ``never_inline`` keeps its calls as calls (one copy of
    its code in generated C instead of one per use; the same operations either way)."""
    return {} if inline else {"never_inline": True}


#: :func:`linear_solver` Functions by sparsity pattern (one per pattern and process).
_SOLVERS: dict[tuple, ca.Function] = {}


def linear_solver(sparsity: ca.Sparsity) -> ca.Function:
    """The linear solve with a matrix of a given sparsity as one Function whose calls stay
    calls.

    CasADi solves a symbolic system by a symbolic QR factorisation of the matrix's sparsity
    pattern: a few hundred operations for a dense 6x6, about a thousand for a 7x7, written out
    in generated C at each use. Kernels that solve by calls of this Function (one per pattern
    and process) hold one copy.

    Args:
        sparsity: the (square) matrix's sparsity.

    Returns:
        (A, b[n]) -> ``A^{-1} b``.
    """
    key = (sparsity.size1(), tuple(sparsity.colind()), tuple(sparsity.row()))
    if key not in _SOLVERS:
        A, b = ca.SX.sym("A", sparsity), ca.SX.sym("b", sparsity.size1())
        # named by the pattern: the generated C does not depend on what was built before
        tag = hashlib.sha256(repr(key).encode()).hexdigest()[:8]
        name = f"scdk_solve{sparsity.size1()}_{tag}"
        _SOLVERS[key] = ca.Function(name, [A, b], [ca.solve(A, b)], function_options(False))
    return _SOLVERS[key]


def solve_by_columns(A: ca.SX, B: ca.SX | ca.DM, inline: bool) -> ca.SX:
    """``A^{-1} B``: CasADi's symbolic solve, or (``inline`` False) calls of
    :func:`linear_solver`, one per column of ``B``."""
    if inline:
        return ca.solve(A, B)
    solver = linear_solver(A.sparsity())
    return ca.horzcat(*[solver(A, B[:, j]) for j in range(B.size2())])


def closure_function(sym, name: str = "scdk_closure", dense: bool = False) -> ca.Function:
    """The closure system and its Jacobians as one Function whose calls stay calls.

    Kernels built from calls of it (``inline=False`` below) hold one copy of the model's
    expressions in generated C, however many of them evaluate the closures; computing ``g``,
    ``J_p`` and ``J_s`` together costs a few percent more than any two of them (their
    subexpressions are shared).

    Args:
        sym: the model's symbolic system (``model.symbolic``).
        name: the Function's name (its C name in generated code).
        dense: True to return every output dense (structural zeros stored), e.g. for a C caller
            indexing dense column-major arrays; the same values.

    Returns:
        (y[m], theta[k], c) -> (g[m], J_p[m,m], J_s[m,k]) [model length unit, per rad].
    """
    outs = [sym.g, sym.J_p, sym.J_s]
    return ca.Function(
        name,
        [sym.y, sym.theta, sym.c],
        [ca.densify(o) for o in outs] if dense else outs,
        ["y", "theta", "c"],
        ["g", "J_p", "J_s"],
        function_options(False),
    )


def newton_correction(sym, inline: bool = True, closure: ca.Function | None = None) -> ca.Function:
    """The Newton correction at fixed ``theta`` (``y - correction`` is one Newton step).

    Args:
        sym: the model's symbolic system (``model.symbolic``).
        inline: False to keep calls of it as calls in the expressions built from it
            (compact generated C).
        closure: with ``inline`` False, the :func:`closure_function` it calls (default: a
            new one; pass one shared by several kernels for one copy in generated C).

    Returns:
        (y[m], theta[k], c) -> ``J_p^{-1} g`` [model length unit, rad].
    """
    y, theta, c = sym.y, sym.theta, sym.c
    if inline:
        g, Jp = sym.g, sym.J_p
    else:
        g, Jp, _ = (closure or closure_function(sym))(y, theta, c)
    # the solve is written out here (one copy, as this Function's calls stay calls): a call of
    # linear_solver on this hot path costs a few percent of a tracking step
    return ca.Function("scdk_newton1", [y, theta, c], [ca.solve(Jp, g)], function_options(inline))


def rk4_in_s(
    sym,
    y0: ca.SX,
    s0,
    s1,
    theta1: ca.SX,
    dtheta: ca.SX,
    steps: int,
    inline: bool = True,
    closure: ca.Function | None = None,
) -> ca.SX:
    """RK4 steps along the curve with ``s`` as the independent variable (valid off the
    singular manifold): ``dy/ds = J_p^{-1} J_s dtheta`` on ``theta = theta1 + s dtheta``.

    Args:
        sym: the model's symbolic system (``model.symbolic``).
        y0: (m,) unknowns at ``s0``.
        s0: start value of ``s`` (a number or a scalar SX).
        s1: end value of ``s``.
        theta1: (k,) actuated values at ``s = 0`` [rad or model length unit].
        dtheta: (k,) direction of the line.
        steps: number of equal RK4 steps from ``s0`` to ``s1``.
        inline: False to evaluate ``dy/ds`` by calls of one Function (compact generated C).
        closure: with ``inline`` False, the :func:`closure_function` ``dy/ds`` calls
            (default: a new one).

    Returns:
        (m,) the unknowns at ``s1``.
    """
    s, a, d = ca.SX.sym("s"), ca.SX.sym("theta1", sym.k), ca.SX.sym("dtheta", sym.k)
    if inline:
        Jp, Js = ca.substitute([sym.J_p, sym.J_s], [sym.theta], [a + s * d])
    else:
        _, Jp, Js = (closure or closure_function(sym))(sym.y, a + s * d, sym.c)
    f = ca.Function(
        "scdk_dyds", [sym.y, s, a, d, sym.c], [ca.solve(Jp, Js @ d)], function_options(inline)
    )
    c = sym.c

    def dyds(y, s_):
        return f(y, s_, theta1, dtheta, c)

    h = (s1 - s0) / steps
    yk, sk = y0, s0
    for _ in range(steps):
        k1 = dyds(yk, sk)
        k2 = dyds(yk + h / 2 * k1, sk + h / 2)
        k3 = dyds(yk + h / 2 * k2, sk + h / 2)
        k4 = dyds(yk + h * k3, sk + h)
        yk = yk + h * (k1 + 2 * k2 + 2 * k3 + k4) / 6
        sk = sk + h
    return yk
