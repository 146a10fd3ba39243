"""The convergent answer along a bent path, where the straight one grazes a fold.

Where the line from the start meets the singular surface nearly tangentially it leaves the
start's side only briefly: the straight path turns back at the fold, while a line bent by a
little towards the start's side stays there. :func:`detour` finds the answer that way.
"""

from __future__ import annotations

import numpy as np

from ..follower.curve import follow
from ..follower.options import FollowOptions
from ..follower.walk import Line
from ..results import SolveResult
from .result import solve_result

#: Offsets of the bend of a detour, in units of |theta0 - theta1|, tried in order.
DETOUR_OFFSETS = (0.01, 0.03, 0.1, 0.3)


def detour(
    model, theta0, start, direction, fold, backend, max_arc, any_fold=False
) -> SolveResult | None:
    """The convergent answer past a fold that the straight path grazes, or None.

    Where the line from the start meets the singular surface nearly tangentially it leaves
    the start's side only briefly (e.g. on Dietmaier's 6-6 platform from starts within
    ``det J_p ~ 1e-6`` of a surface): the straight path turns back at the fold, while a line
    bent by a little towards the start's side stays there. So the path goes from the start to
    the fold's ``theta`` moved along the surface normal towards the side where the start's
    solution exists (:func:`~scdk_sym.follower.surface.inward_normal`), then to ``theta0``,
    each leg along the convergent direction; it is taken only if neither leg meets a singular
    point (the answer is on the start's side, reached continuously), at the smallest of the
    ``DETOUR_OFFSETS`` that works. ``result.path`` is None (the path is not one line).
    With ``any_fold`` (the straight path never reached ``s = 1``) the fold need not be grazed,
    only met before ``theta0``: a line cutting a small cap off the start's side (e.g. Gepetto's
    5-bar with ``theta0`` just before a singular surface) leaves it and comes back just after.
    """
    from ..follower.surface import grazes, inward_normal

    if fold.kind != "fold" or not 0.0 < fold.s <= 1.0:
        return None
    if not (any_fold or grazes(model, fold, theta0 - start.theta)):
        return None
    n = inward_normal(model, fold, backend)
    if n is None:
        return None
    span = float(np.linalg.norm(theta0 - start.theta))
    for offset in DETOUR_OFFSETS:
        cfg = start
        for target in (np.asarray(fold.theta, float) + offset * span * n, theta0):
            line = Line(np.array(cfg.theta, dtype=float), target - cfg.theta)
            options = FollowOptions(
                predictor="cvodes", backend=backend, max_hits=1, max_singular=1, max_arc=max_arc
            )
            tr = follow(model, line, cfg.y, 0.0, direction, options)
            if not tr.hits or tr.hits[0].crossings:
                cfg = None
                break
            cfg = model.configuration(tr.hits[0].y, target)
            if not cfg.residual <= model.tolerance:
                cfg = None
                break
        if cfg is not None:
            return solve_result(model, cfg.y, theta0, (), "convergent", direction, start, None)
    return None
