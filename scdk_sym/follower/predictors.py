"""The predictors of the curve follower: what produces the samples of a walk.

- ``"rk4"``: ``STEPS`` explicit steps of arc length ``h`` per call (RK4 along the tangent field,
  Newton corrections on the plane normal to the tangent), accepted one by one;
- ``"cvodes"``: CasADi's CVODES integrating the stabilised SC ODE over ``GRID`` samples of arc
  length ``h`` (:mod:`scdk_sym.follower.cvodes`), accepted as a whole; the explicit steps take
  over where it fails.

Both return a :class:`Chunk`, judged by the same rules (:mod:`scdk_sym.follower.events`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..interrupts import check
from .context import WalkContext
from .cvodes import GAIN, GRID, Engine, engine
from .follow_rule import (
    CHART_LIMIT,
    MAX_PREDICTOR_ERROR,
    MIN_COS,
    NEWTON_TOL,
    SMOOTH_CORRECTION,
    SMOOTH_COS,
)
from .tangent import dets

#: A CVODES chunk is accepted when its end tangent is within acos(CHUNK_COS) of its start's.
CHUNK_COS = 0.8
#: Rejections after which a walk on CVODES continues on the explicit predictor.
CVODES_REJECTIONS = 16
#: Calls of the explicit predictor after a CVODES chunk it had to take over.
BACKUP_CALLS = 4


@dataclass
class Chunk:
    """The samples of one predictor call.

    Attributes:
        Q: (m+1, n+1) samples ``q = (y local, s)``, the first the current point.
        T: (m+1, n+1) unit tangents.
        D: (n+1,) ``det J_p``.
        ok: accepted steps (leading).
        smooth: every accepted step well inside the tolerances: the step may grow.
        partial: some steps of the call were rejected.
    """

    Q: np.ndarray
    T: np.ndarray
    D: np.ndarray
    ok: int
    smooth: bool
    partial: bool = False


class Predictor(Protocol):
    """A source of samples: one call from the current point with step ``h``."""

    def advance(self, q, t, h: float, c, det: float) -> Chunk:
        """The samples from ``q`` (unit tangent ``t``, chart ``c``, ``det J_p`` ``det``)."""
        ...


class ExplicitSteps:
    """Explicit predictor-corrector steps (:class:`~scdk_sym.follower.calls.FollowerKernels`)."""

    def __init__(self, ctx: WalkContext, min_cos: float = MIN_COS) -> None:
        self.model, self.kern, self.p, self.scale = ctx.model, ctx.kern, ctx.p, ctx.scale
        self.min_cos = min_cos
        self.m = ctx.m
        self.rot_idx = ctx.rot_idx

    def advance(self, q, t, h: float, c, det: float) -> Chunk:
        m = self.m
        X, info, J = (np.array(a) for a in self.kern.steps(np.concatenate([q, t]), h, self.p, c))
        good = (
            np.all(np.isfinite(X), axis=0)
            & (info[0] <= MAX_PREDICTOR_ERROR * h)
            & (info[1] <= NEWTON_TOL * self.scale)
            & (info[2] >= self.min_cos)
        )
        if self.rot_idx:
            good &= np.max(np.abs(X[self.rot_idx]), axis=0) <= CHART_LIMIT
        n_ok = int(np.argmin(good)) if not good.all() else good.size
        Q = np.hstack([q[:, None], X[: m + 1, :n_ok]])
        T = np.hstack([t[:, None], X[m + 1 :, :n_ok]])
        D = np.concatenate([[det], dets(J[:, :n_ok], m)])
        smooth = bool(
            n_ok == good.size
            and info[0].max() < SMOOTH_CORRECTION * h
            and info[2].min() > SMOOTH_COS
        )
        return Chunk(Q, T, D, n_ok, smooth, n_ok < good.size)


class CvodesChunks:
    """CVODES chunks of the stabilised SC field (:mod:`scdk_sym.follower.cvodes`)."""

    def __init__(self, ctx: WalkContext, eng: Engine) -> None:
        self.model, self.eng, self.line, self.w, self.gain = ctx.model, eng, ctx.line, ctx.w, GAIN
        self.m = ctx.m
        self.rot_idx = ctx.rot_idx

    def advance(self, q, t, h: float, c, det: float) -> Chunk:
        m = self.m
        p = np.concatenate([self.line.theta1, self.line.dtheta, t, [GRID * h, self.gain]])
        try:
            X = self.eng.integrate(q, np.concatenate([p, c]))
        except RuntimeError:
            check()  # CasADi reports an interrupt as a RuntimeError: not a failed chunk
            X = np.full((m + 1, GRID), np.nan)
        Q = np.hstack([q[:, None], X])
        bad = Chunk(Q[:, :1], t[:, None], np.array([det]), 0, False)
        if not np.all(np.isfinite(Q)):
            return bad
        if self.rot_idx and np.max(np.abs(Q[self.rot_idx])) > CHART_LIMIT:
            return bad
        T, Jv, _ = self.eng.probe_samples(Q, p, c)
        te = T[:, -1]
        cosine = float(te[:-1] @ t[:-1] + self.w**2 * te[-1] * t[-1])
        if not cosine >= CHUNK_COS:
            return bad
        D = np.concatenate([[det], dets(Jv[:, 1:], m)])
        T[:, 0] = t
        return Chunk(Q, T, D, GRID, cosine > 0.995)


@dataclass(frozen=True)
class Predictors:
    """The predictors of one walk.

    Attributes:
        main: the predictor called first.
        backup: the explicit steps that take over where ``main`` fails (None: ``main`` is
            the explicit one).
        h_max: the longest step [model length unit].
    """

    main: Predictor
    backup: ExplicitSteps | None
    h_max: float


class ExplicitChoice:
    """``"rk4"``: explicit steps alone, up to half a model size long."""

    name = "rk4"

    def predictors(self, ctx: WalkContext, explicit: ExplicitSteps, ell0: float) -> Predictors:
        """The predictors of a walk on ``ctx`` (``ell0``: arc per unit ``s`` at the start)."""
        return Predictors(explicit, None, 0.5 * ctx.scale)


class CvodesChoice:
    """``"cvodes"``: CVODES chunks of at most two arcs per unit ``s``, the explicit steps as
    their backup."""

    name = "cvodes"

    def predictors(self, ctx: WalkContext, explicit: ExplicitSteps, ell0: float) -> Predictors:
        """The predictors of a walk on ``ctx`` (``ell0``: arc per unit ``s`` at the start)."""
        main = CvodesChunks(ctx, engine(ctx.model, ctx.options.backend))
        return Predictors(main, explicit, 2.0 * ell0 / GRID)


class PredictorChoice(Protocol):
    """A predictor :func:`~scdk_sym.follower.curve.follow` offers, by its name."""

    name: str

    def predictors(self, ctx: WalkContext, explicit: ExplicitSteps, ell0: float) -> Predictors:
        """The predictors of a walk on ``ctx`` (``ell0``: arc per unit ``s`` at the start)."""
        ...


#: The predictors offered, by name.
PREDICTORS: tuple[PredictorChoice, ...] = (ExplicitChoice(), CvodesChoice())


def predictor_named(name: str) -> PredictorChoice | None:
    """The offered predictor called ``name`` (None if there is none)."""
    return next((choice for choice in PREDICTORS if choice.name == name), None)
