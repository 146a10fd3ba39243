"""The singularity-consistent (SC) solution curve of the straight path, followed from a start.

Direct kinematics as path tracking (Bhattacharya, Nenchev & Uchiyama): from an assembled
start ``(y1, theta1)``, follow the solution curve of ``g(y, theta1 + s (theta0 - theta1)) = 0``
in ``q = (y, s)`` along the SC field. :func:`trace` reports every ``s = 1`` crossing it meets
(the solve takes the first, the tracker judges several) and every singular point on the way.
"""

from __future__ import annotations

import numpy as np

from ..follower.curve import follow
from ..follower.options import FollowOptions
from ..follower.walk import Line, Walk
from ..results import Configuration
from ..robot import Model


def trace(
    model: Model,
    theta0: np.ndarray,
    start: Configuration,
    direction: float,
    *,
    max_hits: int = 1,
    max_arc: float | None = None,
    backend: str = "cvodes",
    record_path: bool = False,
    predictor: str = "cvodes",
    tangent: np.ndarray | None = None,
) -> Walk:
    """Follow the SC solution curve from ``start`` towards ``theta0`` and collect what it meets.

    The curve follower (:func:`scdk_sym.follower.curve.follow`) on the line from
    ``start.theta`` to ``theta0``, with CVODES integrating the SC ODE (``predictor="cvodes"``).

    Args:
        model: the model.
        theta0: (k,) target actuated values (must differ from ``start.theta``).
        start: assembled start configuration.
        direction: +1 to follow ``nu``, -1 to follow ``-nu`` (the sign of the paper's b).
        max_hits: stop after this many ``s = 1`` crossings.
        max_arc: arc-length budget (default: 60 times the linear prediction of the distance
            to ``s = 1`` plus 20 model sizes).
        backend: kernel backend.
        record_path: keep the sampled curve.
        predictor: "cvodes" or "rk4" (see :mod:`scdk_sym.follower.curve`).
        tangent: (m+1,) the first tangent's orientation when already known (``direction``
            times the unit ``nu`` at the start, e.g. from
            :func:`~scdk_sym.solvers.query.at_start`).

    Returns:
        The :class:`~scdk_sym.follower.walk.Walk`: ``hits`` (``s = 1`` crossings),
        ``singular`` (folds and bifurcations), ``stalled``, ``closed``, ``s_range``, ``path``.
    """
    theta1 = np.array(start.theta, dtype=float)
    line = Line(theta1, np.asarray(theta0, float) - theta1)
    options = FollowOptions(
        predictor=predictor, backend=backend, max_hits=max_hits, max_arc=max_arc, record=record_path
    )
    return follow(model, line, start.y, 0.0, direction, options, tangent=tangent)
