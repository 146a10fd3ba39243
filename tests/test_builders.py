"""Builders: shipped files equal the builders' output, save/load round trips, input validation."""

from __future__ import annotations

import importlib.util
import json
import math
from functools import cache
from pathlib import Path

import numpy as np
import pytest

import scdk_sym as sc
from scdk_sym import builders
from scdk_sym.cli import main
from scdk_sym.errors import InputError

MODELS = Path(__file__).resolve().parents[1] / "models"
BUILT = ("stewart_gough", "planar_3rpr", "delta", "hexa", "five_bar")


@cache
def generator():
    spec = importlib.util.spec_from_file_location("models_generate", MODELS / "generate.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@cache
def built(name: str) -> sc.Model:
    return generator().build(name)


def test_all_is_sorted_and_complete() -> None:
    assert builders.__all__ == sorted(builders.__all__)
    for name in (*BUILT, "planar_3rrr"):
        assert name in builders.__all__
        assert callable(getattr(builders, name))


@pytest.mark.parametrize("name", BUILT)
def test_shipped_model_is_the_builders_output(name: str) -> None:
    shipped = sc.load_model(MODELS / name)
    model = built(name)
    assert shipped.content_hash == model.content_hash
    assert (MODELS / name / "robot.urdf").read_text() == model.urdf_text
    assert (MODELS / name / "robot.yaml").read_text() == model.spec.to_yaml()
    assert shipped.reduction is None and model.reduction is None


@pytest.mark.parametrize("name", BUILT)
def test_save_then_load_is_identical(name: str, tmp_path: Path) -> None:
    model = built(name)
    loaded = sc.load_model(model.save(tmp_path / name))
    assert loaded.content_hash == model.content_hash
    assert (loaded.actuated, loaded.unknowns, loaded.workspace, loaded.frame) == (
        model.actuated,
        model.unknowns,
        model.workspace,
        model.frame,
    )
    assert dict(loaded.home.joints) == dict(model.home.joints)
    # the same closure function at random (not assembled) points
    rng = np.random.default_rng(3)
    for _ in range(5):
        y = model.home.y + rng.normal(0, 0.05, model.m)
        th = model.home.theta + rng.normal(0, 0.05, model.k)
        ya, ca_ = model.chart.to_local(y)
        yb, cb = loaded.chart.to_local(y)
        ga = np.array(model.kernels.g(ya, th, ca_))
        gb = np.array(loaded.kernels.g(yb, th, cb))
        np.testing.assert_allclose(ga, gb, rtol=0, atol=1e-15)


@pytest.mark.parametrize("name", BUILT)
def test_home_is_regular_and_assembled(name: str) -> None:
    model = built(name)
    assert model.home.residual <= 1e-12
    y, c = model.chart.to_local(model.home.y)
    Jp = np.array(model.kernels.jac(y, model.home.theta, c)[0])
    sv = np.linalg.svd(Jp, compute_uv=False)
    assert sv[-1] / sv[0] > 1e-2, sv


def test_delta_home_is_elbows_out_platform_below() -> None:
    m = built("delta")
    theta = m.home.theta
    np.testing.assert_allclose(theta, theta[0], atol=1e-15)  # symmetric home
    assert math.radians(20) == pytest.approx(theta[0], abs=1e-12)
    assert m.home.x[2] < -m.tree.joint("elbow_1_joint").origin[0, 3] * math.sin(theta[0])


def test_planar_3rpr_default_home_avoids_concurrent_legs() -> None:
    # similar concentric triangles: at phi = 0 the three legs meet at the centre (singular)
    ang = np.radians([90.0, 210.0, 330.0])
    unit = np.c_[np.cos(ang), np.sin(ang)]
    m = builders.planar_3rpr(0.5 * unit, 0.2 * unit)
    assert abs(m.home.x[2]) >= math.radians(15) - 1e-12
    with pytest.raises(InputError, match="home"):
        builders.planar_3rpr(0.5 * unit, 0.2 * unit, home_x=[0.0, 0.0, 0.0])


def test_stewart_3_3_via_coincident_points() -> None:
    ang_b = np.radians([0.0, 120.0, 240.0])
    base3 = np.c_[0.5 * np.cos(ang_b), 0.5 * np.sin(ang_b), np.zeros(3)]
    ang_p = np.radians([60.0, 180.0, 300.0])
    plat3 = np.c_[0.25 * np.cos(ang_p), 0.25 * np.sin(ang_p), np.zeros(3)]
    base = base3[[0, 0, 1, 1, 2, 2]]
    plat = plat3[[2, 0, 0, 1, 1, 2]]
    m = builders.stewart_gough(base, plat, home_x=[0, 0, 0.45, 0.05, -0.02, 0.1])
    assert m.reduction is None
    x = np.array([0.02, -0.01, 0.47, 0.1, 0.05, 0.2])
    target = m.inverse_kinematics(x)
    start = m.inverse_kinematics(x + 0.003)
    res = sc.solve(m, target.theta, start=start, record_path=False)
    assert np.abs(res.platform_pose - target.platform_pose).max() <= 1e-9


# ---------------------------------------------------------------------------- bad input

RING = np.radians([0.0, 20.0, 120.0, 140.0, 240.0, 260.0])
BASE6 = np.c_[0.5 * np.cos(RING), 0.5 * np.sin(RING), np.zeros(6)]
PLAT6 = np.c_[0.3 * np.cos(RING + 1.0), 0.3 * np.sin(RING + 1.0), np.zeros(6)]
TRI_A = [[0.0, 0.0], [1.0, 0.0], [0.4, 0.9]]
TRI_C = [[0.0, 0.0], [0.3, 0.0], [0.1, 0.25]]

BAD = {
    "stewart shape": (lambda: builders.stewart_gough(BASE6[:5], PLAT6), "base_points"),
    "stewart 2d points": (lambda: builders.stewart_gough(BASE6, PLAT6[:, :2]), "platform_points"),
    "stewart nan": (lambda: builders.stewart_gough(BASE6 * np.nan, PLAT6), "base_points"),
    "stewart coincident base": (
        lambda: builders.stewart_gough(np.zeros((6, 3)), PLAT6),
        "base_points",
    ),
    "stewart collinear platform": (
        lambda: builders.stewart_gough(BASE6, np.c_[np.linspace(0, 1, 6), np.zeros((6, 2))]),
        "platform_points",
    ),
    "stewart duplicate leg": (
        lambda: builders.stewart_gough(BASE6[[0, 0, 2, 3, 4, 5]], PLAT6[[0, 0, 2, 3, 4, 5]]),
        "base_points/platform_points",
    ),
    "stewart home shape": (
        lambda: builders.stewart_gough(BASE6, PLAT6, home_x=[0, 0, 1]),
        "home_x",
    ),
    "stewart planar similar (singular)": (
        lambda: builders.stewart_gough(BASE6, BASE6 * 0.6, home_x=[0, 0, 0.5, 0, 0, 0]),
        "base_points/platform_points",
    ),
    "3rpr shape": (lambda: builders.planar_3rpr(TRI_A, [[0, 0], [1, 1]]), "platform_points"),
    "3rpr coincident platform": (
        lambda: builders.planar_3rpr(TRI_A, [[0.1, 0.2]] * 3),
        "platform_points",
    ),
    "3rpr coincident base": (lambda: builders.planar_3rpr([[0.0, 0.0]] * 3, TRI_C), "base_points"),
    "3rpr duplicate leg": (
        lambda: builders.planar_3rpr([[0, 0], [0, 0], [1, 0]], [[0, 0], [0, 0], [0.2, 0.1]]),
        "base_points/platform_points",
    ),
    "3rpr zero leg at home": (
        lambda: builders.planar_3rpr(TRI_A, TRI_C, home_x=[0.0, 0.0, 0.0]),
        "home_x",
    ),
    "delta negative arm": (lambda: builders.delta(0.13, 0.03, -0.1, 0.23), "arm"),
    "delta zero rod": (lambda: builders.delta(0.13, 0.03, 0.1, 0.0), "rod"),
    "delta negative platform": (lambda: builders.delta(0.13, -0.03, 0.1, 0.23), "platform_radius"),
    "delta base radius text": (lambda: builders.delta("a", 0.03, 0.1, 0.23), "base_radius"),
    "delta rod too short": (lambda: builders.delta(0.3, 0.03, 0.1, 0.05), "rod"),
    "delta home out of reach": (
        lambda: builders.delta(0.13, 0.03, 0.1, 0.23, home_x=[0, 0, -2.0]),
        "home_x",
    ),
    "hexa negative rod": (lambda: builders.hexa(0.2, 0.1, 0.2, -0.4), "rod"),
    "hexa spread": (lambda: builders.hexa(0.2, 0.1, 0.2, 0.4, base_spread=3.0), "base_spread"),
    "hexa platform spread": (
        lambda: builders.hexa(0.2, 0.1, 0.2, 0.4, platform_spread=-0.1),
        "platform_spread",
    ),
    "five_bar negative arm": (lambda: builders.five_bar([[-0.1, 0], [0.1, 0]], -0.2, 0.25), "arm"),
    "five_bar rods shape": (
        lambda: builders.five_bar([[-0.1, 0], [0.1, 0]], 0.2, [0.25, 0.2, 0.1]),
        "rod",
    ),
    "five_bar base shape": (lambda: builders.five_bar([[-0.1, 0, 0]], 0.2, 0.25), "base_points"),
    "five_bar home out of reach": (
        lambda: builders.five_bar([[-0.1, 0], [0.1, 0]], 0.2, 0.25, home_x=[0, 2.0]),
        "home_x",
    ),
    "five_bar modes": (
        lambda: builders.five_bar([[-0.1, 0], [0.1, 0]], 0.2, 0.25, working_modes=(1, 0)),
        "working_modes",
    ),
    # effector on the line of the elbows (-0.25, h), (0.25, h): rods aligned, J_p singular
    "five_bar singular home (rods aligned)": (
        lambda: builders.five_bar([[-0.1, 0], [0.1, 0]], 0.2, 0.25, home_x=[0, math.sqrt(0.0175)]),
        "home_x",
    ),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_input_names_the_argument(case: str) -> None:
    make, argument = BAD[case]
    with pytest.raises(InputError) as info:
        make()
    message = str(info.value)
    assert argument in message, message
    assert "\n" not in message
    assert isinstance(info.value, sc.ScdkError)


def test_cli_solves_the_shipped_stewart_from_an_rpy_start(capsys) -> None:
    m = sc.load_model(MODELS / "stewart_gough")
    x = np.array([0.02, -0.01, 0.57, 0.1, -0.05, 0.2])  # x, y, z [m], roll, pitch, yaw [rad]
    target = m.inverse_kinematics(x)
    start = x + np.array([0.003, 0.003, -0.003, 0.01, 0.01, -0.01])
    argv = ["solve", str(MODELS / "stewart_gough"), "--theta", ",".join(map(str, target.theta))]
    assert main([*argv, "--from-x", ",".join(map(str, start)), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    np.testing.assert_allclose(out["x"], x, rtol=0, atol=1e-9)
    assert out["crossings"] == [] and out["residual"] <= 1e-12
    # the rpy convention: R = Rz(yaw) Ry(pitch) Rx(roll)
    c, s = np.cos(x[3:]), np.sin(x[3:])
    Rx = np.array([[1, 0, 0], [0, c[0], -s[0]], [0, s[0], c[0]]])
    Ry = np.array([[c[1], 0, s[1]], [0, 1, 0], [-s[1], 0, c[1]]])
    Rz = np.array([[c[2], -s[2], 0], [s[2], c[2], 0], [0, 0, 1]])
    np.testing.assert_allclose(np.array(out["platform_pose"])[:3, :3], Rz @ Ry @ Rx, atol=1e-9)
