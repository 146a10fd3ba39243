"""The singular surface at a point: the side a configuration is on (the sign of ``det J_p``),
whether branches cross there, the surface's normal at a fold and a line grazing it."""

from __future__ import annotations

import math

import numpy as np

from ..kernels.fastcall import model_calls
from ..results import Configuration, Crossing, SolveResult
from .calls import follower_calls


def det_jp(model, cfg: Configuration | SolveResult) -> float:
    """``det J_p`` at a configuration (or a solve result), in the chart centred on it."""
    y, c = model.chart.to_local(cfg.y)
    return float(np.linalg.det(np.array(model_calls(model).jac(y, cfg.theta, c)[0])))


def det_sign(model, cfg: Configuration | SolveResult) -> float:
    """Sign of det J_p at a configuration (or a solve result)."""
    return 1.0 if det_jp(model, cfg) > 0 else -1.0


def branches_cross(Jp: np.ndarray, Js: np.ndarray) -> bool:
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
