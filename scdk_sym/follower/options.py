"""How a walk is made: the predictor, the kernels, what it reports and when it stops."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .follow_rule import MIN_COS


@dataclass(frozen=True)
class FollowOptions:
    """The tuning of :func:`~scdk_sym.follower.curve.follow` (every field has its default).

    Attributes:
        predictor: "rk4" (explicit predictor-corrector) or "cvodes" (the SC ODE by CVODES).
        backend: kernels, "cvodes" (SX) or "compiled" (generated C); see
            :mod:`scdk_sym.backends`.
        levels: levels of ``s`` whose crossings are reported (and finished at
            ``line.at(level)``).
        max_hits: stop after this many level crossings.
        max_singular: stop after this many singular points (folds and bifurcations).
        max_arc: arc-length budget [model length unit] (default: 60 arc lengths per unit of
            ``s`` at the start plus 20 model sizes).
        max_steps: stop after this many accepted steps.
        deadline: ``time.perf_counter()`` value at which to stop [s].
        step: initial arc length per step [model length unit] (default: a sixteenth of the
            arc per unit ``s``, at most ``FIRST_STEP`` model sizes).
        record: keep the sampled curve in ``walk.path``.
        stop_when_closed: stop when the curve comes back to its start.
        locate: locate folds by Newton (else: interpolated between the samples, their ``x``
            not computed, for searches that only count them).
        min_cos: an explicit step is accepted only if the tangent turned by less than
            ``acos(min_cos)`` (small turns keep two nearby crossing branches apart; a search
            that only collects solutions may take larger ones).
    """

    predictor: str = "rk4"
    backend: str = "cvodes"
    levels: tuple[float, ...] = (1.0,)
    max_hits: int | float = math.inf
    max_singular: int | float = math.inf
    max_arc: float | None = None
    max_steps: int = 20000
    deadline: float = math.inf
    step: float | None = None
    record: bool = False
    stop_when_closed: bool = True
    locate: bool = True
    min_cos: float = MIN_COS
