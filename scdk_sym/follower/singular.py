"""Crossing the nearest singular surface: the divergent branch of the SC method.

The divergent branch is "the solution across the singular surface". The paper's straight line
from the start's ``theta`` to ``theta0`` reaches that surface only if the line happens to cross
it: near a tangency, or with revolute actuators whose line wraps around, it never folds. So
:func:`across` heads for the surface instead: from the start it follows, with the one curve
follower, the line in joint space along which ``|det J_p|`` decreases fastest on the start's
sheet (``d det / d theta`` with ``dy / d theta = J_p^{-1} J_s``), re-aimed from where each line
ends, until the curve turns (a fold) or passes a bifurcation; the curve continued through it
comes back on the other sheet to the line's start, the mirror configuration, from which a
convergent solve reaches ``theta0`` (the paper allows any parameterisation that is transversal
at the singularity).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..results import Configuration, Crossing, PathSamples
from .calls import follower_calls
from .curve import follow
from .options import FollowOptions
from .surface import det_sign
from .walk import Line

#: Lines aimed at the singular surface before giving up.
AIMS = 12
#: Steps of the follower per aimed line.
AIM_STEPS = 2000
#: Relative tilt of each aim (a fixed random direction, see :func:`_descent`).
TILT = 0.05
TILT_SEED = 20240501


@dataclass(frozen=True)
class Across:
    """The other side of the nearest singular surface.

    Attributes:
        start: assembled configuration on the other side (``det J_p`` of the opposite sign to
            the start's).
        crossing: the singular point crossed (``s`` on the line it was met on).
        aims: lines aimed at the surface (0: the ``first`` line was taken).
        path: the sampled curve of the ``first`` line, when taken and recorded.
    """

    start: Configuration
    crossing: Crossing
    aims: int
    path: PathSamples | None = None


def _descent(model, kern, y_loc, theta, c) -> tuple[np.ndarray, float, float]:
    """(unit direction of theta along which the smallest singular value of J_p decreases
    fastest on the start's sheet, det J_p, estimated distance to the singular surface along it
    [rad or model length unit])."""
    m = model.m
    _g, Jp, Js, dJ = (np.array(a) for a in kern.singular(y_loc, theta, c))
    det = float(np.linalg.det(Jp))
    U, S, Vt = np.linalg.svd(Jp)
    grad = dJ.T @ np.outer(U[:, -1], Vt[-1]).ravel(order="F")  # d sigma_min / d(y, theta)
    g_theta = grad[m:] + grad[:m] @ np.linalg.solve(Jp, Js)
    # a symmetric robot aimed along a symmetric line meets pitchforks (two branches crossing)
    # where a generic line meets folds: tilt the aim by a fixed small random direction
    tilt = _tilt(g_theta.size)
    g_theta = g_theta + TILT * float(np.linalg.norm(g_theta)) * tilt / np.linalg.norm(tilt)
    n = float(np.linalg.norm(g_theta))
    if not (n > 0 and math.isfinite(n)):
        return np.zeros_like(theta), det, math.inf
    return -g_theta / n, det, float(S[-1]) / n


def _tilt(size: int) -> np.ndarray:
    """The fixed random direction of the aims (the seeded draw: the same at every call)."""
    return np.random.default_rng(TILT_SEED).normal(size=size)


def across(
    model,
    start: Configuration,
    *,
    first: np.ndarray | None = None,
    backend: str = "cvodes",
    predictor: str = "rk4",
    record: bool = False,
    paper_only: bool = False,
) -> Across | None:
    """Cross the singular surface nearest to ``start`` (see the module documentation).

    Args:
        model: the model.
        start: assembled, non-singular start.
        first: (k,) a line to try first, ``start.theta + s first`` for s in [0, 1] (the
            paper's divergent direction, away from ``theta0``): taken when the curve turns on
            it and comes back to ``start.theta`` on the other sheet (then the result is the
            paper's divergent path exactly).
        backend: kernel backend.
        predictor: predictor of the curve follower.
        record: keep the sampled curve of the ``first`` line.
        paper_only: try the ``first`` line only.

    Returns:
        The configuration across it, or None when no singular surface was reached.
    """
    kern = follower_calls(model, backend)
    tol = float(model.tolerance)
    scale = max(1.0, float(model.length_scale))
    y_loc, c = model.chart.to_local(start.y)
    if paper_only:  # no aim: det J_p as _descent evaluates it
        det0 = float(np.linalg.det(kern.singular(y_loc, start.theta, c)[1]))
    else:
        d, det0, reach = _descent(model, kern, y_loc, np.array(start.theta, dtype=float), c)
    sign0 = math.copysign(1.0, det0)
    aiming = FollowOptions(
        predictor=predictor, backend=backend, levels=(0.0, 1.0), max_hits=1, max_steps=AIM_STEPS
    )
    if first is not None and np.any(first):
        line = Line(np.array(start.theta, dtype=float), np.asarray(first, float))
        walk = follow(model, line, start.y, 0.0, sign0, replace(aiming, record=record))
        if walk.hits and walk.hits[0].level == 0.0 and walk.hits[0].crossings:
            hit = walk.hits[0]
            cfg = model.configuration(hit.y, start.theta)
            if cfg.residual <= tol and det_sign(model, cfg) * sign0 < 0:
                return Across(cfg, walk.singular[hit.crossings - 1], 0, walk.path)
    if paper_only:
        return None
    cur = start
    lines: list[Line] = []
    for aim in range(1, AIMS + 1):
        if not np.any(d):
            return None
        length = min(max(2.0 * reach, 1e-3 * scale), 2.0 * scale)
        line = Line(np.array(cur.theta, dtype=float), length * d)
        lines.append(line)
        walk = follow(model, line, cur.y, 0.0, det_sign(model, cur), aiming)
        if not walk.hits:
            return None
        hit = walk.hits[0]
        cfg = model.configuration(hit.y, line.at(hit.level))
        if not cfg.residual <= tol:
            return None
        if hit.crossings == 0:
            if hit.level != 1.0:
                return None
            cur = cfg  # the line ended short of the surface: aim again from its end
            yh, ch = model.chart.to_local(cfg.y)
            d, _det, reach = _descent(model, kern, yh, cfg.theta, ch)
            continue
        if det_sign(model, cfg) * sign0 > 0:
            return None  # crossed back: not the other side
        crossing = walk.singular[hit.crossings - 1]
        # come back on the other sheet along the lines followed, to the start's theta
        back = [] if hit.level == 0.0 else [line]
        back += lines[-2::-1]
        returning = FollowOptions(predictor=predictor, backend=backend, levels=(0.0,), max_hits=1)
        return Across(_back_along(model, cfg, back, returning), crossing, aim)
    return None


def _back_along(
    model, cfg: Configuration, back: list[Line], options: FollowOptions
) -> Configuration:
    """From ``cfg`` at ``s = 1`` of the first of ``back``, on its sheet, to ``s = 0`` of each
    line in turn: the configuration at the start of the last line reached (``cfg`` itself
    where the sheet turns on the first)."""
    tol = float(model.tolerance)
    for ln in back:
        w = follow(model, ln, cfg.y, 1.0, -det_sign(model, cfg), options)
        if not w.hits or w.hits[0].crossings:
            break  # the other sheet turns: start from where we are
        nxt = model.configuration(w.hits[0].y, ln.theta1)
        if not nxt.residual <= tol:
            break
        cfg = nxt
    return cfg


#: Length of the lines of :func:`across_axes`: one turn on a revolute actuator, this many
#: model sizes on a prismatic one.
AXIS_REACH = 2.0


def across_axes(model, start: Configuration, backend: str = "cvodes") -> Across | None:
    """Cross the singular surface met nearest to ``start`` on lines along each actuator's
    own axis: for each actuator, both ways, ``start.theta + s d`` with ``d`` one turn (a
    revolute actuator, [rad]) or :data:`AXIS_REACH` model sizes (a prismatic one) along
    it, taken where the curve turns on the line and comes back to ``start.theta`` on the
    other sheet (as the ``first`` line of :func:`across`); of those, the one whose singular
    point is the fewest actuator units away.

    Where ``sigma_min`` has a non-singular valley around the start (a ball joint written as
    three revolutes next to the alignment of its first and last axes: the valley of
    Gepetto's cassie_like), the descent of
    :func:`~scdk_sym.follower.nearest.nearest_singular` and the aims of :func:`across` stay
    in that valley, while a mechanism's own limits (a rocker at a dead point) lie along
    single actuators.

    Returns:
        The configuration across it (``aims`` 0), or None when no line folds back.
    """
    units = model.units
    scale = max(1.0, float(model.length_scale))
    best: tuple[float, Across] | None = None
    for i, name in enumerate(model.actuated):
        span = 2.0 * math.pi if units[name] == "rad" else AXIS_REACH * scale
        for sign in (1.0, -1.0):
            d = np.zeros(model.k)
            d[i] = sign * span
            other = across(model, start, first=d, backend=backend, paper_only=True)
            if other is None:
                continue
            reach = abs(float(other.crossing.theta[i] - start.theta[i])) / span
            if best is None or reach < best[0]:
                best = (reach, other)
    return None if best is None else best[1]
