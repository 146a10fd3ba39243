"""Trajectory tracking with the generated C tracker (scdk_sym.solvers.track_c)."""

import numpy as np
import pytest
import stewart
from factories import MODELS, needs_compiler, shipped
from stewart import fold_path

import scdk_sym as sc
from scdk_sym.codegen import library as clib
from scdk_sym.errors import InputError
from scdk_sym.model.rotations import rot_log, rpy_matrix
from scdk_sym.solvers.solve import solve
from scdk_sym.solvers.track_c import TrackError, track_c

pytestmark = needs_compiler()


A, B = stewart.anchors(MODELS / "stewart_gough")


def leg_lengths(X):
    """Closed-form inverse kinematics of the shipped hexapod [m]."""
    return stewart.leg_lengths(X, A, B)


def canonical_y(X):
    """Floating-joint coordinates (position, rotation vector) of poses [x y z roll pitch yaw]."""
    return np.array([np.r_[x[:3], rot_log(rpy_matrix(*x[3:]))] for x in X])


def smooth_path(home, n):
    """A smooth 6-dof pose path from home: every coordinate a sine of its own frequency."""
    t = np.linspace(0.0, 1.0, n)[:, None]
    amp = np.array([0.04, 0.04, 0.03, 0.10, 0.10, 0.20])  # m, rad
    freq = np.array([1.0, 2.0, 1.5, 1.0, 2.5, 0.5])
    phase = np.array([0.0, 0.5, 1.0, 1.5, 2.0, 2.5])
    return home + amp * (np.sin(2 * np.pi * freq * t + phase) - np.sin(phase))


@pytest.fixture(scope="module")
def hexapod():
    return shipped("stewart_gough")


@pytest.fixture(scope="module")
def smooth(hexapod):
    X = smooth_path(hexapod.home.x, 3000)
    thetas = leg_lengths(X)
    return X, thetas, track_c(hexapod, thetas, hexapod.home)


def test_reproduces_the_inverse_kinematics_path(hexapod, smooth):
    X, thetas, res = smooth
    assert res.x.shape == (3000, 6) and res.y.shape == (3000, 6) and res.backend == "c"
    np.testing.assert_allclose(res.x, X, rtol=0, atol=1e-8)
    np.testing.assert_allclose(res.y, canonical_y(X), rtol=0, atol=1e-8)
    np.testing.assert_array_equal(res.theta, thetas)
    assert np.all(res.residual <= hexapod.tolerance)
    assert res.crossings == () and res.status == "converged"


def test_matches_the_cvodes_reference(hexapod, smooth):
    X, thetas, res = smooth
    prev, ref = hexapod.home, []
    for theta in thetas[:150]:  # chained CVODES solves from the previous sample
        r = solve(hexapod, theta, start=prev, record_path=False, fast=False)
        ref.append(r.x)
        prev = r.configuration
    np.testing.assert_allclose(res.x[:150], np.array(ref), rtol=0, atol=1e-8)


def test_follows_the_motion_across_a_singularity(hexapod):
    X = fold_path(hexapod.home.x, 400)
    thetas = leg_lengths(X)
    start = hexapod.inverse_kinematics(X[0])
    res = track_c(hexapod, thetas[1:], start)
    np.testing.assert_allclose(res.x, X[1:], rtol=0, atol=1e-8)
    # the truth crosses det J_p = 0 exactly once: between samples 193 and 194 of thetas[1:]
    dets = []
    for y, theta in zip(canonical_y(X[1:]), thetas[1:], strict=True):
        y_loc, c = hexapod.chart.to_local(y)
        dets.append(np.linalg.det(np.array(hexapod.kernels.jac(y_loc, theta, c)[0])))
    flips = np.flatnonzero(np.sign(dets[1:]) != np.sign(dets[:-1]))
    assert len(res.crossings) == len(flips) == 1
    cr = res.crossings[0]
    assert cr.index == flips[0]
    assert X[cr.index + 1, 5] - 1e-3 <= cr.x[5] <= X[cr.index + 2, 5] + 1e-3
    y_loc, c = hexapod.chart.to_local(cr.y)
    assert abs(np.linalg.det(np.array(hexapod.kernels.jac(y_loc, cr.theta, c)[0]))) < 1e-8
    # a warm-started Newton tracker turns back on the wrong branch at the fold
    y, c = hexapod.chart.to_local(start.y)
    for theta in thetas[1:]:
        for _ in range(20):
            g = np.array(hexapod.kernels.g(y, theta, c)).ravel()
            y = y - np.linalg.solve(np.array(hexapod.kernels.jac(y, theta, c)[0]), g)
        y, c = hexapod.chart.recentre(y, c)
    x_newton = np.array(hexapod.kernels.pose(y, thetas[-1], c)[1]).ravel()
    assert np.abs(x_newton - X[-1]).max() > 0.1


def test_first_reading_far_from_the_start_is_the_convergent_solution(hexapod):
    x_goal = hexapod.home.x + np.array([0.03, -0.02, 0.05, 0.1, -0.05, 0.3])
    theta = leg_lengths([x_goal])
    res = track_c(hexapod, theta, hexapod.home)
    ref = solve(hexapod, theta[0], start=hexapod.home, branch="convergent", fast=False)
    np.testing.assert_allclose(res.x[0], ref.x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(res.x[0], x_goal, rtol=0, atol=1e-9)


def test_model_without_floating_joints_matches_cvodes():
    model = shipped("planar_3rpr")  # three unknowns (x, y, phi), empty chart
    t = np.linspace(0.0, 1.0, 30)[:, None]
    X = model.home.x + np.array([0.03, 0.02, 0.1]) * np.sin(2 * np.pi * t + np.array([0, 1, 2]))
    thetas = np.array([model.inverse_kinematics(x).theta for x in X])
    res = track_c(model, thetas, model.home)
    np.testing.assert_allclose(res.x, X, rtol=0, atol=1e-9)
    prev, ref = model.home, []
    for theta in thetas:
        r = solve(model, theta, start=prev, record_path=False, fast=False)
        ref.append(r.x)
        prev = r.configuration
    np.testing.assert_allclose(res.x, np.array(ref), rtol=0, atol=1e-9)


def test_bad_readings_are_refused(hexapod):
    thetas = np.tile(hexapod.home.theta, (5, 1))
    thetas[3, 2] = np.nan
    with pytest.raises(InputError, match=r"thetas\[3\]"):
        track_c(hexapod, thetas)
    with pytest.raises(InputError, match="shape"):
        track_c(hexapod, np.ones((4, 5)))


def test_a_failure_in_c_names_the_sample(hexapod):
    X = smooth_path(hexapod.home.x, 10)
    thetas = leg_lengths(X)
    thetas[6] = 0.05  # legs of 5 cm: no assembly exists
    with pytest.raises(TrackError, match="sample 6") as info:
        track_c(hexapod, thetas, hexapod.home)
    assert info.value.index == 6 and info.value.status == clib.ERR_NO_SOLUTION
    np.testing.assert_array_equal(info.value.theta, thetas[6])


def test_c_boundary_reports_nan_and_sizes(hexapod):
    lib = clib.tracker_library(hexapod)
    y0, c0 = hexapod.chart.to_local(hexapod.home.y)
    thetas = leg_lengths(smooth_path(hexapod.home.x, 8))
    thetas[4, 0] = np.nan
    out = lib.track(y0, c0, hexapod.home.theta, thetas)
    assert out.status == clib.ERR_NONFINITE and out.failed == 4
    assert np.all(np.isfinite(out.y[:4])) and np.all(np.isnan(out.y[4:]))
    assert np.all(np.isnan(out.x[4:])) and np.all(np.isnan(out.det[4:]))
    assert list(out.codes[4:]) == [clib.ERR_NONFINITE] + [clib.ERR_STATE] * 3
    bad = lib.track(y0[:5], c0, hexapod.home.theta, thetas[:3])  # 5 unknowns for 6
    assert bad.status == clib.ERR_SIZE and bad.failed == 0 and np.all(np.isnan(bad.y))
    moved = lib.track(y0 + 0.01, c0, hexapod.home.theta, thetas[:3])  # not assembled
    assert moved.status == clib.ERR_NOT_ASSEMBLED
    opt = lib.default_options()
    assert opt.tol == hexapod.tolerance and opt.order == 2
    opt.tol = -1.0
    assert lib.track(y0, c0, hexapod.home.theta, thetas[:3], opt).status == clib.ERR_OPTIONS


def test_c_residuals_equal_the_casadi_residuals(hexapod):
    """The residual function of the C call (``scdk_check``) equals model.residual (CasADi SX)
    at seeded random points off the closure manifold, and the residuals a track returns are
    those of its samples."""
    import ctypes

    lib = clib.tracker_library(hexapod)
    check = lib._lib.scdk_check
    check.restype = ctypes.c_int
    dp = ctypes.POINTER(ctypes.c_double)
    rng = np.random.default_rng(11)
    y0, c0 = hexapod.chart.to_local(hexapod.home.y)
    work = (ctypes.c_double * 4096)()
    iw = (ctypes.c_longlong * 1024)()
    for _ in range(20):
        y = y0 + rng.normal(scale=0.02, size=hexapod.m)
        theta = hexapod.home.theta + rng.normal(scale=0.02, size=hexapod.k)
        r = ctypes.c_double(np.nan)
        ins = [np.ascontiguousarray(a, dtype=float) for a in (y, theta, c0)]
        args = (dp * 3)(*(a.ctypes.data_as(dp) for a in ins))
        res = (dp * 1)(ctypes.cast(ctypes.pointer(r), dp))
        assert check(args, res, iw, work, 0) == 0
        ref = hexapod.residual(y, theta, c0)
        assert ref > 1e-4  # off the manifold: a number worth comparing
        assert r.value == pytest.approx(ref, rel=1e-12)
    X = smooth_path(hexapod.home.x, 100)
    thetas = leg_lengths(X)
    out = lib.track(y0, c0, hexapod.home.theta, thetas)
    ref = [hexapod.residual(y, th, c) for y, th, c in zip(out.y, thetas, out.c, strict=True)]
    assert out.status >= 0 and np.all(out.residual <= 1e-14) and max(ref) <= 1e-14


def test_a_sample_with_a_large_residual_is_refused(hexapod, monkeypatch):
    thetas = leg_lengths(smooth_path(hexapod.home.x, 12))
    real = clib.CTracker.track

    def corrupted(self, *args, **kwargs):
        out = real(self, *args, **kwargs)
        out.residual[7] = 10 * hexapod.tolerance  # a residual over the tolerance
        return out

    monkeypatch.setattr(clib.CTracker, "track", corrupted)
    with pytest.raises(TrackError, match="sample 7 failed verification") as info:
        track_c(hexapod, thetas, hexapod.home)
    assert info.value.index == 7 and info.value.residual > hexapod.tolerance


def test_the_library_is_cached_on_disk(hexapod, monkeypatch):
    path = clib.tracker_library(hexapod).path
    fresh = sc.load_model(MODELS / "stewart_gough")  # a new object: no in-memory library

    def refuse(*args, **kwargs):
        raise AssertionError("compiled again")

    monkeypatch.setattr(clib, "compile_library", refuse)
    assert clib.tracker_library(fresh).path == path


# ------------------------------------------------------------ coarse paths through a fold

SEED_SINGULAR_PHI = 0.575360  # the paper's singular configuration of the seed robot (x = y = 0)


def seed_thetas(phis):
    """Closed-form inverse kinematics of the seed robot (3-RRR, cm, rad) turning at x = y = 0.

    Arm = rod = 7 cm, base side 20 cm, platform side 10 cm; vertex i of both at polar angle
    -30, -150, 90 deg; working mode theta_i = atan2(d) - acos((|d|^2 + arm^2 - rod^2) / (2 arm
    |d|)) with d the platform vertex minus the base vertex (independent of the model).
    """
    arm = rod = 7.0
    a = np.radians([-30.0, -150.0, 90.0])
    base = 20.0 / np.sqrt(3.0) * np.c_[np.cos(a), np.sin(a)]
    rows = []
    for phi in phis:
        d = 10.0 / np.sqrt(3.0) * np.c_[np.cos(a + phi), np.sin(a + phi)] - base
        r = np.linalg.norm(d, axis=1)
        cosine = (r**2 + arm**2 - rod**2) / (2.0 * arm * r)
        rows.append(np.arctan2(d[:, 1], d[:, 0]) - np.arccos(cosine))
    return np.array(rows)


def det_jp(model, y, theta):
    """det J_p at canonical y, from the model's CasADi Jacobian (numpy LU, not the C code)."""
    y_loc, c = model.chart.to_local(y)
    return float(np.linalg.det(np.array(model.kernels.jac(y_loc, theta, c)[0])))


def test_seed_closed_form_is_the_papers_singular_reading():
    # the paper prints theta = [1.166, -0.928, -3.023] at its singular configuration
    np.testing.assert_allclose(seed_thetas([SEED_SINGULAR_PHI])[0], [1.166, -0.928, -3.023],
                               rtol=0, atol=6e-4)  # fmt: skip


# (7 samples: the first step, before any motion is known, ends where the mirror solution is
# only 2.5 times farther than the continuation; the tracker refuses it, see test_track_parity)
@pytest.mark.parametrize("count", [9, 13, 27, 61])
def test_seed_robot_coarse_path_follows_the_motion_through_the_fold(count):
    """Few samples across the fold: the mirror solution lies nearer to the prediction's error
    than the step, and the first reading repeats the start (no motion known yet)."""
    model = shipped("planar_hexa")
    phis = np.linspace(0.4, 1.0, count)
    thetas = seed_thetas(phis)
    start = model.inverse_kinematics([0.0, 0.0, 0.4])
    res = track_c(model, thetas, start)
    np.testing.assert_allclose(res.x, np.c_[0 * phis, 0 * phis, phis], rtol=0, atol=1e-8)
    passive = np.array([model.inverse_kinematics([0.0, 0.0, p]).y for p in phis])
    np.testing.assert_allclose(res.y, passive, rtol=0, atol=1e-8)
    assert len(res.crossings) == 1
    crossing = res.crossings[0]
    assert crossing.index == int(np.flatnonzero(phis < SEED_SINGULAR_PHI)[-1])
    assert abs(crossing.x[2] - SEED_SINGULAR_PHI) < 1e-3
    assert abs(det_jp(model, crossing.y, crossing.theta)) < 1e-8 * abs(
        det_jp(model, start.y, start.theta)
    )


def test_det_output_is_det_jp_where_the_jacobian_has_structural_zeros():
    """The seed robot's J_p has structural zeros (each closure involves some joints only);
    the tracker must read the Jacobian kernel as a dense matrix."""
    model = shipped("planar_hexa")
    assert not model.kernels.jac.sparsity_out(0).is_dense()
    phis = np.linspace(0.30, 0.90, 7)
    thetas = seed_thetas(phis)
    start = model.inverse_kinematics([0.0, 0.0, 0.25])
    y0, c0 = model.chart.to_local(start.y)
    out = clib.tracker_library(model).track(y0, c0, start.theta, thetas)
    assert out.status == 0
    ref = [det_jp(model, model.chart.to_canonical(y, c), th)
           for y, th, c in zip(out.y, thetas, out.c, strict=True)]  # fmt: skip
    np.testing.assert_allclose(out.det, ref, rtol=1e-9, atol=0)
    assert np.sum(np.diff(np.sign(out.det)) != 0) == 1


def _legs(A, B, y):
    """Leg lengths of a 6-6 platform at y = (position, rotation vector) [m]."""
    from scdk_sym.model.rotations import rot_exp

    return np.linalg.norm(y[:3] + B @ rot_exp(y[3:]).T - A, axis=1)


def _leg_jacobian_det(A, B, y):
    """det of the 6x6 platform Jacobian [u_i, (R b_i) x u_i] (u_i unit leg vectors)."""
    from scdk_sym.model.rotations import rot_exp

    Rb = B @ rot_exp(y[3:]).T
    d = y[:3] + Rb - A
    u = d / np.linalg.norm(d, axis=1)[:, None]
    return float(np.linalg.det(np.hstack([u, np.cross(Rb, u)])))


# (5 samples: the first step, before any motion is known, ends where the mirror solution is
# only 2.9 times farther than the continuation; the tracker refuses it)
@pytest.mark.parametrize("count", [7, 9, 17, 33])
def test_hexapod_coarse_path_through_its_twist_singularity(count):
    """A 6-6 platform moved straight through its singular manifold (turned about z), coarsely."""
    from factories import hexapod as general_hexapod

    model = general_hexapod()
    ang_b = np.radians([0, 120, 240]).repeat(2) + np.radians([-12, 12] * 3)
    ang_p = np.roll(np.radians([60, 180, 300]).repeat(2) + np.radians([-20, 20] * 3), 1)
    A = np.c_[0.5 * np.cos(ang_b), 0.5 * np.sin(ang_b), np.zeros(6)]
    B = np.c_[0.3 * np.cos(ang_p), 0.3 * np.sin(ang_p), np.zeros(6)]
    level, twist = np.array([0.0, 0.0, 0.6, 0.0, 0.0, 0.0]), np.eye(6)[5]
    lo, hi = 1.0, 2.0  # bisection on the twist angle for the singular configuration
    sign_lo = np.sign(_leg_jacobian_det(A, B, level + lo * twist))
    assert sign_lo * _leg_jacobian_det(A, B, level + hi * twist) < 0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        same = np.sign(_leg_jacobian_det(A, B, level + mid * twist)) == sign_lo
        lo, hi = (mid, hi) if same else (lo, mid)
    direction = np.array([0.02, -0.03, 0.05, 0.3, -0.2, 1.0])
    direction /= np.linalg.norm(direction)
    t = np.linspace(-0.3, 0.3, count) + 0.0123
    Y = level + lo * twist + t[:, None] * direction
    thetas = np.array([_legs(A, B, y) for y in Y])
    start = model.configuration(Y[0], thetas[0])

    res = track_c(model, thetas, start)
    np.testing.assert_allclose(res.y, Y, rtol=0, atol=1e-8)
    assert len(res.crossings) == 1
    assert res.crossings[0].index == int(np.flatnonzero(t < 0)[-1])
    assert abs(_leg_jacobian_det(A, B, res.crossings[0].y)) < 1e-3 * abs(
        _leg_jacobian_det(A, B, Y[0])
    )


@pytest.mark.parametrize("count", [8, 12, 20, 50])
def test_hexapod_coarse_yaw_path_through_the_singular_orientation(hexapod, count):
    X = fold_path(hexapod.home.x, count)
    thetas = leg_lengths(X)
    res = track_c(hexapod, thetas[1:], hexapod.inverse_kinematics(X[0]))
    np.testing.assert_allclose(res.x, X[1:], rtol=0, atol=1e-8)
    dets = [_leg_jacobian_det(A, B, y) for y in canonical_y(X[1:])]
    flips = np.flatnonzero(np.sign(dets[1:]) != np.sign(dets[:-1]))
    assert len(flips) == 1
    assert [c.index for c in res.crossings] == [int(flips[0])]
