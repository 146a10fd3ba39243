"""Trajectory tracking with the generated C tracker (scdk_sym.solvers.track_c)."""

import shutil
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from factories import MODELS, shipped

import scdk_sym as sc
from scdk_sym.codegen import library as clib
from scdk_sym.errors import InputError
from scdk_sym.model.chart import rot_log
from scdk_sym.model.urdf import rpy_matrix
from scdk_sym.solvers.sc import solve
from scdk_sym.solvers.track_c import TrackError, track_c

pytestmark = pytest.mark.skipif(
    not (shutil.which("gcc") or shutil.which("cc")), reason="needs a C compiler"
)


def anchors(model_dir):
    """(6, 3) base and platform anchors read from the URDF text (independent of the model)."""
    root = ET.parse(model_dir / "robot.urdf").getroot()

    def read(kind):
        rows = []
        for i in range(1, 7):
            origin = root.find(f"joint[@name='{kind}_anchor_{i}_joint']/origin")
            rows.append([float(v) for v in origin.get("xyz").split()])
        return np.array(rows)

    return read("base"), read("platform")


A, B = anchors(MODELS / "stewart_gough")


def leg_lengths(X):
    """Closed-form inverse kinematics of the hexapod: |p + R b_i - a_i| per pose [m]."""
    return np.array([np.linalg.norm(x[:3] + B @ rpy_matrix(*x[3:]).T - A, axis=1) for x in X])


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


def fold_path(home, n):
    """Yaw through the singular orientation (~90 deg) with some translation and roll."""
    t = np.linspace(0.0, 1.0, n)
    X = np.tile(home, (n, 1))
    X[:, 5] = 1.40 + 0.35 * t
    X[:, 0] += 0.02 * np.sin(np.pi * t)
    X[:, 2] += 0.02 * t
    X[:, 3] += 0.05 * t
    return X


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
    assert info.value.index == 6 and info.value.status < 0


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


def test_python_verification_catches_a_wrong_sample(hexapod, monkeypatch):
    thetas = leg_lengths(smooth_path(hexapod.home.x, 12))
    real = clib.CTracker.track

    def corrupted(self, *args, **kwargs):
        out = real(self, *args, **kwargs)
        out.y[7, 2] += 1e-6  # 1 um off: a wrong answer the C status does not show
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
