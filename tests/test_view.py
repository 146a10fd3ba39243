"""The 3-D viewer: its frames against independent geometry, the recorded HTML animation, the
live server, the CLI, and the page rendered by headless Chromium."""

from __future__ import annotations

import base64
import colorsys
import re
import shutil
import subprocess
import sys
import time
import urllib.request
from importlib.util import find_spec

import numpy as np
import pytest
from factories import MODELS, shipped
from references import read_urdf

import scdk_sym as sc
from scdk_sym import view
from scdk_sym.cli import main


def anchors(name: str = "stewart_gough") -> tuple[np.ndarray, np.ndarray]:
    """(6, 3) base and platform attachment points, read from the URDF text."""
    joints = read_urdf(MODELS / name / "robot.urdf")
    A = np.array([joints[f"base_anchor_{i}_joint"].xyz for i in range(1, 7)])
    B = np.array([joints[f"platform_anchor_{i}_joint"].xyz for i in range(1, 7)])
    return A, B


def legs_of(cfg) -> tuple[np.ndarray, np.ndarray]:
    """The legs' ends: base points, and platform points moved by ``cfg.platform_pose``."""
    A, B = anchors()
    T = np.asarray(cfg.platform_pose)
    return A, B @ T[:3, :3].T + T[:3, 3]


# ---------------------------------------------------------------------------- the frames


def test_frame_draws_the_legs_between_the_anchor_points():
    model = shipped("stewart_gough")
    rng = np.random.default_rng(3)
    x = np.array([0.0, 0.0, 0.55, 0.0, 0.0, 0.0]) + rng.uniform(-0.04, 0.04, 6)
    cfg = model.inverse_kinematics(x)
    scene = view.robot_scene(model, cfg)
    f = view.frame(model, scene, cfg)
    A, P = legs_of(cfg)
    assert f.closures.shape == (6, 2, 3)
    assert np.allclose(f.closures[:, 0], A, atol=1e-12)
    assert np.allclose(f.closures[:, 1], P, atol=1e-12)
    assert f.segments.shape == (0, 2, 3) and f.cuts.shape == (0, 3)
    # the platform is highlighted: its outline, in the platform frame, has the six corners
    (platform,) = [b for b in scene.bodies if b.platform]
    assert platform.link == "platform" and platform.color == view.COLORS["platform"]
    _, B = anchors()
    assert len(platform.outline) == 6
    assert all(np.min(np.linalg.norm(B - p, axis=1)) < 1e-12 for p in platform.outline)
    base = [b for b in scene.bodies if not b.platform]
    assert len(base) == 1 and base[0].color == view.COLORS["base"]
    assert np.allclose(f.links["platform"], cfg.platform_pose, atol=1e-12)


def test_solve_path_frames_lie_on_the_straight_theta_line():
    """Each frame of a recorded solve is the configuration at theta1 + s (theta0 - theta1):
    its leg lengths (measured between the drawn ends) are those joint values, from the start
    to the solution."""
    model = shipped("stewart_gough")
    theta0 = np.array([0.66, 0.63, 0.65, 0.62, 0.64, 0.66])
    res = sc.solve(model, theta0, record_path=True)
    cfgs, captions = view.configurations(model, res)
    assert len(cfgs) >= 5 and captions[-1] == "convergent solution: "
    scene = view.robot_scene(model, cfgs[0])
    lengths = []
    for cfg in cfgs:
        f = view.frame(model, scene, cfg)
        lengths.append(np.linalg.norm(f.closures[:, 1] - f.closures[:, 0], axis=1))
    lengths = np.array(lengths)
    theta1 = model.home.theta
    assert np.allclose(lengths[0], theta1, atol=1e-9)
    assert np.allclose(lengths[-1], theta0, atol=1e-9)
    s = (lengths - theta1) @ (theta0 - theta1) / np.dot(theta0 - theta1, theta0 - theta1)
    on_line = theta1 + s[:, None] * (theta0 - theta1)
    assert np.abs(lengths - on_line).max() < 1e-8
    assert np.all(np.diff(s) > 0) and s[-1] == pytest.approx(1.0, abs=1e-9)


def test_track_frames_are_the_samples_and_long_ones_are_thinned():
    model = shipped("stewart_gough")
    rng = np.random.default_rng(5)
    poses = np.array([0, 0, 0.55, 0, 0, 0]) + np.linspace(0, 1, 12)[:, None] * rng.uniform(
        -0.05, 0.05, 6
    )
    thetas = np.array([model.inverse_kinematics(p).theta for p in poses])
    trk = sc.track(model, thetas)
    cfgs, _ = view.configurations(model, trk)
    assert len(cfgs) == 12
    for cfg, pose in zip(cfgs, poses, strict=True):
        assert np.allclose(cfg.x, pose, atol=1e-8)
    few, captions = view.configurations(model, trk, max_frames=4)
    assert [c[: c.index(":")] for c in captions] == [
        "sample 0",
        "sample 4",
        "sample 7",
        "sample 11",
    ]
    assert np.allclose(few[-1].x, poses[-1], atol=1e-8)


def test_what_to_show_is_checked():
    model = shipped("planar_hexa")
    with pytest.raises(view.ViewError, match="cannot show a str"):
        view.configurations(model, "home")
    with pytest.raises(view.ViewError, match="empty sequence"):
        view.configurations(model, [])
    with pytest.raises(view.ViewError, match="got a ndarray"):
        view.configurations(model, [model.home, np.zeros(3)])
    assert issubclass(view.ViewError, sc.ScdkError)


def _model_with_geometry(tmp_path, mesh: bool = True):
    """models/five_bar with a box and a cylinder on one link and a mesh (or a missing one) on
    another, written to ``tmp_path``."""
    trimesh = pytest.importorskip("trimesh")
    text = (MODELS / "five_bar" / "robot.urdf").read_text()
    links = re.findall(r'<link name="([^"]+)"\s*/>', text)
    assert len(links) >= 3, links
    first, second = links[1], links[2]
    box = (
        f'<link name="{first}"><visual><origin xyz="0.01 0 0" rpy="0 0 0.3"/><geometry>'
        '<box size="0.02 0.03 0.04"/></geometry><material name="m"><color rgba="1 0 0 1"/>'
        '</material></visual><visual><geometry><cylinder radius="0.005" length="0.1"/>'
        "</geometry></visual></link>"
    )
    part = (
        f'<link name="{second}"><collision><geometry><mesh filename="package://part.stl" '
        'scale="0.5 0.5 0.5"/></geometry></collision></link>'
    )
    text = text.replace(f'<link name="{first}"/>', box).replace(f'<link name="{second}"/>', part)
    folder = tmp_path / "robot"
    folder.mkdir()
    (folder / "robot.urdf").write_text(text)
    shutil.copy(MODELS / "five_bar" / "robot.yaml", folder / "robot.yaml")
    cube = trimesh.creation.box(extents=(0.2, 0.2, 0.2))
    if mesh:
        cube.export(folder / "part.stl")
    return sc.load_model(folder), first, second, cube


def test_urdf_geometry_is_drawn_and_links_without_it_as_segments(tmp_path):
    model, first, second, cube = _model_with_geometry(tmp_path)
    scene = view.robot_scene(model, model.home)
    kinds = sorted((s.link, s.kind, s.source) for s in scene.shapes)
    assert kinds == sorted(
        [(first, "box", "visual"), (first, "cylinder", "visual"), (second, "mesh", "collision")]
    )
    box = next(s for s in scene.shapes if s.kind == "box")
    assert np.allclose(box.size, [0.02, 0.03, 0.04]) and box.color == (255, 0, 0)
    assert np.allclose(box.origin[:3, 3], [0.01, 0, 0])
    assert np.allclose(
        box.origin[:2, :2], [[np.cos(0.3), -np.sin(0.3)], [np.sin(0.3), np.cos(0.3)]]
    )
    part = next(s for s in scene.shapes if s.kind == "mesh")
    assert np.allclose(np.ptp(part.vertices, axis=0), 0.1) and len(part.faces) == len(cube.faces)
    assert scene.notes == ()
    # the segments of the links with geometry are not drawn, the others are
    drawing = sc.plot.robot_drawing_3d(model, model.home)
    assert len(scene.skeleton) == len(drawing.segment_links) > 0
    for link, drawn in zip(drawing.segment_links, scene.skeleton, strict=True):
        assert drawn == (link not in (first, second))
    bare = view.robot_scene(model, model.home, geometry=False)
    assert bare.shapes == () and all(bare.skeleton)


def test_missing_mesh_is_a_note_and_its_link_a_segment(tmp_path):
    model, _, second, _ = _model_with_geometry(tmp_path, mesh=False)
    scene = view.robot_scene(model, model.home)
    assert [s.link for s in scene.shapes if s.kind == "mesh"] == []
    (note,) = scene.notes
    assert f"{second}: package://part.stl not found beside the model" in note
    drawing = sc.plot.robot_drawing_3d(model, model.home)
    drawn = dict(zip(drawing.segment_links, scene.skeleton, strict=True))
    if second in drawn:
        assert drawn[second]


# ---------------------------------------------------------------------------- viser

needs_viser = pytest.mark.skipif(find_spec("viser") is None, reason="viser is not installed")


def recording(html: str) -> dict:
    """The scene recording embedded in a page written by viser (zstd + msgpack)."""
    import msgspec
    import zstandard

    data = base64.b64decode(re.search(r'__VISER_EMBED_DATA__="([^"]+)"', html).group(1))
    size = int.from_bytes(data[:8], "little")
    inner = zstandard.ZstdDecompressor().decompress(data[8:], max_output_size=size)
    n = int.from_bytes(inner[:8], "little")
    return msgspec.msgpack.decode(inner[8 : 8 + n])


@needs_viser
def test_html_page_records_the_animation(tmp_path):
    model = shipped("stewart_gough")
    theta0 = np.array([0.66, 0.63, 0.65, 0.62, 0.64, 0.66])
    res = sc.solve(model, theta0, record_path=True)
    frames = len(view.configurations(model, res)[0])
    path = view.write_html(model, res, tmp_path / "sub" / "solve.html", seconds=3.0)
    html = path.read_text()
    assert html.lstrip().lower().startswith("<!doctype html")
    assert re.findall(r"https?://[\w.-]+", html) == ["http://www.w3.org"]  # nothing fetched
    rec = recording(html)
    dt = 3.0 / (frames - 1)
    assert rec["durationSeconds"] == pytest.approx(3.0 + max(dt, 0.3))
    updates = [
        t
        for t, m in rec["messages"]
        if m.get("name") == "/robot/closures" and m["type"] == "SceneNodeUpdateMessage"
    ]
    assert len(updates) == frames - 1  # the legs move at each later frame
    assert np.allclose(updates, dt * np.arange(1, frames))
    names = {m.get("name") for _, m in rec["messages"]}
    assert {"/robot/platform", "/robot/platform/body_1", "/robot/closures", "/grid"} <= names
    static = recording(view.write_html(model, None, tmp_path / "home.html").read_text())
    assert static["durationSeconds"] == 0.0
    # a platform that is no plate (the five-bar's effector point) is marked by a ball
    five_bar = shipped("five_bar")
    assert not [b for b in view.robot_scene(five_bar, five_bar.home).bodies if b.platform]
    page = recording(view.write_html(five_bar, None, tmp_path / "five_bar.html").read_text())
    marker = f"/robot/{five_bar.frame}/marker"
    assert any(
        m.get("name") == marker and m["type"] == "IcosphereMessage" for _, m in page["messages"]
    )


def test_missing_viser_stops_with_the_install_hint(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "viser", None)
    with pytest.raises(view.ViewError, match=r'pip install "scdk_sym\[view\]"'):
        view.write_html(shipped("planar_hexa"), None, tmp_path / "x.html")
    assert main(["view", str(MODELS / "planar_hexa"), "--html", str(tmp_path / "y.html")]) == 1
    assert not (tmp_path / "y.html").exists()


@needs_viser
def test_live_viewer_serves_the_client_and_moves_the_robot():
    model = shipped("stewart_gough")
    cfgs = [model.inverse_kinematics([0, 0, z, 0, 0, 0]) for z in (0.5, 0.55, 0.6)]
    viewer = view.show(model, cfgs, port=0, block=False, seconds=0.4)
    try:
        viewer.play(False)
        with urllib.request.urlopen(viewer.url, timeout=30) as reply:
            assert reply.status == 200 and b"<html" in reply.read().lower()

        def shown(i: int) -> bool:
            A, P = legs_of(cfgs[i])
            drawn = np.asarray(viewer._anim.closures.points, dtype=float)
            at = viewer._anim.links["platform"].position
            same = np.allclose(at, cfgs[i].platform_pose[:3, 3], atol=1e-6)
            return bool(same and np.allclose(drawn, np.stack([A, P], axis=1), atol=1e-6))

        viewer.goto(2)
        assert viewer.index == 2 and shown(2) and not shown(0)
        viewer.play()  # a frame every 0.2 s: 2 -> 0 -> 1
        deadline = time.monotonic() + 30
        while viewer.index == 2 and time.monotonic() < deadline:
            time.sleep(0.05)
        viewer.play(False)
        assert viewer.index != 2 and shown(viewer.index)
    finally:
        viewer.stop()


@needs_viser
def test_cli_view_writes_pages(tmp_path, capsys):
    model = str(MODELS / "planar_hexa")
    out = tmp_path / "seed.html"
    code = main(["view", model, "--theta=1.292,-0.802,-2.896", "--from-x", "0,0,0.4",
                 "--branch", "divergent", "--html", str(out)])  # fmt: skip
    assert code == 0 and f"wrote {out}" in capsys.readouterr().out
    rec = recording(out.read_text())
    assert rec["durationSeconds"] > 4.0  # an animation
    # the Gepetto delta: meshes missing beside the fixture, so segments and a note
    code = main(["view", "tests/fixtures/gepetto/robot_delta", "--frame", "effector", "--html",
                 str(tmp_path / "delta.html")])  # fmt: skip
    captured = capsys.readouterr()
    assert code == 0 and "note: 9 link(s) drawn as segments" in captured.err


# ---------------------------------------------------------------------------- in a browser


def chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        found = shutil.which(name)
        if found:
            return found
    return None


def screenshot(page, png, tmp_path) -> np.ndarray:
    """Render a page in headless Chromium (software WebGL) and return the RGB image (H, W, 3)."""
    import matplotlib.image

    cmd = [chromium(), "--headless", "--no-sandbox", "--hide-scrollbars", "--use-angle=swiftshader",
           "--enable-unsafe-swiftshader", f"--user-data-dir={tmp_path / 'profile'}",
           "--window-size=800,600", "--virtual-time-budget=15000", f"--screenshot={png}",
           page.resolve().as_uri()]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert png.exists(), proc.stderr[-2000:]
    return (matplotlib.image.imread(str(png))[:, :, :3] * 255).astype(int)


def robot_pixels(image: np.ndarray) -> dict[str, float]:
    """Fractions of the image: pixels off the white background, and pixels of the hue of the
    platform and of the closure links (saturated, within 12 degrees of the colour's hue)."""
    from matplotlib.colors import rgb_to_hsv

    hsv = rgb_to_hsv(image.reshape(-1, 3) / 255.0)
    out = {"drawn": float(np.mean(np.max(255 - image.reshape(-1, 3), axis=1) > 40))}
    for name in ("platform", "closure"):
        h = colorsys.rgb_to_hsv(*(np.array(view.COLORS[name]) / 255.0))[0]
        dh = np.abs((hsv[:, 0] - h + 0.5) % 1.0 - 0.5)
        out[name] = float(np.mean((dh < 12 / 360) & (hsv[:, 1] > 0.3) & (hsv[:, 2] > 0.3)))
    return out


def shows_robot(fractions: dict[str, float]) -> bool:
    return (
        fractions["drawn"] > 0.05 and fractions["platform"] > 0.002 and fractions["closure"] > 0.001
    )


@needs_viser
@pytest.mark.skipif(chromium() is None, reason="no Chromium binary (chromium, google-chrome) found")
def test_page_shows_the_6_6_platform_in_headless_chromium(tmp_path):
    import viser

    page = view.write_html(shipped("stewart_gough"), None, tmp_path / "sg.html")
    robot = robot_pixels(screenshot(page, tmp_path / "sg.png", tmp_path))
    assert shows_robot(robot), robot
    # negative control: viser's page of an empty scene fails the same check
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        empty = tmp_path / "empty.html"
        empty.write_text(server.scene.as_html())
    finally:
        server.stop()
    blank = robot_pixels(screenshot(empty, tmp_path / "empty.png", tmp_path))
    assert not shows_robot(blank), blank
    assert blank["platform"] < 1e-4 and blank["closure"] < 1e-4
