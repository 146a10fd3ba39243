"""The convergent branch: the solution reached without leaving the start's side.

``b det J_p > 0`` at the start: along the paper's straight path in the direction where ``s``
increases, to the first crossing of ``s = 1`` (bent past a fold the path only grazes,
:mod:`scdk_sym.solvers.detour`). Before the path is integrated, :func:`fast_convergent`
tries one call of the warm kernel (an RK4 step in ``s`` and a Newton polish), accepted only
when it is conclusive.
"""

from __future__ import annotations

import numpy as np

from ..errors import NotAssembledError
from ..follower.cvodes import engine
from ..results import SolveResult
from .line import along_line
from .query import Query


def convergent(query: Query, sign: float, nu: np.ndarray | None) -> SolveResult:
    """The convergent answer along the straight path (``sign``: that of ``det J_p`` at the
    start, the direction followed; ``nu``: the unit SC vector there), bent past a grazed fold
    where that is needed (see :func:`~scdk_sym.solvers.line.along_line`)."""
    return along_line(query, sign, sign, "convergent", nu, with_detour=True)


def fast_convergent(model, theta0, start, backend) -> SolveResult | None:
    """One call of the warm kernel (RK4 in s + Newton + checks); None when not conclusive."""
    eng = engine(model, backend)
    y1, c = model.chart.to_local(start.y)
    y0, corr, res1, res0, J1, J0, T, x = eng.warm(y1, start.theta, theta0, c)
    if not res1[0] <= model.tolerance:
        raise NotAssembledError(
            f"start configuration is not assembled (residual {res1[0]:.3g} > "
            f"{model.tolerance:.1e})",
            float(res1[0]),
        )
    m = model.m
    if not (np.all(np.isfinite(y0)) and res0[0] <= model.tolerance):
        return None
    step = float(np.max(np.abs(y0 - y1)))
    if corr[0] > 1e-7 * step + 1e-13:
        return None
    det1 = np.linalg.det(J1.reshape(m, m, order="F"))
    det0 = np.linalg.det(J0.reshape(m, m, order="F"))
    if not det1 * det0 > 0:
        return None
    y = model.chart.to_canonical(y0, c)
    theta = theta0.copy()
    return SolveResult(
        x=x.copy(),
        y=y,
        theta=theta,
        platform_pose=T.reshape(4, 4, order="F").copy(),
        joints=model.joint_values(y, theta),
        residual=float(res0[0]),
        crossings=(),
        status="converged",
        branch="convergent",
        b=1.0 if det1 > 0 else -1.0,
        start=start,
        path=None,
    )
