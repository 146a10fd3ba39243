"""The curve at one point: its oriented tangent, ``det J_p``, and distances in its metric."""

from __future__ import annotations

import math

import numpy as np


def null_direction(Jp: np.ndarray, js: np.ndarray) -> np.ndarray:
    """Unit vector along nu = [adj(J_p) j_s; det J_p] (generalised cross product of H's rows)."""
    H = np.hstack([Jp, -js[:, None]])
    _, _, Vt = np.linalg.svd(H)
    t = Vt[-1]
    if np.linalg.det(np.vstack([H, t])) < 0:
        t = -t
    return t


def dets(J: np.ndarray, m: int) -> np.ndarray:
    """det of column-major vec(J_p) columns (m*m, N) -> (N,)."""
    if J.shape[1] == 0:
        return np.zeros(0)
    return np.linalg.det(J.T.reshape(-1, m, m).transpose(0, 2, 1))


def tangent_at(kern, q, v, p, c, m: int) -> tuple[np.ndarray, float]:
    """(unit tangent at ``q`` oriented along ``v``, ``det J_p`` there) by the follower's
    ``tangent`` kernel (``p = (theta1, dtheta)``, chart ``c``, ``m`` unknowns)."""
    t, J = kern.tangent(q, v, p, c)
    return np.array(t).ravel(), float(dets(np.array(J), m)[0])


def weighted_distance(weight: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Distance of two points ``q = (y, s)`` in the metric ``|dy|^2 + (|dtheta| ds)^2``
    (``weight``: its diagonal) [model length unit]."""
    d = a - b
    return float(math.sqrt(weight @ (d * d)))
