"""The robot as lines and polygons, without matplotlib: link and joint placements, the rigid
groups of links, and their outlines in the base x-y plane (:func:`robot_drawing`) or in 3-D
(:func:`robot_drawing_3d`). :mod:`scdk_sym.plot` and :mod:`scdk_sym.view` draw them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .model.rotations import rot_exp
from .results import Configuration
from .robot import Model


def placements(model: Model, cfg: Configuration) -> tuple[dict, dict]:
    """World placements of every link and of every joint frame (before its motion).

    Args:
        model: the model.
        cfg: a configuration (its ``joints`` give every joint value).

    Returns:
        (links, frames): link name -> (4, 4) placement in the base frame, joint name ->
        (4, 4) placement of the joint frame [model length unit].
    """
    values = dict(cfg.coordinates)
    links: dict[str, np.ndarray] = {model.tree.root: np.eye(4)}
    frames: dict[str, np.ndarray] = {}
    for j in model.tree.joints:
        F = links[j.parent] @ np.asarray(j.origin, dtype=float)
        frames[j.name] = F
        M = np.eye(4)
        if j.type == "floating":
            c = [values[n] for n in j.coordinates]
            M[:3, :3] = rot_exp(np.array(c[3:]))
            M[:3, 3] = c[:3]
        elif j.type == "prismatic":
            M[:3, 3] = np.asarray(j.axis) * values[j.name]
        elif j.type in ("revolute", "continuous"):
            M[:3, :3] = rot_exp(np.asarray(j.axis) * values[j.name])
        links[j.child] = F @ M
    return links, frames


def rigid_groups(model: Model) -> dict[str, int]:
    """Link -> index of its rigid body (links joined by fixed joints)."""
    parent = {link: link for link in model.tree.links}

    def find(a: str) -> str:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for j in model.tree.joints:
        if j.type == "fixed":
            parent[find(j.child)] = find(j.parent)
    roots = sorted({find(link) for link in model.tree.links})
    return {link: roots.index(find(link)) for link in model.tree.links}


@dataclass(frozen=True)
class RobotDrawing:
    """The robot of one configuration as flat bodies and segments, in the base frame.

    Attributes:
        polygons: (N, d) outlines of the rigid bodies with three or more points that span an
            area, the base first (empty (0, d) when the base is no such body) [model length
            unit].
        polygon_links: a link of each polygon's body ('' for an empty base).
        segments: (2, d) links drawn as a segment from where they are driven to where they
            drive (legs, arms, rods).
        segment_links: the link each segment belongs to.
        closures: (2, d) each loop closure's two frame origins (A, B): a distance closure's
            segment (a leg of fixed or actuated length), a point for the other types.
        closure_types: the type of each closure ("3d", "2d", "6d", "distance").
    """

    polygons: tuple[np.ndarray, ...]
    polygon_links: tuple[str, ...]
    segments: tuple[np.ndarray, ...]
    segment_links: tuple[str, ...]
    closures: tuple[np.ndarray, ...]
    closure_types: tuple[str, ...]


def robot_drawing(model: Model, cfg: Configuration) -> tuple[list, list]:
    """Polygons (rigid bodies with three or more points) and segments of a configuration.

    Returns:
        (polygons, segments): lists of (N, 2) and (2, 2) arrays of x-y points in the base
        frame [model length unit]; the first polygon is the base (empty if it is not one).
    """
    d = _drawing(model, cfg, 2)
    segments = list(d.segments)
    segments += [c for c, t in zip(d.closures, d.closure_types, strict=True) if t == "distance"]
    return list(d.polygons), segments


def robot_drawing_3d(model: Model, cfg: Configuration) -> RobotDrawing:
    """The robot of a configuration in 3-D: bodies outlined in their own plane, segments.

    A body whose points are not coplanar is outlined by the hull of their projection on the
    best-fitting plane.

    Args:
        model: the model.
        cfg: the configuration.

    Returns:
        The drawing, every array with 3 columns (x, y, z) [model length unit].
    """
    return _drawing(model, cfg, 3)


def _drawing(model: Model, cfg: Configuration, dims: int) -> RobotDrawing:
    """The drawing in the x-y plane (``dims`` 2) or in space (``dims`` 3)."""
    links, frames = placements(model, cfg)
    group = rigid_groups(model)
    points: dict[int, list[np.ndarray]] = {}
    members: dict[int, str] = {}
    for link, T in links.items():
        points.setdefault(group[link], []).append(T[:3, 3])
        members.setdefault(group[link], link)
    for j in model.tree.joints:  # joint frames belong to the body of their parent link
        points[group[j.parent]].append(frames[j.name][:3, 3])
    polygons, polygon_links, big = [], [], set()
    base = group[model.tree.root]
    tol = 1e-9 * max(1.0, model.length_scale) ** 2
    for g in sorted(points, key=lambda g: (g != base, g)):  # the base first
        outline = _outline(np.array(points[g]), dims, tol)
        if outline is not None:
            polygons.append(outline)
            polygon_links.append(members[g])
            big.add(g)
    if base not in big:
        polygons.insert(0, np.zeros((0, dims)))
        polygon_links.insert(0, "")
    segments, segment_links = [], []
    entry = {j.child: j for j in model.tree.joints}
    scale = 1e-12 * max(1.0, model.length_scale)
    for j in model.tree.joints:
        into = entry.get(j.parent)
        # a link is a segment from where it is driven to where it drives; links moved by a
        # prismatic or floating joint are displacements (slider chains, legs), not bodies
        if into is None or into.type in ("prismatic", "floating") or group[j.parent] in big:
            continue
        a = frames[into.name][:3, 3]
        b = links[j.child][:3, 3] if j.type == "fixed" else frames[j.name][:3, 3]
        if np.linalg.norm(a - b) > scale:
            segments.append(np.array([a[:dims], b[:dims]]))
            segment_links.append(j.parent)
    framed = [c for c in model.closures if c.type != "coupling"]  # couplings have no points
    closures = tuple(
        np.array([links[c.frame_a][:dims, 3], links[c.frame_b][:dims, 3]]) for c in framed
    )
    return RobotDrawing(
        tuple(polygons),
        tuple(polygon_links),
        tuple(segments),
        tuple(segment_links),
        closures,
        tuple(c.type for c in framed),
    )


def _outline(P: np.ndarray, dims: int, tol: float) -> np.ndarray | None:
    """The hull of a body's points (x-y or in their best plane), ``None`` below area ``tol``."""
    if dims == 2:
        Q = np.unique(np.round(P[:, :2], 12), axis=0)
        if len(Q) >= 3 and _area(Q) > tol:
            return _hull(Q)
        return None
    Q = np.unique(np.round(P, 12), axis=0)
    if len(Q) < 3:
        return None
    centre = Q.mean(axis=0)
    _, _, Vt = np.linalg.svd(Q - centre)
    flat = np.unique(np.round((Q - centre) @ Vt[:2].T, 12), axis=0)
    if len(flat) < 3 or _area(flat) <= tol:
        return None
    return centre + _hull(flat) @ Vt[:2]


def _area(P: np.ndarray) -> float:
    H = _hull(P)
    x, y = H[:, 0], H[:, 1]
    return 0.5 * abs(float(x @ np.roll(y, -1) - y @ np.roll(x, -1)))


def _hull(P: np.ndarray) -> np.ndarray:
    """Convex hull (monotone chain) of 2-D points, counter-clockwise."""
    pts = sorted(map(tuple, P))
    if len(pts) < 3:
        return np.array(pts)

    def half(seq):
        out: list = []
        for p in seq:
            while len(out) >= 2 and _cross(out[-2], out[-1], p) <= 0:
                out.pop()
            out.append(p)
        return out[:-1]

    return np.array(half(pts) + half(reversed(pts)))


def _cross(o, a, b) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


__all__ = ["RobotDrawing", "placements", "rigid_groups", "robot_drawing", "robot_drawing_3d"]
