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
from dataclasses import dataclass
from functools import cache

import numpy as np

from ..kernels.fastcall import model_calls
from ..results import Configuration, Crossing, PathSamples, SolveResult
from .curve import Line, follow
from .kernels import follower_calls

#: Lines aimed at the singular surface before giving up.
AIMS = 12
#: Steps of the follower per aimed line.
AIM_STEPS = 2000
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


@cache
def _tilt(size: int) -> np.ndarray:
    """The fixed random direction of the aims (the seeded draw, drawn once; read-only)."""
    tilt = np.random.default_rng(TILT_SEED).normal(size=size)
    tilt.setflags(write=False)
    return tilt


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
    if first is not None and np.any(first):
        line = Line(np.array(start.theta, dtype=float), np.asarray(first, float))
        walk = follow(model, line, start.y, 0.0, sign0, predictor=predictor, backend=backend,
                      levels=(0.0, 1.0), max_hits=1, record=record,
                      max_steps=AIM_STEPS)  # fmt: skip
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
        walk = follow(model, line, cur.y, 0.0, det_sign(model, cur), predictor=predictor,
                      backend=backend, levels=(0.0, 1.0), max_hits=1,
                      max_steps=AIM_STEPS)  # fmt: skip
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
        for ln in back:
            w = follow(model, ln, cfg.y, 1.0, -det_sign(model, cfg), predictor=predictor,
                       backend=backend, levels=(0.0,), max_hits=1)  # fmt: skip
            if not w.hits or w.hits[0].crossings:
                break  # the other sheet turns: start from where we are
            nxt = model.configuration(w.hits[0].y, ln.theta1)
            if not nxt.residual <= tol:
                break
            cfg = nxt
        return Across(cfg, crossing, aim)
    return None


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
    Gepetto's cassie_like), the descent of :func:`nearest_singular` and the aims of
    :func:`across` stay in that valley, while a mechanism's own limits (a rocker at a dead
    point) lie along single actuators.

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


def det_sign(model, cfg: Configuration | SolveResult) -> float:
    """Sign of det J_p at a configuration (or a solve result)."""
    y, c = model.chart.to_local(cfg.y)
    return 1.0 if np.linalg.det(np.array(model_calls(model).jac(y, cfg.theta, c)[0])) > 0 else -1.0


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

    Where branches cross at the point (see :func:`_branches_cross`) every branch is
    followed from it and a list of such pairs is returned.

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
    if _branches_cross(Jp, Js):
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
            walk = follow(model, line, q1[:m], float(q1[-1]), 1.0, predictor=predictor,
                          backend=backend, levels=(1.0,), max_hits=1, max_steps=LEG_STEPS,
                          max_arc=LEG_ARC * scale, tangent=np.array(t1).ravel(),
                          chart=c)  # fmt: skip
            if walk.hits:
                hit = walk.hits[0]
                found.append((hit.y, walk.singular[: hit.crossings]))
                if want is not None:
                    return found[0]
        if found:
            break
    return found or None


#: Descent iterations onto the singular surface (:func:`nearest_singular`).
DESCENT_ITERATIONS = 100
#: Longest descent step [model sizes].
MAX_STEP = 0.1


def _signed_sigma(Jp: np.ndarray, dJ: np.ndarray) -> tuple[float, np.ndarray, float]:
    """(sign(det J_p) sigma_min(J_p), its gradient over (y, theta), sigma_min / sigma_max)."""
    U, S, Vt = np.linalg.svd(Jp)
    sign = 1.0 if np.linalg.det(Jp) >= 0 else -1.0
    grad = dJ.T @ np.outer(U[:, -1], Vt[-1]).ravel(order="F")
    return sign * float(S[-1]), sign * grad, float(S[-1] / S[0])


def _signed_det(Jp: np.ndarray, dJ: np.ndarray) -> tuple[float, np.ndarray, float]:
    """(det J_p, its gradient over (y, theta), sigma_min / sigma_max); the cofactors from the
    SVD, regular on the singular manifold."""
    U, S, Vt = np.linalg.svd(Jp)
    sign = float(np.linalg.det(U) * np.linalg.det(Vt))
    others = np.array([np.prod(np.delete(S, i)) for i in range(S.size)])
    adj = sign * (Vt.T * others) @ U.T  # adj(J_p) = det(J_p) J_p^-1
    grad = dJ.T @ adj.T.ravel(order="F")
    return sign * float(np.prod(S)), grad, float(S[-1] / S[0])


def nearest_singular(model, start: Configuration, backend: str = "cvodes") -> Crossing | None:
    """A singular configuration near ``start`` on the assembled manifold (or None).

    Descends ``|f|``, ``f = sign(det J_p) sigma_min(J_p)`` (Lipschitz in ``J_p``, about linear in
    the distance to a fold), over ``z = (y, theta)`` on the manifold ``g = 0``: the
    minimum-norm Newton step of ``f`` in the tangent space (at most ``MAX_STEP`` model
    sizes), projected back by minimum-norm Gauss-Newton on ``g`` and halved until ``|f|``
    decreases. Near the surface this is Newton on ``[g; f] = 0``: quadratic convergence to a
    fold. Where the smallest singular value does not move on the manifold (e.g. Gepetto's
    5-bar closed by a 6d weld: 0.126 everywhere near home, while another one vanishes at the
    five-bar's singularity) that descent stops short, and it is repeated with ``f = det J_p``,
    which every vanishing singular value drives to zero.

    Args:
        model: the model.
        start: assembled, non-singular start.
        backend: kernel backend.

    Returns:
        The singular configuration as a ``Crossing`` (``s = 0``; kind "bifurcation" where
        branches cross there, else "fold"), or None when the descent stopped at a non-singular
        point.
    """
    kern = follower_calls(model, backend)
    m = model.m
    y, c = model.chart.to_local(start.y)
    tol = float(model.tolerance)
    cap = MAX_STEP * max(1.0, float(model.length_scale))
    z = np.concatenate([y, np.array(start.theta, dtype=float)])

    def evaluate(z):
        g, Jp, Js, dJ = (np.array(a) for a in kern.singular(z[:m], z[m:], c))
        return g.ravel(), Jp, Js, dJ

    def project(z):
        for _ in range(12):
            g, Jp, Js, _ = evaluate(z)
            if not (np.all(np.isfinite(g)) and np.all(np.isfinite(Jp))):
                return None
            if float(np.max(np.abs(g))) <= 1e-3 * tol:
                return z
            z = z - np.linalg.lstsq(np.hstack([Jp, -Js]), g, rcond=None)[0]
        return z if float(np.max(np.abs(evaluate(z)[0]))) <= 0.1 * tol else None

    def descend(z, objective):
        _g, Jp, Js, dJ = evaluate(z)
        f, grad, rel = objective(Jp, dJ)
        for _ in range(DESCENT_ITERATIONS):
            if rel <= 1e-13:
                break
            G = np.hstack([Jp, -Js])
            gt = grad - G.T @ np.linalg.lstsq(G @ G.T, G @ grad, rcond=None)[0]
            n2 = float(gt @ gt)
            if not n2 > 0:
                return None
            dz = -(f / n2) * gt
            size = float(np.linalg.norm(dz))
            if size > cap:
                dz *= cap / size
            for _halving in range(12):
                z_new = project(z + dz)
                if z_new is not None:
                    _g, Jp_n, Js_n, dJ_n = evaluate(z_new)
                    f_n, grad_n, rel_n = objective(Jp_n, dJ_n)
                    if abs(f_n) < abs(f):
                        break
                dz *= 0.5
            else:
                break
            z, Jp, Js, f, grad, rel = z_new, Jp_n, Js_n, f_n, grad_n, rel_n
        return (z, Jp, Js) if rel <= 1e-9 else None

    found = descend(z, _signed_sigma) or descend(z, _signed_det)
    if found is None:
        return None
    z, Jp, Js = found
    cfg = model.configuration(z[:m], z[m:], c)
    if not cfg.residual <= tol:
        return None
    kind = "bifurcation" if _branches_cross(Jp, Js) else "fold"
    return Crossing(0.0, cfg.x, cfg.y, cfg.theta, kind=kind)


#: Gauss-Newton iterations of :func:`singular_from`.
SINGULAR_ITERATIONS = 30


def singular_from(model, seed: Configuration, backend: str = "cvodes") -> Crossing | None:
    """A singular configuration reached from ``seed`` by Gauss-Newton on ``[g; f] = 0``.

    ``f = sign(det J_p) sigma_min(J_p)``; minimum-norm steps over ``z = (y, theta)``, so the
    point found is near ``seed`` where the singular manifold passes near it, and may be far
    where it does not. ``seed`` need not be assembled: the midpoint of two mirror assemblies
    (the Delta's above and below its base) lies on the singular surface of their closure
    rows without closing them. The fallback of :func:`nearest_singular` where ``sigma_min``
    has a non-singular local minimum on the manifold (the Delta at home).

    Args:
        model: the model.
        seed: first guess (``y``, ``theta``; not necessarily assembled).
        backend: kernel backend.

    Returns:
        The singular configuration as a ``Crossing`` (``s = 0``; kind as in
        :func:`nearest_singular`), or None when Gauss-Newton did not converge.
    """
    kern = follower_calls(model, backend)
    m = model.m
    tol = float(model.tolerance)
    y, c = model.chart.to_local(seed.y)
    z = np.concatenate([y, np.array(seed.theta, dtype=float)])
    for _ in range(SINGULAR_ITERATIONS):
        g, Jp, Js, dJ = (np.array(a) for a in kern.singular(z[:m], z[m:], c))
        g = g.ravel()
        if not (np.all(np.isfinite(g)) and np.all(np.isfinite(Jp))):
            return None
        f, grad, rel = _signed_sigma(Jp, dJ)
        if float(np.max(np.abs(g))) <= 1e-3 * tol and rel <= 1e-9:
            cfg = model.configuration(z[:m], z[m:], c)
            if not cfg.residual <= tol:
                return None
            kind = "bifurcation" if _branches_cross(Jp, Js) else "fold"
            return Crossing(0.0, cfg.x, cfg.y, cfg.theta, kind=kind)
        A = np.vstack([np.hstack([Jp, -Js]), grad[None]])
        z = z - np.linalg.lstsq(A, np.concatenate([g, [f]]), rcond=None)[0]
    return None


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
    from .geometry import difference

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
                          any_sign=_branches_cross(Jp, Js), exclude=exclude)  # fmt: skip


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
    from .geometry import features

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


def _branches_cross(Jp: np.ndarray, Js: np.ndarray) -> bool:
    """``[J_p, -J_s d]`` drops rank for every ``d``: a left null vector of ``J_p`` is also one
    of ``J_s`` (the singularity does not depend on the actuators: branches cross there)."""
    U, S, _ = np.linalg.svd(Jp)
    w = U[:, -1]
    return bool(np.linalg.norm(w @ Js) <= 1e-6 * max(float(np.linalg.norm(Js)), 1e-300))


#: A fold is grazed when the line meets the singular surface at less than this sine of the
#: angle between the line and the surface's tangent plane (in theta).
GRAZING = 0.05


def inward_normal(model, fold: Crossing, backend: str = "cvodes") -> np.ndarray | None:
    """Unit normal of the singular surface at a fold, in theta, towards the side where the two
    solutions meeting there exist (None where branches cross or the fold is degenerate).

    About the fold ``(y_f, theta_f)`` (``J_p u = 0``, ``w^T J_p = 0``) the solutions at
    ``theta_f + d`` are ``y_f + a u + ...`` with ``a^2 = 2 w^T J_s d / q``,
    ``q = w^T (dJ_p/dy . u) u``: two real ones where ``sign(q) w^T J_s d > 0``.

    Args:
        model: the model.
        fold: a fold (a located crossing).
        backend: kernel backend.

    Returns:
        (k,) unit vector [rad or model length unit, normalised], or None.
    """
    kern = follower_calls(model, backend)
    m = model.m
    y, c = model.chart.to_local(fold.y)
    _g, Jp, Js, dJ = (np.array(a) for a in kern.singular(y, np.asarray(fold.theta, float), c))
    U, S, Vt = np.linalg.svd(Jp)
    w, u = U[:, -1], Vt[-1]
    n = Js.T @ w
    q = float(w @ (dJ[:, :m] @ u).reshape(m, m, order="F") @ u)
    size = float(np.linalg.norm(n))
    if not (size > 1e-6 * max(float(np.linalg.norm(Js)), 1e-300) and abs(q) > 0):
        return None
    return math.copysign(1.0, q) * n / size


def grazes(model, fold: Crossing, dtheta: np.ndarray) -> bool:
    """Whether the line along ``dtheta`` meets the singular surface at ``fold`` nearly
    tangentially (sine of the angle below ``GRAZING``): there it leaves the start's side only
    briefly, and where it goes after the fold depends on a tiny bend of the line."""
    y, c = model.chart.to_local(fold.y)
    Jp, Js = (np.array(a) for a in model_calls(model).jac(y, fold.theta, c))
    n = Js.T @ np.linalg.svd(Jp)[0][:, -1]
    size = float(np.linalg.norm(n)) * float(np.linalg.norm(dtheta))
    return bool(size > 0 and abs(float(n @ dtheta)) < GRAZING * size)
