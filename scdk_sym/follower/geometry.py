"""Chart-free comparisons of configurations: which unknowns are angles, features, differences.

Revolute angles are equal modulo 2 pi and floating rotations are compared as rotations, so
two configurations written in different charts or turns compare as the same.
"""

from __future__ import annotations

import math

import numpy as np

from ..model.rotations import cayley, gibbs, rot_exp, rot_log
from ..products import UNKNOWN_KINDS


def kinds(model) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Indices of the unknowns: (revolute angles, floating rotations, the others); cached."""

    def build() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        types = {j.name: j.type for j in model.tree.joints}
        per = [
            i for i, n in enumerate(model.unknowns) if types.get(n) in ("revolute", "continuous")
        ]
        rot = [i for idx in model.chart.rotations for i in idx]
        plain = [i for i in range(model.m) if i not in set(per) | set(rot)]
        a, b, c = (np.array(v, dtype=int) for v in (per, rot, plain))
        return a, b, c

    return model.products.get(UNKNOWN_KINDS, build)


def periodic(model) -> np.ndarray:
    """Indices of the unknowns that are angles of revolute joints (equal modulo 2 pi)."""
    return kinds(model)[0]


def features(model, Y: np.ndarray) -> np.ndarray:
    """Chart-free coordinates of canonical unknowns, for comparisons.

    Revolute angles become ``(cos, sin)``, floating rotations their rotation matrix; other
    unknowns stay. Two configurations coincide when their features do.

    Args:
        model: the model.
        Y: (N, m) canonical unknowns.

    Returns:
        (N, F) features [model length unit or 1].
    """
    Y = np.atleast_2d(np.asarray(Y, float))
    per, _, plain = kinds(model)
    parts = [Y[:, plain], np.cos(Y[:, per]), np.sin(Y[:, per])]
    for idx in model.chart.rotations:
        W = Y[:, list(idx)]
        angle = np.linalg.norm(W, axis=1)
        safe = np.where(angle < 1e-12, 1.0, angle)
        a = np.where(angle < 1e-12, 1.0, np.sin(angle) / safe)[:, None, None]
        b = np.where(angle < 1e-12, 0.5, (1 - np.cos(angle)) / safe**2)[:, None, None]
        K = np.zeros((len(W), 3, 3))
        K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -W[:, 2], W[:, 1], -W[:, 0]
        K = K - K.transpose(0, 2, 1)
        R = np.eye(3) + a * K + b * K @ K
        parts.append(R.reshape(len(W), 9))
    return np.hstack(parts)


def local_features(model, y_loc: np.ndarray, c: np.ndarray) -> np.ndarray:
    """:func:`features` of one vector of unknowns given in the local chart ``c``."""
    per, _, plain = kinds(model)
    parts = [y_loc[plain], np.cos(y_loc[per]), np.sin(y_loc[per])]
    for i, idx in enumerate(model.chart.rotations):
        R = c[9 * i : 9 * i + 9].reshape(3, 3, order="F") @ cayley(y_loc[list(idx)])
        parts.append(R.ravel())
    return np.concatenate(parts)


def difference(model, y_a: np.ndarray, y_b: np.ndarray) -> np.ndarray:
    """``y_a - y_b`` for canonical unknowns: angles wrapped to (-pi, pi], rotations of floating
    joints as the rotation vector of ``R_b^T R_a`` [rad].

    Args:
        model: the model.
        y_a: (m,) canonical unknowns.
        y_b: (m,) canonical unknowns.

    Returns:
        (m,) difference in the tangent space at ``y_b``.
    """
    d = np.asarray(y_a, float) - np.asarray(y_b, float)
    per = periodic(model)
    if per.size:
        d[per] = (d[per] + math.pi) % (2 * math.pi) - math.pi
    for idx in model.chart.rotations:
        ii = list(idx)
        d[ii] = rot_log(rot_exp(y_b[ii]).T @ rot_exp(y_a[ii]))
    return d


def in_chart(q_first, c_first, c, rots) -> np.ndarray | None:
    """The start point ``q_first`` (chart ``c_first``) in chart ``c`` (None if too far)."""
    if not rots:
        return q_first
    q = q_first.copy()
    for i, idx in enumerate(rots):
        ii = list(idx)
        R0 = c_first[9 * i : 9 * i + 9].reshape(3, 3, order="F") @ cayley(q_first[ii])
        Rrel = c[9 * i : 9 * i + 9].reshape(3, 3, order="F").T @ R0
        if 1.0 + float(np.trace(Rrel)) < 0.5:  # more than ~140 deg away: not close
            return None
        q[ii] = gibbs(Rrel)
    return q
