"""The solution at ``theta0`` on the other side of a singular point: followed from the fold
on the other sheet, or reached by Newton from the fold's mirror points, the nearest one kept."""

from __future__ import annotations

import math

import numpy as np

from ..kernels.fastcall import model_calls
from ..results import Configuration, Crossing
from .calls import follower_calls
from .curve import follow
from .geometry import difference, features
from .options import FollowOptions
from .surface import branches_cross, det_sign
from .walk import Line

#: Steps and arc length [model sizes] of the follower from a singular point to theta0.
LEG_STEPS = 400
LEG_ARC = 10.0
#: Mirror points tried by Newton: multiples of the distance from the start to the fold, and
#: fixed distances [model sizes], beyond the fold along the null vector of J_p.
REFLECTIONS = (1.0, 2.0, 4.0)
RADII = (1e-3, 3e-3, 1e-2, 3e-2, 0.1)
#: More polishes of a reflected guess whose residual is still falling (Newton from a point
#: far from the solution takes more than one polish's steps to reach the tolerance).
POLISH_AGAIN = 3

#: Cosine above which two points a step off a singular configuration lie on one half-branch
#: (their chords from it agree to 0.8 degrees; distinct branches cross at larger angles).
SAME_HALF_BRANCH = 0.9999

#: ``sigma_min / sigma_max`` of ``J_p`` below which a point a step off a singular
#: configuration is still singular (the singular set extends along the step at fixed
#: ``theta``, e.g. a five-bar with its two elbows on one point): no sheet to enter there.
DEGENERATE = 1e-10


def from_fold(
    model,
    fold: Crossing,
    theta0: np.ndarray,
    sign0: float,
    *,
    backend: str = "cvodes",
    predictor: str = "rk4",
) -> tuple[np.ndarray, list[Crossing]] | list | None:
    """From a fold, on the other sheet, along the line from its ``theta`` to ``theta0``.

    At the fold ``(y*, theta*)`` the line ``theta* + s (theta0 - theta*)`` has a curve through
    ``(y*, 0)`` with two directions; the one entering the sheet where ``det J_p`` has the sign
    opposite to ``sign0`` is followed to ``s = 1``.

    Args:
        model: the model.
        fold: the fold (a crossing located by the follower).
        theta0: (k,) target.
        sign0: sign of ``det J_p`` on the start's side.
        backend: kernel backend.
        predictor: predictor of the curve follower.

    Where branches cross at the point (see
    :func:`~scdk_sym.follower.surface.branches_cross`) every branch is followed from it and a
    list of such pairs is returned.

    Returns:
        (canonical unknowns at ``theta0``, singular points met after the fold), or None.
    """
    kern = follower_calls(model, backend)
    m = model.m
    tol = float(model.tolerance)
    theta_f = np.asarray(fold.theta, float)
    dtheta = np.asarray(theta0, float) - theta_f
    if not float(np.linalg.norm(dtheta)) > 0:
        return None
    line = Line(theta_f, dtheta)
    p = np.concatenate([theta_f, dtheta])
    y_loc, c = model.chart.to_local(fold.y)
    q_f = np.append(y_loc, 0.0)
    Jp, Js = (np.array(a) for a in model_calls(model).jac(y_loc, theta_f, c))
    H = np.hstack([Jp, -(Js @ dtheta)[:, None]])
    _, S, Vt = np.linalg.svd(H)
    w2 = float(dtheta @ dtheta)
    if branches_cross(Jp, Js):
        # two branches through the point: directions all round the 2-d null space of H
        N = Vt[-2:]
        directions = [np.cos(a) * N[0] + np.sin(a) * N[1] for a in np.arange(8) * np.pi / 4]
        want = None
    else:
        directions = [Vt[-1], -Vt[-1]]
        want = -sign0
    scale = max(1.0, float(model.length_scale))
    found: list[tuple[np.ndarray, list[Crossing]]] = []
    for length in (1e-4 * scale, 1e-3 * scale, 1e-5 * scale):
        entered: list[np.ndarray] = []  # unit chords fold -> q1 of the half-branches followed
        for t in directions:
            v = t / math.sqrt(float(t[:m] @ t[:m]) + w2 * t[m] ** 2)
            q1, res = kern.plane(q_f + length * v, v, p, c)
            q1 = np.array(q1).ravel()
            if not (np.all(np.isfinite(q1)) and float(res) <= 0.1 * tol):
                continue
            chord = (q1 - q_f) / max(float(np.linalg.norm(q1 - q_f)), 1e-300)
            if any(float(chord @ e) > SAME_HALF_BRANCH for e in entered):
                continue  # projected onto a half-branch already followed: the same walk
            entered.append(chord)
            t1, J1 = kern.tangent(q1, v, p, c)
            J1 = np.array(J1).reshape(m, m, order="F")
            S1 = np.linalg.svd(J1, compute_uv=False)
            if not S1[-1] > DEGENERATE * S1[0]:
                continue  # still singular off the point: a self-motion, not a sheet to enter
            det1 = np.linalg.det(J1)
            if want is not None and not det1 * want > 0:
                continue
            options = FollowOptions(
                predictor=predictor,
                backend=backend,
                levels=(1.0,),
                max_hits=1,
                max_steps=LEG_STEPS,
                max_arc=LEG_ARC * scale,
            )
            walk = follow(model, line, q1[:m], float(q1[-1]), 1.0, options,
                          tangent=np.array(t1).ravel(), chart=c)  # fmt: skip
            if walk.hits:
                hit = walk.hits[0]
                found.append((hit.y, walk.singular[: hit.crossings]))
                if want is not None:
                    return found[0]
        if found:
            break
    return found or None


def across_fold(
    model,
    start: Configuration,
    fold: Crossing,
    theta0: np.ndarray,
    *,
    exclude: Configuration | None = None,
    backend: str = "cvodes",
    predictor: str = "rk4",
) -> tuple[Configuration, list[Crossing]] | None:
    """The solution at ``theta0`` on the other side of ``fold``, nearest to it.

    Where two branches cross at the singular configuration (``[J_p, -J_s dtheta]`` drops rank
    for every ``dtheta``, e.g. a parallelogram passing flat), ``det J_p`` changes sign along
    each branch and tells nothing of the side: there the other side is any solution other
    than ``exclude`` (the convergent answer).

    Candidates, each verified (residual) and kept only if ``det J_p`` has the sign opposite to
    the start's: the end of the curve from the fold to ``theta0`` on the other sheet
    (:func:`from_fold`), and Newton at ``theta0`` from points beyond the fold along the null
    vector of ``J_p`` there (near a fold the two sheets are mirror images along it to first
    order; distances ``REFLECTIONS`` times the start's and ``RADII`` model sizes). The one
    nearest to the fold (chart-free features) is returned with the singular points met on
    its way.

    Args:
        model: the model.
        start: the start (non-singular).
        fold: a singular configuration near it.
        theta0: (k,) target.
        backend: kernel backend.
        predictor: predictor of the curve follower.

    Returns:
        (configuration at ``theta0``, singular points met after the fold) or None.
    """
    kern = follower_calls(model, backend)
    sign0 = det_sign(model, start)
    candidates: list[tuple[np.ndarray, list[Crossing]]] = []
    leg = from_fold(model, fold, theta0, sign0, backend=backend, predictor=predictor)
    if isinstance(leg, list):
        candidates.extend(leg)
    elif leg is not None:
        candidates.append(leg)
    y_f, c = model.chart.to_local(fold.y)
    Jp, Js = (np.array(a) for a in model_calls(model).jac(y_f, fold.theta, c))
    # to first order about the fold the configurations over theta are
    # y_f + J_p^+ J_s (theta - theta_f) + t u (u: null vector of J_p), the two sheets having
    # opposite signs of t: Newton at theta0 from points on the other sheet's side, at multiples
    # of the start's |t| and at fixed distances
    u = np.linalg.svd(Jp)[2][-1]
    Jp_pinv = np.linalg.pinv(Jp, rcond=1e-10)
    d = difference(model, start.y, fold.y) - Jp_pinv @ Js @ (start.theta - fold.theta)
    t_s = float(u @ d)
    base = y_f + Jp_pinv @ Js @ (np.asarray(theta0, float) - fold.theta)
    scale = max(1.0, float(model.length_scale))
    radii = [a * abs(t_s) for a in REFLECTIONS if a * abs(t_s) > 0] + [r * scale for r in RADII]
    signs = (-1.0, 1.0) if t_s == 0 else (-math.copysign(1.0, t_s),)
    tol = float(model.tolerance)
    for sgn in signs:
        for r in radii:
            y, res = kern.polish(base + sgn * r * u, theta0, c)
            for _ in range(POLISH_AGAIN):  # from afar Newton may still be converging
                if not 0.1 * tol < float(res) < 1.0:
                    break
                y, res = kern.polish(np.array(y).ravel(), theta0, c)
            y = np.array(y).ravel()
            if np.all(np.isfinite(y)) and float(np.max(np.abs(y - y_f))) <= 10.0 * scale:
                candidates.append((model.chart.to_canonical(y, c), []))
    return nearest_across(model, fold.y, theta0, candidates, sign0,
                          any_sign=branches_cross(Jp, Js), exclude=exclude)  # fmt: skip


def nearest_across(
    model,
    anchor_y: np.ndarray,
    theta0: np.ndarray,
    candidates: list[tuple[np.ndarray, list[Crossing]]],
    sign0: float,
    *,
    any_sign: bool = False,
    exclude: Configuration | None = None,
) -> tuple[Configuration, list[Crossing]] | None:
    """The candidate across the singular surface nearest to ``anchor_y``: the one rule that
    picks the divergent answer, whoever proposed the candidates.

    Kept: candidates that close at ``theta0`` (residual), are not ``exclude`` (chart-free
    features within 1e-7 model sizes) and, unless ``any_sign`` (branches cross at the
    singular point: ``det J_p`` tells nothing of the side), have ``det J_p`` of the sign
    opposite to ``sign0``. Of those, the nearest to ``anchor_y`` (max-norm of the features).

    Args:
        model: the model.
        anchor_y: canonical unknowns of the singular configuration (or of the start).
        theta0: (k,) target.
        candidates: (canonical unknowns at ``theta0``, singular points met on the way).
        sign0: sign of ``det J_p`` on the start's side.
        any_sign: accept either sign.
        exclude: a configuration not to return (the convergent answer).

    Returns:
        (configuration, its singular points met) or None.
    """
    tol = float(model.tolerance)
    scale = max(1.0, float(model.length_scale))
    f_anchor = features(model, anchor_y)[0]
    f_exclude = None if exclude is None else features(model, exclude.y)[0]
    best = None
    for y, met in candidates:
        if not np.all(np.isfinite(y)):
            continue
        cfg = model.configuration(y, theta0)
        if not cfg.residual <= tol:
            continue
        f = features(model, cfg.y)[0]
        if f_exclude is not None and float(np.max(np.abs(f - f_exclude))) <= 1e-7 * scale:
            continue
        if not any_sign and det_sign(model, cfg) * sign0 > 0:
            continue
        dist = float(np.max(np.abs(f - f_anchor)))
        if best is None or dist < best[0] - 1e-9 * scale:
            best = (dist, cfg, met)
    return None if best is None else (best[1], best[2])
