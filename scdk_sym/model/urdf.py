"""URDF spanning trees: parsing (with yourdfpy) and writing.

The tree is reduced to what kinematics needs: for each joint its parent and child links,
its origin (4x4 homogeneous transform, parent link frame -> joint frame), its axis and type.
"""

from __future__ import annotations

import io
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from types import ModuleType
from typing import Any

import numpy as np

from ..errors import ModelError
from .rotations import rpy_from_matrix, rpy_matrix

#: Joint types that move (one coordinate each, six for a floating joint, three for a
#: spherical one).
MOVABLE_TYPES = ("revolute", "continuous", "prismatic", "floating", "spherical")
#: Joint types a URDF file may use (``spherical`` comes only from a Gepetto joint edit).
SUPPORTED_TYPES = ("revolute", "continuous", "prismatic", "floating", "fixed")
#: Joint types whose rotation is an unknown in a local chart (see :mod:`scdk_sym.model.chart`).
ROTATION_TYPES = ("floating", "spherical")
#: Coordinate suffixes of a floating joint: position, then local rotation parameters.
FLOATING_COORDS = ("x", "y", "z", "rx", "ry", "rz")
#: Coordinate suffixes of a spherical (ball) joint: its rotation vector.
SPHERICAL_COORDS = ("rx", "ry", "rz")


@dataclass(frozen=True)
class Joint:
    """One URDF joint.

    Attributes:
        name: joint name.
        type: "revolute", "continuous", "prismatic", "fixed", "floating" or "spherical".
        parent: parent link name.
        child: child link name.
        origin: (4, 4) transform from the parent link frame to the joint frame [m].
        axis: (3,) unit axis in the joint frame.
        lower: lower limit [rad or m] (``-inf`` when absent).
        upper: upper limit [rad or m] (``+inf`` when absent).
    """

    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray
    axis: np.ndarray
    lower: float = -math.inf
    upper: float = math.inf

    @property
    def movable(self) -> bool:
        return self.type in MOVABLE_TYPES

    @property
    def coordinates(self) -> tuple[str, ...]:
        """Coordinate names: the joint name, ``name.x ... name.rz`` for a floating joint,
        ``name.rx, name.ry, name.rz`` for a spherical one."""
        if self.type == "floating":
            return tuple(f"{self.name}.{c}" for c in FLOATING_COORDS)
        if self.type == "spherical":
            return tuple(f"{self.name}.{c}" for c in SPHERICAL_COORDS)
        return (self.name,) if self.movable else ()


@dataclass(frozen=True)
class Tree:
    """A URDF kinematic tree.

    Attributes:
        name: robot name.
        root: the root link.
        links: every link name, root first, parents before children.
        joints: every joint, parents before children.
    """

    name: str
    root: str
    links: tuple[str, ...]
    joints: tuple[Joint, ...]

    @property
    def movable_joints(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints if j.movable)

    @property
    def coordinates(self) -> tuple[str, ...]:
        """Every joint coordinate name, parents first (floating joints give six)."""
        return tuple(c for j in self.joints for c in j.coordinates)

    @property
    def floating_joints(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints if j.type == "floating")

    @property
    def rotation_joints(self) -> tuple[str, ...]:
        """Floating and spherical joints: their rotations are unknowns in local charts."""
        return tuple(j.name for j in self.joints if j.type in ROTATION_TYPES)

    @property
    def single_coordinate_joints(self) -> tuple[str, ...]:
        """Movable joints with one coordinate (those that can be actuated)."""
        return tuple(j.name for j in self.joints if j.movable and j.type not in ROTATION_TYPES)

    def joint(self, name: str) -> Joint:
        for j in self.joints:
            if j.name == name:
                return j
        from ..errors import UnknownNameError

        raise UnknownNameError("joint", name, [j.name for j in self.joints])

    def parent_joint(self, link: str) -> Joint | None:
        for j in self.joints:
            if j.child == link:
                return j
        return None

    def path(self, link: str) -> list[Joint]:
        """The joints from the root to ``link``, root first."""
        out = []
        j = self.parent_joint(link)
        while j is not None:
            out.append(j)
            j = self.parent_joint(j.parent)
        return out[::-1]

    def subtree(self, link: str) -> set[str]:
        """``link`` and every link it carries."""
        out = {link}
        for j in self.joints:  # parents before children
            if j.parent in out:
                out.add(j.child)
        return out


def _check_structure(text: str, path: str | None) -> None:
    """Refuse text that is not a URDF document before yourdfpy reads it: empty, not XML, not a
    ``<robot>``, or joints without their name, type, parent or child."""
    import xml.etree.ElementTree as ET

    if not text.strip():
        raise ModelError("malformed URDF: the file is empty; expected a <robot> XML document", path)
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise ModelError(
            f"malformed URDF: not valid XML ({exc}); expected a <robot> XML document", path
        ) from exc
    if root.tag != "robot":
        raise ModelError(f"root element is <{root.tag}>, expected <robot> (URDF)", path)
    if not root.get("name"):
        raise ModelError('<robot> has no name attribute: write <robot name="...">', path)
    for i, link in enumerate(root.findall("link")):
        if not link.get("name"):
            raise ModelError(f"<link> number {i + 1} has no name attribute", path)
    for i, joint in enumerate(root.findall("joint")):
        name = joint.get("name")
        if not name:
            raise ModelError(f"<joint> number {i + 1} has no name attribute", path)
        if not joint.get("type"):
            raise ModelError(
                f"joint {name!r} has no type attribute; types: {', '.join(SUPPORTED_TYPES)}", path
            )
        for end in ("parent", "child"):
            element = joint.find(end)
            if element is None or not element.get("link"):
                raise ModelError(
                    f'joint {name!r} has no <{end} link="..."/>: every joint needs a parent '
                    "and a child link",
                    path,
                )


def parse_urdf(text: str, path: str | None = None) -> Tree:
    """Parse URDF text into a :class:`Tree`.

    Args:
        text: the URDF XML.
        path: file name used in error messages.

    Raises:
        ModelError: malformed XML, unsupported joint types, or not a tree.
    """
    _check_structure(text, path)
    robot = _load(text, path)
    links = [lk.name for lk in robot.links]
    if not links:
        raise ModelError("URDF has no links", path)
    if len(set(links)) != len(links):
        raise ModelError("URDF has duplicate link names", path)
    joints = [_joint(j, links, path) for j in robot.joints]
    root, order_links, order_joints = _tree_order(links, joints, path)
    return Tree(robot.name, root, order_links, order_joints)


def import_yourdfpy() -> ModuleType:
    """``yourdfpy``, imported without loading trimesh's mesh machinery until it is used.

    yourdfpy imports trimesh at its own import (about 1 s, most of a cold model load) for
    meshes and scenes that parsing a URDF never builds. While yourdfpy is imported for the
    first time, ``trimesh`` is a stand-in package: its submodules load from the real one
    (yourdfpy's ``trimesh.transformations``), the names yourdfpy's annotations read are
    placeholders, and any later use (a mesh, a scene) imports the real trimesh and reads
    from it. Where trimesh or yourdfpy is already imported, this is a plain import.
    """
    import importlib
    import importlib.util
    import logging
    import sys

    if "yourdfpy" in sys.modules or "trimesh" in sys.modules:
        import yourdfpy
    else:
        spec = importlib.util.find_spec("trimesh")
        stand_in = _TrimeshStandIn("trimesh")
        stand_in.__path__ = list(spec.submodule_search_locations or ()) if spec else []
        sys.modules["trimesh"] = stand_in
        try:
            import yourdfpy
        finally:
            if sys.modules.get("trimesh") is stand_in:
                del sys.modules["trimesh"]
    logging.getLogger("yourdfpy").setLevel(logging.ERROR)
    return yourdfpy


class _TrimeshStandIn(ModuleType):
    """``trimesh`` while yourdfpy imports (see :func:`import_yourdfpy`)."""

    def __getattr__(self, name: str) -> Any:
        import importlib
        import sys

        if name.startswith("__"):
            raise AttributeError(name)
        if sys.modules.get("trimesh") is self:  # yourdfpy's annotations, at its import
            return type(name, (), {"__module__": "trimesh"})
        return getattr(importlib.import_module("trimesh"), name)


def _load(text: str, path: str | None):
    """The URDF's robot as yourdfpy reads it (no meshes, no scene graph)."""
    yourdfpy = import_yourdfpy()
    try:
        urdf = yourdfpy.URDF.load(
            io.StringIO(text),
            build_scene_graph=False,
            load_meshes=False,
            build_collision_scene_graph=False,
            load_collision_meshes=False,
        )
    except Exception as exc:  # yourdfpy raises lxml and assorted errors
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ModelError(f"malformed URDF: {msg}", path) from exc
    return urdf.robot


def _joint(j, links: list[str], path: str | None) -> Joint:
    """One yourdfpy joint, checked: a supported type, known links, a unit axis, a finite
    origin; limits of 0 and 0 (unspecified in many exports) read as none."""
    if j.type not in SUPPORTED_TYPES:
        raise ModelError(
            f"joint {j.name!r} has unsupported type {j.type!r}; "
            f"supported: {', '.join(SUPPORTED_TYPES)}",
            path,
        )
    for end in (j.parent, j.child):
        if end not in links:
            raise ModelError(f"joint {j.name!r} refers to unknown link {end!r}", path)
    origin = np.eye(4) if j.origin is None else np.asarray(j.origin, dtype=float)
    axis = np.array([1.0, 0.0, 0.0]) if j.axis is None else np.asarray(j.axis, float)
    if j.type not in ("fixed", "floating"):
        norm = float(np.linalg.norm(axis))
        if not np.isfinite(norm) or norm < 1e-12:
            raise ModelError(f"joint {j.name!r} has a zero axis", path)
        axis = axis / norm
    lower, upper = -math.inf, math.inf
    if j.type in ("revolute", "prismatic") and j.limit is not None:
        if j.limit.lower is not None:
            lower = float(j.limit.lower)
        if j.limit.upper is not None:
            upper = float(j.limit.upper)
        if lower == 0.0 and upper == 0.0:  # unspecified limits in many exports
            lower, upper = -math.inf, math.inf
    if not np.all(np.isfinite(origin)):
        raise ModelError(f"joint {j.name!r} has a non-finite origin", path)
    return Joint(j.name, j.type, j.parent, j.child, origin, axis, lower, upper)


def _tree_order(
    links: list[str], joints: list[Joint], path: str | None
) -> tuple[str, tuple[str, ...], tuple[Joint, ...]]:
    """The root, and the links and joints ordered parents before children (breadth first);
    refuses duplicate joints, a link with two parents, several roots or a disconnected tree."""
    names = [j.name for j in joints]
    if len(set(names)) != len(names):
        raise ModelError("URDF has duplicate joint names", path)
    children = [j.child for j in joints]
    if len(set(children)) != len(children):
        dup = sorted({c for c in children if children.count(c) > 1})
        raise ModelError(f"links with more than one parent joint: {', '.join(dup)}", path)
    roots = [lk for lk in links if lk not in children]
    if len(roots) != 1:
        raise ModelError(f"URDF must have exactly one root link, found {roots}", path)
    order_links = [roots[0]]
    order_joints: list[Joint] = []
    frontier = [roots[0]]
    while frontier:
        link = frontier.pop(0)
        for j in joints:
            if j.parent == link:
                order_joints.append(j)
                order_links.append(j.child)
                frontier.append(j.child)
    if len(order_links) != len(links):
        raise ModelError("URDF is not a connected tree", path)
    return roots[0], tuple(order_links), tuple(order_joints)


# ---------------------------------------------------------------------------- writing


def _fmt(values: Iterable[float]) -> str:
    return " ".join(repr(float(v)) for v in values)


def tree_to_urdf(tree: Tree) -> str:
    """Write a :class:`Tree` as URDF text (links without inertia or geometry)."""
    out = [f'<robot name="{tree.name}">']
    for link in tree.links:
        out.append(f'  <link name="{link}"/>')
    for j in tree.joints:
        xyz = j.origin[:3, 3]
        rpy = rpy_from_matrix(j.origin[:3, :3])
        out.append(f'  <joint name="{j.name}" type="{j.type}">')
        out.append(f'    <parent link="{j.parent}"/>')
        out.append(f'    <child link="{j.child}"/>')
        out.append(f'    <origin xyz="{_fmt(xyz)}" rpy="{_fmt(rpy)}"/>')
        if j.type not in ("fixed", "floating"):
            out.append(f'    <axis xyz="{_fmt(j.axis)}"/>')
        if j.type in ("revolute", "prismatic"):
            lo = -1e6 if not math.isfinite(j.lower) else j.lower
            hi = 1e6 if not math.isfinite(j.upper) else j.upper
            out.append(f'    <limit lower="{lo!r}" upper="{hi!r}" effort="0" velocity="0"/>')
        out.append("  </joint>")
    out.append("</robot>")
    return "\n".join(out) + "\n"


def slides_along_carrier(tree: Tree, names: Sequence[str]) -> tuple[tuple[str, str], ...]:
    """The prismatic joints among ``names`` that slide along the axis of a lone revolute
    joint carrying them (the one whose child link is their parent link, not the last of
    revolutes about one point, as a ball written as three): ``(prismatic, revolute)`` pairs.

    Such a slide only moves the actuator's rod along its hinge axis, whatever the actuator's
    length; in a loop meant to be driven by a linear actuator it is an export defect (the
    slide axis written in the wrong frame). Named in the error of a failed assembly.
    """
    carrier = {j.child: j for j in tree.joints}
    pairs = []
    for j in tree.joints:
        if j.name not in names or j.type != "prismatic":
            continue
        r = carrier.get(j.parent)
        if r is None or r.type not in ("revolute", "continuous"):
            continue
        before = carrier.get(r.parent)
        at_before = float(np.linalg.norm(np.asarray(r.origin, dtype=float)[:3, 3])) < 1e-9
        if at_before and before is not None and before.type in ("revolute", "continuous"):
            continue  # the last revolute of a ball or universal joint: its axis turns
        slide = np.asarray(j.origin, dtype=float)[:3, :3] @ j.axis  # in r's child frame
        if float(np.linalg.norm(np.cross(slide, r.axis))) < 1e-6:
            pairs.append((j.name, r.name))
    return tuple(pairs)


class TreeBuilder:
    """Small helper to assemble a :class:`Tree` programmatically (used by the builders)."""

    def __init__(self, name: str, root: str = "base") -> None:
        self.name = name
        self.links: list[str] = [root]
        self.joints: list[Joint] = []

    def add(
        self,
        name: str,
        type: str,
        parent: str,
        child: str,
        xyz: Sequence[float] = (0.0, 0.0, 0.0),
        rpy: Sequence[float] = (0.0, 0.0, 0.0),
        axis: Sequence[float] = (0.0, 0.0, 1.0),
        limits: tuple[float, float] | None = None,
    ) -> TreeBuilder:
        origin = np.eye(4)
        origin[:3, :3] = rpy_matrix(*rpy)
        origin[:3, 3] = xyz
        lo, hi = limits if limits is not None else (-math.inf, math.inf)
        ax = np.asarray(axis, float)
        self.joints.append(
            Joint(name, type, parent, child, origin, ax / np.linalg.norm(ax), lo, hi)
        )
        self.links.append(child)
        return self

    def build(self) -> Tree:
        return parse_urdf(
            tree_to_urdf(Tree(self.name, self.links[0], tuple(self.links), tuple(self.joints)))
        )
