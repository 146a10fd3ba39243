"""Symbolic steps along the SC curve ``H(q) = 0``, ``q = (y, s)``, ``H = g(y, theta1 + s dtheta)``.

One definition of each, built on a model's symbolic closure: the oriented tangent
(:func:`bordered_tangent`, the bordered solve ``[H'; v^T] t = e_{m+1}``, parallel to the SC
field ``nu = [adj(J_p) j_s; det J_p]``), the Newton correction at fixed ``theta``
(:func:`newton_correction`), the RK4 step in ``s`` (:func:`rk4_in_s`), the closure as one
Function (:func:`closure_function`) and the linear solve of one matrix pattern
(:func:`linear_solver`, or in loops: :func:`loop_solver`; how a kernel solves is a
:class:`Solves`). The CVODES field (:mod:`scdk_sym.kernels.functions`), the curve follower's
kernels (:mod:`scdk_sym.follower.calls`) and the generated C (tracker, solves and the atlas
sweep) are built from them.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import Any

import casadi as ca

#: An SX or MX expression (the kernels of a :func:`compact` model are MX Functions).
Expr = Any

#: Largest system (rows) that kernels built for C (:attr:`Solves.loops`) solve by CasADi's
#: symbolic QR factorisation, written out as straight-line code: about ``n^3`` operations,
#: 5,300 lines of C for a dense 13 x 13 and 64,000 for a 31 x 31, whose compile time grows
#: faster than their length (tens of seconds for the 31 x 31 alone at -O1); a larger one is a
#: call of :func:`loop_solver`, a few hundred lines of C whatever the size, which runs within
#: a quarter of the written-out solve's time from 13 x 13 on and faster from 25 x 25.
WRITTEN_SOLVE_MAX = 12


@dataclass(frozen=True)
class Solves:
    """How a kernel solves its linear systems (the same solutions, to rounding).

    The default writes CasADi's symbolic solve out at each use (the SX kernels that CasADi's
    virtual machine evaluates).

    Attributes:
        calls: systems of at most :data:`WRITTEN_SOLVE_MAX` rows (all of them without
            ``loops``) by calls of :func:`linear_solver`: one copy of the symbolic solve per
            generated source instead of one per use.
        loops: larger systems by calls of :func:`loop_solver` (kernels built to be compiled:
            compact C, compiled in a fraction of the time).
    """

    calls: bool = False
    loops: bool = False

    def written(self, n: int) -> bool:
        """Whether a system of ``n`` rows is solved by CasADi's symbolic QR (written out or
        by calls of :func:`linear_solver`), not in loops."""
        return not self.loops or n <= WRITTEN_SOLVE_MAX

    def solve(self, A: Expr, B: Expr) -> Expr:
        """``A^{-1} B`` for a square ``A`` (n x n) and ``B`` (n x r), SX or MX (an MX system
        of at most :data:`WRITTEN_SOLVE_MAX` rows: by calls of :func:`linear_solver`, the
        symbolic solve)."""
        if not self.written(A.size1()):
            return loop_solver(A.sparsity(), B.size2())(A, B)
        if not self.calls and not isinstance(A, ca.MX):
            return ca.solve(A, B)
        solver = linear_solver(A.sparsity())
        return ca.horzcat(*[solver(A, B[:, j]) for j in range(B.size2())])


#: Solves written out at each use.
WRITTEN = Solves()


def compact(sym, loops: bool) -> bool:
    """Whether a model's kernels built to be compiled (``loops``) from calls of its closure
    Function are MX Functions of those calls: those of a model whose bordered system (``m + 1``
    rows) is larger than :data:`WRITTEN_SOLVE_MAX`. Their generated C moves vectors by loops
    (``casadi_copy``, element-wise loops), where an SX Function copies every element of every
    argument and result of each call in a line of its own: most of the C of a large model's
    kernels."""
    return loops and sym.m + 1 > WRITTEN_SOLVE_MAX


def model_inputs(sym, mx: bool) -> tuple[Expr, Expr, Expr]:
    """``(y, theta, c)``: the model's own SX symbols, or MX symbols of the same sizes."""
    if not mx:
        return sym.y, sym.theta, sym.c
    return ca.MX.sym("y", sym.m), ca.MX.sym("theta", sym.k), ca.MX.sym("c", sym.c.numel())


def bordered_tangent(
    Jp: Expr,
    Js: Expr,
    dtheta: Expr,
    v: Expr,
    rhs: Expr | None = None,
    solves: Solves = WRITTEN,
) -> tuple[Expr, Expr, Expr, Expr | None]:
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
        solves: how the bordered system is solved (:class:`Solves`).

    Returns:
        ``(t, t_hat, w, d)``: the unit tangent in ``(y, s)`` (metric ``|dy|^2 + (|dtheta| ds)^2``)
        [(m+1,)]; the balanced solution before normalisation (its last entry vanishes exactly
        where ``det J_p`` does) [(m+1,)]; ``w = |dtheta|``; ``d`` in ``(y, s)`` (None without
        ``rhs``).
    """
    m = Jp.size1()
    A, w = bordered_matrix(Jp, Js, dtheta, v)
    e = ca.DM.zeros(m + 1)
    e[m] = 1.0
    d = None
    if rhs is None:
        t_hat = solves.solve(A, e)
    else:
        sol = solves.solve(A, ca.horzcat(e, ca.vertcat(rhs, 0)))
        t_hat = sol[:, 0]
        d = ca.vertcat(sol[:m, 1], sol[m, 1] / w)
    t = ca.vertcat(t_hat[:m], t_hat[m] / w) / ca.norm_2(t_hat)
    return t, t_hat, w, d


def bordered_matrix(Jp: Expr, Js: Expr, dtheta: Expr, v: Expr) -> tuple[Expr, Expr]:
    """The matrix ``[J_p, -J_s dtheta / w; v_y^T, w v_s]`` of :func:`bordered_tangent`'s solve
    (in the balanced variables ``(y, w s)``) and ``w = |dtheta|``."""
    m = Jp.size1()
    w = ca.sqrt(ca.dot(dtheta, dtheta) + 1e-300)
    js_hat = Js @ (dtheta / w)
    return ca.vertcat(ca.horzcat(Jp, -js_hat), ca.horzcat(v[:m].T, w * v[m])), w


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


#: :func:`loop_solver` Functions by sparsity pattern and columns (one per process: a source
#: that calls one several times holds one copy of it).
_LOOP_SOLVERS: dict[tuple, ca.Function] = {}


def loop_solver(sparsity: ca.Sparsity, columns: int = 1) -> ca.Function:
    """The linear solve with a matrix of a given sparsity by CasADi's sparse QR factorisation
    in loops (its ``"qr"`` linear solver), as one Function whose calls stay calls.

    Its generated C is a few hundred lines whatever the matrix (the factorisation's loops over
    the pattern's precomputed fill-in), where the symbolic solve is straight-line code of
    about ``n^3`` operations; from 13 x 13 on it runs as fast. A singular matrix gives what
    the symbolic solve gives (divisions by zero), in C and in CasADi's virtual machine alike
    (no rank test: ``eps`` 0).

    Args:
        sparsity: the (square) matrix's sparsity.
        columns: columns of the right-hand side (solved with one factorisation).

    Returns:
        (A, B[n, columns]) -> ``A^{-1} B``.
    """
    n = sparsity.size1()
    key = (n, columns, tuple(sparsity.colind()), tuple(sparsity.row()))
    if key not in _LOOP_SOLVERS:
        A, B = ca.MX.sym("A", sparsity), ca.MX.sym("B", n, columns)
        # named by the pattern: the generated C does not depend on what was built before
        tag = hashlib.sha256(repr(key).encode()).hexdigest()[:8]
        x = ca.solve(A, B, "qr", {"eps": 0.0})
        _LOOP_SOLVERS[key] = ca.Function(f"scdk_qr{n}_{tag}", [A, B], [x], function_options(False))
    return _LOOP_SOLVERS[key]


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


def newton_correction(
    sym, inline: bool = True, closure: ca.Function | None = None, loops: bool = False
) -> ca.Function:
    """The Newton correction at fixed ``theta`` (``y - correction`` is one Newton step).

    Args:
        sym: the model's symbolic system (``model.symbolic``).
        inline: False to keep calls of it as calls in the expressions built from it
            (compact generated C).
        closure: with ``inline`` False, the :func:`closure_function` it calls (default: a
            new one; pass one shared by several kernels for one copy in generated C).
        loops: True to solve a system larger than :data:`WRITTEN_SOLVE_MAX` by a call of
            :func:`loop_solver` (kernels built to be compiled); else written out.

    Returns:
        (y[m], theta[k], c) -> ``J_p^{-1} g`` [model length unit, rad].
    """
    y, theta, c = model_inputs(sym, not inline and compact(sym, loops))
    if inline:
        g, Jp = sym.g, sym.J_p
    else:
        g, Jp, _ = (closure or closure_function(sym))(y, theta, c)
    # the solve is written out here (one copy, as this Function's calls stay calls): a call of
    # linear_solver on this hot path costs a few percent of a tracking step
    step = Solves(loops=loops).solve(Jp, g)
    return ca.Function("scdk_newton1", [y, theta, c], [step], function_options(inline))


def rk4_in_s(
    sym,
    y0: Expr,
    s0,
    s1,
    theta1: Expr,
    dtheta: Expr,
    steps: int,
    closure: ca.Function | None = None,
    loops: bool = False,
    c=None,
):
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
        closure: the :func:`closure_function` that ``dy/ds`` calls, one Function whose calls
            stay calls (compact generated C); default: ``dy/ds`` written out at each use.
        loops: True to solve ``dy/ds`` by a call of :func:`loop_solver` when ``J_p`` is larger
            than :data:`WRITTEN_SOLVE_MAX` (kernels built to be compiled); else written out.
            With ``closure``, on a :func:`compact` model ``dy/ds`` is an MX Function (then
            ``y0``, ``theta1``, ``dtheta`` and ``c`` are MX).
        c: the chart (default: the model's symbol).

    Returns:
        (m,) the unknowns at ``s1``.
    """
    mx = closure is not None and compact(sym, loops)
    X: Any = ca.MX if mx else ca.SX
    s, a, d = X.sym("s"), X.sym("theta1", sym.k), X.sym("dtheta", sym.k)
    y, _, cf = model_inputs(sym, mx)
    if closure is None:
        Jp, Js = ca.substitute([sym.J_p, sym.J_s], [sym.theta], [a + s * d])
    else:
        _, Jp, Js = closure(y, a + s * d, cf)
    dyds_ = Solves(loops=loops).solve(Jp, Js @ d)
    f = ca.Function("scdk_dyds", [y, s, a, d, cf], [dyds_], function_options(closure is None))
    c = sym.c if c is None else c

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
