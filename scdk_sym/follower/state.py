"""The state of one walk: where it is, its step, what it met, and the moves that change them."""

from __future__ import annotations

import math
from enum import IntEnum

import numpy as np

from ..kernels.fastcall import model_calls
from ..results import Crossing
from .context import WalkContext
from .follow_rule import RECENTRE
from .geometry import in_chart, local_features
from .levels import met_before
from .predictors import Chunk
from .tangent import null_direction, tangent_at, weighted_distance
from .walk import Hit, PathRecord, Walk


class Flow(IntEnum):
    """What a step of the walk tells its loop."""

    GO = 0
    STOP = 1


class WalkState:
    """The state of one walk of :func:`~scdk_sym.follower.curve.follow`.

    The current point ``q = (y local, s)`` in chart ``c``, its unit tangent ``t`` and
    ``det J_p``; the step ``h`` with its bounds and the count of halvings in a row (set by the
    loop once it has chosen its predictors); the last accepted points ``hist`` (for
    extrapolation); what was met (``out``, a :class:`~scdk_sym.follower.walk.Walk`).
    """

    def __init__(self, ctx: WalkContext, y_start, s_start: float, direction: float,
                 tangent, chart) -> None:  # fmt: skip
        """The start point in its chart, its oriented unit tangent and ``det J_p``."""
        self.ctx = ctx
        model, m = ctx.model, ctx.m
        if chart is None:
            y_loc, c = model.chart.to_local(y_start)
        else:
            y_loc, c = np.array(y_start, dtype=float), np.array(chart, dtype=float)
        q = np.append(y_loc, float(s_start))
        if tangent is None:
            Jp, Js = (np.array(a) for a in model_calls(model).jac(y_loc, ctx.line.at(s_start), c))
            v0 = direction * null_direction(Jp, Js @ ctx.dtheta)
        else:
            v0 = np.asarray(tangent, float)
        self.q, self.c = q, c
        self.t, self.det = tangent_at(ctx.kern, q, v0, ctx.p, c, m)
        self.out = Walk(det0=self.det)
        self.q_first, self.c_first, self.t_first = q.copy(), c.copy(), self.t.copy()
        self.left = False  # the walk has left its start (for the closure test)
        self.s_lo = self.s_hi = float(q[-1])
        self.f_hits = np.zeros((0, 0))
        self.f_folds: list[tuple[np.ndarray, float]] = []
        self.rec = PathRecord()
        if ctx.options.record:
            self.rec.add(q, c, self.det, 0.0)
        self.skip_level_at_start = True
        self.hist = [q.copy()]  # the last accepted points (same chart), for extrapolation
        # the step and its bounds [model length unit], set by the loop's choice of predictors
        self.h = self.h_min = self.h_good = 0.0
        self.halvings = 0
        self.reject_limit = 0

    # -------------------------------------------------------------------------- what was met

    def add_singular(self, cr: Crossing, arc: float) -> None:
        """Record a singular point met at arc length ``arc``."""
        self.out.singular.append(cr)
        self.out.singular_arcs.append(arc)

    def add_hit(self, y_hit, level, arc: float, before: int, s_a, s_b) -> None:
        """Record the solution ``y_hit`` (chart ``c``) at ``s = level``, met at arc length
        ``arc`` on a stretch from ``s_a`` to ``s_b`` whose singular points start at index
        ``before`` (a solution met before marks the walk repeated instead)."""
        ctx = self.ctx
        f_hit = local_features(ctx.model, y_hit, self.c)[None]
        f_hits = self.f_hits
        if f_hits.size and np.min(np.max(np.abs(f_hits - f_hit), axis=1)) <= 1e-6 * ctx.scale:
            self.out.repeated = True
            return
        self.f_hits = np.vstack([f_hits, f_hit]) if f_hits.size else f_hit
        crossings = met_before(self.out.singular, before, float(s_a), float(level))
        arriving = 1.0 if s_b > s_a else -1.0
        y = ctx.model.chart.to_canonical(y_hit, self.c)
        self.out.hits.append(Hit(y, float(level), arc, crossings, arriving))

    def note_fold(self, f: np.ndarray, arc: float) -> None:
        """Keep the features ``f`` of a fold met at arc length ``arc``; one met before (not
        just now) marks the walk repeated."""
        h = self.h
        for f_old, a_old in self.f_folds:
            if np.max(np.abs(f_old - f)) < 2 * h + 1e-6 * self.ctx.scale and arc - a_old > 4 * h:
                self.out.repeated = True
        self.f_folds.append((f, arc))

    # -------------------------------------------------------------------- taking the samples

    def check_closed(self, ch: Chunk, used: int) -> None:
        """Whether the accepted path came back to the start point (in the current chart)."""
        ctx = self.ctx
        q_ref = in_chart(self.q_first, self.c_first, self.c, ctx.rots)
        if q_ref is None:
            return
        weight, h = ctx.weight, self.h
        Qu = ch.Q[:, : used + 1]
        Dq = Qu - q_ref[:, None]
        if ctx.per.size:
            Dq[ctx.per] = (Dq[ctx.per] + math.pi) % (2 * math.pi) - math.pi
        E = np.diff(Qu, axis=1)
        tau = np.clip(-(weight @ (Dq[:, :-1] * E)) / np.maximum(weight @ (E * E), 1e-300), 0, 1)
        P = Dq[:, :-1] + tau * E
        dist = np.sqrt(weight @ (P * P))
        if not self.left:
            self.left = bool(np.any(dist > 3 * h))
        elif np.any(dist < 0.1 * h):
            jj = int(np.argmin(dist))
            self.out.closed = True
            self.out.reversed = bool(weight @ (ch.T[:, jj + 1] * self.t_first) < 0)

    def accept(self, ch: Chunk, used: int) -> None:
        """Take the chunk's first ``used`` samples."""
        Q, out, h = ch.Q, self.out, self.h
        self.skip_level_at_start = False
        self.s_lo = min(self.s_lo, float(Q[-1, : used + 1].min()))
        self.s_hi = max(self.s_hi, float(Q[-1, : used + 1].max()))
        if self.ctx.options.record:
            for j in range(1, used + 1):
                self.rec.add(Q[:, j], self.c, float(ch.D[j]), out.arc + h * j)
        out.steps += used
        out.arc += h * used
        self.hist = [*self.hist, *(Q[:, i].copy() for i in range(1, used + 1))][-3:]
        self.q, self.t, self.det = Q[:, used].copy(), ch.T[:, used].copy(), float(ch.D[used])

    def jump_to(self, replaced: tuple) -> None:
        """Take the point that replaces a segment's end (a step over a bifurcation)."""
        _j, q_new, t_new, det_new = replaced
        self.moved_to(q_new, t_new, det_new, weighted_distance(self.ctx.weight, q_new, self.q))

    def moved_to(self, q_new, t_new, det_new: float, length: float) -> None:
        """Take a point ``length`` away that is not a predictor's sample (a step over)."""
        self.q, self.t, self.det = q_new, t_new, det_new
        self.hist = [*self.hist[-2:], self.q.copy()]
        self.out.arc += length
        self.out.steps += 1
        self.skip_level_at_start = False
        if self.ctx.options.record:
            self.rec.add(self.q, self.c, self.det, self.out.arc)

    def recentre(self) -> None:
        """A new orientation chart when a rotation's Rodrigues parameters grew large."""
        ctx = self.ctx
        if ctx.rots and np.max(np.abs(self.q[ctx.rot_idx])) > RECENTRE:
            y_new, self.c = ctx.model.chart.recentre(self.q[:-1], self.c)
            self.q = np.append(y_new, self.q[-1])
            self.hist = [self.q.copy()]
            self.t = np.array(ctx.kern.tangent(self.q, self.t, ctx.p, self.c)[0]).ravel()
