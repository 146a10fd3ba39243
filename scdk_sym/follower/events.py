"""Judging a predictor's samples, segment by segment: folds (``s`` turns: ``t_s`` and
``det J_p`` change sign together), bifurcations (``det J_p`` changes sign while ``t_s`` does
not) and level crossings, each recorded, or a smaller step asked for to resolve it."""

from __future__ import annotations

from enum import IntEnum

import numpy as np

from .geometry import features
from .levels import hidden_pair, levels_passed, solve_at_level, turns_beyond
from .locate import interpolated_fold, is_bifurcation, locate_bifurcation, locate_fold
from .predictors import Chunk
from .state import WalkState
from .step_over import step_over, step_over_in_s, straight
from .tangent import tangent_at, weighted_distance


class Verdict(IntEnum):
    """What a segment of a chunk asks of the walk."""

    GO = 0  # take it
    REFINE = 1  # a smaller step, from the segment's start
    REPLACE = 2  # take the point that replaces its end (a step over a bifurcation)
    FULL = 3  # take it and stop judging: the hits are complete


def eventful(Q, T, D, n: int, levels, stop: bool) -> range | list[int]:
    """The segments ``j`` (of samples ``j`` and ``j + 1``, ``j < n``) of a chunk on which
    something may happen: ``s`` turns (``t_s`` changes sign), ``det J_p`` changes sign, or
    ``s`` meets a level; every segment when ``stop`` (the walk has its hits already). The
    same products and comparisons as the walk makes per segment, for all segments at once."""
    if stop or n == 0:
        return range(n)
    s, ts, det = Q[-1, : n + 1], T[-1, : n + 1], D[: n + 1]
    event = (ts[:-1] * ts[1:] < 0) | (det[:-1] * det[1:] < 0)
    for L in levels:
        event |= (s[:-1] - L) * (s[1:] - L) <= 0
    return np.flatnonzero(event).tolist()


def judge(st: WalkState, ch: Chunk) -> tuple[int | None, tuple | None, int]:
    """Walk the accepted segments in order; stop at the first that needs a smaller step
    (``refine_at``) or is replaced by a step over a bifurcation (``replaced``); ``last``:
    the samples to take when neither (fewer when the hits are complete).

    Only segments where ``s`` turns, ``det J_p`` changes sign or a level is crossed can
    act: a rule acting on other segments must add its condition to :func:`eventful`.
    """
    o = st.ctx.options
    full = len(st.out.hits) >= o.max_hits
    for j in eventful(ch.Q, ch.T, ch.D, ch.ok, o.levels, full):
        verdict, replaced = _segment(st, ch, j)
        if verdict == Verdict.REFINE:
            return j, None, ch.ok
        if verdict == Verdict.REPLACE:
            return None, replaced, ch.ok
        if verdict == Verdict.FULL:
            return None, None, j + 1
    return None, None, ch.ok


def _segment(st: WalkState, ch: Chunk, j: int) -> tuple[Verdict, tuple | None]:
    """The events of segment ``j``: GO, REFINE, REPLACE (with the replacement
    ``(j, q, t, det)``) or FULL (the hits are complete)."""
    Q, T, D, h, levels = ch.Q, ch.T, ch.D, st.h, st.ctx.options.levels
    can_refine = h / 4 >= st.h_min
    before_segment = len(st.out.singular)
    turn = T[-1, j] * T[-1, j + 1] < 0
    flip = D[j] * D[j + 1] < 0
    at_start = st.skip_level_at_start and j == 0
    crossing_levels = levels_passed(levels, float(Q[-1, j]), float(Q[-1, j + 1]), at_start)
    hidden = any(hidden_pair(Q[-1, j], Q[-1, j + 1], T[-1, j], T[-1, j + 1], h, L) for L in levels)
    # leaving a level and turning back through it within one step
    hidden |= bool(turn and at_start and Q[-1, 0] in levels)
    if turn and not flip and can_refine:
        # s turned while det J_p kept its sign: not a fold (there both change sign
        # together) but a step that jumped onto a nearby branch (e.g. across the gap
        # where the line grazes the singular surface); smaller steps stay on the curve
        return Verdict.REFINE, None
    if (hidden or (crossing_levels and turn)) and can_refine:
        return Verdict.REFINE, None
    if flip and not turn:
        verdict, replaced = _flip_without_turn(st, ch, j)
        if verdict != Verdict.GO:
            return verdict, replaced
    if turn:
        verdict, replaced = _turn(st, ch, j)
        if verdict != Verdict.GO:
            return verdict, replaced
    return _levels_crossed(st, ch, j, crossing_levels, before_segment), None


def _flip_without_turn(st: WalkState, ch: Chunk, j: int) -> tuple[Verdict, tuple | None]:
    """``det J_p`` changed sign without a turn of ``s``: two branches crossing (``H'``
    drops rank at the point) or a step that jumped across a fold (then ``H'`` keeps its
    rank, and smaller steps show the turn); first at fixed ``s`` on the incoming branch
    (which also locates the point on it), else straight."""
    ctx = st.ctx
    Q, T, D, h, c = ch.Q, ch.T, ch.D, st.h, st.c
    model, weight = ctx.model, ctx.weight
    past = [*st.hist, *(Q[:, i] for i in range(1, j + 1))][-3:]
    got = step_over_in_s(ctx, past, T[:, j], c, D[j])
    if got is not None and is_bifurcation(model, got[4], ctx.dtheta):
        st.add_singular(got[4], st.out.arc + h * (j + 0.5))
        return Verdict.REPLACE, (j, got[0], got[1], got[2])
    length = weighted_distance(weight, Q[:, j + 1], Q[:, j])
    replaced = None
    q_str = straight(ctx, Q[:, j], T[:, j], length, c)
    if q_str is not None and weighted_distance(weight, q_str, Q[:, j + 1]) > 0.05 * length:
        t_str, det_str = tangent_at(ctx.kern, q_str, T[:, j], ctx.p, c, ctx.m)
        replaced = (j, q_str, t_str, det_str)
    q_b = replaced[1] if replaced is not None else Q[:, j + 1]
    cr = locate_bifurcation(ctx, Q[:, j], q_b, c, D[j])
    if not is_bifurcation(model, cr, ctx.dtheta) and h / 4 >= st.h_min:
        return Verdict.REFINE, None
    st.add_singular(cr, st.out.arc + h * (j + 0.5))
    return (Verdict.REPLACE, replaced) if replaced is not None else (Verdict.GO, None)


def _turn(st: WalkState, ch: Chunk, j: int) -> tuple[Verdict, tuple | None]:
    """``s`` turned on segment ``j``: a fold, located (or interpolated) and recorded; or,
    where two branches cross there, a step straight over the point."""
    ctx = st.ctx
    Q, T, D, h, c = ch.Q, ch.T, ch.D, st.h, st.c
    model, weight = ctx.model, ctx.weight
    locate, can_refine = ctx.options.locate, h / 4 >= st.h_min
    if locate:
        cr = locate_fold(ctx, Q[:, j], Q[:, j + 1], T[:, j], T[:, j + 1], c)
    else:
        cr = interpolated_fold(ctx, Q[:, j], Q[:, j + 1], T[:, j], T[:, j + 1], c)
    if locate and is_bifurcation(model, cr, ctx.dtheta):
        # not a fold: two branches cross there and the predictor swung onto the other
        # one; step straight over the point from the sample before it
        length = weighted_distance(weight, Q[:, j + 1], Q[:, j])
        stepped = step_over(ctx, Q[:, j], T[:, j], c, length)
        if stepped is not None:
            q_new, t_new, det_new, _len = stepped
            if det_new * D[j] < 0:
                cr = locate_bifurcation(ctx, Q[:, j], q_new, c, D[j])
                st.add_singular(cr, st.out.arc + h * (j + 0.5))
            return Verdict.REPLACE, (j, q_new, t_new, det_new)
        if can_refine:
            return Verdict.REFINE, None
    levels = ctx.options.levels
    if locate and can_refine and turns_beyond(levels, Q[-1, j], Q[-1, j + 1], cr.s):
        # the located fold lies past a level both samples are short of: the step hid two
        # crossings of it (too close to the fold for the interpolation to show); smaller
        # steps put a sample between them
        return Verdict.REFINE, None
    f = np.append(features(model, cr.y)[0], cr.s * ctx.w)
    st.note_fold(f, st.out.arc + h * j)
    st.add_singular(cr, st.out.arc + h * (j + 0.5))
    return Verdict.GO, None


def _levels_crossed(st: WalkState, ch: Chunk, j: int, crossing_levels, before: int) -> Verdict:
    """Finish each level crossed on segment ``j`` (a hit), or ask for a smaller step."""
    Q, T, h, max_hits = ch.Q, ch.T, st.h, st.ctx.options.max_hits
    for L in crossing_levels:
        y_hit = solve_at_level(st.ctx, Q[:, j], Q[:, j + 1], T[:, j], T[:, j + 1], h, L, st.c)
        if y_hit is None:
            if h / 4 >= st.h_min:
                return Verdict.REFINE
            continue
        st.add_hit(y_hit, L, st.out.arc + h * (j + 0.5), before, Q[-1, j], Q[-1, j + 1])
        if len(st.out.hits) >= max_hits:
            break
    return Verdict.FULL if len(st.out.hits) >= max_hits else Verdict.GO
