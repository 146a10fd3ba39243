"""Singular points met by a walk: folds and bifurcations located between two samples, and told
apart (two branches crossing, or the line tangent to the singular surface)."""

from __future__ import annotations

import math

import numpy as np

from ..kernels.fastcall import model_calls
from ..results import Crossing
from .context import WalkContext
from .follow_rule import STRUCTURAL
from .tangent import tangent_at

#: det J_p changing sign without a turn of s is a bifurcation where H' = [J_p, -j_s] has
#: sigma_min / sigma_max below this (else the step jumped across a fold and is refined) and
#: the left null vector of J_p is one of J_s too (:data:`follow_rule.STRUCTURAL`).
BIFURCATION_RANK = 1e-3


def locate_bifurcation(ctx: WalkContext, qa, qb, c, det_a: float) -> Crossing:
    """Where ``det J_p`` vanishes between two points of one branch: bisection on points of the
    curve (the chord's points corrected on planes normal to it).

    Args:
        ctx: the walk.
        qa: (m+1,) the point before, ``(y local, s)`` in chart ``c``.
        qb: (m+1,) the point after.
        c: their chart.
        det_a: ``det J_p`` at ``qa``.
    """
    m, kern, p, weight = ctx.m, ctx.kern, ctx.p, ctx.weight
    d = qb - qa
    d = d / math.sqrt(float(weight @ (d * d)) + 1e-300)
    lo, hi = 0.0, 1.0
    best = 0.5 * (qa + qb)
    for _ in range(24):
        mid = 0.5 * (lo + hi)
        q_mid, _res = kern.plane(qa + mid * (qb - qa), d, p, c)
        q_mid = np.array(q_mid).ravel()
        if not np.all(np.isfinite(q_mid)):
            break
        best = q_mid
        _t, det_mid = tangent_at(kern, q_mid, d, p, c, m)
        if det_mid * det_a > 0:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-7:
            break
    theta = ctx.line.at(float(best[-1]))
    cfg = ctx.model.configuration(best[:m], theta, c)
    return Crossing(float(best[-1]), cfg.x, cfg.y, cfg.theta, kind="bifurcation")


def locate_fold(ctx: WalkContext, qa, qb, ta, tb, c) -> Crossing:
    """The turning point of ``s`` between two samples (Newton on ``[g; t_s] = 0`` from the
    point where the interpolated ``t_s`` vanishes; that point itself if Newton strays)."""
    m = ctx.m
    alpha = ta[-1] / (ta[-1] - tb[-1])
    q0 = qa + alpha * (qb - qa)
    q1 = np.array(ctx.kern.fold(q0, ta, ctx.p, c)).ravel()
    seg = float(np.linalg.norm(qb - qa))
    if not np.all(np.isfinite(q1)) or float(np.linalg.norm(q1 - q0)) > 2 * seg + 1e-12:
        q1 = q0
    cfg = ctx.model.configuration(q1[:m], ctx.line.at(float(q1[-1])), c)
    return Crossing(float(q1[-1]), cfg.x, cfg.y, cfg.theta, kind="fold")


def interpolated_fold(ctx: WalkContext, qa, qb, ta, tb, c) -> Crossing:
    """The turning point of ``s`` interpolated between two samples (``x`` left empty)."""
    model, m = ctx.model, ctx.m
    alpha = ta[-1] / (ta[-1] - tb[-1])
    q = qa + alpha * (qb - qa)
    theta = ctx.line.at(float(q[-1]))
    return Crossing(float(q[-1]), np.zeros(0), model.chart.to_canonical(q[:m], c), theta)


def is_bifurcation(model, cr: Crossing, dtheta: np.ndarray) -> bool:
    """Whether two solution branches cross at a singular point: H' = [J_p, -J_s dtheta /
    |dtheta|] drops rank (sigma_min / sigma_max < ``BIFURCATION_RANK``) for every line, i.e.
    the left null vector w of J_p annihilates J_s (|w^T J_s| / |J_s| < ``STRUCTURAL``).

    Where only ``w^T J_s dtheta`` vanishes the line is tangent to the singular surface: a
    fold (or two folds close together where the line grazes it), on which ``det J_p`` keeps
    the sign of the side the curve is on; stepping across would land on the other sheet.
    """
    y, c = model.chart.to_local(cr.y)
    Jp, Js = (np.array(a) for a in model_calls(model).jac(y, cr.theta, c))
    js = Js @ dtheta / max(float(np.linalg.norm(dtheta)), 1e-300)
    S = np.linalg.svd(np.hstack([Jp, -js[:, None]]), compute_uv=False)
    if not S[-1] < BIFURCATION_RANK * S[0]:
        return False
    w = np.linalg.svd(Jp)[0][:, -1]
    return bool(np.linalg.norm(w @ Js) < STRUCTURAL * max(float(np.linalg.norm(Js)), 1e-300))
