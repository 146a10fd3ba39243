"""Figures: the drawn geometry against the paper's dimensions, and the PNGs' content."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from factories import MODELS, SEED_THETA0, SEED_X1, shipped

import scdk_sym as sc
from scdk_sym import plot

matplotlib_image = pytest.importorskip("matplotlib.image")


def rgb(hex_color: str) -> np.ndarray:
    return np.array([int(hex_color[i : i + 2], 16) for i in (1, 3, 5)]) / 255.0


#: matplotlib's tab:blue, tab:orange, tab:red.
BLUE, ORANGE, RED = rgb("#1f77b4"), rgb("#ff7f0e"), rgb("#d62728")


def tinted(color: np.ndarray, alpha: float) -> np.ndarray:
    """A colour drawn with opacity ``alpha`` on white."""
    return alpha * color + (1 - alpha) * np.ones(3)


def pixels(path, color: np.ndarray, tol: float = 0.03) -> int:
    """Number of pixels of a PNG within ``tol`` of an RGB colour."""
    image = matplotlib_image.imread(str(path))[:, :, :3]
    return int(np.sum(np.max(np.abs(image - color), axis=2) < tol))


def same_points(P: np.ndarray, Q: np.ndarray, tol: float) -> bool:
    return len(P) == len(Q) and all(np.min(np.linalg.norm(Q - p, axis=1)) < tol for p in P)


@pytest.mark.parametrize("name", ["planar_hexa", "planar_hexa_reduced"])
def test_seed_robot_drawing_has_the_papers_dimensions(name):
    """Base triangle side 20 cm, platform side 10 cm turned by phi, arms and rods 7 cm."""
    model = shipped(name)
    cfg = model.inverse_kinematics(SEED_X1)
    polygons, segments = plot.robot_drawing(model, cfg)
    angles = np.radians([-30.0, -150.0, 90.0])
    unit = np.c_[np.cos(angles), np.sin(angles)]
    base, platform = unit * 20 / np.sqrt(3), unit * 10 / np.sqrt(3)
    phi = SEED_X1[2]
    turned = platform @ np.array([[np.cos(phi), np.sin(phi)], [-np.sin(phi), np.cos(phi)]])
    assert same_points(polygons[0], base, 1e-9)
    assert len(polygons) == 2 and same_points(polygons[1], turned, 1e-9)
    lengths = sorted(float(np.linalg.norm(s[1] - s[0])) for s in segments)
    assert np.allclose(lengths, 7.0, atol=1e-9) and len(lengths) == 6
    ends = np.array([s[i] for s in segments for i in (0, 1)])
    for p in (*base, *turned):  # every arm starts on the base, every rod ends on the platform
        assert np.min(np.linalg.norm(ends - p, axis=1)) < 1e-9


def test_plot_solve_writes_the_three_figures(tmp_path):
    model = shipped("planar_hexa")
    start = model.inverse_kinematics(SEED_X1)
    paths = plot.plot_solve(model, SEED_THETA0, start, tmp_path, prefix="seed")
    assert [p.name for p in paths] == [
        "seed_configurations.png",
        "seed_det_jp.png",
        "seed_phase.png",
    ]
    for p in paths:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    configurations, det_jp, phase = paths
    h, w, _ = matplotlib_image.imread(str(configurations)).shape
    assert (w, h) == (720, 720)
    # both branches and the singular configuration are drawn in their colours
    assert pixels(configurations, BLUE) > 200
    assert pixels(configurations, ORANGE) > 200
    assert pixels(configurations, RED) > 200
    for path in (det_jp, phase):  # the convergent curve is drawn wide and translucent
        assert pixels(path, tinted(BLUE, 0.45), 0.05) > 200
        assert pixels(path, ORANGE) > 200
    assert pixels(det_jp, RED) > 20  # the crossing marker at det J_p = 0


def test_plot_track_marks_crossings(tmp_path):
    model = shipped("planar_hexa")
    through = np.array(
        [model.inverse_kinematics([0, 0, p]).theta for p in np.linspace(0.5, 0.65, 8)]
    )
    before = np.array([model.inverse_kinematics([0, 0, p]).theta for p in np.linspace(0.3, 0.5, 8)])
    start = model.inverse_kinematics([0.0, 0.0, 0.5])
    crossing = plot.plot_track(model, sc.track(model, through, start=start), tmp_path / "a.png")
    regular = sc.track(model, before, start=model.inverse_kinematics([0.0, 0.0, 0.3]))
    assert regular.crossings == ()
    plain = plot.plot_track(model, regular, tmp_path / "b.png")
    assert pixels(crossing, RED, 0.1) > 100
    assert pixels(plain, RED, 0.1) == 0
    assert pixels(plain, BLUE) > 100


def test_plot_errors_are_package_errors(tmp_path, monkeypatch):
    model = shipped("planar_hexa")
    res = sc.solve(model, SEED_THETA0, start=model.inverse_kinematics(SEED_X1), record_path=False)
    with pytest.raises(plot.PlotError, match="record_path=True"):
        plot.plot_det_jp([res], tmp_path / "x.png")
    with pytest.raises(plot.PlotError, match="no configuration"):
        plot.plot_configurations(model, [], tmp_path / "x.png")
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(plot.PlotError, match="cannot write"):
        plot.plot_configurations(model, [("home", model.home, "gray")], blocker / "x.png")
    monkeypatch.setitem(sys.modules, "matplotlib.figure", None)
    with pytest.raises(plot.PlotError, match=r'pip install "scdk_sym\[plot\]"'):
        plot.plot_configurations(model, [("home", model.home, "gray")], tmp_path / "y.png")
    assert issubclass(plot.PlotError, sc.ScdkError)


def _drawn_segments_3d(fig) -> list[np.ndarray]:
    """Every straight line of the figure's single 3-D axes as a (2, 3) array of its ends."""
    (ax,) = fig.axes
    assert ax.name == "3d"
    out = []
    for line in ax.get_lines():
        x, y, z = (np.asarray(v, dtype=float) for v in line.get_data_3d())
        if len(x) == 2:
            out.append(np.c_[x, y, z])
    return out


def _has_segment(drawn: list[np.ndarray], a: np.ndarray, b: np.ndarray, tol: float) -> bool:
    return any(min(np.abs(S - [a, b]).max(), np.abs(S - [b, a]).max()) < tol for S in drawn)


def test_spatial_configuration_is_drawn_in_3d_with_its_legs():
    """The 6-6 hexapod's six legs join the base points to the platform points moved by the
    configuration's platform_pose (computed here from the builder's inputs), in 3-D axes."""
    from factories import hexapod

    model = hexapod()
    ang_b = np.radians([0, 120, 240]).repeat(2) + np.radians([-12, 12] * 3)
    ang_p = np.roll(np.radians([60, 180, 300]).repeat(2) + np.radians([-20, 20] * 3), 1)
    A = np.c_[0.5 * np.cos(ang_b), 0.5 * np.sin(ang_b), np.zeros(6)]  # as factories.hexapod
    B = np.c_[0.3 * np.cos(ang_p), 0.3 * np.sin(ang_p), np.zeros(6)]
    rng = np.random.default_rng(7)
    x = np.array([0.0, 0.0, 0.6, 0.0, 0.0, 0.0]) + rng.uniform(-0.05, 0.05, 6)
    cfg = model.inverse_kinematics(x)
    T = np.asarray(cfg.platform_pose)
    P = B @ T[:3, :3].T + T[:3, 3]
    assert np.allclose(np.linalg.norm(P - A, axis=1), cfg.theta, atol=1e-9)  # the legs
    fig = plot.configurations_figure(model, [("moved", cfg, "tab:blue")])
    drawn = _drawn_segments_3d(fig)
    for a, p in zip(A, P, strict=True):
        assert _has_segment(drawn, a, p, 1e-9), (a, p)
    # a leg through the wrong platform point (the pose ignored) is not drawn
    assert not _has_segment(drawn, A[0], B[0] + [0.0, 0.0, 0.6], 1e-3)
    # the base and the platform are outlined by those six corners each
    outlines = plot.robot_drawing_3d(model, cfg).polygons
    assert len(outlines) == 2
    assert same_points(outlines[0], A, 1e-9) and same_points(outlines[1], P, 1e-9)
    assert len(fig.axes[0].collections) == 2  # both filled


def test_shipped_6_6_legs_end_at_the_urdf_anchor_points():
    """models/stewart_gough: leg ends from the URDF text (anchor joint origins) and the pose."""
    from references import read_urdf

    model = shipped("stewart_gough")
    joints = read_urdf(MODELS / "stewart_gough" / "robot.urdf")
    A = np.array([joints[f"base_anchor_{i}_joint"].xyz for i in range(1, 7)])
    B = np.array([joints[f"platform_anchor_{i}_joint"].xyz for i in range(1, 7)])
    cfg = model.inverse_kinematics([0.02, -0.03, 0.58, 0.05, -0.04, 0.1])
    T = np.asarray(cfg.platform_pose)
    P = B @ T[:3, :3].T + T[:3, 3]
    drawn = _drawn_segments_3d(plot.configurations_figure(model, [("c", cfg, "tab:orange")]))
    assert sum(_has_segment(drawn, a, p, 1e-9) for a, p in zip(A, P, strict=True)) == 6
    assert not _has_segment(drawn, A[0], P[1], 1e-3)


@pytest.mark.parametrize("name", ["planar_hexa", "planar_3rpr", "five_bar"])
def test_planar_configurations_stay_2d(name):
    model = shipped(name)
    assert not plot.is_spatial(model, [model.home])
    fig = plot.configurations_figure(model, [("home", model.home, "tab:blue")])
    assert [ax.name for ax in fig.axes] == ["rectilinear"]
