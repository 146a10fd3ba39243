"""The direct kinematics in one call of the generated C follower (``backend="c"``).

:func:`solve_c` runs ``<prefix>_solve_convergent`` or ``<prefix>_solve_divergent`` of the
model's C tracker library (:mod:`scdk_sym.codegen.library`, compiled once and cached). From the
assembled start both follow the singularity-consistent curve of the straight line
``theta1 + s (theta0 - theta1)`` with the tracker's follower (the RK4 predictor-corrector steps
of :mod:`scdk_sym.follower.calls`, the step control of
``scdk_sym.follower.curve.follow(predictor="rk4")``):

- the convergent solve in the convergent direction (``s`` increasing, ``b det J_p > 0``) to
  its first crossing of ``s = 1``; it refuses a path that meets a turn of ``s`` or a sign
  change of ``det J_p`` before the solution (it locates no crossing);
- the divergent solve where it is the first way (``"paper"``) of
  :func:`scdk_sym.solvers.divergent.divergent`, the paper's divergent path: in the direction
  where ``s`` decreases, through exactly one fold (located, reported as the answer's one
  crossing) back through ``s = 0`` on the other sheet, then to the first crossing of
  ``s = 1`` without another singular point; it refuses every other walk (a bifurcation, a
  second fold, ``s = -1`` first, ...).

Both refuse a path without an answer within their arc budgets. Those cases, an explicit ``b``,
a recorded path and an explicit ``max_arc`` are handed over (a :class:`HandOver` saying why):
the caller, :func:`scdk_sym.solvers.solve.solve`, solves them with the compiled kernels, as it
does a divergent answer that is singular or fails its checks. Every answer is verified
(:func:`scdk_sym.solvers.result.solve_result`'s residual check, by the library's own generated
pose, closure and Jacobian kernels at the answer in the chart centred on it, and the parity of
``det J_p`` after the crossings of :func:`scdk_sym.follower.finish.parity_checked`), so
nothing unverified is returned.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike

from ..codegen.library import (
    ERR_NO_SOLUTION,
    ERR_NOT_ASSEMBLED,
    ERR_SINGULAR_PATH,
    STATUS,
    BoundSolve,
    SolveOutput,
    tracker_library,
)
from ..errors import NotAssembledError, PathError, SolveError, VerificationError
from ..follower.finish import clearly_regular, jacobian, singular_jp
from ..products import BOUND_C_SOLVES
from ..results import Configuration, Crossing, SolveResult
from ..robot import Model
from .query import target, validate_start
from .result import Checks, solve_result

__all__ = ["HandOver", "bound_solve", "convergent_answer", "solve_c"]


@dataclass(frozen=True)
class HandOver:
    """A query the C follower does not answer, handed over to the compiled follower.

    Attributes:
        theta0: the query's actuated values, as the compiled solve is to receive them.
        start: its start (the checked one once :func:`solve_c` has checked it).
        why: what the C follower refused (the end of the answer's ``fallback``).
    """

    theta0: ArrayLike
    start: Configuration | None
    why: str


def solve_c(
    model: Model,
    theta0: ArrayLike,
    start: Configuration | None = None,
    branch: str = "convergent",
    b: float | None = None,
    backend: str = "c",
    **kwargs,
) -> SolveResult | HandOver:
    """:func:`scdk_sym.solvers.solve.solve` with the generated C follower (``backend="c"``).

    Args:
        model: the model.
        theta0: (k,) actuated joint values [rad or model length unit].
        start: assembled start configuration (default: ``model.home``).
        branch: "convergent" or "divergent", each solved in one C call where the C follower
            can (see the module documentation), else handed over.
        b: the paper's signed scalar (handed over).
        backend: the name the answer carries (the resolved ``"c"`` of the call).
        **kwargs: the other keywords of :func:`scdk_sym.solvers.solve.solve`; ``record_path``
            (the sampled curve) and ``max_arc`` are handed over.

    Returns:
        A verified :class:`~scdk_sym.results.SolveResult`, the same as the compiled solve's
        (equal to 1e-9 in the tests, the same crossings), or the :class:`HandOver` of a query
        for ``solve(..., backend="compiled")``.

    Raises:
        The errors of :func:`scdk_sym.solvers.solve.solve`; BuildError without a C compiler.
    """
    if b is not None:
        return HandOver(theta0, start, "b is solved by the compiled follower")
    if branch not in ("convergent", "divergent"):
        return HandOver(theta0, start, f"branch {branch!r}")
    if kwargs.get("record_path", False):
        return HandOver(theta0, start, "record_path=True (the C follower keeps no sampled curve)")
    if kwargs.get("max_arc") is not None:
        return HandOver(theta0, start, "max_arc is applied by the compiled follower")
    th0 = target(model, theta0)
    start, call = bound_solve(model, start, branch)
    out = call(th0)
    if out.status in (ERR_SINGULAR_PATH, ERR_NO_SOLUTION):
        return HandOver(th0, start, f"the C follower returned {STATUS.get(out.status, out.status)}")
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
    if branch == "convergent":
        return convergent_answer(model, out, th0, start, backend)
    y = model.chart.to_canonical(out.y, out.c)
    res = _divergent_result(model, th0, start, y, out, backend, _c_checks(out))
    if res is None:
        return HandOver(th0, start, "its divergent answer is singular or failed its checks")
    return res


def bound_solve(
    model: Model, start: Configuration | None, branch: str
) -> tuple[Configuration, BoundSolve]:
    """The start (default home, its shapes checked) and the model's C solve of ``branch``
    bound to it (:meth:`~scdk_sym.codegen.library.CTracker.bound_solve`): bound once per start,
    so that repeated solves from one start check and convert it once."""
    held: dict[str, tuple[Configuration, BoundSolve]]
    held = model.products.get(BOUND_C_SOLVES, dict)
    if start is None:
        start = model.home
    got = held.get(branch)
    if got is not None and got[0] is start:
        return got
    start = validate_start(model, start, check_residual=False)
    y1, c1 = model.chart.to_local(start.y)
    call = tracker_library(model).bound_solve(y1, c1, start.theta, branch == "divergent")
    held[branch] = (start, call)
    return start, call


def convergent_answer(model: Model, out: SolveOutput, theta0: np.ndarray, start: Configuration,
                      backend: str = "c") -> SolveResult:  # fmt: skip
    """The verified answer of a call of ``<prefix>_solve_convergent`` that solved ``theta0``
    ((k,) checked) from ``start`` (``out``: its output, status >= 0).

    Raises:
        VerificationError: the answer does not close to the model's tolerance.
    """
    y = model.chart.to_canonical(out.y, out.c)
    sign = float(np.sign(out.det))
    return solve_result(model, y, theta0, (), "convergent", sign, start, None, backend,
                        _c_checks(out))  # fmt: skip


def _c_checks(out: SolveOutput) -> Checks:
    """The :data:`~scdk_sym.solvers.result.Checks` of an answer of the C follower, from its
    own output (``out``: the residual, pose and ``J_p`` of the library's generated kernels at
    the answer, in the follower's chart); ``J_p``'s singular values decide where its
    determinant bound does not."""

    def checks(model: Model, y_loc: np.ndarray, theta: np.ndarray, c: np.ndarray):
        assert out.checks is not None
        T = out.checks[:16].reshape(4, 4, order="F").copy(order="C")
        regular = clearly_regular(float(out.checks[16]), float(out.checks[17]), model.m)
        singular = not regular and singular_jp(jacobian(model, y_loc, theta, c))
        return T, out.x, out.residual, singular

    return checks


def _divergent_result(model: Model, theta0: np.ndarray, start: Configuration, y: np.ndarray,
                      out, backend: str, checks: Checks) -> SolveResult | None:  # fmt: skip
    """The verified answer of ``<prefix>_solve_divergent`` (its output ``out``, the answer's
    canonical ``y``), with the fold crossed as its one crossing, as the first way (``"paper"``) of
    :func:`scdk_sym.solvers.divergent.divergent` reports it; None where the answer is singular or
    fails its residual or parity check (the compiled solve decides those)."""
    from ..follower.finish import parity_checked
    from ..follower.surface import det_sign

    sign0 = det_sign(model, start)
    theta_f = start.theta + out.fold_s * (theta0 - start.theta)
    y_f = model.chart.to_canonical(out.fold_y, out.fold_c)
    fold = Crossing(out.fold_s, out.fold_x, y_f, theta_f, kind="fold")
    try:
        res = solve_result(model, y, theta0, (fold,), "divergent", -sign0, start, None, backend,
                           checks)  # fmt: skip
        if res.status == "singular":
            return None
        return replace(parity_checked(model, res, sign0), strategy="paper")
    except (VerificationError, PathError):
        return None
