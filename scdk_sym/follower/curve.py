"""The curve follower: one implementation of following a solution curve of the closures.

For a line ``theta(s) = theta1 + s dtheta`` in joint space the solutions of
``g(y, theta(s)) = 0`` form curves in ``q = (y, s)``. :func:`follow` walks such a curve from
an assembled point along the oriented singularity-consistent tangent (see
:mod:`scdk_sym.follower.calls`) and reports what it meets
(:mod:`scdk_sym.follower.events`):

- **level crossings** (``s`` passes a level, e.g. ``s = 1``: a direct-kinematics solution at
  ``theta(1)``), finished by Newton at fixed ``theta`` from a cubic Hermite guess and
  verified (:mod:`scdk_sym.follower.levels`);
- **folds** (``s`` turns: ``t_s`` and ``det J_p`` change sign together), located by Newton on
  ``[g; t_s] = 0`` (:mod:`scdk_sym.follower.locate`);
- **bifurcations** (two branches cross: ``H' = [J_p, -j_s]`` drops rank because the left null
  vector of ``J_p`` is one of ``J_s`` too, ``det J_p`` changes sign while ``t_s`` does not),
  stepped over one at a time at fixed ``s`` from the extrapolation of the incoming branch
  (Newton at fixed ``theta``: the walk continues the incoming branch even where the other one
  has nearly the same tangent) or, failing that, along the incoming tangent with a corrector
  on the plane normal to it (:mod:`scdk_sym.follower.step_over`), and located by bisection of
  ``det J_p``. Where ``H'`` nearly drops rank only because the line is tangent to the singular
  surface, the point is a fold.

Two predictors produce the samples, judged by the same rules
(:mod:`scdk_sym.follower.predictors`): ``"rk4"``, ``STEPS`` explicit steps of arc length ``h``
per call, accepted one by one; ``"cvodes"``, CVODES integrating the stabilised SC ODE over
``GRID`` samples of arc length ``h``, accepted as a whole.

Step control: a rejected step halves ``h`` (a quarter where an event needs resolution: a
level crossing and a fold in one step, a turning point that could hide two crossings of a
level, a finish that left the curve, a turn of ``s`` without a sign change of ``det J_p``); a
smooth chunk grows it by 1.6. When ``h`` has shrunk ``STALL_HALVINGS`` times in a row (calls
rejected in whole or in part) the follower tries to step over (a bifurcation, where no
tangent field is smooth); failing that the walk ends ``stalled``.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError
from .calls import follower_calls
from .context import WalkContext
from .events import judge
from .follow_rule import GROW
from .options import FollowOptions
from .predictors import (
    BACKUP_CALLS,
    CVODES_REJECTIONS,
    PREDICTORS,
    Chunk,
    ExplicitSteps,
    PredictorChoice,
    predictor_named,
)
from .state import Flow, WalkState
from .step_over import step_over_stall
from .walk import Line, Walk

if TYPE_CHECKING:
    from ..robot import Model

#: Rejections in a row (each halving the step) before stepping over.
STALL_HALVINGS = 6
#: Bound on the follower's loop iterations, in accepted-step budgets (a guard: each iteration
#: advances, shrinks the step or stops, so it is never reached on a curve it can follow).
LOOP_FACTOR = 10
#: Largest initial step [model sizes].
FIRST_STEP = 0.01
#: Rejected steps after which a walk ends as stalled.
MAX_REJECTED = 200


def follow(
    model: Model,
    line: Line,
    y_start: np.ndarray,
    s_start: float,
    direction: float,
    options: FollowOptions | None = None,
    *,
    tangent: np.ndarray | None = None,
    chart: np.ndarray | None = None,
) -> Walk:
    """Follow the solution curve of ``g(y, line.at(s)) = 0`` from ``(y_start, s_start)``.

    The walk is a loop of predictor calls: each call's accepted samples are judged segment
    by segment (folds, bifurcations, level crossings), taken up to the first segment that
    needs a smaller step, and the step adapted; where the step keeps shrinking the follower
    steps over the point (see the module documentation).

    Args:
        model: the model.
        line: the line in joint space.
        y_start: (m,) canonical unknowns of an assembled point of the curve (or local ones
            with ``chart``).
        s_start: its path parameter.
        direction: +1 to follow ``nu = [adj(J_p) j_s; det J_p]`` (``s' = det J_p``), -1 for
            ``-nu``; ignored when ``tangent`` is given.
        options: the predictor, the kernels, the levels, the stop rules and the step
            (default: :class:`~scdk_sym.follower.options.FollowOptions` ``()``).
        tangent: (m+1,) initial tangent orientation (instead of ``direction``).
        chart: chart of ``y_start`` when it is given in local coordinates.

    Returns:
        A :class:`~scdk_sym.follower.walk.Walk`.

    Raises:
        InputError: unknown predictor or backend.
    """
    o = FollowOptions() if options is None else options
    choice = predictor_named(o.predictor)
    if choice is None:
        names = ", ".join(p.name for p in PREDICTORS)
        raise InputError(f"unknown predictor {o.predictor!r}; predictors: {names}")
    ctx = WalkContext(model, line, follower_calls(model, o.backend), o)
    walker = Walker(WalkState(ctx, y_start, s_start, direction, tangent, chart), choice)
    return walker.run(direction)


class Walker:
    """The loop of one walk of :func:`follow`: its predictors and the step control around
    the state it advances (:class:`~scdk_sym.follower.state.WalkState`)."""

    def __init__(self, st: WalkState, choice: PredictorChoice) -> None:
        """The predictors, the arc budget and the step bounds, from the start's arc per ``s``."""
        self.st = st
        ctx, o = st.ctx, st.ctx.options
        scale, w = ctx.scale, ctx.w
        ell0 = min(1.0 / max(abs(st.t[-1]) * w, 1e-6) * w, 1e3 * scale) if w > 0 else scale
        ell0 = max(ell0, 1e-9 * scale)
        self.budget = 60.0 * ell0 + 20.0 * scale if o.max_arc is None else float(o.max_arc)
        chosen = choice.predictors(ctx, ExplicitSteps(ctx, o.min_cos), ell0)
        self.pred, self.backup, self.h_max = chosen.main, chosen.backup, chosen.h_max
        st.h = min(ell0 / 16, FIRST_STEP * scale) if o.step is None else float(o.step)
        st.h_min = 1e-12 * max(ell0, 1e-6 * scale)
        self.h_first = st.h_good = st.h
        st.halvings = 0
        st.reject_limit = MAX_REJECTED
        self.backup_left = 0

    def run(self, direction: float) -> Walk:
        """Predict, judge and take steps until a stop rule holds; the walk's report."""
        st = self.st
        out, o = st.out, st.ctx.options
        turns = 0  # loop iterations: every one either advances, shrinks h or stops
        while out.arc < self.budget and out.steps < o.max_steps:
            turns += 1
            if turns > LOOP_FACTOR * o.max_steps:
                out.stalled = True
                break
            if st.halvings >= STALL_HALVINGS or st.h < st.h_min:
                if self.backup is not None:
                    self._explicit_from_here()
                    continue
                if step_over_stall(st) is Flow.STOP:
                    break
                continue
            if out.rejected > st.reject_limit:
                out.stalled = True
                break
            if time.perf_counter() > o.deadline:
                out.timed_out = True
                break
            ch = self._advance()
            if ch.ok == 0:
                out.rejected += 1
                st.halvings += 1
                st.h /= 2
                continue
            if self._take(ch) is Flow.STOP:
                break
        out.s_range = (st.s_lo, st.s_hi)
        out.end = (st.q, st.t, st.c)
        if o.record and st.rec.q:
            out.path = st.rec.samples(st.ctx.model, st.ctx.line, direction)
        return out

    def _explicit_from_here(self) -> None:
        """CVODES creeps (its error control, not the curve, may be at fault): explicit steps
        from here; only their stall is a point to step over."""
        assert self.backup is not None
        st = self.st
        self.pred, self.backup = self.backup, None
        st.h, st.halvings = max(st.h_good, self.h_first), 0
        st.reject_limit = max(st.reject_limit, st.out.rejected + CVODES_REJECTIONS)

    def _advance(self) -> Chunk:
        """One predictor call from the current point (the explicit one where CVODES fails)."""
        st = self.st
        q, t, h, c, det = st.q, st.t, st.h, st.c, st.det
        if self.backup is not None and st.out.rejected >= CVODES_REJECTIONS:
            self.pred, self.backup = self.backup, None  # CVODES keeps failing here: explicit
            st.h, st.halvings = max(h, self.h_first), 0  # steps from now on
            st.reject_limit = st.out.rejected + CVODES_REJECTIONS
            h = st.h
        if self.backup is not None and self.backup_left > 0:
            self.backup_left -= 1
            return self.backup.advance(q, t, h, c, det)
        ch = self.pred.advance(q, t, h, c, det)
        if ch.ok == 0 and self.backup is not None:
            # CVODES could not integrate this stretch (e.g. next to two crossing branches,
            # where no smooth field exists): the explicit predictor-corrector takes over for
            # the next few calls
            ch = self.backup.advance(q, t, h, c, det)
            self.backup_left = BACKUP_CALLS if ch.ok else 0
        return ch

    def _take(self, ch: Chunk) -> Flow:
        """Judge a chunk's samples, take them up to the first event that needs a smaller
        step (or a step over a bifurcation), adapt the step; STOP when a rule says so."""
        st = self.st
        o = st.ctx.options
        refine_at, replaced, last = judge(st, ch)
        used = last if refine_at is None else refine_at
        if replaced is not None:
            used = replaced[0]
        if o.stop_when_closed and used > 0:
            st.check_closed(ch, used)
        if used > 0:
            st.accept(ch, used)
        if replaced is not None:
            st.jump_to(replaced)
        st.t = st.t / math.sqrt(float(st.ctx.weight @ (st.t * st.t)))
        out = st.out
        if out.closed or out.repeated or len(out.hits) >= o.max_hits:
            return Flow.STOP
        if len(out.singular) >= o.max_singular:
            return Flow.STOP
        st.recentre()
        self._adapt_step(ch, refine_at, replaced, used, last)
        return Flow.GO

    def _adapt_step(self, ch: Chunk, refine_at, replaced, used: int, last: int) -> None:
        """A quarter step to resolve an event, half after a partial call, else grow."""
        st = self.st
        if refine_at is not None:
            st.h /= 4
            st.out.rejected += 1
            if self.backup is not None:
                self.backup_left = BACKUP_CALLS  # resolve the event with the explicit steps
        elif ch.partial and replaced is None:
            st.h /= 2
            st.out.rejected += 1
            st.halvings += 1
        else:
            st.halvings = 0
            st.h_good = st.h
            if ch.smooth:
                st.h = min(GROW * st.h, self.h_max)
        if replaced is not None or (used == last and not ch.partial):
            st.halvings = 0
