"""Independent references for 6-6 Stewart-Gough platforms, shared by tests and benchmarks.

Written from first principles in numpy (of the package only the URDF roll-pitch-yaw matrix):
random-start Levenberg-Marquardt on the leg equations, closed-form leg lengths, anchors read
from the URDF text, Dietmaier's 40-mode platform.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from scdk_sym.model.rotations import rpy_matrix  # checked against first principles in test_urdf


def anchors(model_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    """(6, 3) base and platform anchors [m], read from the URDF text."""
    root = ET.parse(Path(model_dir) / "robot.urdf").getroot()

    def read(kind):
        rows = []
        for i in range(1, 7):
            origin = root.find(f"joint[@name='{kind}_anchor_{i}_joint']/origin")
            rows.append([float(v) for v in origin.get("xyz").split()])
        return np.array(rows)

    return read("base"), read("platform")


def leg_lengths(X, A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Closed-form inverse kinematics: |p + R b_i - a_i| per pose x = [p, roll, pitch, yaw]."""
    return np.array(
        [np.linalg.norm(x[:3] + B @ rpy_matrix(*x[3:]).T - A, axis=1) for x in np.asarray(X)]
    )


def rotations(w: np.ndarray) -> np.ndarray:
    """Rotation matrices of rotation vectors (N, 3) -> (N, 3, 3)."""
    angle = np.linalg.norm(w, axis=1)[:, None, None]
    K = np.zeros((len(w), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    K = K - K.transpose(0, 2, 1)
    safe = np.where(angle < 1e-12, 1.0, angle)
    a = np.where(angle < 1e-12, 1.0, np.sin(safe) / safe)
    b = np.where(angle < 1e-12, 0.5, (1 - np.cos(safe)) / safe**2)
    return np.eye(3) + a * K + b * K @ K


def fold_path(home: np.ndarray, n: int) -> np.ndarray:
    """(n, 6) poses turning the platform through yaw = 90 deg (a direct-kinematic singularity of
    models/stewart_gough), with some translation and roll: yaw 1.40 -> 1.75 rad."""
    t = np.linspace(0.0, 1.0, n)
    X = np.tile(home, (n, 1))
    X[:, 5] = 1.40 + 0.35 * t
    X[:, 0] += 0.02 * np.sin(np.pi * t)
    X[:, 2] += 0.02 * t
    X[:, 3] += 0.05 * t
    return X


def lm_poses(residual, jacobian, p, R, iterations: int, singular: float):
    """Batched Levenberg-Marquardt on poses (p (N, 3), R (N, 3, 3)): ``iterations`` damped
    Gauss-Newton steps with updates p += dp, R = exp(dw) R (a step kept only where it lowers
    the cost), then 6 Newton steps where |det J| > ``singular``. ``residual(p, R) -> (r (N,
    6), d)``, ``jacobian(R, d) -> J (N, 6, 6)``. Returns (p, R, r) at the end."""
    starts = len(p)
    r, d = residual(p, R)
    cost = np.sum(r * r, axis=1)
    mu = np.full(starts, 1e-2)
    for _ in range(iterations):
        J = jacobian(R, d)
        JtJ = J.transpose(0, 2, 1) @ J
        damped = JtJ + mu[:, None, None] * (np.eye(6) * (1 + np.einsum("nii->ni", JtJ)[:, :, None]))
        step = -np.linalg.solve(damped, np.einsum("nki,nk->ni", J, r)[..., None])[..., 0]
        p_new, R_new = p + step[:, :3], rotations(step[:, 3:]) @ R
        r_new, d_new = residual(p_new, R_new)
        c_new = np.sum(r_new * r_new, axis=1)
        ok = c_new < cost
        p[ok], R[ok], r[ok], d[ok], cost[ok] = p_new[ok], R_new[ok], r_new[ok], d_new[ok], c_new[ok]
        mu = np.where(ok, mu / 3, mu * 4)
    for _ in range(6):
        J = jacobian(R, d)
        regular = np.abs(np.linalg.det(J)) > singular
        step = np.zeros((starts, 6))
        step[regular] = -np.linalg.solve(J[regular], r[regular][..., None])[..., 0]
        p, R = p + step[:, :3], rotations(step[:, 3:]) @ R
        r, d = residual(p, R)
    return p, R, r


def stewart_reference(A, B, lengths, starts: int, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Real poses (p, R) of a 6-6 platform: |p + R B_i - A_i| = L_i, by random-start LM.

    Uniform random rotations and positions in a ball-bounding box of the reach; 60 damped
    Gauss-Newton (Levenberg-Marquardt) iterations on (|d_i|^2 - L_i^2) / 2 with updates
    p += dp, R = exp(dw) R, then 6 Newton steps; converged (1e-11) poses are deduplicated.
    """
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(starts, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    w, x, y, z = q.T
    R = np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=1,
    )
    reach = lengths.max() + np.linalg.norm(A, axis=1).max() + np.linalg.norm(B, axis=1).max()
    p = rng.uniform(-reach, reach, size=(starts, 3))

    def residual(p, R):
        d = p[:, None, :] + np.einsum("nij,kj->nki", R, B) - A[None]
        return 0.5 * (np.sum(d * d, axis=2) - lengths**2), d

    def jacobian(R, d):
        return np.concatenate([d, np.cross(np.einsum("nij,kj->nki", R, B), d)], axis=2)

    p, R, r = lm_poses(residual, jacobian, p, R, iterations=60, singular=1e-14)
    good = np.all(np.isfinite(r), axis=1) & (np.abs(r).max(axis=1) < 1e-11)
    sols: list[tuple[np.ndarray, np.ndarray]] = []
    for pi, Ri in zip(p[good], R[good], strict=True):
        if not any(np.abs(pi - q).max() < 1e-6 and np.abs(Ri - S).max() < 1e-6 for q, S in sols):
            sols.append((pi, Ri))
    return sols


#: Dietmaier's 6-6 platform with 40 real assembly modes (Mech. Mach. Theory 1998), as
#: published to six decimals (anchors [m], leg lengths).
DIETMAIER_BASE = np.array(
    [
        [0.0, 0.0, 0.0],
        [1.107915, 0.0, 0.0],
        [0.549094, 0.756063, 0.0],
        [0.735077, -0.223935, 0.525991],
        [0.514188, -0.526063, -0.368418],
        [0.590473, 0.094733, -0.205018],
    ]
)
DIETMAIER_PLATFORM = np.array(
    [
        [0.0, 0.0, 0.0],
        [0.542805, 0.0, 0.0],
        [0.956919, -0.528915, 0.0],
        [0.665885, -0.353482, 1.402538],
        [0.478359, 1.158742, 0.107672],
        [-0.137087, -0.235121, 0.353913],
    ]
)
DIETMAIER_LENGTHS = np.array([1.0, 0.645275, 1.086284, 1.503439, 1.281933, 0.771071])


def random_platform(seed: int):
    """A general 6-6 platform (anchors near two parallel planes) and the legs of a pose."""
    rng = np.random.default_rng(seed)
    ab, ap = rng.uniform(0, 2 * np.pi, 6), rng.uniform(0, 2 * np.pi, 6)
    rb, rp = rng.uniform(0.3, 0.6, 6), rng.uniform(0.15, 0.35, 6)
    A = np.c_[rb * np.cos(ab), rb * np.sin(ab), rng.uniform(-0.1, 0.1, 6)]
    B = np.c_[rp * np.cos(ap), rp * np.sin(ap), rng.uniform(-0.1, 0.1, 6)]
    position = np.array([*rng.uniform(-0.1, 0.1, 2), rng.uniform(0.4, 0.7)])
    R = rotations(rng.normal(size=(1, 3)) * 0.3)[0]
    return A, B, np.linalg.norm(position + B @ R.T - A, axis=1)
