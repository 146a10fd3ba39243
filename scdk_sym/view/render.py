"""The scene drawn with viser: a live viewer in the browser, or a self-contained HTML page.

viser is an optional dependency (``pip install "scdk_sym[view]"``), imported only here and
only when a scene is drawn.
"""

from __future__ import annotations

import contextlib
import io
import threading
from pathlib import Path

import numpy as np

from ..errors import ViewError
from ..optional import require
from ..robot import Model
from .scene import COLORS, Frame, RobotScene, configurations, frame, robot_scene

#: How to get the optional viewer dependency.
INSTALL_HINT = 'pip install "scdk_sym[view]"'


def require_viser():
    """Import viser.

    Returns:
        The ``viser`` module.

    Raises:
        ViewError: it is not installed (the message gives the install command).
    """
    return require(
        ("viser", "viser.transforms"),
        needed_for="the 3-D viewer",
        install=f"{INSTALL_HINT} (or pip install viser)",
        error=ViewError,
    )


@contextlib.contextmanager
def _quiet():
    """Keep viser's banners (server started / stopped) off the caller's output."""
    sink = io.StringIO()
    with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
        yield


def _wxyz(R: np.ndarray) -> np.ndarray:
    import viser.transforms as tf

    return np.asarray(tf.SO3.from_matrix(np.asarray(R, dtype=float)).wxyz, dtype=float)


def _fan(n: int) -> np.ndarray:
    """Triangles of a convex polygon of ``n`` corners (a fan from corner 0)."""
    return np.array([[0, i, i + 1] for i in range(1, n - 1)], dtype=np.uint32)


class _Animator:
    """The viser nodes of a scene and how each frame moves them."""

    def __init__(self, server, scene: RobotScene, frames: list[Frame]) -> None:
        self.frames = frames
        self.scene = scene
        api = server.scene
        size = scene.size
        width = 0.012 * size
        f0 = frames[0]
        bottom = scene.floor - 0.02 * size  # below the robot, not through a planar one
        api.add_grid(
            "/grid", width=1.5 * size, height=1.5 * size, cell_size=0.1 * size,
            section_size=0.5 * size, position=(scene.centre[0], scene.centre[1], bottom),
            infinite_grid=False,
        )  # fmt: skip
        self.links = {}
        for name in scene.moving_links:
            T = f0.links[name]
            self.links[name] = api.add_frame(
                f"/robot/{name}", show_axes=False, position=T[:3, 3], wxyz=_wxyz(T[:3, :3])
            )
        for n, shape in enumerate(scene.shapes):
            at = f"/robot/{shape.link}/geometry_{n}"
            pose = {"position": shape.origin[:3, 3], "wxyz": _wxyz(shape.origin[:3, :3])}
            if shape.kind == "box":
                api.add_box(at, dimensions=tuple(shape.size), color=shape.color, **pose)
            elif shape.kind == "cylinder":
                api.add_cylinder(at, radius=float(shape.size[0]), height=float(shape.size[1]),
                                 color=shape.color, **pose)  # fmt: skip
            elif shape.kind == "sphere":
                api.add_icosphere(at, radius=float(shape.size[0]), color=shape.color, **pose)
            else:
                assert shape.vertices is not None and shape.faces is not None
                api.add_mesh_simple(at, vertices=shape.vertices.astype(np.float32),
                                    faces=shape.faces.astype(np.uint32), color=shape.color,
                                    **pose)  # fmt: skip
        has_platform_body = False
        for n, body in enumerate(scene.bodies):
            has_platform_body |= body.platform
            api.add_mesh_simple(
                f"/robot/{body.link}/body_{n}", vertices=body.outline.astype(np.float32),
                faces=_fan(len(body.outline)), color=body.color, side="double",
                opacity=None if body.platform else 0.4,
            )  # fmt: skip
            outline = np.stack([body.outline, np.roll(body.outline, -1, axis=0)], axis=1)
            api.add_line_segments(f"/robot/{body.link}/edge_{n}", points=outline.astype(np.float32),
                                  colors=body.color, thickness=0.5 * width)  # fmt: skip
        if not has_platform_body and scene.platform in self.links:
            api.add_icosphere(f"/robot/{scene.platform}/marker", radius=0.04 * size,
                              color=COLORS["platform"])  # fmt: skip
        self.segments = self.closures = self.cuts = None
        if len(f0.segments):
            self.segments = api.add_line_segments(
                "/robot/links", points=f0.segments.astype(np.float32), colors=COLORS["link"],
                thickness=width,
            )  # fmt: skip
        if len(f0.closures):
            self.closures = api.add_line_segments(
                "/robot/closures", points=f0.closures.astype(np.float32),
                colors=COLORS["closure"], thickness=width,
            )  # fmt: skip
        if len(f0.cuts):
            self.cuts = api.add_point_cloud(
                "/robot/cuts", points=f0.cuts.astype(np.float32), colors=COLORS["closure"],
                point_size=0.03 * size, point_shape="circle", precision="float32",
            )  # fmt: skip

    def apply(self, i: int) -> None:
        """Move every node to frame ``i``."""
        f = self.frames[i]
        for name, handle in self.links.items():
            T = f.links[name]
            handle.position = T[:3, 3]
            handle.wxyz = _wxyz(T[:3, :3])
        if self.segments is not None:
            self.segments.points = f.segments.astype(np.float32)
        if self.closures is not None:
            self.closures.points = f.closures.astype(np.float32)
        if self.cuts is not None:
            self.cuts.points = f.cuts.astype(np.float32)


def _frames(model: Model, what, max_frames: int, geometry: bool):
    cfgs, captions = configurations(model, what, max_frames)
    scene = robot_scene(model, cfgs[0], geometry)
    return scene, [frame(model, scene, c, t) for c, t in zip(cfgs, captions, strict=True)]


def _camera(server, scene: RobotScene) -> None:
    c = np.asarray(scene.centre, dtype=float)
    server.initial_camera.look_at = tuple(c)
    server.initial_camera.position = tuple(c + scene.size * np.array([0.8, -1.0, 0.6]))


def _start(viser, host: str, port: int):
    try:
        with _quiet():
            return viser.ViserServer(host=host, port=port, verbose=False)
    except OSError as exc:
        raise ViewError(
            f"cannot start the viewer on {host}:{port}: {exc.strerror or exc}; try another --port"
        ) from exc


def write_html(
    model: Model,
    what=None,
    path: str | Path = "scene.html",
    *,
    seconds: float = 4.0,
    max_frames: int = 300,
    geometry: bool = True,
) -> Path:
    """Write a self-contained HTML page of the robot in 3-D (opens without a server).

    The page holds viser's web client and the recorded scene; an animation (a solve's path,
    a track) plays in a loop with a play/pause button and a time slider: frame ``i`` at
    ``i * seconds / (N - 1)``, the last one held ``max(seconds / (N - 1), seconds / 10)``.

    Args:
        model: the model.
        what: what to show (see :func:`~scdk_sym.view.scene.configurations`): ``None`` for the
            home configuration, a Configuration, a SolveResult, a TrackResult or a sequence
            of Configurations.
        path: HTML file to write (its folder is created if needed).
        seconds: duration of one pass of an animation [s].
        max_frames: at most this many frames (evenly subsampled).
        geometry: draw the URDF geometry where present.

    Returns:
        The path written.

    Raises:
        ViewError: viser is missing, nothing can be shown, or the file cannot be written.
    """
    viser = require_viser()
    if not seconds > 0:
        raise ViewError(f"seconds must be positive, got {seconds}")
    scene, frames = _frames(model, what, max_frames, geometry)
    server = _start(viser, "127.0.0.1", 0)
    try:
        _camera(server, scene)
        anim = _Animator(server, scene, frames)
        recording = server.get_scene_serializer()
        dt = seconds / max(len(frames) - 1, 1)
        for i in range(1, len(frames)):
            recording.insert_sleep(dt)
            anim.apply(i)
        if len(frames) > 1:  # the last frame (a solution) stays a moment before the loop
            recording.insert_sleep(max(dt, 0.1 * seconds))
        html = recording.as_html()
    finally:
        with _quiet():
            server.stop()
    p = Path(path)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(html, encoding="utf-8")
    except OSError as exc:
        raise ViewError(f"cannot write {str(p)!r}: {exc.strerror or exc}") from exc
    return p


class Viewer:
    """A live viewer: a viser server showing the robot, with a slider over the frames.

    Attributes:
        server: the ``viser.ViserServer``.
        url: the address to open in a browser.
        scene: the static picture.
        frames: the animation frames.
    """

    def __init__(self, server, scene: RobotScene, frames: list[Frame], seconds: float) -> None:
        self.server = server
        self.scene = scene
        self.frames = frames
        self.url = f"http://{_host(server)}:{server.get_port()}"
        self._anim = _Animator(server, scene, frames)
        self._dt = seconds / max(len(frames) - 1, 1)
        self._stop = threading.Event()
        self._shown = 0
        gui = server.gui
        gui.set_panel_label(scene.name)
        self._caption = gui.add_markdown(frames[0].caption)
        self._slider = gui.add_slider("frame", min=0, max=max(len(frames) - 1, 1), step=1,
                                      initial_value=0, disabled=len(frames) < 2)  # fmt: skip
        self._play = gui.add_checkbox("play", initial_value=len(frames) > 1,
                                      disabled=len(frames) < 2)  # fmt: skip

        @self._slider.on_update
        def _(_event) -> None:
            self.goto(int(self._slider.value))

        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._thread.start()

    def goto(self, i: int) -> None:
        """Show frame ``i`` (clipped to the frames), as the slider does."""
        i = int(np.clip(i, 0, len(self.frames) - 1))
        self._anim.apply(i)
        self._caption.content = self.frames[i].caption
        self._shown = i
        if int(self._slider.value) != i:
            self._slider.value = i

    @property
    def index(self) -> int:
        """The frame shown."""
        return self._shown

    def play(self, on: bool = True) -> None:
        """Start (or stop) playing the frames in a loop, as the checkbox does."""
        self._play.value = bool(on)

    def _loop(self) -> None:
        while not self._stop.wait(self._dt):
            if self._play.value and len(self.frames) > 1:
                self._slider.value = (int(self._slider.value) + 1) % len(self.frames)

    def wait(self) -> None:
        """Block until Ctrl-C, then stop the server."""
        try:
            while not self._stop.wait(0.5):
                pass
        except KeyboardInterrupt:
            pass
        finally:
            self.stop()

    def stop(self) -> None:
        """Stop the animation and the server."""
        if not self._stop.is_set():
            self._stop.set()
            with _quiet():
                self.server.stop()


def _host(server) -> str:
    host = server.get_host()
    return "localhost" if host in ("0.0.0.0", "::") else host


def show(
    model: Model,
    what=None,
    *,
    host: str = "127.0.0.1",
    port: int = 8080,
    seconds: float = 4.0,
    max_frames: int = 300,
    geometry: bool = True,
    block: bool = True,
) -> Viewer:
    """Show the robot in 3-D in a browser (a viser server on ``host:port``).

    A slider picks the frame and a checkbox plays the animation in a loop.

    Args:
        model: the model.
        what: what to show, as for :func:`write_html`.
        host: address to listen on ("0.0.0.0" for every interface).
        port: first port tried (the next free one is taken when it is in use).
        seconds: duration of one pass of an animation [s].
        max_frames: at most this many frames.
        geometry: draw the URDF geometry where present.
        block: wait until Ctrl-C (then stop the server) before returning.

    Returns:
        The viewer (already stopped when ``block``).

    Raises:
        ViewError: viser is missing, nothing can be shown, or the server cannot start.
    """
    viser = require_viser()
    if not seconds > 0:
        raise ViewError(f"seconds must be positive, got {seconds}")
    scene, frames = _frames(model, what, max_frames, geometry)
    server = _start(viser, host, port)
    _camera(server, scene)
    viewer = Viewer(server, scene, frames, seconds)
    if block:
        viewer.wait()
    return viewer
