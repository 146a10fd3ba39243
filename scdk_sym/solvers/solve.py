"""The singularity-consistent (SC) direct-kinematics solve: the public entry, dispatch only.

Direct kinematics as path tracking (Bhattacharya, Nenchev & Uchiyama): from an assembled
start ``(y1, theta1)``, follow the solution curve of ``g(y, theta1 + s (theta0 - theta1)) = 0``
in ``q = (y, s)`` along the SC field until ``s = 1``. The field is integrated with CasADi's
CVODES in chunks of arc length; every crossing of the singular manifold (``det J_p`` changes
sign, ``s`` turns) is located by Newton on ``[g; t_s] = 0``; each ``s = 1`` crossing is finished
with ``dy/ds = J_p^{-1} j_s`` and a Newton polish, then verified.

:func:`solve` checks the query (:mod:`~scdk_sym.solvers.query`) and hands it to one of: the
blocks of the model (:mod:`~scdk_sym.solvers.blockwise`), the generated C follower
(:mod:`~scdk_sym.solvers.solve_c`, whose refusals it solves with the compiled kernels), the
path of an explicit ``b`` (:mod:`~scdk_sym.solvers.line`), the convergent branch
(:mod:`~scdk_sym.solvers.convergent`) or the divergent one
(:mod:`~scdk_sym.solvers.divergent`).
"""

from __future__ import annotations

from dataclasses import replace

from numpy.typing import ArrayLike

from ..backends import Resolved, resolve
from ..errors import SolveError
from ..results import Configuration, SolveResult
from ..robot import Model
from .background import without_waiting
from .blockwise import solve_blocks
from .convergent import convergent, fast_convergent
from .divergent import divergent
from .line import along_line
from .query import (
    Query,
    at_start,
    check_options,
    same_theta,
    singular_start,
    target,
    validate_start,
)
from .result import solve_result
from .solve_c import HandOver, solve_c


def solve(
    model: Model,
    theta0: ArrayLike,
    start: Configuration | None = None,
    branch: str = "convergent",
    b: float | None = None,
    *,
    backend: str = "cvodes",
    max_arc: float | None = None,
    record_path: bool = True,
    fast: bool = True,
) -> SolveResult:
    """Solve the direct kinematics at ``theta0`` by the singularity-consistent method.

    Args:
        model: the model.
        theta0: (k,) actuated joint values [rad or model length unit].
        start: assembled start configuration (default: ``model.home``).
        branch: "convergent" (``b det J_p > 0`` at the start: the solution reached without
            leaving the start's side of the singular surface, along the paper's straight path)
            or "divergent" (the solution across the nearest singular surface: the nearest
            singular configuration on the assembled manifold is located, crossed, and the
            path converges from the other side to ``theta0``; see
            :mod:`scdk_sym.follower.singular`).
        b: the paper's signed scalar; when given, its sign selects the direction of ``nu``
            on the paper's straight path ``theta1 + s (theta0 - theta1)`` and overrides
            ``branch`` (the literal algorithm).
        backend: a name of :mod:`scdk_sym.backends` that solve offers
            (``backends.offered("solve")``): "cvodes" (default), "compiled", "c" (the
            convergent solve, and the divergent one along the paper's divergent path, in one
            call of the generated C follower, :mod:`scdk_sym.solvers.solve_c`) or "auto".
        max_arc: arc-length budget of the path (see :func:`~scdk_sym.solvers.trace.trace`).
        record_path: keep the sampled curve in ``result.path`` (for plots).
        fast: for a convergent solve without ``record_path``, first try one call of the warm
            kernel (an RK4 step in s with a Newton polish); it is accepted only if the polish
            moved the prediction by less than 1e-7 (relative) and ``det J_p`` kept its sign,
            else the full CVODES path is integrated.

    Returns:
        A verified :class:`SolveResult`; ``result.crossings`` lists the singular points met on
        the way (each with ``kind`` "fold" or "bifurcation"); ``result.status`` is
        "converged", or "singular" when the solution itself is singular (``theta0`` on the
        singular surface: ``J_p`` singular to 1e-6 relative).

    Raises:
        InputError: bad shapes, NaN, unknown branch, a backend solve does not offer.
        SolveError: the start is singular and no ``b`` was given (the branch is undefined).
        PathError: no solution was reached (the message says what was tried; every real
            solution at ``theta0`` is listed by :func:`scdk_sym.assembly_modes`).
        VerificationError: the final configuration failed its residual check.
    """
    name = without_waiting(
        model,
        resolve(backend, "solve"),
        lambda built: _warm(model, built),
    )
    res = _solve(model, theta0, start, branch, b, name, max_arc, record_path, fast)
    return res if res.backend else replace(res, backend=name)


def _warm(model: Model, backend: Resolved) -> None:
    """One solve at home with ``backend`` each way it can run (the C follower's one call,
    and the compiled follower it hands a recorded path to): what builds its products."""
    solve(model, model.home.theta, model.home, backend=backend, record_path=False)
    solve(model, model.home.theta, model.home, backend=backend)


def _solve(
    model: Model,
    theta0: ArrayLike,
    start: Configuration | None,
    branch: str,
    b: float | None,
    backend: str,
    max_arc: float | None,
    record_path: bool,
    fast: bool,
) -> SolveResult:
    """:func:`solve` (its arguments in order); the result's backend is set by the caller."""
    subs = model.blocks
    if len(subs) > 1:  # independent blocks (the legs of a biped): one solve each
        theta0 = target(model, theta0)
        options = dict(branch=branch, b=b, backend=backend, max_arc=max_arc)
        options.update(record_path=False, fast=fast)
        return solve_blocks(model, subs, theta0, validate_start(model, start), solve, **options)
    if backend == "c":  # one call of the generated C follower (scdk_sym.solvers.solve_c)
        out = solve_c(model, theta0, start, branch, b, backend, max_arc=max_arc,
                      record_path=record_path)  # fmt: skip
        if isinstance(out, HandOver):  # solved by the compiled follower, not chosen again
            handed = solve(model, out.theta0, out.start, branch, b, max_arc=max_arc,
                           record_path=record_path, backend=Resolved("compiled", "c"))  # fmt: skip
            return replace(handed, fallback=f"backend 'c' handed over to 'compiled': {out.why}")
        return out
    theta0 = target(model, theta0)
    check_options(branch, b, max_arc)
    checked = False
    if fast and not record_path and b is None and branch == "convergent":
        start = validate_start(model, start, check_residual=False)
        res = fast_convergent(model, theta0, start, backend)
        if res is not None:
            return res
        checked = True  # the warm kernel checked the start's residual (it raises otherwise)
    start = validate_start(model, start, check_residual=not checked)
    nu, det0, Jp = at_start(model, theta0, start)
    same = same_theta(theta0, start.theta)
    query = Query(model, theta0, start, backend, max_arc, record_path)
    if b is not None:
        if same:
            return solve_result(model, start.y, theta0, (), "convergent", 1.0, start, None)
        direction = 1.0 if b > 0 else -1.0
        name = "convergent" if direction * det0 > 0 else "divergent"
        return along_line(query, 1.0 if det0 > 0 else -1.0, direction, name, nu)
    if singular_start(model, start, Jp):
        raise SolveError(
            f"the start configuration is singular (J_p singular, det {det0:.3g}): the branch "
            "is undefined; pass b=+1 or b=-1, or start from a nearby non-singular configuration"
        )
    sign = 1.0 if det0 > 0 else -1.0
    if branch == "convergent":
        if same:
            return solve_result(model, start.y, theta0, (), "convergent", sign, start, None)
        return convergent(query, sign, nu)
    return divergent(query, sign, nu, solve)
