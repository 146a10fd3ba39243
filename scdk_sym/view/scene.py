"""What the 3-D viewer draws, computed without viser (numpy only).

A :class:`RobotScene` is the static part of a model's picture: the URDF's visual (else
collision) geometry of each link in its link frame, the filled outline of each rigid body
(base, platform highlighted, other plates), and which skeleton segments stand for links that
have no geometry. A :class:`Frame` is one sample of an animation: link placements, the
skeleton segments, the closure links (distance closures as segments, the cut points of the
other closures) and a caption. :func:`configurations` turns what is to be shown (a
configuration, a solve with its recorded path, a track) into the configurations of the frames.
"""

from __future__ import annotations

import io
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import numpy as np

from ..errors import ViewError
from ..model.urdf import import_yourdfpy
from ..plot import first_hit, format_vector, placements, rigid_groups, robot_drawing_3d
from ..results import Configuration, SolveResult, TrackResult
from ..robot import Model

#: Colours (RGB, 0-255) of the picture: links drawn as segments, closure links (the cut loop
#: pairs), the platform, other rigid bodies, the base, and URDF geometry without a colour.
COLORS = {
    "link": (50, 100, 220),
    "closure": (20, 170, 70),
    "platform": (230, 30, 90),
    "body": (150, 155, 170),
    "base": (120, 120, 125),
    "geometry": (175, 180, 190),
}


@dataclass(frozen=True)
class Shape:
    """One URDF geometry element, in its link's frame.

    Attributes:
        link: the link it belongs to.
        kind: "box", "cylinder", "sphere" or "mesh".
        origin: (4, 4) placement in the link frame [model length unit].
        size: box (3,) edge lengths; cylinder (2,) radius, length (along z); sphere (1,)
            radius [model length unit]; mesh: (3,) scale.
        vertices: (V, 3) mesh vertices, scaled [model length unit] (None unless a mesh).
        faces: (F, 3) mesh triangles (None unless a mesh).
        color: RGB 0-255.
        source: "visual" or "collision".
    """

    link: str
    kind: str
    origin: np.ndarray
    size: np.ndarray
    vertices: np.ndarray | None
    faces: np.ndarray | None
    color: tuple[int, int, int]
    source: str


@dataclass(frozen=True)
class Body:
    """The filled outline of a rigid body, in the frame of one of its links.

    Attributes:
        link: the link whose frame carries the outline.
        outline: (N, 3) polygon corners in that frame [model length unit].
        color: RGB 0-255.
        platform: whether it is the platform (the model's reported frame).
    """

    link: str
    outline: np.ndarray
    color: tuple[int, int, int]
    platform: bool


@dataclass(frozen=True)
class RobotScene:
    """The static part of a model's 3-D picture.

    Attributes:
        name: the model's name.
        platform: the platform link (the model's reported frame).
        shapes: URDF geometry, per link (visual where a link has one, else collision).
        bodies: filled outlines of the rigid bodies; the base's link is the root.
        skeleton: for each segment of :func:`~scdk_sym.plot.robot_drawing_3d`, whether it is
            drawn (its link has no geometry).
        size: the picture's extent [model length unit] (for line widths and the camera).
        centre: (3,) centre of the picture at the first frame [model length unit].
        floor: lowest z of the picture at the first frame [model length unit].
        notes: what could not be drawn as the URDF describes (missing mesh files).
    """

    name: str
    platform: str
    shapes: tuple[Shape, ...]
    bodies: tuple[Body, ...]
    skeleton: tuple[bool, ...]
    size: float
    centre: np.ndarray
    floor: float
    notes: tuple[str, ...]

    @property
    def moving_links(self) -> tuple[str, ...]:
        """Links whose placement the frames carry: the platform, links with geometry or a
        body outline."""
        names = {s.link for s in self.shapes} | {b.link for b in self.bodies} | {self.platform}
        return tuple(sorted(names))


@dataclass(frozen=True)
class Frame:
    """One sample of an animation.

    Attributes:
        links: link -> (4, 4) placement in the base frame, for ``RobotScene.moving_links``.
        segments: (S, 2, 3) skeleton segments drawn (links without geometry).
        closures: (C, 2, 3) distance closures, from frame A to frame B.
        cuts: (P, 3) frame origins of the point, planar and weld closures (A and B of each).
        caption: one line naming the sample and its workspace coordinates.
    """

    links: Mapping[str, np.ndarray]
    segments: np.ndarray
    closures: np.ndarray
    cuts: np.ndarray
    caption: str


def robot_scene(model: Model, first: Configuration, geometry: bool = True) -> RobotScene:
    """The static picture of a model, laid out at its first configuration.

    Args:
        model: the model.
        first: the configuration of the first frame (rigid outlines are taken there).
        geometry: draw the URDF's visual/collision geometry where present (else every link is
            drawn as segments between its joint origins).

    Returns:
        The scene.
    """
    shapes, notes = _urdf_shapes(model) if geometry else ((), ())
    with_geometry = {s.link for s in shapes}
    group = rigid_groups(model)
    dressed = {group[link] for link in with_geometry}
    links, _ = placements(model, first)
    drawing = robot_drawing_3d(model, first)
    platform_group = group[model.frame]
    bodies = []
    for n, (P, link) in enumerate(zip(drawing.polygons, drawing.polygon_links, strict=True)):
        if not len(P):
            continue
        is_platform = group[link] == platform_group
        if group[link] in dressed and not is_platform:
            continue
        T = links[link]
        local = (P - T[:3, 3]) @ T[:3, :3]
        if is_platform:
            color = COLORS["platform"]
        else:
            color = (
                COLORS["base"]
                if n == 0 and group[link] == group[model.tree.root]
                else COLORS["body"]
            )
        bodies.append(Body(link, local, color, is_platform))
    skeleton = tuple(link not in with_geometry for link in drawing.segment_links)
    pts = [P for P in (*drawing.polygons, *drawing.segments, *drawing.closures) if len(P)]
    pts += [links[s.link][:3, 3][None] for s in shapes]
    P = np.vstack(pts) if pts else np.zeros((1, 3))
    lo, hi = P.min(axis=0), P.max(axis=0)
    size = float(np.max(hi - lo))
    if size <= 1e-12:
        size = max(model.length_scale, 1.0)
    return RobotScene(
        model.name, model.frame, tuple(shapes), tuple(bodies), skeleton, size,
        0.5 * (lo + hi), float(lo[2]), tuple(notes),
    )  # fmt: skip


def frame(model: Model, scene: RobotScene, cfg: Configuration, caption: str = "") -> Frame:
    """One animation sample of a configuration.

    Args:
        model: the model.
        scene: its scene (:func:`robot_scene`).
        cfg: the configuration.
        caption: text before the workspace coordinates.

    Returns:
        The frame.
    """
    links, _ = placements(model, cfg)
    drawing = robot_drawing_3d(model, cfg)
    segments = [S for S, drawn in zip(drawing.segments, scene.skeleton, strict=True) if drawn]
    closures: list[np.ndarray] = []
    cuts: list[np.ndarray] = []
    for S, kind in zip(drawing.closures, drawing.closure_types, strict=True):
        if kind == "distance":
            closures.append(S)
        else:
            cuts.extend(S)
    names = ", ".join(model.workspace)
    text = f"{caption}({names}) = {format_vector(cfg.x)[4:]}".strip()
    return Frame(
        MappingProxyType({name: links[name] for name in scene.moving_links}),
        np.array(segments, dtype=np.float64).reshape(-1, 2, 3),
        np.array(closures, dtype=np.float64).reshape(-1, 2, 3),
        np.array(cuts, dtype=np.float64).reshape(-1, 3),
        text,
    )


def configurations(
    model: Model, what=None, max_frames: int = 300
) -> tuple[tuple[Configuration, ...], tuple[str, ...]]:
    """The configurations to show, and a caption of each.

    Args:
        model: the model.
        what: ``None`` (the home configuration), a :class:`Configuration`, a
            :class:`SolveResult` (its recorded path up to the solution, else start and
            solution), a :class:`TrackResult` (every sample), or a sequence of configurations.
        max_frames: at most this many frames (long paths and tracks are subsampled evenly,
            the first and last kept).

    Returns:
        (configurations, captions).

    Raises:
        ViewError: ``what`` is none of these, or an empty sequence.
    """
    if max_frames < 1:
        raise ViewError(f"max_frames must be at least 1, got {max_frames}")
    if what is None:
        cfgs, captions = [model.home], ["home: "]
    elif isinstance(what, Configuration):
        cfgs, captions = [what], [""]
    elif isinstance(what, SolveResult):
        cfgs, captions = _solve_frames(model, what)
    elif isinstance(what, TrackResult):
        cfgs = [model.configuration(y, t) for y, t in zip(what.y, what.theta, strict=True)]
        captions = [f"sample {i}: " for i in range(len(cfgs))]
    elif isinstance(what, Sequence) and not isinstance(what, (str, bytes)):
        cfgs = list(what)
        bad = [type(c).__name__ for c in cfgs if not isinstance(c, Configuration)]
        if bad or not cfgs:
            got = f"a {bad[0]}" if bad else "an empty sequence"
            raise ViewError(f"nothing to show: expected Configurations, got {got}")
        captions = [f"{i}: " for i in range(len(cfgs))]
    else:
        raise ViewError(
            f"cannot show a {type(what).__name__}: give a Configuration, a SolveResult, a "
            "TrackResult or a sequence of Configurations"
        )
    if len(cfgs) > max_frames:
        keep = np.unique(np.round(np.linspace(0, len(cfgs) - 1, max_frames)).astype(int))
        cfgs, captions = [cfgs[i] for i in keep], [captions[i] for i in keep]
    return tuple(cfgs), tuple(captions)


def _solve_frames(model: Model, res: SolveResult) -> tuple[list, list]:
    """The recorded path of a solve up to its solution (first ``s = 1``), then the solution."""
    start = res.start
    if res.path is None:
        return [start, res.configuration], ["start: ", f"{res.branch} solution: "]
    s = np.asarray(res.path.s, dtype=float)
    hit = first_hit(s)
    last = len(s) if hit is None else hit[0] + 1
    step = res.theta - start.theta
    cfgs, captions = [], []
    for i in range(last):
        cfgs.append(model.configuration(res.path.y[i], start.theta + s[i] * step))
        captions.append(f"s = {s[i]:.4g}: ")
    cfgs.append(res.configuration)
    captions.append(f"{res.branch} solution: ")
    return cfgs, captions


# ---------------------------------------------------------------------------- URDF geometry


def _urdf_shapes(model: Model) -> tuple[list[Shape], list[str]]:
    """Visual (else collision) geometry of every link, and notes on what was not found."""
    yourdfpy = import_yourdfpy()
    robot = yourdfpy.URDF.load(
        io.StringIO(model.urdf_text),
        build_scene_graph=False,
        load_meshes=False,
        build_collision_scene_graph=False,
        load_collision_meshes=False,
    ).robot
    materials = {m.name: m for m in robot.materials if m.name}
    folder = Path(model.path).parent if model.path else None
    shapes: list[Shape] = []
    missing: dict[str, str] = {}
    for link in robot.links:
        problems: list[str] = []
        for source, elements in (("visual", link.visuals), ("collision", link.collisions)):
            found = []
            for el in elements:
                shape = _shape(link.name, el, source, materials, folder, problems)
                if shape is not None:
                    found.append(shape)
            if found:  # the visual geometry where there is some, else the collision one
                shapes.extend(found)
                break
        else:
            if problems:
                missing[link.name] = ", ".join(dict.fromkeys(problems))
    notes = []
    if missing:
        listed = "; ".join(f"{name}: {why}" for name, why in missing.items())
        notes.append(f"{len(missing)} link(s) drawn as segments, their mesh unusable ({listed})")
    return shapes, notes


def _shape(link: str, el, source: str, materials: dict, folder: Path | None, notes: list):
    g = el.geometry
    origin = np.eye(4) if el.origin is None else np.asarray(el.origin, dtype=float)
    color = COLORS["geometry"]
    material = getattr(el, "material", None)
    if material is not None:
        if material.color is None and material.name in materials:
            material = materials[material.name]
        if material.color is not None:
            rgba = np.clip(np.asarray(material.color.rgba, dtype=float)[:3], 0.0, 1.0)
            r, g_, b = (int(round(255 * c)) for c in rgba)
            color = (r, g_, b)
    if g is None:
        return None
    if g.box is not None:
        return Shape(link, "box", origin, np.asarray(g.box.size, float), None, None, color, source)
    if g.cylinder is not None:
        size = np.array([g.cylinder.radius, g.cylinder.length], dtype=float)
        return Shape(link, "cylinder", origin, size, None, None, color, source)
    if g.sphere is not None:
        size = np.array([g.sphere.radius], dtype=float)
        return Shape(link, "sphere", origin, size, None, None, color, source)
    if g.mesh is not None:
        scale = np.ones(3) if g.mesh.scale is None else np.broadcast_to(g.mesh.scale, 3)
        scale = np.asarray(scale, dtype=float)
        loaded = _load_mesh(g.mesh.filename, folder)
        if isinstance(loaded, str):
            notes.append(loaded)
            return None
        V, F = loaded
        return Shape(link, "mesh", origin, scale, V * scale, F, color, source)
    return None


def _load_mesh(filename: str, folder: Path | None):
    """(vertices, faces) of a mesh file beside the model, or why it cannot be had."""
    name = filename
    for prefix in ("package://", "file://"):
        if name.startswith(prefix):
            name = name[len(prefix) :]
    candidates = [Path(name)] if Path(name).is_absolute() else []
    if folder is not None:
        rel = name.lstrip("/")
        candidates += [folder / rel, folder / Path(rel).name]
    path = next((p for p in candidates if p.is_file()), None)
    if path is None:
        return f"{filename} not found beside the model"
    try:
        import trimesh

        mesh = trimesh.load(str(path), force="mesh")
        V = np.asarray(mesh.vertices, dtype=np.float64)  # type: ignore[attr-defined]
        F = np.asarray(mesh.faces, dtype=np.int64)  # type: ignore[attr-defined]
    except Exception as exc:  # trimesh raises assorted errors on unreadable files
        return f"{path} unreadable ({type(exc).__name__})"
    if not len(V) or not len(F):
        return f"{path} is empty"
    return V, F
