"""The convergent direct kinematics in one call of the generated C follower.

:func:`solve_c` runs ``<prefix>_solve_convergent`` of the model's C tracker library
(:mod:`scdk_sym.codegen.library`, compiled once and cached): from the assembled start it
follows the singularity-consistent curve of the straight line ``theta1 + s (theta0 -
theta1)`` in the convergent direction (``s`` increasing, ``b det J_p > 0``) with the tracker's
follower (the RK4 predictor-corrector steps of :mod:`scdk_sym.follower.kernels`, the step
control of ``scdk_sym.follower.curve.follow(predictor="rk4")``) to its first crossing of
``s = 1``. The C call refuses a path that meets a turn of ``s`` or a sign change of
``det J_p`` before the solution (it locates no crossing) and a path without a crossing within
its arc budget; those cases, the divergent branch, an explicit ``b`` and a recorded path are
solved by :func:`scdk_sym.solvers.sc.solve` with the compiled kernels. The answer is verified
in Python (:func:`scdk_sym.solvers.sc.solve`'s own check), so nothing unverified is returned.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..errors import NotAssembledError, SolveError
from ..results import Configuration, SolveResult
from ..robot import Model, as_vector

__all__ = ["solve_c"]


def solve_c(
    model: Model,
    theta0: ArrayLike,
    start: Configuration | None = None,
    branch: str = "convergent",
    b: float | None = None,
    **kwargs,
) -> SolveResult:
    """:func:`scdk_sym.solvers.sc.solve` with the generated C follower (``backend="c"``).

    Args:
        model: the model.
        theta0: (k,) actuated joint values [rad or model length unit].
        start: assembled start configuration (default: ``model.home``).
        branch: "convergent" is solved in one C call where the C follower can; "divergent"
            (and every case the C call refuses) by ``solve(..., backend="compiled")``.
        b: the paper's signed scalar (solved by ``solve(..., backend="compiled")``).
        **kwargs: the other keywords of :func:`scdk_sym.solvers.sc.solve`; ``record_path``
            (the sampled curve) is solved by ``solve(..., backend="compiled")``.

    Returns:
        A verified :class:`~scdk_sym.results.SolveResult`, the same as ``solve``'s (equal to
        1e-9 in the tests, the same crossings).

    Raises:
        The errors of :func:`scdk_sym.solvers.sc.solve`; BuildError without a C compiler.
    """
    from ..codegen.library import (
        ERR_NO_SOLUTION,
        ERR_NOT_ASSEMBLED,
        ERR_SINGULAR_PATH,
        STATUS,
        tracker_library,
    )
    from .sc import _result, solve, validate_start

    kwargs.pop("backend", None)
    fallback = dict(kwargs, backend="compiled")
    if b is not None or branch != "convergent" or kwargs.get("record_path", False):
        return solve(model, theta0, start, branch, b, **fallback)
    th0 = as_vector(theta0, model.k, f"theta0 ({', '.join(model.actuated)})")
    start = validate_start(model, start, check_residual=False)
    lib = tracker_library(model)
    y1, c1 = model.chart.to_local(start.y)
    out = lib.solve_convergent(y1, c1, start.theta, th0)
    if out.status in (ERR_SINGULAR_PATH, ERR_NO_SOLUTION):
        return solve(model, th0, start, branch, b, **fallback)
    if out.status == ERR_NOT_ASSEMBLED:
        residual = model.residual(start.y, start.theta)
        raise NotAssembledError(
            f"start configuration is not assembled (residual {residual:.3g} > "
            f"{model.tolerance:.1e}); start from a solution, e.g. model.inverse_kinematics(x)",
            residual,
        )
    if out.status < 0:
        raise SolveError(
            f"C solve at theta0={th0.tolist()} failed: {STATUS.get(out.status, out.status)} "
            f"(status {out.status}); try backend='compiled'"
        )
    y = model.chart.to_canonical(out.y, out.c)
    return _result(model, y, th0, (), "convergent", float(np.sign(out.det)), start, None)
