"""Stepping over a point the predictors cannot pass (two branches crossing, where no tangent
field is smooth): at fixed ``s`` from the extrapolation of the incoming branch, or straight
along the incoming tangent with a corrector on the plane normal to it."""

from __future__ import annotations

import numpy as np

from ..results import Crossing
from .context import WalkContext
from .levels import levels_passed, solve_at_level
from .locate import locate_bifurcation
from .predictors import CVODES_REJECTIONS
from .state import Flow, WalkState
from .tangent import tangent_at, weighted_distance

#: A stepped-over point must continue the incoming tangent within acos(STEP_OVER_COS).
STEP_OVER_COS = 0.9
#: Lengths of the straight step-over, in units of the last good step, tried in turn.
STEP_OVER_FACTORS = (2.0, 8.0, 32.0, 128.0, 0.5)
#: A step-over past a level of ``s`` is at most this many last good steps long.
SHORT_OVER = 2.0
#: Steps in s of the step-over at fixed s (:func:`step_over_in_s`): the first is this
#: fraction of the last step's, each next one twice the previous.
S_STEP_FIRST = 0.5
S_STEP_TRIES = 24


def straight(ctx: WalkContext, q, t, length: float, c) -> np.ndarray | None:
    """The curve point on the plane normal to ``t`` at ``length`` along it (None if Newton
    did not converge there or moved off by more than half the length)."""
    q_pred = q + length * t
    q_new, res = ctx.kern.plane(q_pred, t, ctx.p, c)
    q_new = np.array(q_new).ravel()
    if not (np.all(np.isfinite(q_new)) and float(res) <= 0.1 * ctx.tol):
        return None
    if float(np.max(np.abs(q_new - q_pred))) > 0.5 * length:
        return None
    return q_new


def step_over(ctx: WalkContext, q, t, c, h_good: float, factors=STEP_OVER_FACTORS):
    """Step over a point the predictors cannot pass (a bifurcation): straight along ``t`` with
    a corrector on the plane normal to it, at ``factors`` times ``h_good`` in turn; the new
    point must continue the incoming tangent. Returns (q, t, det, length) or None."""
    weight = ctx.weight
    for f in factors:
        length = f * h_good
        q_new = straight(ctx, q, t, length, c)
        if q_new is None:
            continue
        t_new, det_new = tangent_at(ctx.kern, q_new, t, ctx.p, c, ctx.m)
        if not np.all(np.isfinite(t_new)):
            continue
        if float(weight @ (t_new * t)) >= STEP_OVER_COS:
            return q_new, t_new, det_new, weighted_distance(weight, q_new, q)
    return None


def step_over_located(ctx: WalkContext, q, t, c, det: float, h_good: float, factors):
    """:func:`step_over` at ``factors`` times ``h_good``, with the crossing located where
    ``det J_p`` changed sign: ``((q, t, det, length), crossing or None)``, or ``(None, None)``
    if no step-over continues the tangent or the sign change is not on its chord."""
    got = step_over(ctx, q, t, c, h_good, factors)
    if got is None or got[2] * det > 0:
        return got, None
    at = locate_bifurcation(ctx, q, got[0], c, det)
    lo, hi = sorted((float(q[-1]), float(got[0][-1])))
    if not lo - 1e-9 <= at.s <= hi + 1e-9:
        return None, None  # det J_p changed sign off the chord: no crossing located
    return got, at


def step_over_in_s(ctx: WalkContext, hist, t, c, det: float):
    """Step over a point where two branches cross at fixed ``s``: past it, the solution of
    ``g(y, theta(s)) = 0`` nearest to the extrapolation of the incoming branch.

    At a bifurcation ``s`` keeps increasing (or decreasing) along the incoming branch, so ``s``
    parametrises it; the quadratic in ``s`` through its last three accepted points continues
    it to second order, while the other branch leaves along another direction: Newton at
    fixed ``theta`` from the extrapolation stays on the incoming branch (the way a
    continuation in the actuated joints with a secant predictor moves the robot), even where
    the two branches have nearly the same tangent (there the tangent itself is ill-conditioned
    and is not used). Steps in ``s`` grow from half the last one until ``det J_p`` has changed
    sign (one crossing passed), without passing a level of the walk's levels.

    Args:
        ctx: the walk.
        hist: the last accepted points ``q = (y, s)`` of the walk, the current one last.
        t: (m+1,) unit tangent at the current point.
        c: the chart of the points.
        det: ``det J_p`` at the current point.

    Returns:
        (q, t, det, length, crossing) or None (fewer than three points, ``s`` not monotone
        over them, Newton strayed, or no sign change within ``S_STEP_TRIES`` steps).
    """
    model, kern, line, p, m, tol = ctx.model, ctx.kern, ctx.line, ctx.p, ctx.m, ctx.tol
    if len(hist) < 3:
        return None
    P = np.array(hist[-3:])
    q = P[-1]
    S = P[:, -1] - q[-1]
    ds0 = float(S[2] - S[1])
    if not ((S[1] - S[0]) * ds0 > 0 and ds0 * float(t[-1]) > 0):
        return None

    # Lagrange quadratic through the three points, in s relative to the current one
    def extrapolate(ds):
        w = [
            (ds - S[1]) * (ds - S[2]) / ((S[0] - S[1]) * (S[0] - S[2])),
            (ds - S[0]) * (ds - S[2]) / ((S[1] - S[0]) * (S[1] - S[2])),
            (ds - S[0]) * (ds - S[1]) / ((S[2] - S[0]) * (S[2] - S[1])),
        ]
        return w[0] * P[0, :m] + w[1] * P[1, :m] + w[2] * P[2, :m]

    def solve_at(ds):
        y_pred = extrapolate(ds)
        y, res = kern.polish(y_pred, line.at(float(q[-1] + ds)), c)
        y = np.array(y).ravel()
        if not (np.all(np.isfinite(y)) and float(res) <= 0.1 * tol):
            return None
        move = float(np.linalg.norm(y - y_pred))
        if move > 0.5 * float(np.linalg.norm(y_pred - q[:m])) + 10 * tol:
            return None  # Newton went elsewhere (e.g. s turns ahead: no solution near)
        q_new = np.append(y, q[-1] + ds)
        t_new, det_new = tangent_at(kern, q_new, t, p, c, m)
        return q_new, t_new, det_new

    ds = S_STEP_FIRST * ds0
    for _ in range(S_STEP_TRIES):
        s_new = float(q[-1] + ds)
        if any((L - q[-1]) * (L - s_new) < 0 for L in ctx.options.levels):
            return None
        got = solve_at(ds)
        if got is None:
            return None
        q_new, t_new, det_new = got
        if det_new * det < 0:
            if not (np.all(np.isfinite(t_new)) and t_new[-1] * ds0 > 0):
                return None
            # the crossing: bisection of det J_p in s on the same extrapolated branch
            lo, hi, y_mid = 0.0, ds, q_new[:m]
            for _ in range(40):
                mid = 0.5 * (lo + hi)
                got_mid = solve_at(mid)
                if got_mid is None:
                    break
                y_mid = got_mid[0][:m]
                if got_mid[2] * det > 0:
                    lo = mid
                else:
                    hi = mid
                if abs(hi - lo) <= 1e-12 * max(1.0, abs(float(q[-1]))):
                    break
            s_cr = float(q[-1] + 0.5 * (lo + hi))
            cfg = model.configuration(y_mid, line.at(s_cr), c)
            cr = Crossing(s_cr, cfg.x, cfg.y, cfg.theta, kind="bifurcation")
            return q_new, t_new, det_new, weighted_distance(ctx.weight, q_new, q), cr
        ds *= 2.0
    return None


def step_over_stall(st: WalkState) -> Flow:
    """The step keeps shrinking (next to crossing branches no tangent field is smooth and
    the predictors creep towards the point): step over it, finishing every level the step
    passes (a solution it skipped would be lost, or a later one taken for the first)."""
    ctx, o = st.ctx, st.ctx.options
    stepped, cr = _try_step_over(st)
    out, q = st.out, st.q
    finished: list[tuple[float, np.ndarray | None]] = []
    if stepped is not None:
        q_new, t_new, det_new, length = stepped[:4]
        passed = levels_passed(o.levels, float(q[-1]), float(q_new[-1]), st.skip_level_at_start)
        finished = [
            (L, solve_at_level(ctx, q, q_new, st.t, t_new, length, L, st.c)) for L in passed
        ]
    if stepped is None or any(y_hit is None for _L, y_hit in finished):
        # nothing to step over (a tight turn of a smooth curve, e.g. next to a point
        # where two branches nearly cross, or a tight fold), or a step-over passing a
        # level with no solution on its chord (it jumped between such branches): smaller
        # steps follow the curve; halve on, down to h_min, else stalled
        if st.h / 2 >= st.h_min:
            st.halvings = 0
            st.h /= 2
            return Flow.GO
        out.stalled = True
        return Flow.STOP
    out.step_overs += 1
    before = len(out.singular)
    if cr is not None:
        st.add_singular(cr, out.arc + 0.5 * length)
    for L, y_hit in finished:
        if len(out.hits) < o.max_hits:
            st.add_hit(y_hit, L, out.arc + 0.5 * length, before, q[-1], q_new[-1])
    st.moved_to(q_new, t_new, det_new, length)
    st.h, st.halvings = st.h_good, 0
    st.reject_limit = max(st.reject_limit, out.rejected + CVODES_REJECTIONS)
    if out.repeated or len(out.hits) >= o.max_hits:
        return Flow.STOP
    return Flow.STOP if len(out.singular) >= o.max_singular else Flow.GO


def _try_step_over(st: WalkState) -> tuple[tuple | None, Crossing | None]:
    """A step over the point ahead: at fixed ``s`` first, else straight (only short
    straight steps may pass a level of ``s``)."""
    ctx = st.ctx
    stepped = step_over_in_s(ctx, st.hist, st.t, st.c, st.det)
    if stepped is not None:
        return stepped, stepped[4]
    got, cr = step_over_located(ctx, st.q, st.t, st.c, st.det, st.h_good, STEP_OVER_FACTORS)
    if (
        got is not None
        and got[3] > SHORT_OVER * st.h_good
        and levels_passed(ctx.options.levels, float(st.q[-1]), float(got[0][-1]), False)
    ):
        # a long step-over past a level cannot be finished there reliably
        short = tuple(f for f in STEP_OVER_FACTORS if f <= SHORT_OVER)
        got, cr = step_over_located(ctx, st.q, st.t, st.c, st.det, st.h_good, short)
    return got, cr
