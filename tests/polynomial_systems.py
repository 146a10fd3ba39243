"""Hand-written polynomial systems (PolynomialSystem protocol) for the homotopy tests.

- :class:`Quadrics`: n dense random quadrics in n unknowns (2^n roots by Bezout);
- :class:`QuarticPair`: x^2 - y + p0 = 0 and p5 y^2 + p1 x y + p2 x + p3 y + p4 = 0, whose
  x-roots are those of one univariate quartic (:meth:`QuarticPair.univariate`);
- :class:`StewartGough`: the general 6-6 platform with a quaternion in a real affine chart.
"""

from __future__ import annotations

import hashlib

import numpy as np


def _cnormal(rng, shape):
    return (rng.normal(size=shape) + 1j * rng.normal(size=shape)) / np.sqrt(2.0)


def _digest(*arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


class Quadrics:
    """G_i(z, p) = z^T A_i z + p_i (c_i . z) + d_i, real random coefficients; offsets on every row.

    Args:
        n: number of unknowns and rows.
        seed: seed of the coefficients.
    """

    def __init__(self, n: int, seed: int) -> None:
        rng = np.random.default_rng(seed)
        self.n, self.n_params = n, n
        self.A = rng.normal(size=(n, n, n))
        self.c = rng.normal(size=(n, n))
        self.d = rng.normal(size=n)
        self.offset_rows = np.ones(n, dtype=bool)

    def evaluate(self, z, p):
        quad = np.einsum("mj,ijk,mk->mi", z, self.A, z)
        lin = z @ self.c.T  # (M, n): c_i . z
        G = quad + p * lin + self.d
        Gz = (
            np.einsum("ijk,mk->mij", self.A + self.A.transpose(0, 2, 1), z) + p[:, :, None] * self.c
        )
        Gp = np.zeros((len(z), self.n, self.n), dtype=complex)
        Gp[:, np.arange(self.n), np.arange(self.n)] = lin
        return G, Gz, Gp

    def random_point(self, rng):
        return _cnormal(rng, self.n), _cnormal(rng, self.n)

    def content_hash(self) -> str:
        return _digest(b"quadrics", self.A, self.c, self.d)


class QuarticPair:
    """x^2 - y + p0 = 0, p5 y^2 + p1 x y + p2 x + p3 y + p4 = 0 (4 roots for p5 != 0)."""

    n, n_params = 2, 6
    offset_rows = np.array([True, True])

    def evaluate(self, z, p):
        x, y = z[:, 0], z[:, 1]
        G = np.stack(
            [
                x * x - y + p[:, 0],
                p[:, 5] * y * y + p[:, 1] * x * y + p[:, 2] * x + p[:, 3] * y + p[:, 4],
            ],
            axis=1,
        )
        Gz = np.zeros((len(z), 2, 2), dtype=complex)
        Gz[:, 0, 0], Gz[:, 0, 1] = 2 * x, -1.0
        Gz[:, 1, 0] = p[:, 1] * y + p[:, 2]
        Gz[:, 1, 1] = 2 * p[:, 5] * y + p[:, 1] * x + p[:, 3]
        Gp = np.zeros((len(z), 2, 6), dtype=complex)
        Gp[:, 0, 0] = 1.0
        Gp[:, 1, 1], Gp[:, 1, 2], Gp[:, 1, 3], Gp[:, 1, 4], Gp[:, 1, 5] = x * y, x, y, 1.0, y * y
        return G, Gz, Gp

    def random_point(self, rng):
        return _cnormal(rng, 2), _cnormal(rng, 6)

    def content_hash(self) -> str:
        return _digest(b"quartic-pair")

    @staticmethod
    def univariate(p) -> np.ndarray:
        """Coefficients (highest first) of the quartic in x after y = x^2 + p0."""
        p0, p1, p2, p3, p4, p5 = p
        return np.array([p5, p1, 2 * p5 * p0 + p3, p1 * p0 + p2, p5 * p0 * p0 + p3 * p0 + p4])

    @staticmethod
    def params_for(coeffs, p0: float = 0.5) -> np.ndarray:
        """Parameters whose univariate polynomial is ``coeffs`` = [a4, a3, a2, a1, a0]."""
        a4, a3, a2, a1, a0 = coeffs
        p5, p1 = a4, a3
        p3 = a2 - 2 * p5 * p0
        p2 = a1 - p1 * p0
        p4 = a0 - p5 * p0 * p0 - p3 * p0
        return np.array([p0, p1, p2, p3, p4, p5], dtype=float)


def rotation_numerator(q: np.ndarray) -> np.ndarray:
    """(M, 4) quaternions (w, x, y, z) -> (M, 3, 3) rotation numerators (R (q.q) for |q| = 1)."""
    q0, q1, q2, q3 = q.T
    return np.stack(
        [
            np.stack(
                [
                    q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3,
                    2 * (q1 * q2 - q0 * q3),
                    2 * (q1 * q3 + q0 * q2),
                ],
                -1,
            ),
            np.stack(
                [
                    2 * (q1 * q2 + q0 * q3),
                    q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3,
                    2 * (q2 * q3 - q0 * q1),
                ],
                -1,
            ),
            np.stack(
                [
                    2 * (q1 * q3 - q0 * q2),
                    2 * (q2 * q3 + q0 * q1),
                    q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3,
                ],
                -1,
            ),
        ],
        axis=1,
    )


def quaternions(R: np.ndarray) -> np.ndarray:
    """(M, 3, 3) rotations -> (M, 4) unit quaternions (w, x, y, z) (Shepperd's method)."""
    out = np.empty((len(R), 4))
    for k, m in enumerate(R):
        tr = np.trace(m)
        i = int(np.argmax([tr, m[0, 0], m[1, 1], m[2, 2]]))
        if i == 0:
            s = 2.0 * np.sqrt(1.0 + tr)
            q = [s / 4, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
        else:
            a, b, c = (i - 1, i % 3, (i + 1) % 3)
            s = 2.0 * np.sqrt(1.0 + m[a, a] - m[b, b] - m[c, c])
            v = np.empty(3)
            v[a], v[b], v[c] = s / 4, (m[b, a] + m[a, b]) / s, (m[c, a] + m[a, c]) / s
            q = [(m[c, b] - m[b, c]) / s, *v]
        out[k] = q
    return out


class StewartGough:
    """General 6-6 platform: z = (p (3), q (4), w), parameters the leg lengths L (6).

    Rows 0-5 (offset): |p + w R(q) b_i - a_i|^2 - L_i^2, R(q) the rotation numerator;
    row 6 (structural): chart . q - 1; row 7 (structural): w (q . q) - 1.
    With ``A = B = None`` the anchors are parameters too: p = (A (18), B (18), L (6)), the
    whole family of 6-6 platforms (:meth:`params` builds p).

    Args:
        A: (6, 3) base anchors, or None.
        B: (6, 3) platform anchors, or None.
        chart: (4,) real chart vector (default: random, seeded by ``seed``).
        seed: seed of the chart.
    """

    n = 8

    def __init__(self, A=None, B=None, chart=None, seed: int = 7) -> None:
        self.free = A is None
        self.A = None if self.free else np.asarray(A, dtype=float)
        self.B = None if self.free else np.asarray(B, dtype=float)
        self.n_params = 42 if self.free else 6
        rng = np.random.default_rng(seed)
        self.chart = rng.normal(size=4) if chart is None else np.asarray(chart, dtype=float)
        self.offset_rows = np.array([True] * 6 + [False, False])

    def params(self, A, B, L) -> np.ndarray:
        """Parameters of a platform: L (6,), or (A, B, L) flattened when anchors are free."""
        if not self.free:
            return np.asarray(L, dtype=float)
        return np.concatenate([np.ravel(A), np.ravel(B), np.ravel(L)])

    def evaluate(self, z, p):
        M = len(z)
        q0, q1, q2, q3, w = (z[:, k : k + 1] for k in range(3, 8))  # (M, 1) each
        if self.free:
            A, B, L = p[:, :18].reshape(M, 6, 3), p[:, 18:36].reshape(M, 6, 3), p[:, 36:]
            ax, ay, az = A[..., 0], A[..., 1], A[..., 2]
            vx, vy, vz = B[..., 0], B[..., 1], B[..., 2]  # (M, 6) each
        else:
            (ax, ay, az), (vx, vy, vz), L = self.A.T, self.B.T, p  # (6,) each
        uv = q1 * vx + q2 * vy + q3 * vz  # (M, 6)
        s = q0 * q0 - q1 * q1 - q2 * q2 - q3 * q3
        cx, cy, cz = q2 * vz - q3 * vy, q3 * vx - q1 * vz, q1 * vy - q2 * vx  # u x v
        rx = s * vx + 2 * uv * q1 + 2 * q0 * cx  # R(q) b, (M, 6) per component
        ry = s * vy + 2 * uv * q2 + 2 * q0 * cy
        rz = s * vz + 2 * uv * q3 + 2 * q0 * cz
        dx = z[:, 0:1] + w * rx - ax
        dy = z[:, 1:2] + w * ry - ay
        dz = z[:, 2:3] + w * rz - az
        qq = q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3
        G = np.empty((M, 8), dtype=complex)
        G[:, :6] = dx * dx + dy * dy + dz * dz - L * L
        G[:, 6] = z[:, 3:7] @ self.chart - 1.0
        G[:, 7] = (w * qq - 1.0)[:, 0]
        dv = dx * vx + dy * vy + dz * vz
        du = dx * q1 + dy * q2 + dz * q3
        dc = dx * cx + dy * cy + dz * cz  # d . (u x v)
        w4 = 4.0 * w
        Gz = np.zeros((M, 8, 8), dtype=complex)
        Gz[:, :6, 0], Gz[:, :6, 1], Gz[:, :6, 2] = 2 * dx, 2 * dy, 2 * dz
        Gz[:, :6, 3] = w4 * (q0 * dv + dc)
        # d . dRb/du_k = -2 u_k (d.v) + 2 v_k (d.u) + 2 (u.v) d_k + 2 q0 (v x d)_k
        Gz[:, :6, 4] = w4 * (-q1 * dv + vx * du + uv * dx + q0 * (vy * dz - vz * dy))
        Gz[:, :6, 5] = w4 * (-q2 * dv + vy * du + uv * dy + q0 * (vz * dx - vx * dz))
        Gz[:, :6, 6] = w4 * (-q3 * dv + vz * du + uv * dz + q0 * (vx * dy - vy * dx))
        Gz[:, :6, 7] = 2 * (dx * rx + dy * ry + dz * rz)
        Gz[:, 6, 3:7] = self.chart
        Gz[:, 7, 3:7] = 2 * w * z[:, 3:7]
        Gz[:, 7, 7] = qq[:, 0]
        Gp = np.zeros((M, 8, self.n_params), dtype=complex)
        legs = np.arange(6)
        Gp[:, legs, self.n_params - 6 + legs] = -2 * L
        if self.free:
            d = np.stack([dx, dy, dz], axis=2)  # (M, 6, 3)
            Rtd = np.einsum("mkj,mik->mij", rotation_numerator(z[:, 3:7]), d)  # R^T d_i
            for j in range(3):
                Gp[:, legs, 3 * legs + j] = -2 * d[..., j]
                Gp[:, legs, 18 + 3 * legs + j] = 2 * w * Rtd[..., j]
        return G, Gz, Gp

    def random_point(self, rng):
        t = _cnormal(rng, 3)
        q = _cnormal(rng, 4)
        q = q / (q @ self.chart)
        w = 1.0 / np.sum(q * q)
        L = 1.0 + 0.3 * _cnormal(rng, 6)
        if self.free:
            return np.concatenate([t, q, [w]]), np.concatenate([0.5 * _cnormal(rng, 36), L])
        return np.concatenate([t, q, [w]]), L

    def content_hash(self) -> str:
        if self.free:
            return _digest(b"stewart-gough-family", self.chart)
        return _digest(b"stewart-gough", self.A, self.B, self.chart)

    def trace_map(self, z: np.ndarray) -> np.ndarray:
        """(N, 8) -> (N, 12): translation and rotation entries, finite where the chart's q is not
        (the functions whose trace the trace test checks)."""
        R = rotation_numerator(z[:, 3:7]) * z[:, 7, None, None]
        return np.concatenate([z[:, :3], R.reshape(-1, 9)], axis=1)

    def poses(self, z: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        """(K, n) real solutions -> [(translation (3,), rotation (3, 3))]."""
        z = np.asarray(z, dtype=float)
        R = rotation_numerator(z[:, 3:7]) * z[:, 7, None, None]
        return [(z[k, :3], R[k]) for k in range(len(z))]
