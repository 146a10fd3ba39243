"""A singular configuration near a given one on the assembled manifold: a descent of the
smallest singular value of ``J_p`` (or of ``det J_p``), or Gauss-Newton from a guess."""

from __future__ import annotations

import numpy as np

from ..results import Configuration, Crossing
from .calls import follower_calls
from .surface import branches_cross

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
    kind = "bifurcation" if branches_cross(Jp, Js) else "fold"
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
            kind = "bifurcation" if branches_cross(Jp, Js) else "fold"
            return Crossing(0.0, cfg.x, cfg.y, cfg.theta, kind=kind)
        A = np.vstack([np.hstack([Jp, -Js]), grad[None]])
        z = z - np.linalg.lstsq(A, np.concatenate([g, [f]]), rcond=None)[0]
    return None
