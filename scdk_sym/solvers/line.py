"""The first answer along the paper's straight path ``theta1 + s (theta0 - theta1)``.

:func:`along_line` follows the SC curve (:func:`~scdk_sym.solvers.trace.trace`) in one
direction to its first ``s = 1`` crossing (or the singular solution where it only touches
``s = 1``), with CVODES first and the explicit predictor-corrector where CVODES stalls or
lands on another sheet, and checks the answer's side against the crossings met. The
convergent branch, the divergent one's ``"straight"`` way and an explicit ``b`` all end here.
"""

from __future__ import annotations

import numpy as np

from ..errors import PathError
from ..follower.finish import parity_checked, touching
from ..follower.walk import Line, Walk
from ..results import SolveResult
from .detour import detour
from .query import Query
from .result import solve_result
from .trace import trace


def along_line(
    query: Query,
    sign0: float,
    direction: float,
    name: str,
    nu: np.ndarray | None = None,
    with_detour: bool = False,
) -> SolveResult:
    """The first ``s = 1`` crossing along the straight path in one direction (or the singular
    solution where the curve only touches ``s = 1``).

    With ``with_detour`` (the convergent branch): where the path leaves the start's side at a
    fold before ``theta0`` that it grazes, or leaves it and never reaches ``s = 1``, the
    solution reached on the start's side along a bent path (see
    :func:`~scdk_sym.solvers.detour.detour`) is returned when there is one.

    Args:
        query: the checked query (model, ``theta0``, start, backend, arc budget, recording).
        sign0: the sign of ``det J_p`` at the start.
        direction: +1 to follow ``nu``, -1 to follow ``-nu``.
        name: the branch the answer is reported on ("convergent" or "divergent").
        nu: the unit SC vector at the start (:func:`~scdk_sym.solvers.query.at_start`),
            when known.
        with_detour: try the bent path as stated above.

    Raises:
        PathError: the curve did not reach ``s = 1`` (the message says why), or the answer's
            side does not match the crossings met.
    """
    model, theta0, start = query.model, query.theta0, query.start
    backend, max_arc, record_path = query.backend, query.max_arc, query.record_path
    tangent = first_tangent(theta0, start, direction, nu)

    def walk(predictor: str) -> Walk:
        return trace(model, theta0, start, direction, max_arc=max_arc, backend=backend,
                     record_path=record_path, predictor=predictor, tangent=tangent)  # fmt: skip

    def first_hit(tr: Walk) -> SolveResult:
        hit = tr.hits[0]
        crossings = tuple(tr.singular[: hit.crossings])
        res = solve_result(model, hit.y, theta0, crossings, name, direction, start, tr.path)
        return parity_checked(model, res, sign0)

    tr = walk("cvodes")
    explicit = not tr.hits and tr.stalled
    if explicit:  # CVODES stalled: the explicit predictor-corrector
        tr = walk("rk4")
    if with_detour and tr.singular and (not tr.hits or tr.hits[0].crossings):
        res = detour(model, theta0, start, direction, tr.singular[0], backend, max_arc,
                     any_fold=not tr.hits)  # fmt: skip
        if res is not None:
            return res
    if tr.hits:
        try:
            return first_hit(tr)
        except PathError:
            if explicit:
                raise
            # the CVODES walk's answer is on another sheet (it crossed between two close
            # sheets without a sign change in its samples): the explicit
            # predictor-corrector's, if its parity holds (else the first answer's error)
            again = walk("rk4")
            if not again.hits:
                raise
        return first_hit(again)
    touch = touching(model, theta0, tr, sign0)
    if touch is not None:
        y, n = touch
        crossings = tuple(tr.singular[:n])
        res = solve_result(model, y, theta0, crossings, name, direction, start, tr.path)
        return parity_checked(model, res, sign0)
    if tr.stalled:
        why = "the curve could not be followed further"
    elif tr.closed:
        why = "the curve closed on itself"
    else:
        why = f"not within arc length {tr.arc:.3g}"
    raise PathError(
        f"{name} branch: the solution curve from the start did not reach s = 1 (theta0="
        f"{theta0.tolist()}): {why}; s stayed in [{tr.s_range[0]:.3g}, {tr.s_range[1]:.3g}]; "
        "every real solution: sc.assembly_modes(model, theta0)"
    )


def first_tangent(theta0, start, direction, nu) -> np.ndarray | None:
    """``direction * nu``: the orientation the follower computes at the start of the line from
    ``start`` to ``theta0``, where ``nu`` was evaluated at the same point (the line's
    ``theta(0)`` equal to ``start.theta`` bit for bit), else None."""
    if nu is None:
        return None
    theta1 = np.array(start.theta, dtype=float)
    line = Line(theta1, np.asarray(theta0, float) - theta1)
    if line.at(0.0).tobytes() != theta1.tobytes():
        return None
    return direction * nu
