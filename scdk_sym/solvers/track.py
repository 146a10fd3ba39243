"""Direct kinematics along a sequence of joint readings, preserving the continuity of motion.

A controller reads the actuated joints ``theta_0, theta_1, ...`` and needs the platform pose
at each. Warm-started Newton converges to the solution nearest to the previous one; through
a direct-kinematic singularity (a fold: two solutions meet and leave) that is the mirror
solution, and the tracked pose turns back while the robot goes on. The paper's remedy: the
sign of ``b`` picks the solution reached by the motion. Near a fold both candidate solutions
lie ahead of the previous one along the singularity-consistent solution curve, the
physically continuous one often as the SECOND crossing of ``s = 1`` (``s`` overshoots, turns on
the singular manifold and comes back). So at each sample :func:`track` follows the curve from
the previous solution in both directions within a short arc-length budget, collects the
``s = 1`` crossings and keeps the one that agrees best with the motion predicted by
extrapolating the last two solutions.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..errors import InputError, PathError
from ..model.model import Model
from ..results import Configuration, Crossing, TrackResult
from .modes import curve_kernels, difference
from .sc import solve, trace, validate_start

BACKENDS = ("c", "cvodes")
#: Arc-length budget of each direction, in multiples of the predicted arc of the step.
BUDGET_FACTOR = 8.0
#: Budgets tried (each twice the previous) before settling for the best candidate met.
ATTEMPTS = 4
#: Crossings of s = 1 collected per direction.
HITS_PER_DIRECTION = 2
#: The convergent continuation is taken without tracing when it misses the predicted motion
#: by less than this fraction of the predicted step.
AGREEMENT = 0.25


def _thetas(model: Model, thetas) -> np.ndarray:
    try:
        arr = np.asarray(thetas, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"thetas must be an (N, {model.k}) array of numbers") from exc
    if arr.ndim != 2 or arr.shape[1] != model.k or arr.shape[0] < 1:
        raise InputError(
            f"thetas must have shape (N, {model.k}) (columns {', '.join(model.actuated)}), "
            f"got {arr.shape}"
        )
    bad = np.nonzero(~np.all(np.isfinite(arr), axis=1))[0]
    if bad.size:
        raise InputError(f"thetas row {int(bad[0])} is not finite: {arr[bad[0]].tolist()}")
    return arr


def track(
    model: Model,
    thetas: Sequence[Sequence[float]] | np.ndarray,
    start: Configuration | None = None,
    backend: str = "cvodes",
) -> TrackResult:
    """Direct kinematics along joint readings, following the motion through singularities.

    The first sample is solved from ``start`` on the convergent branch (the solution in the
    start's compartment). At each following one, when the convergent continuation from the
    previous solution stays in its compartment and agrees with the predicted motion, it is
    the answer; otherwise (near a singularity) the answer is the ``s = 1`` crossing, met along the
    singularity-consistent solution curve from the previous solution in either direction
    (up to two per direction, within ``BUDGET_FACTOR`` times the predicted arc length), that
    is nearest to the extrapolation of the last two solutions (readings at a steady rate).

    Args:
        model: the model.
        thetas: (N, k) actuated joint readings [rad or model length unit], in time order.
        start: assembled configuration the robot starts from (default ``model.home``).
        backend: "cvodes" (CVODES via CasADi) or "c" (the generated-C tracker).

    Returns:
        A :class:`~scdk_sym.results.TrackResult`: ``x`` (N, n), ``y`` (N, m), ``residual``
        (N,), and every singular-manifold crossing, with ``index = i`` when it occurs between
        samples ``i`` and ``i + 1``.

    Raises:
        InputError: bad shapes, non-finite readings or an unknown backend.
        NotAssembledError: ``start`` is not assembled.
        PathError: no solution was met from a sample towards the next one (the readings
            jump out of the reachable set, or too far for the budget).
    """
    if backend == "c":
        from .track_c import track_c

        return track_c(model, thetas, start)
    if backend != "cvodes":
        raise InputError(f"unknown backend {backend!r}; backends: {', '.join(BACKENDS)}")
    thetas = _thetas(model, thetas)
    start = validate_start(model, start)
    configs: list[Configuration] = []
    crossings: list[Crossing] = []
    theta_first = thetas[0]
    if np.allclose(theta_first, start.theta, rtol=0.0, atol=1e-14 * max(1.0, model.length_scale)):
        configs.append(model.configuration(start.y, theta_first))
    else:
        configs.append(solve(model, theta_first, start=start, record_path=False).configuration)
    for i in range(1, len(thetas)):
        configs.append(_next(model, configs, thetas, i, crossings))
    return TrackResult(
        x=np.array([c.x for c in configs]),
        y=np.array([c.y for c in configs]),
        theta=thetas,
        residual=np.array([c.residual for c in configs]),
        crossings=tuple(crossings),
        status="converged",
        backend="cvodes",
    )


def _next(
    model: Model,
    configs: list[Configuration],
    thetas: np.ndarray,
    i: int,
    crossings: list[Crossing],
) -> Configuration:
    prev = configs[-1]
    theta = thetas[i]
    step = theta - prev.theta
    size = float(np.linalg.norm(step))
    if size == 0.0:
        return prev
    # samples are taken at a steady rate: the motion goes on as in the last step (not scaled
    # by the joint steps, which shrink to nothing at a fold while the platform moves on)
    predicted = np.zeros(model.m)
    if len(configs) >= 2:
        predicted = difference(model, prev.y, configs[-2].y)
    # regular case: the continuation from the previous solution (an Euler step in s and
    # Newton) stays in its compartment and agrees with the predicted motion
    y_fast = _continuation(model, prev, theta)
    if y_fast is not None:
        miss = float(np.linalg.norm(difference(model, y_fast, prev.y) - predicted))
        if len(configs) < 2 or miss <= AGREEMENT * float(np.linalg.norm(predicted)):
            return model.configuration(y_fast, theta)
    expected = math.hypot(float(np.linalg.norm(predicted)), size)
    best = None
    agree = AGREEMENT * float(np.linalg.norm(predicted))
    for attempt in range(ATTEMPTS):
        # budget doubled until a candidate agrees with the predicted motion (or the last try)
        budget = BUDGET_FACTOR * expected * 2**attempt + 1e-9 * max(1.0, model.length_scale)
        candidates = []
        for direction in (1.0, -1.0):
            tr = trace(model, theta, prev, direction, max_hits=HITS_PER_DIRECTION, max_arc=budget)
            for hit in tr.hits:
                miss = float(np.linalg.norm(difference(model, hit.y, prev.y) - predicted))
                candidates.append((miss, hit.arc, hit, tr.crossings[: hit.crossings]))
        if candidates:
            best = min(candidates, key=lambda c: (c[0], c[1]))
            if best[0] <= agree or len(configs) < 2:
                break
    if best is None:
        raise PathError(
            f"sample {i}: no solution at theta={theta.tolist()} was met from sample {i - 1} "
            "along the solution curve (the readings leave the reachable set or jump too far)"
        )
    _, _, hit, met = best
    for cr in met:
        crossings.append(Crossing(cr.s, cr.x, cr.y, cr.theta, index=i - 1))
    cfg = model.configuration(hit.y, theta)
    return cfg


def _continuation(model: Model, prev: Configuration, theta: np.ndarray) -> np.ndarray | None:
    """The solution at ``theta`` continuing ``prev`` in its compartment, or None.

    An Euler step ``dy = J_p^{-1} J_s dtheta`` and Newton at ``theta``; accepted when Newton
    converged, moved the prediction by less than a tenth of the step and ``det J_p`` kept its
    sign (no singular manifold in between, as far as this cheap test can tell).
    """
    y_loc, c = model.chart.to_local(prev.y)
    Jp, Js = (np.array(a) for a in model.kernels.jac(y_loc, prev.theta, c))
    det_prev = float(np.linalg.det(Jp))
    try:
        dy = np.linalg.solve(Jp, Js @ (theta - prev.theta))
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(dy)) or np.max(np.abs(dy)) > max(1.0, model.length_scale):
        return None  # (nearly) singular: no continuation to trust
    y, res = curve_kernels(model).polish(y_loc + dy, theta, c)
    y = np.array(y).ravel()
    if not (np.all(np.isfinite(y)) and float(res) <= 0.1 * model.tolerance):
        return None
    if float(np.linalg.norm(y - y_loc - dy)) > 0.1 * float(np.linalg.norm(dy)) + 1e-12:
        return None
    det_new = float(np.linalg.det(np.array(model.kernels.jac(y, theta, c)[0])))
    if not det_new * det_prev > 0:
        return None
    return model.chart.to_canonical(y, c)
