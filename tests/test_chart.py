"""The floating-joint chart: re-centred Rodrigues parameters add no singularity of their own.

At the chart centre (rho = 0) the closure Jacobian of a Stewart-Gough platform must equal,
row by row, the first-principles one: ``J_p = J_line diag(I, 2 R)`` where ``J_line`` has rows
``[u_i, (R b_i) x u_i]`` (the Plücker coordinates of the legs). ``diag(I, 2 R)`` has
condition number 2 at every orientation, so ``det J_p = 0`` exactly where the legs are
linearly dependent: tilted 80 deg, pitched 90 deg (the roll-pitch-yaw gimbal lock) or turned
170 deg about z, the platform solves like at home, and every crossing reported is one of the
mechanism.
"""

from __future__ import annotations

import math
from functools import cache
from pathlib import Path

import numpy as np
import pytest

import scdk_sym as sc
from scdk_sym.model.chart import Chart
from scdk_sym.model.rotations import cayley, rot_exp, rot_log

MODELS = Path(__file__).resolve().parents[1] / "models"


@cache
def stewart() -> sc.Model:
    return sc.load_model(MODELS / "stewart_gough")


def skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def rodrigues(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation by ``angle`` about the unit ``axis`` (Rodrigues' formula)."""
    K = skew(axis)
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    ez, ey, ex = np.eye(3)[2], np.eye(3)[1], np.eye(3)[0]
    return rodrigues(ez, yaw) @ rodrigues(ey, pitch) @ rodrigues(ex, roll)


def anchors(model: sc.Model, prefix: str) -> np.ndarray:
    return np.array([model.tree.joint(f"{prefix}_{i}_joint").origin[:3, 3] for i in range(1, 7)])


def line_jacobian(model: sc.Model, T: np.ndarray) -> np.ndarray:
    """Rows [u_i, (R b_i) x u_i] of the six legs at platform placement T."""
    a, b = anchors(model, "base_anchor"), anchors(model, "platform_anchor")
    arms = b @ T[:3, :3].T
    d = T[:3, 3] + arms - a
    u = d / np.linalg.norm(d, axis=1)[:, None]
    return np.hstack([u, np.cross(arms, u)])


def min_sv_ratio(J: np.ndarray) -> float:
    sv = np.linalg.svd(J, compute_uv=False)
    return float(sv[-1] / sv[0])


# ---------------------------------------------------------------------------- the maps


ANGLES = [0.0, 1e-8, 0.3, 1.5, 2.9, math.pi - 1.1e-3, math.pi - 0.9e-3, math.pi - 1e-4,
          math.pi - 2e-6, math.pi - 1e-8]  # fmt: skip


@pytest.mark.parametrize("angle", ANGLES)
def test_rot_exp_log_and_cayley_against_rodrigues(angle: float) -> None:
    rng = np.random.default_rng(int(angle * 1e3) + 1)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    R = rodrigues(axis, angle)
    np.testing.assert_allclose(rot_exp(angle * axis), R, rtol=0, atol=1e-15)
    # accurate to rounding up to the half turn (where acos-based formulas lose digits)
    np.testing.assert_allclose(rot_log(R), angle * axis, rtol=0, atol=1e-12)
    if angle < 3.0:  # Rodrigues (Gibbs) parameters tan(angle / 2) axis
        np.testing.assert_allclose(cayley(math.tan(angle / 2) * axis), R, rtol=0, atol=1e-14)


def test_rot_log_of_a_half_turn() -> None:
    axis = np.array([2.0, -1.0, 2.0]) / 3.0
    w = rot_log(rodrigues(axis, math.pi))
    assert abs(np.linalg.norm(w) - math.pi) <= 1e-15
    assert np.abs(np.abs(w / math.pi) - np.abs(axis)).max() <= 1e-15  # +-axis: the same rotation
    np.testing.assert_allclose(rot_exp(w), rodrigues(axis, math.pi), rtol=0, atol=1e-15)


def test_chart_round_trip_and_recentre() -> None:
    rng = np.random.default_rng(21)
    chart = Chart.for_unknowns(stewart().unknowns, stewart().tree.floating_joints)
    assert chart.rotations == ((3, 4, 5),)
    for _ in range(20):
        w = rng.normal(size=3)
        w *= rng.uniform(0.0, math.pi - 1e-3) / np.linalg.norm(w)
        y = np.r_[rng.normal(size=3), w]
        loc, c = chart.to_local(y)
        np.testing.assert_array_equal(loc[3:], 0.0)
        np.testing.assert_allclose(c.reshape(3, 3, order="F"), rodrigues(w / np.linalg.norm(w),
                                   np.linalg.norm(w)), atol=1e-14)  # fmt: skip
        np.testing.assert_allclose(chart.to_canonical(loc, c), y, atol=1e-12)
        # move in the chart, re-centre: same rotation, rho back to zero
        rho = rng.normal(0, 0.3, 3)
        moved = np.r_[loc[:3], rho]
        R = c.reshape(3, 3, order="F") @ cayley(rho)
        y2, c2 = chart.recentre(moved, c)
        np.testing.assert_array_equal(y2[3:], 0.0)
        np.testing.assert_allclose(c2.reshape(3, 3, order="F"), R, atol=1e-14)


# ---------------------------------------------------------------------------- Stewart-Gough

POSES = {
    "tilted 80 deg about x": [0.0, 0.0, 0.55, math.radians(80), 0.0, 0.0],
    "tilted 80 deg about y": [0.0, 0.0, 0.55, 0.0, math.radians(80), 0.0],
    "pitch 90 deg (rpy gimbal lock)": [0.0, 0.0, 0.55, 0.0, math.pi / 2, 0.0],
    "turned 170 deg about z": [0.0, 0.0, 0.55, 0.0, 0.0, math.radians(170)],
    "turned 170 deg about z, off-centre": [0.05, -0.03, 0.5, 0.3, -0.2, math.radians(170)],
}


@pytest.mark.parametrize("label", list(POSES))
def test_jacobian_in_the_chart_is_the_leg_jacobian(label: str) -> None:
    m = stewart()
    cfg = m.inverse_kinematics(POSES[label])
    T = np.array(cfg.platform_pose)
    np.testing.assert_allclose(T[:3, :3], rpy(*POSES[label][3:]), atol=1e-12)
    y, c = m.chart.to_local(cfg.y)
    Jp = np.array(m.kernels.jac(y, cfg.theta, c)[0])
    expected = line_jacobian(m, T) @ np.block(
        [[np.eye(3), np.zeros((3, 3))], [np.zeros((3, 3)), 2 * T[:3, :3]]]
    )
    np.testing.assert_allclose(Jp, expected, rtol=0, atol=1e-12)
    # far from a singularity of the mechanism, and so of the chart
    assert min_sv_ratio(Jp) > 1e-2


@pytest.mark.parametrize("label", list(POSES))
def test_extreme_orientations_solve_like_any_pose(label: str) -> None:
    m = stewart()
    x = np.array(POSES[label])
    target = m.inverse_kinematics(x)
    near = x + np.array([2e-3, -2e-3, 2e-3, 1e-2, -1e-2, 1e-2])
    res = sc.solve(m, target.theta, start=m.inverse_kinematics(near), record_path=False)
    assert res.crossings == ()
    assert np.abs(res.platform_pose[:3, :3] - rpy(*x[3:])).max() <= 1e-9
    assert np.abs(res.platform_pose[:3, 3] - x[:3]).max() <= 1e-9
    # the full path (CVODES, re-centred at every chunk) agrees and reports no crossing
    traced = sc.solve(m, target.theta, start=m.inverse_kinematics(near), fast=False)
    assert traced.crossings == ()
    assert np.abs(traced.platform_pose - res.platform_pose).max() <= 1e-9


def test_path_through_the_half_turn_of_the_rotation_vector() -> None:
    # yaw 170 deg -> 190 deg: the rotation vector jumps from +170 deg to -170 deg about z
    m = stewart()
    start = m.inverse_kinematics([0.0, 0.0, 0.55, 0.05, 0.0, math.radians(170)])
    goal = [0.0, 0.0, 0.55, 0.05, 0.0, math.radians(190)]
    target = m.inverse_kinematics(goal)
    assert abs(np.linalg.norm(start.y[3:]) - math.radians(170)) < 0.01
    assert abs(np.linalg.norm(target.y[3:]) - math.radians(170)) < 0.01
    assert target.y[5] * start.y[5] < 0  # the rotation vector flipped
    for fast in (True, False):
        res = sc.solve(m, target.theta, start=start, fast=fast, record_path=False)
        assert res.crossings == ()
        assert np.abs(res.platform_pose[:3, :3] - rpy(*goal[3:])).max() <= 1e-9
        assert np.abs(res.platform_pose[:3, 3] - goal[:3]).max() <= 1e-9


def test_crossings_are_singularities_of_the_mechanism() -> None:
    m = stewart()
    res = sc.solve(m, [0.62, 0.6, 0.61, 0.6, 0.6, 0.6], branch="divergent", record_path=False)
    assert len(res.crossings) >= 1
    for cr in res.crossings:
        cfg = m.configuration(cr.y, cr.theta)
        ratio = min_sv_ratio(line_jacobian(m, np.array(cfg.platform_pose)))
        assert ratio < 1e-6, ratio
    # and the solution itself is regular
    assert min_sv_ratio(line_jacobian(m, np.array(res.platform_pose))) > 1e-3


def test_symbolic_recentring_matches_axis_angle() -> None:
    """``Chart.recentred`` (CasADi, used inside compiled kernels): the new reference rotation
    is ``R_ref`` times the rotation of angle ``2 atan |rho|`` about ``rho`` (Rodrigues'
    formula here), the rotation parameters become 0 and the other unknowns stay."""
    import casadi as ca

    chart = Chart(((1, 2, 3), (5, 6, 7)))
    y, c = ca.SX.sym("y", 9), ca.SX.sym("c", 18)
    f = ca.Function("recentred", [y, c], list(chart.recentred(y, c)))
    rng = np.random.default_rng(5)
    for _ in range(5):
        yv = rng.uniform(-1.5, 1.5, 9)
        refs = [rodrigues(*unit_and_norm(rng.normal(size=3))) for _ in range(2)]
        cv = np.concatenate([R.flatten(order="F") for R in refs])
        y0, c0 = (np.array(o).ravel() for o in f(yv, cv))
        for b, idx in enumerate(chart.rotations):
            rho = yv[list(idx)]
            axis, size = unit_and_norm(rho)
            expect = refs[b] @ rodrigues(axis, 2 * math.atan(size))
            np.testing.assert_allclose(c0[9 * b : 9 * b + 9], expect.flatten(order="F"),
                                       rtol=0, atol=1e-14)  # fmt: skip
            np.testing.assert_array_equal(y0[list(idx)], 0.0)
        np.testing.assert_array_equal(y0[[0, 4, 8]], yv[[0, 4, 8]])


def unit_and_norm(v: np.ndarray) -> tuple[np.ndarray, float]:
    n = float(np.linalg.norm(v))
    return v / n, n
