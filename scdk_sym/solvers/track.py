"""Direct kinematics along a sequence of joint readings, preserving the continuity of motion.

A controller reads the actuated joints ``theta_0, theta_1, ...`` and needs the platform pose
at each. Warm-started Newton converges to the solution nearest to the previous one; through
a direct-kinematic singularity (a fold: two solutions meet and leave) that is the mirror
solution, and the tracked pose turns back while the robot goes on. The paper's remedy: the
sign of ``b`` picks the solution reached by the motion. Near a fold both candidate solutions
lie ahead of the previous one along the singularity-consistent solution curve, the
physically continuous one often as the SECOND crossing of ``s = 1`` (``s`` overshoots, turns on
the singular manifold and comes back).

So :func:`track`, at each reading, predicts the motion by extrapolating the last two
solutions (readings at a steady rate) and

1. takes the continuation of the previous solution (an Euler step in ``s`` and Newton) when
   it stays in the same compartment (``det J_p`` keeps its sign) and agrees with the
   prediction: the regular case, one Newton solve;
2. otherwise follows the SC solution curve from the previous solution in both directions
   with CVODES (:func:`~scdk_sym.solvers.sc.trace`) within an arc-length budget (doubled
   until a crossing agrees with the prediction), collects up to two ``s = 1`` crossings per
   direction and keeps the verified one nearest to the prediction;
3. when nothing agrees (a reading on, or within rounding of, the singular manifold, where
   the two solutions nearly coincide and the curve only grazes ``s = 1``), searches again
   with the small-step predictor-corrector of :mod:`~scdk_sym.solvers.modes`, which refines
   turning points of ``s``, and with Newton from the prediction.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..errors import InputError, PathError
from ..model.model import Model
from ..results import Configuration, Crossing, TrackResult
from .modes import curve_kernels, difference, follow_curve
from .sc import engine, solve, trace, validate_start

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
        samples ``i`` and ``i + 1`` (``det J_p`` changes sign between them; a solution curve
        that crosses the manifold and comes back between two readings does not count).

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
    recent = configs[-3:][::-1]
    steps = [difference(model, a.y, b.y) for a, b in zip(recent[:-1], recent[1:], strict=True)]
    predicted = steps[0] if steps else np.zeros(model.m)
    # accuracy of that extrapolation: the last second difference of the motion
    accuracy = float(np.linalg.norm(steps[0] - steps[1])) if len(steps) == 2 else 0.0
    # regular case: the continuation from the previous solution (an Euler step in s and
    # Newton) stays in its compartment and agrees with the predicted motion
    fast = _continuation(model, prev, theta)
    if fast is not None:
        miss = float(np.linalg.norm(difference(model, fast.y, prev.y) - predicted))
        if len(configs) < 2 or miss <= AGREEMENT * float(np.linalg.norm(predicted)):
            return fast
    expected = math.hypot(float(np.linalg.norm(predicted)), size)
    judge = _Judge(model, prev, theta, predicted if len(configs) >= 2 else None, accuracy)
    best = None
    for attempt in range(ATTEMPTS):
        # budget doubled until a candidate agrees with the predicted motion (or the last try)
        budget = BUDGET_FACTOR * expected * 2**attempt + 1e-9 * max(1.0, model.length_scale)
        candidates = []
        for direction in (1.0, -1.0):
            try:
                tr = trace(model, theta, prev, direction, max_hits=HITS_PER_DIRECTION,
                           max_arc=budget)  # fmt: skip
            except PathError:
                continue  # the integration failed on this side: the refined search may not
            for hit in tr.hits:
                judge.add(candidates, hit.y, hit.arc, tr.crossings[: hit.crossings])
        best = judge.best(candidates)
        if best is not None and (best[0] <= judge.agree or judge.predicted is None):
            break
    if best is None or (judge.predicted is not None and best[0] > judge.agree):
        # nothing agrees with the motion: search again with small steps (a start or a
        # reading next to the singular manifold)
        best = judge.best([*candidates, *_refined(model, prev, theta, expected, judge)])
    if best is None:
        raise PathError(
            f"sample {i}: no solution at theta={theta.tolist()} was met from sample {i - 1} "
            "along the solution curve (the readings leave the reachable set or jump too far)"
        )
    *_, cfg, met = best
    change = _det(model, cfg) * _det(model, prev)
    if change > 0 and len(met) % 2 == 0:
        met = []  # the curve crossed the singular manifold and came back: not the motion
    elif change < 0 and not met:
        # det J_p changed sign, but the path started or ended on the singular manifold
        # (within rounding), where no sign change was seen: the crossing is at that end
        on = min((prev, cfg), key=lambda c: abs(_det(model, c)))
        met = [Crossing(0.0 if on is prev else 1.0, on.x, on.y, on.theta)]
    for cr in met:
        crossings.append(Crossing(cr.s, cr.x, cr.y, cr.theta, index=i - 1))
    return cfg


def _det(model: Model, cfg: Configuration) -> float:
    y_loc, c = model.chart.to_local(cfg.y)
    return float(np.linalg.det(np.array(model.kernels.jac(y_loc, cfg.theta, c)[0])))


class _Judge:
    """Verifies candidate solutions at ``theta`` and ranks them against the predicted motion.

    A candidate is (miss, -advance, arc, configuration, crossings): ``miss`` is the distance
    of its displacement from the predicted one, ``advance`` the projection of its
    displacement on the predicted one. Misses closer than the accuracy of the extrapolation
    (the last second difference of the motion) tie; a tie goes to the candidate farther along
    the motion: a reading so close to the singular manifold that its two solutions are nearer
    to each other than the extrapolation is accurate is taken on the side the robot heads to.
    """

    def __init__(self, model: Model, prev: Configuration, theta, predicted, accuracy=0.0):
        self.model, self.prev, self.theta, self.predicted = model, prev, theta, predicted
        self.agree = AGREEMENT * float(np.linalg.norm(predicted)) if predicted is not None else 0
        self.tie = float(accuracy)

    def add(self, candidates: list, y: np.ndarray, arc: float, met) -> None:
        model = self.model
        cfg = model.configuration(y, self.theta)
        if not cfg.residual <= model.tolerance:
            return  # not verified: never returned
        d = difference(model, cfg.y, self.prev.y)
        p = self.predicted if self.predicted is not None else np.zeros(model.m)
        advance = float(d @ p) / max(float(np.linalg.norm(p)), 1e-300)
        candidates.append((float(np.linalg.norm(d - p)), -advance, arc, cfg, list(met)))

    def best(self, candidates: list):
        if not candidates:
            return None
        least = min(c[0] for c in candidates)
        tied = [c for c in candidates if c[0] <= least + self.tie]
        return min(tied, key=lambda c: (c[1], c[0], c[2]))


def _predicted_local(model: Model, prev: Configuration, predicted: np.ndarray):
    """The predicted configuration ``prev + predicted`` in the chart centred on ``prev``."""
    y_loc, c = model.chart.to_local(prev.y)
    y = y_loc + predicted
    for idx in model.chart.rotations:  # rotation vector -> Rodrigues parameters
        w = predicted[list(idx)]
        angle = float(np.linalg.norm(w))
        y[list(idx)] = w * (math.tan(angle / 2) / angle if 1e-12 < angle < 3.0 else 0.5)
    return y, c


def _refined(model: Model, prev: Configuration, theta: np.ndarray, expected: float, judge):
    """Candidates by a search with small steps and turning-point refinement.

    For a reading on (or within rounding of) the singular manifold, the two solutions nearly
    coincide and the curve only grazes ``s = 1``: the predictor-corrector follower of
    :mod:`~scdk_sym.solvers.modes`, started with steps a sixteenth of the predicted arc,
    refines the step where a turning point of ``s`` could hide two crossings. Failing that
    (a double root), Newton from the predicted configuration and from the turning points of
    ``s`` next to ``s = 1``.
    """
    dtheta = theta - prev.theta
    budget = BUDGET_FACTOR * expected * 2**ATTEMPTS
    candidates: list = []
    turns = []
    for direction in (1.0, -1.0):
        curve = follow_curve(model, prev.theta, dtheta, prev.y, 0.0, direction,
                             max_arc=budget, max_hits=2, step=expected / 16)  # fmt: skip
        turns += [(y_t, s_t) for _, y_t, s_t in curve.turns]
        for y, arc in zip(curve.hits, curve.hit_arcs, strict=True):
            met = []
            for arc_t, y_t, s_t in curve.turns:
                if arc_t < arc:
                    cfg = model.configuration(y_t, prev.theta + s_t * dtheta)
                    met.append(Crossing(s_t, cfg.x, cfg.y, cfg.theta))
            judge.add(candidates, y, arc, met)
    if candidates:
        return candidates
    kern = curve_kernels(model)
    y_pred, c = _predicted_local(model, prev, judge.predicted if judge.predicted is not None
                                 else np.zeros(model.m))  # fmt: skip
    guesses = [(y_pred, c)] + [
        model.chart.to_local(y_t) for y_t, s_t in turns if abs(s_t - 1) < 0.1
    ]
    for y, cg in guesses:
        for _ in range(6):  # Newton converges only linearly to a double root
            y, res = kern.polish(y, theta, cg)
            y = np.array(y).ravel()
            if not np.all(np.isfinite(y)) or float(res) <= 1e-3 * model.tolerance:
                break
        if np.all(np.isfinite(y)):
            judge.add(candidates, model.chart.to_canonical(y, cg), 0.0, [])
    return candidates


def _continuation(model: Model, prev: Configuration, theta: np.ndarray) -> Configuration | None:
    """The solution at ``theta`` continuing ``prev`` in its compartment, or None.

    One zero-copy call of the warm kernel (an RK4 step in ``s`` from ``prev`` and Newton at
    ``theta``, with the residuals and ``J_p`` at both ends); accepted when Newton converged,
    moved the prediction by less than a tenth of the step and ``det J_p`` kept its sign (no
    singular manifold in between, as far as this cheap test can tell).
    """
    y_loc, c = model.chart.to_local(prev.y)
    y, corr, _, res, J1, J0, T, x = engine(model).warm(y_loc, prev.theta, theta, c)
    if not (np.all(np.isfinite(y)) and res[0] <= 0.1 * model.tolerance):
        return None
    step = float(np.max(np.abs(y - y_loc)))
    if step > max(1.0, model.length_scale) or corr[0] > 0.1 * step + 1e-12:
        return None
    m = model.m
    if (
        not np.linalg.det(J1.reshape(m, m, order="F")) * np.linalg.det(J0.reshape(m, m, order="F"))
        > 0
    ):
        return None
    y_can = model.chart.to_canonical(y, c)
    theta = np.array(theta, dtype=float)
    return Configuration(
        theta, y_can, x.copy(), T.reshape(4, 4, order="F").copy(),
        model.joint_values(y_can, theta), float(res[0]),
    )  # fmt: skip
