"""Rotation maps, one definition each: skew, exp (Rodrigues) and log, Cayley (Rodrigues-Gibbs
parameters) and its inverse, URDF roll-pitch-yaw, quaternions.

Numeric maps take one vector or matrix, or a stack of them (leading axes, e.g. ``(N, 3)`` ->
``(N, 3, 3)``). :func:`skew`, :func:`cayley`, :func:`axis_rotation` and
:func:`quaternion_numerator` also take CasADi symbols (``SX``/``MX``) and then build the same
expression symbolically; this module never imports CasADi for numeric arguments.

Conventions: a rotation vector ``w`` has angle ``|w|`` [rad] about ``w / |w|``; Gibbs
parameters ``rho = tan(angle / 2) axis``; quaternions are scalar first ``(w, x, y, z)``;
URDF ``rpy`` is ``R = Rz(yaw) Ry(pitch) Rx(roll)``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

#: Angle below which exp and log use their first-order forms [rad].
SMALL_EXP = 1e-12
SMALL_LOG = 1e-9
#: Distance from a half turn below which log takes the axis from the symmetric part [rad].
NEAR_HALF_TURN = 1e-3


def is_symbolic(x: Any) -> bool:
    """True for a CasADi expression (``SX``, ``MX``, ``DM``)."""
    return type(x).__module__.partition(".")[0] == "casadi"


def skew(v: Any) -> Any:
    """Skew matrix ``[v]_x`` (``[v]_x u = v x u``) of a 3-vector, a stack ``(..., 3)`` ->
    ``(..., 3, 3)``, or a CasADi 3-vector."""
    if is_symbolic(v):
        import casadi as ca

        return ca.vertcat(
            ca.horzcat(0, -v[2], v[1]),
            ca.horzcat(v[2], 0, -v[0]),
            ca.horzcat(-v[1], v[0], 0),
        )
    v = np.asarray(v, dtype=float)
    if v.ndim == 1:
        return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2], S[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    S[..., 1, 0], S[..., 2, 0], S[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    return S


def vee(M: Any) -> Any:
    """``(M[2,1] - M[1,2], M[0,2] - M[2,0], M[1,0] - M[0,1])``: twice the vector of the skew
    part of ``M`` (``(..., 3, 3)`` -> ``(..., 3)``, or a CasADi 3 x 3 -> 3-vector)."""
    if is_symbolic(M):
        import casadi as ca

        return ca.vertcat(M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1])
    M = np.asarray(M, dtype=float)
    if M.ndim == 2:
        return np.array([M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]])
    return np.stack(
        [M[..., 2, 1] - M[..., 1, 2], M[..., 0, 2] - M[..., 2, 0], M[..., 1, 0] - M[..., 0, 1]],
        axis=-1,
    )


def rot_exp(w: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector [rad] (Rodrigues' formula); ``(..., 3)`` ->
    ``(..., 3, 3)``."""
    w = np.asarray(w, dtype=float)
    if w.ndim == 1:
        angle = float(np.linalg.norm(w))
        if angle < SMALL_EXP:
            return np.eye(3) + skew(w)
        K = skew(w / angle)
        return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K
    angle = np.linalg.norm(w, axis=-1)
    tiny = angle < SMALL_EXP
    safe = np.where(tiny, 1.0, angle)
    K = skew(w / safe[..., None])
    s = np.where(tiny, 0.0, np.sin(angle))[..., None, None]
    c = np.where(tiny, 0.0, 1 - np.cos(angle))[..., None, None]
    R = np.eye(3) + s * K + c * (K @ K)
    if tiny.any():
        R[tiny] = np.eye(3) + skew(w[tiny])
    return R


def rot_log(R: np.ndarray) -> np.ndarray:
    """Rotation vector [rad] of a rotation matrix (angle in [0, pi]); ``(..., 3, 3)`` ->
    ``(..., 3)``.

    The angle is ``atan2`` of (sin, cos): accurate to rounding at every angle (``acos`` loses
    digits near 0 and pi); within :data:`NEAR_HALF_TURN` of a half turn the axis comes from
    the symmetric part.
    """
    R = np.asarray(R, dtype=float)
    if R.ndim == 2:
        return _rot_log_one(R)
    flat = R.reshape(-1, 3, 3)
    w = vee(flat)
    angle = np.arctan2(0.5 * np.linalg.norm(w, axis=-1), (np.trace(flat, axis1=1, axis2=2) - 1) / 2)
    small = angle < SMALL_LOG
    near = np.pi - angle < NEAR_HALF_TURN
    factor = np.where(small, 0.5, angle / (2 * np.sin(np.where(small | near, 1.0, angle))))
    out = factor[:, None] * w
    for i in np.flatnonzero(near):
        out[i] = _rot_log_one(flat[i])
    return out.reshape(R.shape[:-2] + (3,))


def _rot_log_one(R: np.ndarray) -> np.ndarray:
    w = vee(R)
    angle = math.atan2(0.5 * float(np.linalg.norm(w)), (float(np.trace(R)) - 1) / 2)
    if angle < SMALL_LOG:
        return 0.5 * w
    if math.pi - angle < NEAR_HALF_TURN:  # near a half turn: axis from the symmetric part
        B = (R + R.T) / 2 - math.cos(angle) * np.eye(3)  # = (1 - cos a) axis axis^T
        i = int(np.argmax(np.diag(B)))
        axis = B[:, i] / np.linalg.norm(B[:, i])
        if w @ axis < 0:
            axis = -axis
        return angle * axis
    return angle / (2 * math.sin(angle)) * w


def cayley(rho: Any) -> Any:
    """Rotation of Rodrigues (Gibbs) parameters ``rho = tan(angle/2) axis``.

    ``R = I + 2 (W + W^2) / (1 + |rho|^2)``, ``W = skew(rho)``: rational, regular for every
    rotation of less than a half turn, the identity at ``rho = 0``. Takes a 3-vector, a stack
    ``(..., 3)`` or a CasADi 3-vector.
    """
    W = skew(rho)
    if is_symbolic(rho):
        import casadi as ca

        return type(W).eye(3) + 2 * (W + W @ W) / (1 + ca.dot(rho, rho))
    rho = np.asarray(rho, dtype=float)
    if rho.ndim == 1:
        return np.eye(3) + 2 * (W + W @ W) / (1 + float(rho @ rho))
    return np.eye(3) + 2 * (W + W @ W) / (1 + np.sum(rho * rho, axis=-1))[..., None, None]


def gibbs(R: np.ndarray) -> np.ndarray:
    """Rodrigues (Gibbs) parameters of a rotation (inverse of :func:`cayley`); ``inf`` or
    ``nan`` at a half turn."""
    R = np.asarray(R, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return vee(R) / (1.0 + np.trace(R, axis1=-2, axis2=-1))[..., None]


def gibbs_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Gibbs parameters of ``cayley(a) @ cayley(b)``: ``(a + b + a x b) / (1 - a . b)``
    (Rodrigues' composition; ``(3,)`` each)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return (a + b + np.cross(a, b)) / (1.0 - float(a @ b))


def axis_rotation(axis: np.ndarray, c: Any, s: Any) -> Any:
    """``I + s K + (1 - c) K^2`` with ``K = skew(axis)``: the rotation about a unit ``axis``
    whose angle has cosine ``c`` and sine ``s`` (numbers or CasADi expressions)."""
    if is_symbolic(c) or is_symbolic(s):
        import casadi as ca

        K = skew(ca.DM(np.asarray(axis, dtype=float)))
        return ca.SX.eye(3) + s * K + (1 - c) * (K @ K)
    K = skew(axis)
    return np.eye(3) + s * K + (1 - c) * (K @ K)


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Rotation matrix of URDF roll-pitch-yaw angles [rad]: ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    cr, sr, cp, sp, cy, sy = (
        math.cos(roll),
        math.sin(roll),
        math.cos(pitch),
        math.sin(pitch),
        math.cos(yaw),
        math.sin(yaw),
    )
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def rpy_from_matrix(rot: np.ndarray) -> np.ndarray:
    """URDF roll-pitch-yaw [rad] of a rotation matrix (``R = Rz(yaw) Ry(pitch) Rx(roll)``)."""
    pitch = math.atan2(-rot[2, 0], math.hypot(rot[0, 0], rot[1, 0]))
    roll = math.atan2(rot[2, 1], rot[2, 2])
    yaw = math.atan2(rot[1, 0], rot[0, 0])
    return np.array([roll, pitch, yaw])


def quaternion_numerator(q: Any) -> Any:
    """(3, 3) ``N(q)`` with ``R = N(q) / (q . q)`` the rotation of the quaternion ``q``
    (scalar first), quadratic in ``q``; a 4-vector, a stack ``(..., 4)`` or CasADi."""
    a, b, c, d = (q[i] for i in range(4)) if is_symbolic(q) else np.moveaxis(np.asarray(q), -1, 0)
    rows = [
        [a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)],
        [2 * (b * c + a * d), a * a - b * b + c * c - d * d, 2 * (c * d - a * b)],
        [2 * (b * d - a * c), 2 * (c * d + a * b), a * a - b * b - c * c + d * d],
    ]
    if is_symbolic(q):
        import casadi as ca

        return ca.vertcat(*[ca.horzcat(*r) for r in rows])
    return np.moveaxis(np.array(rows, dtype=float), (0, 1), (-2, -1))


def quaternion_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a quaternion (scalar first, any nonzero norm); ``(..., 4)`` ->
    ``(..., 3, 3)``."""
    q = np.asarray(q, dtype=float)
    return quaternion_numerator(q) / np.sum(q * q, axis=-1)[..., None, None]


def quaternion_of(R: np.ndarray) -> np.ndarray:
    """(4,) unit quaternion (scalar first) of a rotation matrix (Shepperd's method)."""
    t = np.trace(R)
    cand = np.array([t, R[0, 0], R[1, 1], R[2, 2]])
    i = int(np.argmax(cand))
    if i == 0:
        r = np.sqrt(1 + t)
        q = [r, (R[2, 1] - R[1, 2]) / r, (R[0, 2] - R[2, 0]) / r, (R[1, 0] - R[0, 1]) / r]
    elif i == 1:
        r = np.sqrt(1 + 2 * R[0, 0] - t)
        q = [(R[2, 1] - R[1, 2]) / r, r, (R[0, 1] + R[1, 0]) / r, (R[0, 2] + R[2, 0]) / r]
    elif i == 2:
        r = np.sqrt(1 + 2 * R[1, 1] - t)
        q = [(R[0, 2] - R[2, 0]) / r, (R[0, 1] + R[1, 0]) / r, r, (R[1, 2] + R[2, 1]) / r]
    else:
        r = np.sqrt(1 + 2 * R[2, 2] - t)
        q = [(R[1, 0] - R[0, 1]) / r, (R[0, 2] + R[2, 0]) / r, (R[1, 2] + R[2, 1]) / r, r]
    out = 0.5 * np.array(q)
    return out / np.linalg.norm(out)
