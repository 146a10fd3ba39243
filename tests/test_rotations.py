"""Rotation maps (scdk_sym.model.rotations) against closed forms and finite differences.

References here are independent of the module: elementary rotations about x, y, z written
out, the half-angle quaternion of an axis-angle pair, numpy's cross product, central finite
differences of ``t -> exp(t w)``.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

from scdk_sym.model import rotations as rot

RNG_SEED = 20240611


def Rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def Ry(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def Rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def half_angle_quaternion(axis: np.ndarray, angle: float) -> np.ndarray:
    return np.r_[math.cos(angle / 2), math.sin(angle / 2) * axis]


def quaternion_rotation(q: np.ndarray) -> np.ndarray:
    """R u = q u q* for a unit quaternion, by the Hamilton product (independent form)."""

    def mul(p, r):
        return np.r_[
            p[0] * r[0] - p[1:] @ r[1:], p[0] * r[1:] + r[0] * p[1:] + np.cross(p[1:], r[1:])
        ]

    conj = np.r_[q[0], -q[1:]]
    return np.array([mul(mul(q, np.r_[0.0, e]), conj)[1:] for e in np.eye(3)]).T


def random_axes(n: int, rng: np.random.Generator) -> np.ndarray:
    a = rng.normal(size=(n, 3))
    return a / np.linalg.norm(a, axis=1)[:, None]


def test_skew_and_vee():
    rng = np.random.default_rng(RNG_SEED)
    v, u = rng.normal(size=(2, 5, 3))
    S = rot.skew(v)
    assert S.shape == (5, 3, 3)
    np.testing.assert_allclose(np.einsum("nij,nj->ni", S, u), np.cross(v, u), atol=1e-15)
    for i in range(5):
        np.testing.assert_array_equal(rot.skew(v[i]), S[i])
    np.testing.assert_allclose(rot.vee(S), 2 * v, atol=1e-15)
    f = ca.Function("skew", [x := ca.SX.sym("x", 3)], [rot.skew(x)])
    np.testing.assert_array_equal(np.array(f(v[0])), S[0])
    M = rng.normal(size=(3, 3))  # symbolic vee = numeric vee, on a matrix with a symmetric part
    g = ca.Function("vee", [X := ca.SX.sym("X", 3, 3)], [rot.vee(X)])
    np.testing.assert_array_equal(np.array(g(M)).ravel(), rot.vee(M))
    np.testing.assert_allclose(rot.vee(M), rot.vee(0.5 * (M - M.T)), atol=1e-15)


@pytest.mark.parametrize(("axis", "R"), [((1, 0, 0), Rx), ((0, 1, 0), Ry), ((0, 0, 1), Rz)])
def test_exp_of_elementary_rotations(axis, R):
    for a in (-3.0, -1e-13, 0.0, 0.3, 2.5, math.pi):
        np.testing.assert_allclose(rot.rot_exp(a * np.array(axis, float)), R(a), atol=1e-15)


def test_exp_equals_the_half_angle_quaternion_and_log_inverts_it():
    rng = np.random.default_rng(RNG_SEED)
    axes = random_axes(200, rng)
    angles = np.r_[rng.uniform(0, math.pi, 194), 0.0, 1e-13, 1e-10, 1e-4, math.pi - 1e-6, 3.1]
    W = axes * angles[:, None]
    R = rot.rot_exp(W)
    assert R.shape == (200, 3, 3)
    for i in range(200):
        ref = quaternion_rotation(half_angle_quaternion(axes[i], angles[i]))
        np.testing.assert_allclose(R[i], ref, atol=2e-15)
        np.testing.assert_allclose(rot.rot_exp(W[i]), R[i], atol=1e-15)
        np.testing.assert_allclose(
            rot.rot_log(R[i]), W[i], atol=5e-15 / max(1e-3, math.pi - angles[i])
        )
    L = rot.rot_log(R)  # batched, near-half-turn rows included
    for i in range(200):
        np.testing.assert_allclose(L[i], rot.rot_log(R[i]), atol=1e-15)
    assert rot.rot_log(R.reshape(20, 10, 3, 3)).shape == (20, 10, 3)


def test_log_of_a_half_turn_is_pi_about_the_axis():
    rng = np.random.default_rng(RNG_SEED)
    for axis in random_axes(20, rng):
        w = rot.rot_log(rot.rot_exp(math.pi * axis))
        assert np.linalg.norm(w) == pytest.approx(math.pi, abs=1e-12)
        assert abs(abs(w @ axis) - math.pi) < 1e-7  # +-axis: the same rotation


def test_exp_derivative_by_finite_differences():
    rng = np.random.default_rng(RNG_SEED)
    for w in rng.normal(size=(10, 3)):
        h, t = 1e-6, 0.7
        fd = (rot.rot_exp((t + h) * w) - rot.rot_exp((t - h) * w)) / (2 * h)
        np.testing.assert_allclose(fd, rot.skew(w) @ rot.rot_exp(t * w), atol=1e-8)


def test_cayley_is_exp_of_the_gibbs_angle_and_gibbs_inverts_it():
    rng = np.random.default_rng(RNG_SEED)
    axes = random_axes(50, rng)
    angles = rng.uniform(-3.0, 3.0, 50)
    rho = np.tan(angles / 2)[:, None] * axes
    C = rot.cayley(rho)
    np.testing.assert_allclose(C, rot.rot_exp(axes * angles[:, None]), atol=1e-13)
    np.testing.assert_allclose(rot.gibbs(C), rho, rtol=1e-11, atol=1e-13)
    for i in range(50):
        np.testing.assert_allclose(rot.cayley(rho[i]), C[i], atol=1e-15)
        np.testing.assert_allclose(rot.gibbs(C[i]), rho[i], rtol=1e-11, atol=1e-13)
    for kind in (ca.SX, ca.MX):
        x = kind.sym("rho", 3)
        f = ca.Function("cayley", [x], [rot.cayley(x)])
        np.testing.assert_allclose(np.array(f(rho[0])), C[0], atol=1e-15)
    assert np.all(~np.isfinite(rot.gibbs(Rz(math.pi))))  # a half turn has no Gibbs vector


def test_gibbs_product_is_the_product_of_the_cayley_rotations():
    rng = np.random.default_rng(RNG_SEED)
    for a, b in rng.normal(scale=0.5, size=(5, 2, 3)):
        ref = rot.gibbs(rot.cayley(a) @ rot.cayley(b))
        np.testing.assert_allclose(rot.gibbs_product(a, b), ref, atol=1e-12)


def test_axis_rotation_numeric_and_symbolic():
    rng = np.random.default_rng(RNG_SEED)
    for axis, a in zip(random_axes(5, rng), rng.uniform(-3, 3, 5), strict=True):
        ref = rot.rot_exp(a * axis)
        np.testing.assert_allclose(
            rot.axis_rotation(axis, math.cos(a), math.sin(a)), ref, atol=1e-15
        )
        q = ca.SX.sym("q")
        f = ca.Function("R", [q], [rot.axis_rotation(axis, ca.cos(q), ca.sin(q))])
        np.testing.assert_allclose(np.array(f(a)), ref, atol=1e-15)


def test_rpy_is_z_y_x_and_inverts():
    rng = np.random.default_rng(RNG_SEED)
    for r, p, y in zip(*rng.uniform(-1, 1, (3, 20)) * [[3.0], [1.5], [3.0]], strict=True):
        R = rot.rpy_matrix(r, p, y)
        np.testing.assert_allclose(R, Rz(y) @ Ry(p) @ Rx(r), atol=1e-15)
        np.testing.assert_allclose(rot.rpy_from_matrix(R), [r, p, y], atol=1e-12)


def test_quaternions():
    rng = np.random.default_rng(RNG_SEED)
    axes = random_axes(30, rng)
    angles = rng.uniform(0, math.pi, 30)
    Q = np.array([half_angle_quaternion(a, t) for a, t in zip(axes, angles, strict=True)])
    R = rot.rot_exp(axes * angles[:, None])
    np.testing.assert_allclose(rot.quaternion_matrix(Q), R, atol=1e-15)
    np.testing.assert_allclose(rot.quaternion_matrix(3.0 * Q), R, atol=1e-15)  # any norm
    np.testing.assert_allclose(rot.quaternion_numerator(2.0 * Q), 4.0 * R, atol=1e-14)
    for i in range(30):
        q = rot.quaternion_of(R[i])
        assert abs(abs(q @ Q[i]) - 1) < 1e-14  # the same unit quaternion up to sign
        np.testing.assert_allclose(rot.quaternion_matrix(Q[i]), R[i], atol=1e-15)
    x = ca.SX.sym("q", 4)
    f = ca.Function("N", [x], [rot.quaternion_numerator(x)])
    np.testing.assert_allclose(np.array(f(Q[0])), R[0], atol=1e-15)


def test_numeric_maps_do_not_import_casadi():
    import subprocess
    import sys

    code = (
        "import sys, numpy as np\nfrom scdk_sym.model import rotations as r\n"
        "r.cayley(np.ones(3)); r.skew(np.ones((2, 3))); r.quaternion_numerator(np.ones(4))\n"
        "print('casadi' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
